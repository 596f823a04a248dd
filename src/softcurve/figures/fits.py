"""The figure of a fit: measured against fitted signals, residuals below."""

from __future__ import annotations

import numpy as np

from softcurve.figures.drawing import panels

PANEL_WIDTH, PANEL_HEIGHT = 5.0, 2.5
"""Size of one panel of a new figure [inch]."""


def plot_fit(report, ax=None, *, title: str | None = None):
    """Each fitted signal, measured against the model at the estimate, with its residuals
    below: one column of two panels per signal.

    Parameters
    ----------
    report : softcurve.FitReport
        Read: ``abscissa`` shape (T,), ``measured`` and ``predicted`` shape (T, k),
        ``residuals``, ``signals``, ``units`` and ``abscissa_label``.
    ax : None or sequence of matplotlib.axes.Axes, shape (2 k,) or (2, k)
        The k signal panels, then the k residual panels (row by row); None draws a new
        figure.
    title : str, optional
        Title of the figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    k = len(report.signals)
    figure, axes = panels(
        ax,
        2 * k,
        "the fit figure",
        rows=2,
        sharex="col",
        figsize=(PANEL_WIDTH * k, 2 * PANEL_HEIGHT),
    )
    order = np.argsort(report.abscissa, kind="stable")
    x = report.abscissa[order]
    style = "-" if report.abscissa_label.startswith("t [") else "."  # time series as lines
    for j, name in enumerate(report.signals):
        unit = report.units[j] if j < len(report.units) else ""
        top, bottom = axes[j], axes[k + j]
        top.plot(x, report.measured[order, j], "k" + style, ms=3, lw=1, label="measured")
        top.plot(x, report.predicted[order, j], "C1-", lw=1.5, label="model")
        top.set_ylabel(f"{name} [{unit}]" if unit else name)
        top.legend(loc="best", fontsize=8)
        bottom.plot(x, report.residuals[order, j], "C3" + style, ms=2, lw=1)
        bottom.axhline(0.0, color="0.5", lw=0.5)
        bottom.set_ylabel(f"model - measured [{unit}]" if unit else "model - measured")
        bottom.set_xlabel(report.abscissa_label)
    if title:
        figure.suptitle(title)
    return figure
