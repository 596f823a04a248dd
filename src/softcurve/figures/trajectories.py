"""Figures of trajectories: the states (paper Fig. 4) with the actuator's inputs, the tip
path (Fig. 5), the tips of a batch, and an animation of the backbone; the states, the
tip path and the animation show the same time window, the motion's."""

from __future__ import annotations

import re
import shutil
import subprocess
from pathlib import Path

import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.base.files import atomic_path
from softcurve.base.progress import ProgressLine
from softcurve.base.validation import ParameterError, real_scalar
from softcurve.description.curvature import COORDINATES as CURVATURE_COORDINATES
from softcurve.figures.actuation import plot_inputs
from softcurve.figures.drawing import (
    element_shapes,
    model_rows,
    panels,
    state_rows,
    whole_number,
)
from softcurve.figures.obstacles import draw_obstacles
from softcurve.figures.scales import (
    NOISE,
    equal_limits,
    negligible,
    time_window,
    window_note,
)

MM_PER_M = 1e3
STATE_LABELS = ("length l [m]", r"curvature $\kappa_x$ [1/m]", r"curvature $\kappa_y$ [1/m]")
"""Per segment, the coordinates are ``(l, kx, ky)``: one panel each."""
ANIMATION_SUFFIXES = (".gif", ".mp4")
RIGID_LINE = {"lw": 9, "color": "0.35", "solid_capstyle": "butt"}
"""A rigid body in the animation: a thick dark grey bar, where soft segments are blue."""
STRIPE_LINE = {"lw": 1.2, "color": "tab:orange"}
"""The stripe along a soft segment's surface (its material x axis), which shows twist."""
LEGEND_ROWS = 8
"""Entries per column of the states figure's legend, beside its top panel (2 inches
tall: eight entries in small print fill it)."""
MARGIN = 1.1
"""Axis limits of the animation: the space the backbone sweeps, 10 % wider."""
MINIMUM_REACH = 0.1
"""Half-width of the animation's x-y axes at least, over the rest length: a robot that
stays straight is still drawn in a box, not on a line."""
ANIMATION_TICKS = 4
"""Ticks per axis of the animation at most: at 400 px, more labels run into each other
where two axes meet at the corner of the box."""
GIF_COLOURS = 256
"""Colours of the GIF's one palette, taken from the first frame (GIF allows 256): every
frame draws the same artists in the same colours, so one palette serves all of them."""


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
    "inputs": (
        "bool, optional",
        "Add a panel of the actuator's inputs (:func:`softcurve.figures.plot_inputs`) "
        "below the states; default: when the trajectory holds ``inputs`` and its "
        "``actuator`` and no ``ax`` is given (with ``ax``, pass True and four Axes).",
    ),
    "progress": (
        "bool, optional",
        "Count the frames on a line on stderr while they are drawn.",
    ),
}
"""Options of the animation and the batch figure (``ax``: its panels), documented once for
the figure functions and the result methods that call them
(:func:`softcurve.base.docs.parameters_from`); ``animation_options`` also writes the
Returns section of the animations, the file written."""

figure_options = parameters_from(FIGURE_OPTIONS)
animation_options = parameters_from(FIGURE_OPTIONS, returns=("pathlib.Path", "``path``."))


def drawn_states(q, robot=None) -> tuple[np.ndarray, set]:
    """The coordinates as the figures draw them: a curvature that stays below ``NOISE``
    (1e-9) over the segment's length is round-off of an exact zero (a planar run), drawn
    as zero. Only for constant-curvature segments: the coordinates of other kinds are
    drawn as they are.

    Parameters
    ----------
    q : array_like, shape (T, n)
        Coordinates; ``(l, kx, ky)`` per segment [m, 1/m, 1/m] without ``robot``.
    robot : softcurve.Robot, optional
        The robot of ``q`` (default: constant-curvature segments).

    Returns
    -------
    drawn : ndarray, shape (T, 3 N)
        The coordinates, round-off curvatures set to zero [m, 1/m, 1/m].
    zeroed : set of int
        The rows of the states figure (1: ``kx``, 2: ``ky``) with a curvature zeroed.
    """
    drawn, zeroed = np.array(q, dtype=np.float64), set()
    if robot is not None and not robot.constant_curvature:
        return drawn, zeroed
    for column in range(drawn.shape[1]):
        row, first = column % len(STATE_LABELS), column - column % len(STATE_LABELS)
        length = np.abs(drawn[:, first]).max(initial=0.0)
        if row and length > 0 and negligible(drawn[:, column], 1.0 / length):
            drawn[:, column] = 0.0
            zeroed.add(row)
    return drawn, zeroed


def motion_window(trajectory, window="auto") -> tuple[float, float]:
    """The time range the states figure, the tip figure and the animation show
    (:func:`softcurve.figures.scales.time_window` of the states as drawn, so that
    round-off "moving" until late does not stretch it).

    Parameters
    ----------
    trajectory : softcurve.Trajectory
        Read: ``t`` shape (T,) [s] and ``q`` shape (T, 3 N).
    window : "auto", "all" or (float, float)
        As :func:`softcurve.figures.scales.time_window` [s].

    Returns
    -------
    tuple of float
        ``(start, end)`` [s].
    """
    return time_window(trajectory.t, _drawn_states(trajectory)[0], window)


def _robot(trajectory):
    """The robot of a trajectory's model, or None (a loaded trajectory has no model)."""
    model = getattr(trajectory, "model", None)
    return None if model is None else model.robot


NUMBERED = re.compile(r"^(.*\D)(\d+)$")
"""A coordinate's column: its name and its element's number from 1 (``twist2``)."""


def _named_rows(trajectory) -> tuple | None:
    """The rows of :func:`~softcurve.figures.drawing.state_rows` from a trajectory's
    ``coordinate_names`` and ``coordinate_units`` (a loaded file's), or None where they
    are those of constant-curvature segments (or the trajectory has none)."""
    names = getattr(trajectory, "coordinate_names", None)
    units = getattr(trajectory, "coordinate_units", None)
    parts = [NUMBERED.match(c) for c in names or ()]
    if not names or not units or not all(parts):
        return None
    if {m.group(1) for m in parts} <= set(CURVATURE_COORDINATES):
        return None
    rows: dict[str, tuple[str, list]] = {}
    for column, (m, unit) in enumerate(zip(parts, units, strict=True)):
        rows.setdefault(m.group(1), (unit, []))[1].append((int(m.group(2)) - 1, column))
    return tuple((name, unit, tuple(columns)) for name, (unit, columns) in rows.items())


def _drawn_states(trajectory) -> tuple[np.ndarray, set]:
    """:func:`drawn_states` of a trajectory: its coordinates drawn as they are unless
    they are constant curvature's."""
    if _robot(trajectory) is None and _named_rows(trajectory) is not None:
        return np.array(trajectory.q, dtype=np.float64), set()
    return drawn_states(trajectory.q, _robot(trajectory))


def _state_rows(trajectory) -> tuple:
    """The states figure's rows: ``(label, ((segment, column), ...))`` each; ``l``,
    ``kx``, ``ky`` for constant-curvature segments (or a trajectory that names no
    others), else one row per coordinate name of the robot's elements (or of a loaded
    file's)."""
    robot = _robot(trajectory)
    named = _named_rows(trajectory) if robot is None else state_rows(robot)
    if named is None or (robot is not None and robot.constant_curvature):
        segments = trajectory.q.shape[1] // len(STATE_LABELS)
        return tuple(
            (label, tuple((i, len(STATE_LABELS) * i + row) for i in range(segments)))
            for row, label in enumerate(STATE_LABELS)
        )
    return tuple((f"{name} [{unit or '-'}]", columns) for name, unit, columns in named)


@figure_options
def plot_states(trajectory, ax=None, *, window="auto", inputs=None):
    """``l``, ``kx`` and ``ky`` of every segment against time, one panel each (Fig. 4),
    and the actuator's inputs below them when the trajectory holds them; for other
    element kinds, one panel per coordinate (``bend_x``, ``twist``, ...) with every
    element that has it.

    A curvature that stays below ``NOISE`` (1e-9) over the segment's length is round-off
    of an exact zero (a planar run) and is drawn as zero, as its axis label says.

    Parameters
    ----------
    trajectory : softcurve.Trajectory
        Read: ``t`` shape (T,) [s], ``q`` shape (T, 3 N) [m, 1/m, 1/m], ``success``,
        and, for the inputs' panel, ``inputs`` shape (T, m) and ``actuator``.
    ax : None or sequence of matplotlib.axes.Axes, shape (3,) or (4,)
        Panels for ``l``, ``kx`` and ``ky`` (and the inputs), or one per coordinate
        name of other kinds; None draws a new figure.
    %(window)s
    %(inputs)s

    Returns
    -------
    matplotlib.figure.Figure
    """
    actuated = getattr(trajectory, "inputs", None) is not None and (
        getattr(trajectory, "actuator", None) is not None
    )
    if inputs is None:
        inputs = actuated and ax is None
    elif inputs and not actuated:
        raise ParameterError(
            "inputs=True needs a trajectory with inputs and its actuator (simulate with "
            "actuator=); a loaded file keeps the inputs but not the actuator"
        )
    state_panels = _state_rows(trajectory)
    rows = len(state_panels) + bool(inputs)
    figure, axes = panels(ax, rows, "the states figure", sharex=True, figsize=(7.0, 2.0 * rows))
    segments = len({i for _, columns in state_panels for i, _ in columns})
    drawn, zeroed_rows = _drawn_states(trajectory)
    start, end = time_window(trajectory.t, drawn, window)
    for row, (label, columns) in enumerate(state_panels):
        zeroed = row in zeroed_rows
        for i, column in columns:
            axes[row].plot(
                trajectory.t,
                drawn[:, column],
                lw=0.9,
                color=f"C{i % 10}",
                label=f"segment {i + 1}" if segments > 1 else None,
            )
        axes[row].set_ylabel(label + (f"\n(below {NOISE:g}/l: 0)" if zeroed else ""))
        axes[row].grid(True, alpha=0.3)
    if inputs:
        plot_inputs(trajectory, trajectory.actuator, axes[-1])
    if trajectory.t.size > 1:
        axes[-1].set_xlim(start, end)
    if segments > 1:  # beside the panels, where it covers no curve
        axes[0].legend(
            loc="upper left",
            bbox_to_anchor=(1.01, 1.0),
            borderaxespad=0.0,
            fontsize="small",
            ncols=-(-segments // LEGEND_ROWS),
        )
    axes[-1].set_xlabel("time t [s]")
    title = "State trajectories" + window_note(trajectory.t, start, end)
    if not trajectory.success:
        title += f" (FAILED at t = {trajectory.t[-1]:.4g} s)" if trajectory.t.size else " (FAILED)"
    axes[0].set_title(title)
    return figure


@figure_options
def plot_tip(trajectory, ax=None, *, window="auto"):
    """The tip position in 3-D over the motion's time window, colored by time, with its
    start and end marked (Fig. 5).

    The axes have equal scales. A coordinate that stays below ``NOISE`` (1e-9) of the
    tip's distance from the base is round-off of an exact zero (a planar run) and is
    drawn as zero, as its axis label says. The window is the states figure's
    (:func:`motion_window`); the title says which it is when it is not the whole record.

    Parameters
    ----------
    trajectory : softcurve.Trajectory
        Read: ``t`` shape (T,) [s], ``q`` shape (T, n) and ``tip`` shape (T, 3) [m].
    ax : None or matplotlib.axes.Axes, shape (1,)
        A 3-D Axes (``projection="3d"``); None draws a new figure.
    %(window)s

    Returns
    -------
    matplotlib.figure.Figure
    """
    figure, (ax,) = panels(ax, 1, "the tip figure", projection="3d", figsize=(6.0, 5.5))
    start, end = motion_window(trajectory, window)
    shown = (trajectory.t >= start) & (trajectory.t <= end)
    t, tip = trajectory.t[shown], np.array(trajectory.tip[shown] * MM_PER_M)
    zeroed = []
    if tip.shape[0]:
        scale = np.linalg.norm(tip, axis=1).max()
        zeroed = [k for k in range(3) if negligible(tip[:, k], scale)]
        tip[:, zeroed] = 0.0
        points = ax.scatter(tip[:, 0], tip[:, 1], tip[:, 2], c=t, s=1.0, cmap="viridis")
        ax.plot(tip[:, 0], tip[:, 1], tip[:, 2], lw=0.4, color="0.4", alpha=0.6)
        ax.scatter(*tip[0], color="tab:red", s=25, label=f"start, t = {t[0]:.3g} s")
        ax.scatter(*tip[-1], color="black", marker="x", s=40, label=f"end, t = {t[-1]:.3g} s")
        figure.colorbar(points, ax=ax, shrink=0.6, label="time t [s]")
        ax.legend(loc="upper left", fontsize="small")
        limits = equal_limits(tip, least=1e-3 * scale)
        ax.set(xlim=limits[0], ylim=limits[1], zlim=limits[2])
        ax.set_box_aspect((1.0, 1.0, 1.0))
    for k, name in enumerate("xyz"):
        note = f" (< {NOISE:g} reach: 0)" if k in zeroed else ""
        getattr(ax, f"set_{name}label")(f"{name} [mm]{note}")
    draw_obstacles(ax, getattr(trajectory, "model", None))
    # the window as drawn, its first and last samples: the legend's start and end
    drawn = (float(t[0]), float(t[-1])) if t.size else (start, end)
    ax.set_title("End-effector trajectory" + window_note(trajectory.t, *drawn))
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


def animation_axes(figsize, limits, dpi: float = 100):
    """The figure and 3-D axes of the animation: equal scales, every label inside, at
    most ``ANIMATION_TICKS`` ticks per axis in small print so that none overlap.

    Parameters
    ----------
    figsize : tuple of float
        ``(width, height)`` [inches].
    limits : ndarray, shape (3, 2)
        Axis limits [mm], of equal lengths.
    dpi : float, optional
        Resolution [dots per inch]; the frames are ``figsize * dpi`` pixels.

    Returns
    -------
    figure : matplotlib.figure.Figure
    ax : mpl_toolkits.mplot3d.axes3d.Axes3D
    """
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure
    from matplotlib.ticker import MaxNLocator

    # not through pyplot: the figure only feeds the file, so no window may show it
    figure = Figure(figsize=figsize, dpi=dpi)
    FigureCanvasAgg(figure)
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
    for axis in (ax.xaxis, ax.yaxis, ax.zaxis):
        axis.set_major_locator(MaxNLocator(ANIMATION_TICKS))
        axis.set_tick_params(labelsize="small")
    ax.set_box_aspect((1.0, 1.0, 1.0), zoom=0.85)
    return figure, ax


@figure_options
def frame_samples(trajectory, *, window="auto", fps: float = 25, speed: float = 1.0):
    """The output samples an animation shows, one per frame: every ``speed / fps``
    seconds of simulated time over the window, the sample nearest each.

    Parameters
    ----------
    trajectory : softcurve.Trajectory
        Read: ``t`` shape (T,) [s], T >= 2, and ``q`` shape (T, n).
    %(window)s
    %(fps)s
    %(speed)s

    Returns
    -------
    ndarray of int, shape (frames,)
        Indices into ``trajectory.t``.
    """
    fps = real_scalar("fps", fps, positive=True)
    speed = real_scalar("speed", speed, positive=True)
    t = trajectory.t
    if t.size < 2:
        raise ParameterError("the trajectory has fewer than two samples: nothing to animate")
    start, end = motion_window(trajectory, window)
    start, end = max(start, float(t[0])), min(end, float(t[-1]))
    if not end > start:
        raise ParameterError(
            f"window must overlap the record t = {t[0]:.6g} .. {t[-1]:.6g} s, got {window!r}"
        )
    times = np.arange(start, end, speed / fps)
    after = np.searchsorted(t, times).clip(1, t.size - 1)
    return np.where(times - t[after - 1] <= t[after] - times, after - 1, after)


def blitted_frames(figure, animated, update, count: int):
    """Draw ``figure`` once without the ``animated`` artists, then yield ``count`` frames
    that redraw only them over that background (a full redraw of a 3-D axes costs about
    50 ms, most of it ticks and panes that never change).

    The artists are drawn in the order given, so list them back to front.

    Parameters
    ----------
    figure : matplotlib.figure.Figure
        With an Agg canvas (:func:`animation_axes`).
    animated : sequence of matplotlib.artist.Artist
        What changes between frames (and what must be drawn over it).
    update : callable
        ``update(i)`` sets the artists to frame ``i``.
    count : int
        Number of frames.

    Yields
    ------
    ndarray of uint8, shape (height, width, 3)
        The frame's RGB pixels.
    """
    canvas = figure.canvas
    for artist in animated:
        artist.set_animated(True)
    canvas.draw()
    background = canvas.copy_from_bbox(figure.bbox)
    for i in range(count):
        canvas.restore_region(background)
        update(i)
        for artist in animated:
            artist.axes.draw_artist(artist)
        yield np.asarray(canvas.buffer_rgba())[..., :3].copy()


def write_gif(frames, path, fps: float) -> None:
    """Write RGB frames as a looping GIF with one palette, the first frame's.

    Parameters
    ----------
    frames : iterable of ndarray, shape (height, width, 3), uint8
        The frames.
    path : str or pathlib.Path
        The file.
    fps : float
        Frames per second [1/s].
    """
    from PIL import Image

    images = [Image.fromarray(frame) for frame in frames]
    palette = images[0].quantize(GIF_COLOURS)
    quantized = [image.quantize(palette=palette, dither=Image.Dither.NONE) for image in images]
    quantized[0].save(
        path,
        format="GIF",
        save_all=True,
        append_images=quantized[1:],
        duration=round(1000 / fps),
        loop=0,
    )


def write_mp4(frames, path, fps: float) -> None:
    """Write RGB frames as an H.264 MP4 through ffmpeg, fed raw pixels on its stdin.

    Parameters
    ----------
    frames : iterable of ndarray, shape (height, width, 3), uint8
        The frames, all of one size.
    path : str or pathlib.Path
        The file.
    fps : float
        Frames per second [1/s].
    """
    frames = iter(frames)
    first = next(frames)
    height, width = first.shape[:2]
    command = [
        "ffmpeg", "-y", "-loglevel", "error",
        "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}", "-r", f"{fps:g}",
        "-i", "-",
        # H.264 in yuv420p needs even sizes; players expect that pixel format
        "-vf", "scale=trunc(iw/2)*2:trunc(ih/2)*2", "-vcodec", "h264", "-pix_fmt", "yuv420p",
        "-f", "mp4", str(path),
    ]  # fmt: skip
    with subprocess.Popen(command, stdin=subprocess.PIPE, stderr=subprocess.PIPE) as ffmpeg:
        try:
            ffmpeg.stdin.write(first.tobytes())
            for frame in frames:
                ffmpeg.stdin.write(frame.tobytes())
        except BrokenPipeError:
            pass  # ffmpeg stopped: its exit code and message follow
        finally:
            ffmpeg.stdin.close()
        message = ffmpeg.stderr.read().decode(errors="replace").strip()
    if ffmpeg.returncode:
        raise RuntimeError(f"ffmpeg failed writing {Path(path).name}: {message}")


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
    window="auto",
    progress: bool = False,
) -> Path:
    """Write an animation of the backbone over the motion's time window to ``path``,
    whole or not at all, on 3-D axes of equal scales.

    The frames are drawn over one background of axes, ticks and panes
    (:func:`blitted_frames`); the obstacles are drawn over the robot, as the static
    figures draw them.

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
    %(window)s
    %(progress)s
    """
    model_rows(model, trajectory.q[:1], "the trajectory")
    path = Path(path)
    if path.suffix not in ANIMATION_SUFFIXES:
        raise ParameterError(f"animation path must end in .gif or .mp4, got {path.name!r}")
    if path.suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise RuntimeError("writing .mp4 needs ffmpeg on the PATH; write a .gif instead")
    fps = real_scalar("fps", fps, positive=True)
    dpi = real_scalar("dpi", dpi, positive=True)
    points = whole_number("points", points, 2)
    figsize = _figure_size(figsize)
    frames = frame_samples(trajectory, window=window, fps=fps, speed=speed)
    per_element = max(2, -(-points // model.robot.n_segments) + 1)
    parts = element_shapes(model, trajectory.q[frames], per_element)
    shapes = np.concatenate([part.backbone for part in parts], axis=1) * MM_PER_M
    least_reach = MINIMUM_REACH * model.robot.rest_length * MM_PER_M
    limits = equal_limits(shapes, least=least_reach)
    limits = limits.mean(axis=1, keepdims=True) + MARGIN * (
        limits - limits.mean(axis=1, keepdims=True)
    )
    figure, ax = animation_axes(figsize, limits, dpi)
    stripes = not model.robot.constant_curvature
    drawn = []  # (artist, positions (F, P, 3) [mm]): each element, and its stripe
    for part in parts:
        style = RIGID_LINE if part.rigid else {"lw": 4, "color": "tab:blue"}
        drawn.append((ax.plot([], [], [], **style)[0], part.backbone * MM_PER_M))
        if stripes and not part.rigid:
            drawn.append((ax.plot([], [], [], **STRIPE_LINE)[0], part.stripe * MM_PER_M))
    (tip,) = ax.plot([], [], [], "o", color="tab:red")
    title = ax.set_title("")
    # drawn after the robot, as a full redraw of the 3-D axes orders them
    obstacles = draw_obstacles(ax, model)
    bar = ProgressLine(len(frames), show=progress, unit="frames", label=f"drawing {path.name}")

    def draw(i):
        shape = shapes[i]
        for artist, positions in drawn:
            artist.set_data_3d(*positions[i].T)
        tip.set_data_3d(shape[-1:, 0], shape[-1:, 1], shape[-1:, 2])
        title.set_text(f"t = {trajectory.t[frames[i]]:.3f} s")
        bar.update(i + 1)

    artists = [artist for artist, _ in drawn]
    pixels = blitted_frames(figure, [*artists, tip, *obstacles, title], draw, len(frames))
    write = write_gif if path.suffix == ".gif" else write_mp4
    try:
        with atomic_path(path) as tmp:
            write(pixels, tmp, fps)
    finally:
        bar.close()
    return path
