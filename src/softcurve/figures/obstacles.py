"""Figures of the contact: the forces of the obstacles against time over the contact
(with a zoom on a short impact), and the obstacles themselves (planes, spheres,
capsules) drawn into the 3-D plots and animations.

Obstacles are given in the robot's base frame; they are drawn in the world frame (turned
by ``Robot.base_rotation``), like the backbone, in millimetres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.figures.drawing import panels
from softcurve.figures.scales import SHORT_IMPACT, contact_window, impact_window, window_note

MM_PER_M = 1e3
OBSTACLE_STYLE = {"color": "0.55", "alpha": 0.25, "linewidth": 0.0}
"""How obstacles look: translucent grey surfaces."""
FEW_SAMPLES = 60
"""Below this many output samples in the contact figure's window, each is marked: a
contact of a few samples is otherwise drawn as a smooth line the record does not hold."""
INSET = (0.55, 0.3, 0.42, 0.55)
"""Where the zoom on an impact sits in the magnitude panel: (left, bottom, width,
height), fractions of the panel; on the right, or mirrored to the left when the impact
is in the right half."""
RESOLUTION = 16
"""Points per circle of a sphere or capsule surface."""


def _tangents(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors orthogonal to ``normal`` and to each other."""
    helper = np.eye(3)[int(np.argmin(np.abs(normal)))]
    first = np.cross(normal, helper)
    first /= np.linalg.norm(first)
    return first, np.cross(normal, first)


def obstacle_surfaces(obstacle, extent: float) -> list[tuple[np.ndarray, ...]]:
    """Grids ``(X, Y, Z)`` [m] of the obstacle's surface in its own (base) frame.

    Parameters
    ----------
    obstacle : Plane, Sphere or Capsule
        The obstacle (duck-typed on its fields ``normal``, ``center`` or ``a``).
    extent : float
        Half-width [m] of the square drawn for a plane, centred on the point of the plane
        nearest the robot's base.

    Returns
    -------
    list of tuple of ndarray
        One ``(X, Y, Z)`` triple of equal 2-D arrays per surface patch.
    """
    angle = np.linspace(0.0, 2.0 * np.pi, RESOLUTION + 1)
    if hasattr(obstacle, "normal"):  # a plane: a square around the foot of the base
        n = obstacle.normal
        centre = np.dot(obstacle.point, n) * n
        u, v = _tangents(n)
        a, b = np.meshgrid([-extent, extent], [-extent, extent])
        grid = centre[:, None, None] + u[:, None, None] * a + v[:, None, None] * b
        return [tuple(grid)]
    if hasattr(obstacle, "center"):  # a sphere
        return [tuple(obstacle.center[:, None, None] + obstacle.radius * _ball(np.eye(3), 0, 1))]
    w = obstacle.axis  # a capsule: a tube and a half ball at each end
    u, v = _tangents(w)
    ring = obstacle.radius * (np.outer(u, np.cos(angle)) + np.outer(v, np.sin(angle)))
    tube = np.stack([obstacle.a[:, None] + ring, obstacle.b[:, None] + ring], axis=2)
    frame = np.column_stack([u, v, w])
    ends = [
        tuple(end[:, None, None] + obstacle.radius * _ball(frame, *half))
        for end, half in ((obstacle.a, (0.5, 1.0)), (obstacle.b, (0.0, 0.5)))
    ]
    return [tuple(tube), *ends]


_mesh_parameters = parameters_from(
    {
        "obstacle": ("Plane, Sphere or Capsule", "The obstacle."),
        "extent": ("float", "Half-width [m] of the square drawn for a plane."),
        "rotation": (
            "array_like, shape (3, 3)",
            "The robot's base rotation: obstacles are given in the base frame, the robot "
            "is drawn in the world frame.",
        ),
        "position": (
            "array_like, shape (3,), optional",
            "The robot's base position [m] in the world frame (default: the origin).",
        ),
    }
)


@_mesh_parameters
@dataclass(frozen=True)
class ObstacleMesh:
    """An obstacle of the environment as a triangle mesh, for the 3-D viewer
    (:func:`softcurve.figures.scene.drawable_obstacles`).

    Parameters
    ----------
    %(obstacle)s
    %(extent)s
    %(rotation)s
    %(position)s
    """

    obstacle: object
    extent: float
    rotation: np.ndarray
    position: np.ndarray | None = None

    def surface(self) -> tuple[np.ndarray, np.ndarray]:
        """``(vertices (V, 3) [m], triangles (M, 3))`` in the world frame: each grid patch
        of :func:`world_surfaces` split into two triangles per cell."""
        vertices, triangles = [], []
        for grid in world_surfaces(self.obstacle, self.extent, self.rotation, self.position):
            x = np.moveaxis(grid, 0, -1)  # (rows, columns, 3)
            rows, columns = x.shape[:2]
            first = sum(len(v) for v in vertices)
            index = first + np.arange(rows * columns).reshape(rows, columns)
            a, b = index[:-1, :-1].ravel(), index[:-1, 1:].ravel()
            c, d = index[1:, :-1].ravel(), index[1:, 1:].ravel()
            triangles.append(np.concatenate([np.stack([a, b, d], 1), np.stack([a, d, c], 1)]))
            vertices.append(x.reshape(-1, 3))
        return np.concatenate(vertices), np.concatenate(triangles)


@_mesh_parameters
def environment_meshes(model, extent: float) -> tuple[ObstacleMesh, ...]:
    """The obstacles of ``model.environment`` as meshes (none without an environment).

    Parameters
    ----------
    model : Model
        The model; its ``environment`` may be None.
    %(extent)s
    """
    environment = getattr(model, "environment", None)
    if environment is None:
        return ()
    rotation = np.asarray(model.robot.base_rotation, dtype=float)
    position = np.asarray(model.robot.base_position, dtype=float)
    return tuple(ObstacleMesh(o, extent, rotation, position) for o in environment.obstacles)


@_mesh_parameters
def world_surfaces(obstacle, extent: float, rotation, position=None) -> list[np.ndarray]:
    """The grids of :func:`obstacle_surfaces` in the world frame [m], each (3, rows,
    columns): the one place where obstacles (given in the base frame) are turned into the
    frame the robot is drawn in.

    Parameters
    ----------
    %(obstacle)s
    %(extent)s
    %(rotation)s
    %(position)s
    """
    rotation = np.asarray(rotation, dtype=float)
    origin = np.zeros(3) if position is None else np.asarray(position, dtype=float)
    return [
        np.einsum("ij,j...->i...", rotation, np.stack(grid)) + origin[:, None, None]
        for grid in obstacle_surfaces(obstacle, extent)
    ]


def _ball(frame: np.ndarray, first: float, last: float) -> np.ndarray:
    """Unit sphere points (3, azimuths, polar angles) between the polar angles
    ``first pi`` and ``last pi`` from the third column of ``frame`` (3, 3)."""
    angle = np.linspace(0.0, 2.0 * np.pi, RESOLUTION + 1)
    polar = np.linspace(first * np.pi, last * np.pi, RESOLUTION // 2 + 1)
    local = np.stack(
        [
            np.outer(np.cos(angle), np.sin(polar)),
            np.outer(np.sin(angle), np.sin(polar)),
            np.outer(np.ones_like(angle), np.cos(polar)),
        ]
    )
    return np.einsum("ij,j...->i...", frame, local)


def draw_obstacles(ax, model, extent: float | None = None) -> list:
    """Draw the obstacles of ``model``'s environment into the 3-D Axes ``ax``, in mm.

    Parameters
    ----------
    ax : matplotlib.axes.Axes
        A 3-D Axes (``projection="3d"``) whose units are millimetres.
    model : softcurve.Model or None
        Read: ``environment`` (nothing is drawn without one), ``robot.base_rotation``
        (3, 3), ``robot.base_position`` (3,) [m] and ``robot.rest_length`` [m]; None
        draws nothing.
    extent : float, optional
        Half-width [m] of the square drawn for a plane (default: the robot's rest
        length).

    Returns
    -------
    list
        The Matplotlib artists drawn (empty without an environment).
    """
    environment = getattr(model, "environment", None)
    if environment is None:
        return []
    rotation = np.asarray(model.robot.base_rotation, dtype=float)
    position = np.asarray(model.robot.base_position, dtype=float)
    extent = model.robot.rest_length if extent is None else extent
    artists = []
    for obstacle in environment.obstacles:
        for grid in world_surfaces(obstacle, extent, rotation, position):
            artists.append(ax.plot_surface(*(grid * MM_PER_M), **OBSTACLE_STYLE))
    return artists


def plot_contact_forces(contact, ax=None):
    """The force of each obstacle on the robot against time: its magnitude and, below,
    its three components, base frame; over the contact alone.

    The time axis spans the contact (:func:`softcurve.figures.scales.contact_window`:
    from the sample before the first force to the one after the last, a quarter of that
    on either side), as the title says; the whole record without contact. An impact
    shorter than ``SHORT_IMPACT`` (5 %) of that span gets a zoom of its own inside the
    magnitude panel (:func:`softcurve.figures.scales.impact_window`).

    Parameters
    ----------
    contact : softcurve.ContactHistory
        Read: ``t`` shape (T,) [s], ``forces`` shape (T, n_obstacles, 3) [N] and
        ``labels`` (n_obstacles,).
    ax : None or sequence of matplotlib.axes.Axes, shape (2,)
        Panels for the magnitudes and the components; None draws a new figure.

    Returns
    -------
    matplotlib.figure.Figure
    """
    figure, axes = panels(ax, 2, "the contact force figure", sharex=True, figsize=(7.0, 5.0))
    t = contact.t
    magnitude = np.linalg.norm(contact.forces, axis=2)
    window = contact_window(t, magnitude)
    whole = (float(t[0]), float(t[-1])) if t.size else (0.0, 1.0)
    start, end = window if window is not None else whole
    shown = np.count_nonzero((t >= start) & (t <= end))
    marker = {"marker": ".", "ms": 4} if shown < FEW_SAMPLES else {}
    for o, label in enumerate(contact.labels):
        (line,) = axes[0].plot(t, magnitude[:, o], lw=1.0, label=label, **marker)
        for k, style in enumerate(("-", "--", ":")):
            axes[1].plot(
                t,
                contact.forces[:, o, k],
                style,
                color=line.get_color(),
                lw=0.9,
                label=f"{label}, {'xyz'[k]}",
                **marker,
            )
    if t.size > 1:
        axes[1].set_xlim(start, end)
    impact = impact_window(t, magnitude)
    zoomed = impact is not None and impact[1] - impact[0] < SHORT_IMPACT * (end - start)
    legend = "upper right"
    if zoomed:
        left = sum(impact) > start + end  # the impact in the right half: the zoom left
        _impact_zoom(axes[0], t, magnitude, impact, left)
        legend = "upper right" if left else "upper left"
    axes[0].set_ylabel("contact force |F| [N]")
    axes[1].set_ylabel("components F [N]")
    axes[1].set_xlabel("time t [s]")
    note = window_note(t, start, end) if window is not None else " (no contact)"
    axes[0].set_title("Forces of the obstacles on the robot" + note)
    for a in axes:
        a.grid(True, alpha=0.3)
        a.legend(loc=legend, fontsize="small")
    return figure


def _impact_zoom(ax, t, magnitude, impact, left: bool) -> None:
    """A zoom on the impact inside ``ax`` (on its left or right), each sample marked,
    its span outlined."""
    x, y, width, height = INSET
    inset = ax.inset_axes((1.0 - x - width if left else x, y, width, height))
    inside = (t >= impact[0]) & (t <= impact[1])
    for o in range(magnitude.shape[1]):
        inset.plot(t[inside], magnitude[inside, o], lw=1.0, marker=".", ms=3)
    inset.set_xlim(*impact)
    inset.text(0.03, 0.95, "impact", transform=inset.transAxes, va="top", fontsize="small")
    inset.tick_params(labelsize="x-small")
    inset.grid(True, alpha=0.3)
    ax.indicate_inset_zoom(inset, edgecolor="0.4")
