"""Figures of a trajectory: the states (paper Fig. 4), the tip path (Fig. 5), an animation.

Matplotlib with the Agg backend (files only, no windows). Figures are returned so
callers can adjust them; with a ``path`` they are also written, whole or not at all.
"""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np

from softcurve.base.files import atomic_path


def _pyplot():
    import matplotlib

    if matplotlib.get_backend().lower() != "agg":
        matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    return plt


def _save(figure, path, dpi):
    if path is not None:
        path = Path(path)
        with atomic_path(path) as tmp:
            figure.savefig(tmp, dpi=dpi, format=path.suffix.lstrip(".") or "png")
    return figure


def plot_states(trajectory, path=None, *, dpi: int = 110):
    """``l``, ``kx`` and ``ky`` of every segment against time, one panel each.

    Parameters
    ----------
    trajectory : Trajectory
    path : str or Path, optional
        Where to write the figure (format from the suffix).
    """
    plt = _pyplot()
    figure, axes = plt.subplots(3, 1, sharex=True, figsize=(7.0, 6.0), layout="constrained")
    labels = (
        ("l", "length l [m]"),
        ("kx", r"curvature $\kappa_x$ [1/m]"),
        ("ky", r"curvature $\kappa_y$ [1/m]"),
    )
    segments = trajectory.n // 3
    for row, (_, label) in enumerate(labels):
        for i in range(segments):
            axes[row].plot(
                trajectory.t,
                trajectory.q[:, 3 * i + row],
                lw=0.9,
                label=f"segment {i + 1}" if segments > 1 else None,
            )
        axes[row].set_ylabel(label)
        axes[row].grid(True, alpha=0.3)
    if segments > 1:
        axes[0].legend(loc="upper right", fontsize="small")
    axes[-1].set_xlabel("time t [s]")
    title = "State trajectories"
    if not trajectory.success:
        title += f" (FAILED at t = {trajectory.t[-1]:.4g} s)" if trajectory.t.size else " (FAILED)"
    axes[0].set_title(title)
    return _save(figure, path, dpi)


def plot_tip(trajectory, path=None, *, dpi: int = 110):
    """The tip position in 3-D, coloured by time, with its start and end marked."""
    plt = _pyplot()
    figure = plt.figure(figsize=(6.0, 5.5), layout="constrained")
    ax = figure.add_subplot(projection="3d")
    tip = trajectory.tip * 1e3
    if tip.shape[0]:
        points = ax.scatter(tip[:, 0], tip[:, 1], tip[:, 2], c=trajectory.t, s=1.0, cmap="viridis")
        ax.plot(tip[:, 0], tip[:, 1], tip[:, 2], lw=0.4, color="0.4", alpha=0.6)
        ax.scatter(*tip[0], color="tab:red", s=25, label="start")
        ax.scatter(*tip[-1], color="black", marker="x", s=40, label="end")
        figure.colorbar(points, ax=ax, shrink=0.6, label="time t [s]")
        ax.legend(loc="upper left", fontsize="small")
    ax.set_xlabel("x [mm]")
    ax.set_ylabel("y [mm]")
    ax.set_zlabel("z [mm]")
    ax.set_title("End-effector trajectory")
    return _save(figure, path, dpi)


def animate(
    trajectory, path, model, *, fps: int = 25, speed: float = 1.0, points: int = 20, dpi: int = 60
) -> Path:
    """Write an animation of the backbone to ``path``.

    Parameters
    ----------
    trajectory : Trajectory
    path : str or Path
        ``.gif`` (Pillow, always available) or ``.mp4`` (needs ffmpeg on the PATH).
    model : Model
        Gives the backbone shape of each frame.
    fps : int
        Frames per second of the file.
    speed : float
        Simulated seconds per second of animation.
    points : int
        Points along the backbone.
    """
    from matplotlib import animation

    path = Path(path)
    if path.suffix == ".mp4" and shutil.which("ffmpeg") is None:
        raise RuntimeError("writing .mp4 needs ffmpeg on the PATH; write a .gif instead")
    if path.suffix not in (".gif", ".mp4"):
        raise ValueError(f"animation path must end in .gif or .mp4, got {path.name!r}")
    if trajectory.t.size < 2:
        raise ValueError("the trajectory has fewer than two samples")
    plt = _pyplot()
    frame_times = np.arange(trajectory.t[0], trajectory.t[-1], speed / fps)
    frames = np.searchsorted(trajectory.t, frame_times).clip(0, trajectory.t.size - 1)
    s = np.linspace(0.0, 1.0, points)
    q = np.repeat(trajectory.q[frames], points, axis=0)
    positions = model.evaluate_along("pose", q, np.tile(s, frames.size)[:, None])[1]
    shapes = positions.reshape(frames.size, points, 3) * 1e3
    reach = max(np.abs(shapes[..., :2]).max(), 1e-3 * model.robot.rest_length) * 1.1
    top = max(shapes[..., 2].max(), 0.0) * 1.1
    bottom = min(shapes[..., 2].min(), 0.0) * 1.1
    figure = plt.figure(figsize=(4.0, 4.0))
    ax = figure.add_subplot(projection="3d")
    ax.set(
        xlim=(-reach, reach),
        ylim=(-reach, reach),
        zlim=(bottom, top),
        xlabel="x [mm]",
        ylabel="y [mm]",
        zlabel="z [mm]",
    )
    (line,) = ax.plot([], [], [], lw=4, color="tab:blue")
    (tip,) = ax.plot([], [], [], "o", color="tab:red")
    title = ax.set_title("")

    def draw(i):
        s = shapes[i]
        line.set_data_3d(s[:, 0], s[:, 1], s[:, 2])
        tip.set_data_3d(s[-1:, 0], s[-1:, 1], s[-1:, 2])
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
    plt.close(figure)
    return path
