"""Figures of trajectories: the states (paper Fig. 4), the tip path (Fig. 5), the tips
of a batch, and an animation of the backbone."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.base.files import atomic_path
from softcurve.base.validation import ParameterError, real_scalar
from softcurve.figures.drawing import backbones, panels, whole_number
from softcurve.figures.obstacles import draw_obstacles
from softcurve.figures.scales import NOISE, equal_limits, negligible, time_window

MM_PER_M = 1e3
STATE_LABELS = ("length l [m]", r"curvature $\kappa_x$ [1/m]", r"curvature $\kappa_y$ [1/m]")
"""Per segment, the coordinates are ``(l, kx, ky)``: one panel each."""
ANIMATION_SUFFIXES = (".gif", ".mp4")
MARGIN = 1.1
"""Axis limits of the animation: the space the backbone sweeps, 10 % wider."""
MINIMUM_REACH = 0.1
"""Half-width of the animation's x-y axes at least, over the rest length: a robot that
stays straight is still drawn in a box, not on a line."""


FIGURE_OPTIONS = {
    "fps": ("float, optional", "Frames per second of the file [1/s]."),
    "speed": ("float, optional", "Simulated time per time of animation [s/s]."),
    "points": ("int, optional", "Points along the backbone [count]."),
    "dpi": ("float, optional", "Resolution of the frames [dots per inch]."),
    "figsize": (
        "tuple of float, optional",
        "``(width, height)`` of the frames [inches]; pixels are ``figsize * dpi``.",
    ),
    "window": (
        "'auto', 'all' or tuple of float, optional",
        "The time range shown [s]: ``'auto'`` follows the motion (from the start to a "
        "quarter past the time the states settle), ``'all'`` the whole record, or "
        "``(start, end)``.",
    ),
    "ax": (
        "None or sequence of matplotlib.axes.Axes, shape (3,)",
        "Panels for tip x, y and z; None draws a new figure.",
    ),
    "members": ("int, optional", "How many members to draw (the first ones) [count]."),
}
"""Options of the animation and the batch figure (``ax``: its panels), documented once for
the figure functions and the result methods that call them
(:func:`softcurve.base.docs.parameters_from`); ``animation_options`` also writes the
Returns section of the animations, the file written."""

figure_options = parameters_from(FIGURE_OPTIONS)
animation_options = parameters_from(FIGURE_OPTIONS, returns=("pathlib.Path", "``path``."))


@figure_options
def plot_states(trajectory, ax=None, *, window="auto"):
    """``l``, ``kx`` and ``ky`` of every segment against time, one panel each (Fig. 4).

    A curvature that stays below ``NOISE`` (1e-9) over the segment's length is round-off
    of an exact zero (a planar run) and is drawn as zero, as its axis label says.

    Parameters
    ----------
    trajectory : softcurve.Trajectory
        Read: ``t`` shape (T,) [s], ``q`` shape (T, 3 N) [m, 1/m, 1/m], ``success``.
    ax : None or sequence of matplotlib.axes.Axes, shape (3,)
        Panels for ``l``, ``kx`` and ``ky``; None draws a new figure.
    %(window)s

    Returns
    -------
    matplotlib.figure.Figure
    """
    figure, axes = panels(
        ax, len(STATE_LABELS), "the states figure", sharex=True, figsize=(7.0, 6.0)
    )
    segments = trajectory.q.shape[1] // len(STATE_LABELS)
    drawn, zeroed_rows = np.array(trajectory.q, dtype=np.float64), set()
    for column in range(drawn.shape[1]):
        row, first = column % len(STATE_LABELS), column - column % len(STATE_LABELS)
        length = np.abs(drawn[:, first]).max(initial=0.0)
        if row and length > 0 and negligible(drawn[:, column], 1.0 / length):
            drawn[:, column] = 0.0
            zeroed_rows.add(row)
    # the window follows what is drawn: round-off "moving" until late does not stretch it
    start, end = time_window(trajectory.t, drawn, window)
    for row, label in enumerate(STATE_LABELS):
        zeroed = row in zeroed_rows
        for i in range(segments):
            values = drawn[:, len(STATE_LABELS) * i + row]
            axes[row].plot(
                trajectory.t, values, lw=0.9, label=f"segment {i + 1}" if segments > 1 else None
            )
        axes[row].set_ylabel(label + (f"\n(below {NOISE:g}/l: 0)" if zeroed else ""))
        axes[row].grid(True, alpha=0.3)
    if trajectory.t.size > 1:
        axes[-1].set_xlim(start, end)
    if segments > 1:
        axes[0].legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("time t [s]")
    title = "State trajectories"
    if trajectory.t.size > 1 and (start, end) != (trajectory.t[0], trajectory.t[-1]):
        title += f", t = {start:.3g} .. {end:.3g} s of {trajectory.t[-1]:.3g} s"
    if not trajectory.success:
        title += f" (FAILED at t = {trajectory.t[-1]:.4g} s)" if trajectory.t.size else " (FAILED)"
    axes[0].set_title(title)
    return figure


def plot_tip(trajectory, ax=None):
    """The tip position in 3-D, colored by time, with its start and end marked (Fig. 5).

    The axes have equal scales. A coordinate that stays below ``NOISE`` (1e-9) of the
    tip's distance from the base is round-off of an exact zero (a planar run) and is
    drawn as zero, as its axis label says.

    Parameters
    ----------
    trajectory : softcurve.Trajectory
        Read: ``t`` shape (T,) [s] and ``tip`` shape (T, 3) [m].
    ax : None or matplotlib.axes.Axes, shape (1,)
        A 3-D Axes (``projection="3d"``); None draws a new figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    figure, (ax,) = panels(ax, 1, "the tip figure", projection="3d", figsize=(6.0, 5.5))
    tip = np.array(trajectory.tip * MM_PER_M)
    zeroed = []
    if tip.shape[0]:
        scale = np.linalg.norm(tip, axis=1).max()
        zeroed = [k for k in range(3) if negligible(tip[:, k], scale)]
        tip[:, zeroed] = 0.0
        points = ax.scatter(tip[:, 0], tip[:, 1], tip[:, 2], c=trajectory.t, s=1.0, cmap="viridis")
        ax.plot(tip[:, 0], tip[:, 1], tip[:, 2], lw=0.4, color="0.4", alpha=0.6)
        ax.scatter(*tip[0], color="tab:red", s=25, label="start")
        ax.scatter(*tip[-1], color="black", marker="x", s=40, label="end")
        figure.colorbar(points, ax=ax, shrink=0.6, label="time t [s]")
        ax.legend(loc="upper left", fontsize="small")
        limits = equal_limits(tip, least=1e-3 * scale)
        ax.set(xlim=limits[0], ylim=limits[1], zlim=limits[2])
        ax.set_box_aspect((1.0, 1.0, 1.0))
    for k, name in enumerate("xyz"):
        note = f" (< {NOISE:g} reach: 0)" if k in zeroed else ""
        getattr(ax, f"set_{name}label")(f"{name} [mm]{note}")
    draw_obstacles(ax, getattr(trajectory, "model", None))
    ax.set_title("End-effector trajectory")
    return figure


def _figure_size(figsize) -> tuple[float, float]:
    try:
        width, height = figsize
    except (TypeError, ValueError):
        raise ParameterError(
            f"figsize must be (width, height) in inches, got {figsize!r}"
        ) from None
    return (
        real_scalar("figsize width", width, positive=True),
        real_scalar("figsize height", height, positive=True),
    )


@figure_options
def plot_batch_tips(batch, ax=None, *, members: int = 50):
    """The tip position of the first ``members`` members of a batch against time, one
    panel per world axis.

    Parameters
    ----------
    batch : softcurve.BatchTrajectory
        Read: ``t`` shape (T,) [s], ``tip`` shape (B, T, 3) [m], ``size``.
    %(ax)s
    %(members)s

    Returns
    -------
    matplotlib.figure.Figure
    """
    members = whole_number("members", members, 1)
    figure, axes = panels(ax, 3, "the batch tip figure", sharex=True, figsize=(7.0, 6.0))
    for row, axis in enumerate("xyz"):
        axes[row].plot(batch.t, MM_PER_M * batch.tip[:members, :, row].T, lw=0.6, alpha=0.7)
        axes[row].set_ylabel(f"tip {axis} [mm]")
    axes[-1].set_xlabel("time [s]")
    axes[0].set_title(f"{min(members, batch.size)} of {batch.size} members")
    return figure


def animation_axes(figsize, limits):
    """The figure and 3-D axes of the animation: equal scales, every label inside.

    Parameters
    ----------
    figsize : tuple of float
        ``(width, height)`` [inches].
    limits : ndarray, shape (3, 2)
        Axis limits [mm], of equal lengths.

    Returns
    -------
    figure : matplotlib.figure.Figure
    ax : mpl_toolkits.mplot3d.axes3d.Axes3D
    """
    from matplotlib.figure import Figure

    # not through pyplot: the figure only feeds the file, so no window may show it
    figure = Figure(figsize=figsize)
    # room on the right for the z label, which a 3-D axes draws outside its box
    figure.subplots_adjust(left=0.0, right=0.88, bottom=0.04, top=0.94)
    ax = figure.add_subplot(projection="3d")
    ax.set(
        xlim=limits[0],
        ylim=limits[1],
        zlim=limits[2],
        xlabel="x [mm]",
        ylabel="y [mm]",
        zlabel="z [mm]",
    )
    ax.set_box_aspect((1.0, 1.0, 1.0), zoom=0.85)
    return figure, ax


@animation_options
def animate(
    trajectory,
    path,
    model,
    *,
    fps: float = 25,
    speed: float = 1.0,
    points: int = 20,
    dpi: float = 80,
    figsize=(5.0, 5.0),
) -> Path:
    """Write an animation of the backbone to ``path``, whole or not at all, on axes of
    equal scales.

    Parameters
    ----------
    trajectory : softcurve.Trajectory
        Read: ``t`` shape (T,) [s], T >= 2, and ``q`` shape (T, n).
    path : str or pathlib.Path
        ``.gif`` (Pillow, always available) or ``.mp4`` (needs ffmpeg on the PATH).
    model : softcurve.Model
        Gives the backbone shape of each frame.
    %(fps)s
    %(speed)s
    %(points)s
    %(dpi)s
    %(figsize)s
    """
    from matplotlib import animation  # on first use, like drawing.pyplot

    path = Path(path)
    if path.suffix not in ANIMATION_SUFFIXES:
        raise ParameterError(f"animation path must end in .gif or .mp4, got {path.name!r}")
    if path.suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise RuntimeError("writing .mp4 needs ffmpeg on the PATH; write a .gif instead")
    fps = real_scalar("fps", fps, positive=True)
    speed = real_scalar("speed", speed, positive=True)
    dpi = real_scalar("dpi", dpi, positive=True)
    points = whole_number("points", points, 2)
    figsize = _figure_size(figsize)
    if trajectory.t.size < 2:
        raise ParameterError("the trajectory has fewer than two samples: nothing to animate")
    frame_times = np.arange(trajectory.t[0], trajectory.t[-1], speed / fps)
    frames = np.searchsorted(trajectory.t, frame_times).clip(0, trajectory.t.size - 1)
    shapes = backbones(model, trajectory.q[frames], points) * MM_PER_M
    least_reach = MINIMUM_REACH * model.robot.rest_length * MM_PER_M
    limits = equal_limits(shapes, least=least_reach)
    limits = limits.mean(axis=1, keepdims=True) + MARGIN * (
        limits - limits.mean(axis=1, keepdims=True)
    )
    figure, ax = animation_axes(figsize, limits)
    draw_obstacles(ax, model)
    (line,) = ax.plot([], [], [], lw=4, color="tab:blue")
    (tip,) = ax.plot([], [], [], "o", color="tab:red")
    title = ax.set_title("")

    def draw(i):
        shape = shapes[i]
        line.set_data_3d(shape[:, 0], shape[:, 1], shape[:, 2])
        tip.set_data_3d(shape[-1:, 0], shape[-1:, 1], shape[-1:, 2])
        title.set_text(f"t = {trajectory.t[frames[i]]:.3f} s")
        return line, tip, title

    movie = animation.FuncAnimation(figure, draw, frames=len(frames), blit=False)
    writer = (
        animation.PillowWriter(fps=fps)
        if path.suffix == ".gif"
        else animation.FFMpegWriter(fps=fps)
    )
    with atomic_path(path) as tmp:
        movie.save(str(tmp), writer=writer, dpi=dpi)
    return path
