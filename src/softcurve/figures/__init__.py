"""Every Matplotlib figure of softcurve, as functions of the results they draw.

The results' ``.plot(ax=None)`` methods call these and return the
:class:`matplotlib.figure.Figure`. This layer sits below the results, so the functions
read them duck-typed. New figures are made with :mod:`matplotlib.pyplot`, so a script
shows them with ``plt.show()``; nothing here changes Matplotlib's backend (the
``softcurve`` command chooses a non-interactive one itself). :func:`save_figure` writes
a figure whole or not at all.
"""

from softcurve.figures.actuation import plot_backbones, plot_inputs
from softcurve.figures.drawing import save_figure
from softcurve.figures.fits import plot_fit
from softcurve.figures.obstacles import draw_obstacles, plot_contact_forces
from softcurve.figures.shapes import (
    plot_configuration,
    plot_eigenvalues,
    plot_input_bounds,
    plot_member_tips,
)
from softcurve.figures.statics import plot_equilibria, plot_input_sweep
from softcurve.figures.sweeps import plot_sweep
from softcurve.figures.trajectories import animate, plot_batch_tips, plot_states, plot_tip

__all__ = [
    "animate",
    "draw_obstacles",
    "plot_backbones",
    "plot_batch_tips",
    "plot_configuration",
    "plot_contact_forces",
    "plot_eigenvalues",
    "plot_equilibria",
    "plot_fit",
    "plot_input_bounds",
    "plot_input_sweep",
    "plot_inputs",
    "plot_member_tips",
    "plot_states",
    "plot_sweep",
    "plot_tip",
    "save_figure",
]
