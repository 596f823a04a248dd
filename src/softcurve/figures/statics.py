"""Figures of static analyses: the backbones of equilibria, and a pressure sweep."""

from __future__ import annotations

import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.figures.drawing import chain_lines, draw_rigid_body, panels

BACKBONE_POINTS = 40
STABILITY_STYLES = {"stable": "-", "unstable": "--", "saddle": ":", "degenerate": "-."}
DISPLAY_UNITS = {"Pa": ("kPa", 1e-3)}
"""Input units drawn in another unit: ``{unit: (display unit, factor to it)}``."""
MM_PER_M = 1e3


def plot_equilibria(table, ax=None):
    """The backbone of every equilibrium in the x-z plane [mm], styled by stability (a ring
    of equilibria is drawn by its representative); rigid bodies as dark grey bars.

    Parameters
    ----------
    table : softcurve.analysis.statics.EquilibriumTable
        Read: ``equilibria`` (each with ``q`` shape (n,), ``stability``, ``continuum``)
        and ``load.model``.
    ax : None or matplotlib.axes.Axes, shape (1,)
        Where to draw; None draws a new figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    figure, (ax,) = panels(ax, 1, "the equilibria figure", figsize=(5.0, 5.0))
    equilibria = tuple(table.equilibria)
    lines, rigid = chain_lines(table.load.model, [e.q for e in equilibria], BACKBONE_POINTS)
    for k, (e, shape) in enumerate(zip(equilibria, MM_PER_M * lines, strict=True)):
        label = f"#{k} {e.stability}" + (" ring" if e.continuum else "")
        ax.plot(shape[:, 0], shape[:, 2], STABILITY_STYLES.get(e.stability, "-"), label=label)
        for part in rigid:
            first = k == 0 and part is rigid[0]
            draw_rigid_body(ax, part, k, (0, 2), MM_PER_M, "rigid body" if first else None)
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("z [mm]")
    ax.set_aspect("equal")
    ax.grid(True, alpha=0.3)
    count = f"{len(equilibria)} equilibri{'um' if len(equilibria) == 1 else 'a'}"
    ax.set_title(f"{count}, seen along y")
    if equilibria:
        ax.legend(fontsize="small")
    return figure


def plot_input_sweep(sweep, ax=None, *, x=None, x_label: str | None = None):
    """Tip position and curvature along a sweep of actuator inputs; points that are not
    stable are marked.

    Parameters
    ----------
    sweep : softcurve.analysis.quasistatic.InputSweep
        Read: ``inputs`` shape (k, m) [its ``input_unit``, when it has one],
        ``tip`` shape (k, 3) [m], ``curvature`` shape (k, N) [1/m] and ``stability`` (k,).
    ax : None or sequence of matplotlib.axes.Axes, shape (2,)
        Panels for the tip position and the curvature; None draws a new figure.
    x : array_like, shape (k,), optional
        The abscissa (default: the input that varies most, pressures in kPa).
    x_label : str, optional
        Label of the abscissa, with its unit (default: the input's name, or none for a
        given ``x``).

    Returns
    -------
    matplotlib.figure.Figure
    """
    points = sweep.inputs.shape[0]
    if x is None:
        column = int(np.argmax(np.ptp(sweep.inputs, axis=0)))
        unit = getattr(sweep, "input_unit", "")  # sweeps that do not know it draw raw numbers
        unit, factor = DISPLAY_UNITS.get(unit, (unit, 1.0))
        x = sweep.inputs[:, column] * factor
        if x_label is None:
            x_label = f"u{column + 1}" + (f" [{unit}]" if unit else "")
    x_label = "" if x_label is None else x_label
    x = np.asarray(x, dtype=np.float64)
    if x.shape != (points,):
        raise ParameterError(f"x must have shape ({points},), one value a point, got {x.shape}")
    figure, (ax_tip, ax_k) = panels(ax, 2, "the input sweep figure", rows=1, figsize=(9.0, 3.5))
    for i, name in enumerate("xyz"):
        ax_tip.plot(x, MM_PER_M * sweep.tip[:, i], label=f"tip {name}")
    ax_tip.set_xlabel(x_label)
    ax_tip.set_ylabel("tip position [mm]")
    ax_tip.legend()
    curvature = sweep.curvature
    for j in range(curvature.shape[1]):
        ax_k.plot(x, curvature[:, j], label=f"segment {j}")
    unstable = np.array([s != "stable" for s in sweep.stability], dtype=bool)
    if unstable.any():
        ax_k.plot(x[unstable], curvature[unstable, 0], "rx", label="not stable")
    ax_k.set_xlabel(x_label)
    ax_k.set_ylabel("curvature |kappa| [1/m]")
    ax_k.legend()
    return figure
