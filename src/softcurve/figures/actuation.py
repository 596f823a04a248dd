"""Figures of actuated runs: the actuator's inputs against time with their bounds, and the
backbone at chosen times with a reference path."""

from __future__ import annotations

import numpy as np

from softcurve.base.validation import ParameterError, real_array
from softcurve.figures.drawing import chain_lines, draw_rigid_body, panels, whole_number
from softcurve.figures.shapes import VIEWS, draw_views, finish_views, input_label

MM_PER_M = 1e3
BOUND_STYLE = {"color": "0.35", "lw": 0.9, "ls": "--"}


def plot_inputs(trajectory, actuator, ax=None, *, labels=None):
    """The actuator's inputs against time, one line each, with their bounds drawn.

    The axis is labelled with the actuator's ``input_name`` and ``input_unit``
    (``"tensions [N]"``; pressures are drawn in kPa).

    Parameters
    ----------
    trajectory : softcurve.Trajectory
        Read: ``t`` shape (T,) [s] and ``inputs`` shape (T, m) [the actuator's
        ``input_unit``] (a run with ``actuator=``).
    actuator : Actuator
        Gives ``lower``, ``upper`` (drawn as dashed lines), ``input_name`` and
        ``input_unit``.
    ax : None or matplotlib.axes.Axes, shape (1,)
        Where to draw; None draws a new figure.
    labels : sequence of str, optional
        A legend entry per input (default ``1 .. m``).

    Returns
    -------
    matplotlib.figure.Figure
    """
    inputs = getattr(trajectory, "inputs", None)
    if inputs is None:
        raise ParameterError(
            "the trajectory holds no actuator inputs: simulate it with actuator= to draw them"
        )
    inputs = np.asarray(inputs, dtype=np.float64)
    m = actuator.n_inputs
    if inputs.ndim != 2 or inputs.shape[1] != m:
        raise ParameterError(
            f"the trajectory's inputs have shape {inputs.shape}, the actuator has {m} inputs"
        )
    labels = [str(i + 1) for i in range(m)] if labels is None else [str(a) for a in labels]
    if len(labels) != m:
        raise ParameterError(f"labels must name the {m} inputs, got {len(labels)}")
    label, factor = input_label(actuator)
    figure, (ax,) = panels(ax, 1, "the inputs figure", figsize=(7.0, 3.8))
    for i in range(m):
        ax.plot(trajectory.t, factor * inputs[:, i], lw=1.0, label=labels[i])
    bounds = np.unique(np.concatenate([actuator.lower, actuator.upper]))
    for k, value in enumerate(bounds):
        ax.axhline(factor * value, **BOUND_STYLE, label="bounds" if k == 0 else None)
    ax.set_xlabel("time t [s]")
    ax.set_ylabel(label)
    ax.legend(
        title=actuator.input_name,
        fontsize="small",
        ncol=max(1, (m + 1) // 4),
        loc="center left",
        bbox_to_anchor=(1.0, 0.5),
    )
    ax.grid(True, alpha=0.3)
    return figure


def plot_backbones(trajectory, times, ax=None, *, model=None, path=None, points: int = 40):
    """The backbone at chosen times, seen from the side (x-z) and from above (x-y), with
    a reference path of the tip; rigid bodies as dark grey bars.

    Parameters
    ----------
    trajectory : softcurve.Trajectory
        Read: ``t`` shape (T,) [s], ``q`` shape (T, n) [m, 1/m, 1/m] and ``model``; the
        output sample nearest each time is drawn.
    times : array_like, shape (k,)
        The times to draw [s].
    ax : None or sequence of matplotlib.axes.Axes, shape (2,)
        Panels for the side and the top view; None draws a new figure.
    model : softcurve.Model, optional
        Gives the backbone's shape (default ``trajectory.model``).
    path : array_like, shape (P, 3), optional
        A reference path of the tip [m], drawn dashed in both views.
    points : int, optional
        Points along each backbone [count].

    Returns
    -------
    matplotlib.figure.Figure
    """
    model = getattr(trajectory, "model", None) if model is None else model
    if model is None:
        raise ParameterError("the trajectory has no model attached: pass model=Model(robot)")
    points = whole_number("points", points, 2)
    times = np.atleast_1d(np.asarray(times, dtype=np.float64))
    if times.ndim != 1 or not np.all(np.isfinite(times)):
        raise ParameterError(f"times must be a finite 1-D array [s], got shape {times.shape}")
    if trajectory.t.size == 0:
        raise ParameterError("the trajectory has no samples: nothing to draw")
    index = np.abs(trajectory.t[None, :] - times[:, None]).argmin(axis=1)
    lines, rigid = chain_lines(model, trajectory.q[index], points)
    shapes = lines * MM_PER_M
    ends_rigid = rigid and rigid[-1].index == model.robot.n_segments - 1  # a gripper, say
    tips = MM_PER_M * (rigid[-1].backbone[:, -1] if ends_rigid else lines[:, -1])
    figure, views = panels(ax, 2, "the backbones figure", rows=1, figsize=(9.0, 4.2))
    colors = _colors(len(index))
    if path is not None:
        path = real_array("path", path, (np.asarray(path).shape[0], 3)) * MM_PER_M
        draw_views(views, path, "k--", lw=0.9, label="reference path")
    for c, (shape, k, color) in enumerate(zip(shapes, index, colors, strict=True)):
        draw_views(views, shape, color=color, lw=2.0, label=f"t = {trajectory.t[k]:.2f} s")
        for part in rigid:
            for ax, (_, plane) in zip(views, VIEWS, strict=True):
                first = c == 0 and part is rigid[0] and ax is views[0]
                draw_rigid_body(ax, part, c, plane, MM_PER_M, "rigid body" if first else None)
        draw_views(views, tips[c], "o", color=color, ms=4)
    finish_views(views)
    views[0].legend(fontsize="small", loc="lower right")
    return figure


def _colors(count: int) -> list:
    from matplotlib import colormaps  # on first use, like drawing.pyplot

    return [colormaps["viridis"](v) for v in np.linspace(0.0, 0.9, max(count, 1))][:count]
