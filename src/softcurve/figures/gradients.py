"""The figure of a rollout's gradient: along the input samples against time, and the
parameters' largest relative sensitivities (``RolloutGradient.plot``)."""

from __future__ import annotations

import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.figures.drawing import panels
from softcurve.figures.shapes import input_label


def gradient_figure(t, inputs, relative, names, actuator, largest=10, title=None, ax=None):
    """The gradient along the input samples, held as they are, and the ``largest``
    relative sensitivities ``p_i d value / d p_i`` as bars.

    Parameters
    ----------
    t : ndarray, shape (T,)
        Output times [s].
    inputs : ndarray, shape (T, n_u) or None
        ``d value / d u_k`` [unit of the cost per unit of each input]; None: not computed.
    relative : ndarray, shape (n_p,) or None
        ``p_i d value / d p_i`` [unit of the cost]; None: not computed.
    names : sequence of str
        The parameters' names.
    actuator : Actuator or None
        Gives the inputs' name and unit; None: generalized forces.
    largest : int
        Bars drawn, the largest in magnitude, >= 1.
    title : str, optional
        The figure's title.
    ax : None or sequence of matplotlib.axes.Axes, shape (2,)
        Where to draw; None draws a new figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    if not (isinstance(largest, int | np.integer) and largest >= 1):
        raise ParameterError(f"largest must be an integer >= 1, got {largest!r}")
    figure, (top, bottom) = panels(ax, 2, "the gradient figure", figsize=(7.0, 6.0))
    label, factor = ("generalized forces", 1.0) if actuator is None else input_label(actuator)
    if inputs is not None:
        for i in range(inputs.shape[1]):
            top.step(t, inputs[:, i] / factor, where="post", lw=1.0, label=str(i + 1))
        top.legend(fontsize="small", loc="best")
    top.set_xlabel("time t [s]")
    top.set_ylabel(f"d cost / d input [per {label.split('[')[-1]}" if "[" in label
                   else "d cost / d input [per unit]")  # fmt: skip
    top.grid(True, alpha=0.3)
    if relative is not None:
        order = np.argsort(-np.abs(relative))[: int(largest)][::-1]
        bottom.barh(np.arange(order.size), relative[order], color="tab:blue")
        bottom.set_yticks(np.arange(order.size), [names[k] for k in order], fontsize="small")
    bottom.axvline(0.0, color="0.3", lw=0.8)
    bottom.set_xlabel("p_i d cost / d p_i [unit of the cost]")
    bottom.grid(True, axis="x", alpha=0.3)
    if title:
        figure.suptitle(title)
    return figure
