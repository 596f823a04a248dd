"""The figure of a planned motion: the tip's coordinates and the inputs against time
(``TrajectoryPlan.plot``)."""

from __future__ import annotations

import numpy as np

from softcurve.figures.actuation import BOUND_STYLE, MM_PER_M
from softcurve.figures.drawing import panels
from softcurve.figures.shapes import input_label


def plan_figure(t, tip, u, actuator, marks=(), title: str | None = None, ax=None):
    """The planned tip (x, y, z) [mm] and the inputs held over each step, against time.

    Parameters
    ----------
    t : ndarray, shape (K + 1,)
        The plan's nodes [s].
    tip : ndarray, shape (K + 1, 3)
        The tip's position at the nodes [m].
    u : ndarray, shape (K, m)
        The inputs held over each step, in the actuator's unit (or the generalized
        forces' without one).
    actuator : Actuator or None
        Gives the inputs' name, unit and bounds (drawn dashed); None: generalized forces.
    marks : sequence of (float, ndarray (3,))
        Targets of the tip: a time [s] and a position [m], drawn as crosses.
    title : str, optional
        The figure's title.
    ax : None or sequence of matplotlib.axes.Axes, shape (2,)
        Where to draw; None draws a new figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    figure, (top, bottom) = panels(ax, 2, "the plan figure", figsize=(7.0, 5.6), sharex=True)
    for i, axis in enumerate("xyz"):
        line = top.plot(t, MM_PER_M * tip[:, i], lw=1.2, label=axis)[0]
        for when, where in marks:
            top.plot([when], [MM_PER_M * where[i]], "x", color=line.get_color(), ms=8)
    top.set_ylabel("tip [mm]")
    top.legend(fontsize="small", loc="best")
    top.grid(True, alpha=0.3)
    held = np.vstack([u, u[-1:]])
    label, factor = ("generalized forces", 1.0) if actuator is None else input_label(actuator)
    for i in range(u.shape[1]):
        bottom.step(t, factor * held[:, i], where="post", lw=1.0, label=str(i + 1))
    if actuator is not None:
        for k, value in enumerate(np.unique(np.concatenate([actuator.lower, actuator.upper]))):
            bottom.axhline(factor * value, **BOUND_STYLE, label="bounds" if k == 0 else None)
    bottom.set_xlabel("time t [s]")
    bottom.set_ylabel(label)
    bottom.legend(fontsize="small", loc="center left", bbox_to_anchor=(1.0, 0.5))
    bottom.grid(True, alpha=0.3)
    if title:
        figure.suptitle(title)
    return figure
