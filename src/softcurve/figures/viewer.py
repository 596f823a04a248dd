"""The interactive 3-D viewer: one self-contained HTML file (Plotly embedded, no network)
showing the robot as a tube of its radius, element by element (soft segments in colour
with a stripe along them that shows twist, rigid bodies as grey cylinders), with its base
frame, its tip path, its tendons and obstacles; play/pause, a time slider, real-time or slowed
playback, orbit and zoom, equal axes (docs/viewer.md).

Plotly comes with the optional extra ``viewer`` (``pip install "softcurve[viewer]"``);
the rest of softcurve does not need it.
"""

from __future__ import annotations

import html
import json
from pathlib import Path

import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.base.files import atomic_write
from softcurve.base.validation import ParameterError
from softcurve.figures.drawing import model_rows
from softcurve.figures.scene import Scene, build_scene, frame_indices
from softcurve.figures.viewer_page import PAGE, SCRIPT

VIEWER_OPTIONS = {
    "fps": (
        "float, optional",
        "Frames per second of simulated time stored in the file [1/s]; the file grows "
        "with it (about 30 kB per second of motion and segment at 25).",
    ),
    "rings": ("int, optional", "Rings per element that shape the tube [count], >= 2."),
    "obstacles": (
        "sequence, optional",
        "Static obstacles to draw, each with a ``surface()`` method returning "
        "``(vertices (V, 3) [m], triangles (M, 3))``.",
    ),
    "actuator": (
        "softcurve.Actuator, optional",
        "The actuator that drove the robot (default: the one recorded); the tendons of "
        "a TendonActuator are drawn.",
    ),
}
"""Options of the viewer, documented once for the functions and the result methods
(:func:`softcurve.base.docs.parameters_from`); ``viewer_options`` also writes their
Returns section, the path written."""

viewer_options = parameters_from(VIEWER_OPTIONS, returns=("pathlib.Path", "``path``."))


def plotly_bundle() -> str:
    """The source of plotly.js shipped with the ``plotly`` package.

    Returns
    -------
    str
    """
    try:
        from plotly.offline import get_plotlyjs
    except ImportError:  # the optional extra
        raise ImportError(
            'the 3-D viewer needs Plotly: pip install "softcurve[viewer]" (or pip install plotly)'
        ) from None
    return get_plotlyjs()


def page(scene: Scene) -> str:
    """The viewer's HTML page of ``scene``: one document, every script embedded.

    Parameters
    ----------
    scene : softcurve.figures.scene.Scene
        What to draw.

    Returns
    -------
    str
    """
    data = json.dumps(scene.payload(), separators=(",", ":"), allow_nan=False)
    data = data.replace("</", "<\\/")  # cannot close the script element it sits in
    parts = {
        "__TITLE__": html.escape(scene.title),
        "__SCENE__": data,
        "__SCRIPT__": SCRIPT,
        "__PLOTLY__": plotly_bundle(),
    }
    text = PAGE
    for key in ("__TITLE__", "__SCENE__", "__SCRIPT__", "__PLOTLY__"):  # bundle last
        text = text.replace(key, parts[key])
    return text


def write_page(scene: Scene, path) -> Path:
    """Write the viewer of ``scene`` to ``path`` (``.html``), whole or not at all.

    Parameters
    ----------
    scene : softcurve.figures.scene.Scene
        What to draw.
    path : str or pathlib.Path
        The file, ending in ``.html`` or ``.htm``.

    Returns
    -------
    pathlib.Path
        ``path``.
    """
    path = Path(path)
    if path.suffix.lower() not in (".html", ".htm"):
        raise ParameterError(f"the viewer's path must end in .html, got {path.name!r}")
    return atomic_write(path, page(scene).encode("utf-8"))


@viewer_options
def trajectory_viewer(
    trajectory, path, model, *, actuator=None, obstacles=(), fps: float = 25, rings: int = 16
) -> Path:
    """Write the viewer of a trajectory: the robot at ``fps`` frames per simulated second.

    Parameters
    ----------
    trajectory : softcurve.Trajectory
        Read: ``t`` shape (T,) [s], ``q`` shape (T, n) and ``tip`` shape (T, 3) [m].
    path : str or pathlib.Path
        The ``.html`` file.
    model : softcurve.Model
        Gives the robot's shape (``pose(q, s)``) and its segments' radii.
    %(actuator)s
    %(obstacles)s
    %(fps)s
    %(rings)s

    """
    model_rows(model, trajectory.q[:1], "the trajectory")
    frames = frame_indices(trajectory.t, fps)
    times = trajectory.t[frames]
    status = "" if trajectory.success else f" (failed at t = {trajectory.t[-1]:.4g} s)"
    scene = build_scene(
        model,
        trajectory.q[frames],
        [f"t = {t:.3f} s" for t in times],
        times=times,
        tip_path=trajectory.tip,
        actuator=actuator,
        obstacles=obstacles,
        rings=rings,
        title=f"softcurve: {model.robot.n_segments}-{model.robot.element_word} robot, "
        f"t = {times[0]:.4g} .. {times[-1]:.4g} s{status}",
    )
    return write_page(scene, path)


@viewer_options
def equilibria_viewer(
    equilibria, path, model, *, actuator=None, obstacles=(), rings: int = 16
) -> Path:
    """Write the viewer of one or more equilibria, one frame each (no playback).

    Parameters
    ----------
    equilibria : sequence of softcurve.Equilibrium
        Read: ``q`` shape (n,) and ``stability``.
    path : str or pathlib.Path
        The ``.html`` file.
    model : softcurve.Model
        Gives the robot's shape and its segments' radii.
    %(actuator)s
    %(obstacles)s
    %(rings)s

    """
    equilibria = list(equilibria)
    if not equilibria:
        raise ParameterError("equilibria is empty: nothing to show")
    q = np.array([e.q for e in equilibria])
    labels = [f"equilibrium {i}: {e.stability}" for i, e in enumerate(equilibria)]
    scene = build_scene(
        model,
        q,
        labels,
        actuator=actuator,
        obstacles=obstacles,
        rings=rings,
        title=f"softcurve: {len(equilibria)} equilibri{'um' if len(q) == 1 else 'a'}",
    )
    return write_page(scene, path)
