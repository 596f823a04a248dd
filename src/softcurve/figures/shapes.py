"""Figures of single results: the backbone at one configuration seen from the side and
from above with the points that matter (tip, target, a measurement), an actuator's inputs
against their bounds, the eigenvalues of a linearization in the complex plane, and the
tips of a batch's members after one step."""

from __future__ import annotations

import textwrap

import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.base.validation import ParameterError, real_array
from softcurve.figures.drawing import (
    backbones,
    draw_rigid_body,
    element_shapes,
    panels,
    whole_number,
)
from softcurve.figures.statics import BACKBONE_POINTS, DISPLAY_UNITS

MM_PER_M = 1e3
VIEWS = (("side view", (0, 2)), ("top view", (0, 1)))
"""The two views of a shape: their titles and the world coordinates drawn (x-z, x-y)."""
AXES = "xyz"
MARKERS = ("*", "P", "D", "v")
"""Markers of the named points of :func:`plot_configuration`, in the order given."""
RANGE_STYLE = {"color": "0.6", "lw": 6.0, "alpha": 0.5}
"""The admissible range of an input: a thick grey bar from its lower to its upper bound."""
STABLE_SHADE = {"color": "tab:green", "alpha": 0.08}
"""The stable half-plane ``Re(s) < 0`` of the eigenvalue figure."""
TITLE_WIDTH = 60
"""Characters per line of a title made of a result's message, wrapped to fit a panel."""
STRIPE_STYLE = {"color": "tab:orange", "lw": 1.0}
"""The stripe on a soft segment's surface (along its material x axis)."""
MARGIN = 0.15
"""The eigenvalue figure's limits reach this fraction of the eigenvalues' spread beyond
them, so the points sit inside the frame."""

RESULT_FIGURE_OPTIONS = {
    "model": (
        "Model",
        "The model the result was computed for; gives the backbone's shape.",
    ),
}
"""Options that the shape figures and the results' ``plot`` methods share
(:func:`softcurve.base.docs.parameters_from`); ``result_figure_options`` also writes their
Returns section, the figure drawn."""

result_figure_options = parameters_from(
    RESULT_FIGURE_OPTIONS,
    returns=("matplotlib.figure.Figure", "Write it with :func:`softcurve.figures.save_figure`."),
)


def draw_views(views, positions, *style, **options) -> None:
    """Draw world positions into the side (x-z) and top (x-y) views with ``Axes.plot``.

    Parameters
    ----------
    views : sequence of matplotlib.axes.Axes, shape (2,)
        The side and the top view.
    positions : array_like, shape (k, 3)
        The points, in the views' unit [mm].
    *style
        Matplotlib's format string (``"o"``, ``"k--"``), passed on.
    **options
        Keywords of ``Axes.plot`` (``color``, ``label``...), passed on.
    """
    positions = np.asarray(positions, dtype=np.float64).reshape(-1, 3)
    for ax, (_, (i, j)) in zip(views, VIEWS, strict=True):
        ax.plot(positions[:, i], positions[:, j], *style, **options)


def draw_robot(views, model, q, points: int) -> None:
    """Draw the robot at one configuration into the side and top views: each soft
    element's backbone with a stripe painted on its surface (it winds round a twisted
    segment), each rigid body as a bar of its diameter from its base to its tip in a
    colour of its own. A robot of constant-curvature segments alone, which cannot
    twist, is drawn as its backbone only.

    Parameters
    ----------
    views : sequence of matplotlib.axes.Axes, shape (2,)
        The side and the top view.
    model : softcurve.Model
        Gives the poses.
    q : array_like, shape (n,)
        The configuration.
    points : int
        Points along each element [count].
    """
    stripes = not model.robot.constant_curvature
    labelled: set[str] = set()

    def label(name: str) -> str | None:
        first = name not in labelled
        labelled.add(name)
        return name if first else None

    for part in element_shapes(model, q[None], points):
        backbone, stripe = MM_PER_M * part.backbone[0], MM_PER_M * part.stripe[0]
        if part.rigid:
            for ax, (_, plane) in zip(views, VIEWS, strict=True):
                draw_rigid_body(ax, part, 0, plane, MM_PER_M, label("rigid body"))
            continue
        draw_views(views, backbone, color="C0", lw=2.0, label=label("backbone"))
        if stripes:
            draw_views(views, stripe, **STRIPE_STYLE, label=label("stripe (twist)"))


def finish_views(views) -> None:
    """Titles, axis labels [mm], equal scales and a grid of the side and top views.

    Parameters
    ----------
    views : sequence of matplotlib.axes.Axes, shape (2,)
        The side and the top view.
    """
    for ax, (title, (i, j)) in zip(views, VIEWS, strict=True):
        ax.set(xlabel=f"{AXES[i]} [mm]", ylabel=f"{AXES[j]} [mm]", title=title)
        ax.set_aspect("equal", adjustable="datalim")  # true shapes, panels filled
        ax.grid(True, alpha=0.3)


def input_label(actuator) -> tuple[str, float]:
    """The axis label of an actuator's inputs with their unit, and the factor to it.

    Parameters
    ----------
    actuator : Actuator
        Gives ``input_name`` and ``input_unit`` (pressures are drawn in kPa).

    Returns
    -------
    label : str
        E.g. ``"tensions [N]"``.
    factor : float
        Multiplies an input in the actuator's unit into the label's unit [-].
    """
    unit, factor = DISPLAY_UNITS.get(actuator.input_unit, (actuator.input_unit, 1.0))
    return (f"{actuator.input_name} [{unit}]" if unit else actuator.input_name), factor


def plot_input_bounds(inputs, actuator, ax=None, *, saturated=None, title: str | None = None):
    """The actuator's inputs against their bounds: one grey bar per input from its lower
    to its upper bound, the input a dot on it, those at a bound crossed in red.

    Parameters
    ----------
    inputs : array_like, shape (m,)
        The inputs [the actuator's ``input_unit``; pressures drawn in kPa].
    actuator : Actuator
        Gives ``lower``, ``upper``, ``input_name`` and ``input_unit``.
    ax : None or matplotlib.axes.Axes, shape (1,)
        Where to draw; None draws a new figure.
    saturated : array_like of bool, shape (m,), optional
        The inputs to mark as at a bound (default: none marked).
    title : str, optional
        The panel's title.

    Returns
    -------
    matplotlib.figure.Figure
    """
    m = actuator.n_inputs
    inputs = real_array("inputs", inputs, (m,))
    marked = np.zeros(m, dtype=bool) if saturated is None else np.asarray(saturated, dtype=bool)
    if marked.shape != (m,):
        raise ParameterError(f"saturated must have shape ({m},), got {marked.shape}")
    figure, (ax,) = panels(ax, 1, "the inputs figure", figsize=(max(4.0, 0.6 * m + 2.0), 3.8))
    label, factor = input_label(actuator)
    index = np.arange(1, m + 1)
    ax.vlines(
        index, factor * actuator.lower, factor * actuator.upper, **RANGE_STYLE, label="bounds"
    )
    ax.plot(index, factor * inputs, "o", color="C0", label=actuator.input_name)
    if marked.any():
        ax.plot(
            index[marked], factor * inputs[marked], "x", color="tab:red", ms=10, label="at a bound"
        )
    ax.set(xlabel="input [index]", ylabel=label, xticks=index, xlim=(0.4, m + 0.6))
    ax.grid(True, axis="y", alpha=0.3)
    ax.legend(fontsize="small")
    if title:
        ax.set_title(_wrapped(title), fontsize="small")
    return figure


@result_figure_options
def plot_configuration(
    model,
    q,
    ax=None,
    *,
    marks=None,
    actuator=None,
    inputs=None,
    saturated=None,
    title: str | None = None,
    points: int = BACKBONE_POINTS,
):
    """The backbone at one configuration, seen from the side (x-z) and from above (x-y),
    its tip and the given points marked; with ``inputs``, a third panel of the inputs
    against their bounds (:func:`plot_input_bounds`).

    Parameters
    ----------
    %(model)s
    q : array_like, shape (n,)
        The configuration [m, 1/m, 1/m per segment].
    ax : None or sequence of matplotlib.axes.Axes, shape (2,) or (3,)
        Panels for the side view, the top view and, with ``inputs``, the inputs; None
        draws a new figure.
    marks : dict of str to array_like, shape (3,), optional
        Named world points to mark, e.g. ``{"target": target}`` [m].
    actuator : Actuator, optional
        The actuator of ``inputs`` (its bounds, name and unit); given with ``inputs``.
    inputs : array_like, shape (m,), optional
        The actuator's inputs at this configuration [its ``input_unit``].
    saturated : array_like of bool, shape (m,), optional
        The inputs to mark as at a bound.
    title : str, optional
        The figure's title (a new figure only: given Axes keep their figure's).
    points : int, optional
        Points along the backbone [count].

    """
    if (actuator is None) != (inputs is None):
        raise ParameterError("the inputs figure needs both actuator= and inputs=, or neither")
    points = whole_number("points", points, 2)
    q = real_array("q", q, (model.n,))
    marks = {} if marks is None else dict(marks)
    if len(marks) > len(MARKERS):
        raise ParameterError(f"at most {len(MARKERS)} marks can be drawn, got {len(marks)}")
    count = 2 if inputs is None else 3
    figure, axes = panels(ax, count, "the shape figure", rows=1, figsize=(4.2 * count, 4.2))
    shape = MM_PER_M * backbones(model, q, points)[0]
    views = axes[:2]
    draw_robot(views, model, q, points)
    draw_views(views, shape[:1], "s", color="0.3", ms=5, label="base")
    draw_views(views, shape[-1:], "o", color="C0", ms=6, label="tip")
    for (name, point), marker in zip(marks.items(), MARKERS, strict=False):
        point = MM_PER_M * real_array(f"mark {name!r}", point, (3,))
        draw_views(views, point, marker, ms=10, color="tab:red", ls="none", label=name)
    finish_views(views)
    views[0].legend(fontsize="small")
    if inputs is not None:
        plot_input_bounds(inputs, actuator, axes[2], saturated=saturated, title="inputs")
    if title and ax is None:
        figure.suptitle(title)
    return figure


def plot_eigenvalues(linearization, ax=None):
    """The eigenvalues of ``A`` in the complex plane, the stable half-plane ``Re(s) < 0``
    shaded; eigenvalues with ``Re(s) >= 0`` are drawn in red.

    Parameters
    ----------
    linearization : softcurve.Linearization
        Read: ``eigenvalues`` shape (n_state,), complex [1/s] (NaN where the
        derivatives were not finite: nothing drawn), ``message``.
    ax : None or matplotlib.axes.Axes, shape (1,)
        Where to draw; None draws a new figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    s = np.asarray(linearization.eigenvalues, dtype=np.complex128)
    figure, (ax,) = panels(ax, 1, "the eigenvalue figure", figsize=(6.0, 4.5))
    finite = s[np.isfinite(s)]
    unstable = finite.real >= 0
    ax.plot(
        finite.real[~unstable], finite.imag[~unstable], "x", color="C0", ms=8, label="eigenvalues"
    )
    if unstable.any():
        ax.plot(
            finite.real[unstable],
            finite.imag[unstable],
            "x",
            color="tab:red",
            ms=8,
            label="Re(s) >= 0",
        )
    re = np.append(finite.real, 0.0)  # the imaginary axis is always in view
    im = np.append(finite.imag, 0.0)
    spread = max(float(np.ptp(re)), float(np.ptp(im)), 1.0)
    left, right = re.min() - MARGIN * spread, re.max() + MARGIN * spread
    ax.axvspan(left, 0.0, **STABLE_SHADE, label="stable: Re(s) < 0")
    ax.axvline(0.0, color="0.3", lw=0.8)
    ax.axhline(0.0, color="0.3", lw=0.8)
    ax.set(
        xlim=(left, right),
        ylim=(im.min() - MARGIN * spread, im.max() + MARGIN * spread),
        xlabel="real part Re(s) [1/s]",
        ylabel="imaginary part Im(s) [rad/s]",
    )
    ax.set_title(_wrapped(linearization.message), fontsize="small")
    ax.grid(True, alpha=0.3)
    ax.legend(fontsize="small", loc="upper left")
    return figure


def plot_member_tips(step, ax=None):
    """The tip of every member at the end of one period, seen from the side (x-z) and
    from above (x-y); members that failed (at their kept state) drawn as red crosses.

    Parameters
    ----------
    step : softcurve.simulation.stepper.StepResult
        Read: ``tip`` shape (N, 3) [m], ``ok`` shape (N,) and ``message``.
    ax : None or sequence of matplotlib.axes.Axes, shape (2,)
        Panels for the side and the top view; None draws a new figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    tip, ok = MM_PER_M * np.asarray(step.tip, dtype=np.float64), np.asarray(step.ok, dtype=bool)
    figure, views = panels(ax, 2, "the member tips figure", rows=1, figsize=(8.4, 4.2))
    draw_views(views, tip[ok], "o", color="C0", ms=4, label=f"advanced ({int(ok.sum())})")
    if not ok.all():
        draw_views(
            views, tip[~ok], "x", color="tab:red", ms=8, label=f"failed ({int((~ok).sum())})"
        )
    finish_views(views)
    views[0].legend(fontsize="small")
    views[0].set_title(_wrapped(f"side view: {step.message}"), fontsize="small")
    return figure


def _wrapped(text: str) -> str:
    return "\n".join(textwrap.wrap(text, TITLE_WIDTH))
