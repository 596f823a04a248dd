"""What the interactive viewer draws, computed in NumPy: the robot's backbone frames at
the shown instants, its tendons, its tip path and the obstacles around it.

The page (:mod:`softcurve.figures.viewer`) receives, per frame, the position and the
first two axes of the material frame at a few rings along each element, and builds the
tube (radius of each element), the tendons (offset ``rho`` at azimuth ``phi`` in the
same frames) and a stripe along each soft segment's material x axis (it winds round a
twisted segment) in the browser; a rigid body is a grey cylinder from its base to its
tip. Sending frames rather than meshes keeps a 10 s trajectory
at 25 frames per second to a few hundred kilobytes.
"""

from __future__ import annotations

import base64
import warnings
from dataclasses import dataclass

import numpy as np

from softcurve.base.validation import ParameterError, real_array, real_scalar
from softcurve.description.tendons import TendonActuator
from softcurve.figures.drawing import RIGID_KIND, element_poses, model_rows, whole_number
from softcurve.figures.obstacles import environment_meshes

MM_PER_M = 1e3
FRAME_VALUES = 9
"""Per ring and frame: the position and the material frame's x and y axes."""
MAX_PATH_POINTS = 4000
"""The tip path is thinned to at most this many points [count]."""
AXES_MARGIN = 1.15
"""The cube of the equal axes: the extent of the robot's motion, 15 % wider."""


@dataclass(frozen=True)
class Scene:
    """Everything the viewer page draws, in millimetres.

    Parameters
    ----------
    labels : tuple of str
        The caption of each frame (``"t = 0.040 s"``, ``"equilibrium 2, stable"``).
    times : ndarray, shape (F,) or None
        The instant of each frame [s]; None for frames that are not instants
        (equilibria), which the page steps through without playback.
    rings : ndarray, shape (F, R, 9)
        Per frame and ring: position, material x axis and material y axis [mm, -, -].
    rings_per_segment : int
        Rings along each element, both ends included [count].
    radii : ndarray, shape (N,)
        The tube's radius of each element [mm].
    kinds : tuple of str
        ``"soft"`` or ``"rigid"`` per element: a rigid body is drawn grey, its rings
        across the line from its base to its tip (:func:`bar_rings`).
    stripes : bool
        Draw a stripe along each soft segment's material x axis, which shows twist; off
        for a robot of constant-curvature segments alone (they cannot twist).
    tendons : tuple of dict
        ``{"azimuth": phi [rad], "distance": rho [mm], "rings": count}``: the tendon runs
        through the first ``rings`` rings of every frame.
    tip_path : ndarray, shape (P, 3)
        The tip's path [mm] (empty for equilibria).
    obstacles : tuple of dict
        ``{"vertices": (V, 3) [mm], "triangles": (M, 3) indices}`` per obstacle, the part
        of it inside ``bounds`` (:func:`clip_mesh`); an obstacle wholly outside is left
        out, with a ``UserWarning`` that says so.
    base_axes : float
        Length of the drawn base frame's axes [mm].
    bounds : ndarray, shape (3, 2)
        The equal axes' ranges: a cube [mm] around the robot's motion (its tube at every
        frame, the tip path and the base frame), :data:`AXES_MARGIN` wider.
    title : str
        The page's heading.
    """

    labels: tuple
    times: np.ndarray | None
    rings: np.ndarray
    rings_per_segment: int
    radii: np.ndarray
    kinds: tuple
    stripes: bool
    tendons: tuple
    tip_path: np.ndarray
    obstacles: tuple
    base_axes: float
    bounds: np.ndarray
    title: str

    def payload(self) -> dict:
        """The scene as JSON-ready values; the rings as base64 of little-endian float32.

        Returns
        -------
        dict
        """
        rings = np.ascontiguousarray(self.rings, dtype="<f4")
        return {
            "title": self.title,
            "labels": list(self.labels),
            "times": None if self.times is None else [round(float(t), 9) for t in self.times],
            "frames": int(rings.shape[0]),
            "ringsPerFrame": int(rings.shape[1]),
            "ringsPerSegment": self.rings_per_segment,
            "rings": base64.b64encode(rings.tobytes()).decode("ascii"),
            "radii": [round(float(r), 6) for r in self.radii],
            "kinds": list(self.kinds),
            "stripes": bool(self.stripes),
            "tendons": list(self.tendons),
            "tipPath": np.round(self.tip_path, 4).tolist(),
            "obstacles": list(self.obstacles),
            "baseAxes": round(float(self.base_axes), 4),
            "bounds": np.round(self.bounds, 4).tolist(),
        }


def frame_indices(t, fps: float) -> np.ndarray:
    """Indices of the samples shown at ``fps`` frames per simulated second: the sample at
    or just after each frame time, the last sample always included.

    Parameters
    ----------
    t : array_like, shape (T,)
        Sample times [s], increasing.
    fps : float
        Frames per second of simulated time [1/s].

    Returns
    -------
    ndarray of int, shape (F,)
    """
    t = np.asarray(t, dtype=np.float64)
    if t.size == 0:
        raise ParameterError("the trajectory has no samples: nothing to show")
    fps = real_scalar("fps", fps, positive=True)
    wanted = np.arange(t[0], t[-1], 1.0 / fps)
    frames = np.searchsorted(t, wanted - 1e-12 * max(abs(t[-1]), 1.0)).clip(0, t.size - 1)
    return np.unique(np.append(frames, t.size - 1))


def ring_frames(model, q, rings_per_segment: int) -> np.ndarray:
    """Positions and material frames at ``rings_per_segment`` rings of every segment.

    Parameters
    ----------
    model : softcurve.Model
        Gives the pose at each material coordinate (``pose(q, s)``).
    q : array_like, shape (F, n)
        Configurations (``robot.coordinate_names()``).
    rings_per_segment : int
        Rings along each segment, both ends included [count].

    Returns
    -------
    ndarray, shape (F, N rings_per_segment, 9)
        Position [mm], material x axis and material y axis (unit vectors).
    """
    rotation, position = element_poses(model, q, rings_per_segment)
    frames = rotation.shape[0]
    rotation = rotation.reshape(frames, -1, 3, 3)
    position = position.reshape(frames, -1, 3) * MM_PER_M
    return np.concatenate([position, rotation[..., :, 0], rotation[..., :, 1]], axis=-1)


def bar_rings(rings, kinds, rings_per_segment: int) -> np.ndarray:
    """The rings with those of each rigid body turned across the line from its base to
    its tip, so that it is drawn as a straight cylinder (the model gives its points the
    base's orientation, which a body whose tip is off its base's z axis does not share).

    Parameters
    ----------
    rings : ndarray, shape (F, N rings_per_segment, 9)
        :func:`ring_frames`.
    kinds : sequence of str
        ``"soft"`` or ``"rigid"`` per element.
    rings_per_segment : int
        Rings along each element [count].

    Returns
    -------
    ndarray, shape (F, N rings_per_segment, 9)
        A copy; soft elements' rings unchanged.
    """
    rings = np.array(rings, dtype=np.float64)
    for i, kind in enumerate(kinds):
        if kind != "rigid":
            continue
        part = rings[:, i * rings_per_segment : (i + 1) * rings_per_segment]
        axis = part[:, -1, :3] - part[:, 0, :3]
        length = np.linalg.norm(axis, axis=-1, keepdims=True)
        base_z = np.cross(part[:, 0, 3:6], part[:, 0, 6:9])  # a body of no length: its own
        axis = np.where(length > 0, axis / np.maximum(length, np.finfo(float).tiny), base_z)
        x = part[:, 0, 3:6] - np.sum(part[:, 0, 3:6] * axis, axis=-1, keepdims=True) * axis
        small = np.linalg.norm(x, axis=-1) < 1e-9  # the base's x along the bar: use its y
        x[small] = np.cross(part[small, 0, 6:9], axis[small])
        x /= np.linalg.norm(x, axis=-1, keepdims=True)
        part[..., 3:6] = x[:, None, :]
        part[..., 6:9] = np.cross(axis, x)[:, None, :]
    return rings


def tendon_paths(actuator, model, rings_per_segment: int) -> tuple:
    """The tendons of a :class:`~softcurve.TendonActuator` as the viewer draws them;
    ``()`` for any other actuator or None.

    Parameters
    ----------
    actuator : softcurve.Actuator or None
        The actuator that drove the robot.
    model : softcurve.Model
        The robot the tendons run along.
    rings_per_segment : int
        Rings along each segment [count].

    Returns
    -------
    tuple of dict
        ``{"azimuth": [rad], "distance": [mm], "rings": count}`` per tendon.
    """
    if not isinstance(actuator, TendonActuator):
        return ()
    if actuator.n_segments != model.robot.n_segments:
        raise ParameterError(
            f"actuator drives {actuator.n_segments} segment(s), the model has "
            f"{model.robot.n_segments}"
        )
    return tuple(
        {
            "azimuth": round(float(tendon.azimuth), 9),
            "distance": round(float(tendon.distance) * MM_PER_M, 6),
            "rings": (tendon.anchor + 1) * rings_per_segment,
        }
        for tendon in actuator.tendons
    )


def _points(name: str, value) -> np.ndarray:
    """``value`` as a finite float array of shape (k, 3), or raise ParameterError."""
    points = np.asarray(value, dtype=np.float64) if np.size(value) else np.empty((0, 3))
    if points.ndim != 2 or points.shape[1] != 3 or not np.isfinite(points).all():
        raise ParameterError(f"{name} must be finite points of shape (k, 3), got {points.shape}")
    return points


def drawable_obstacles(obstacles) -> tuple:
    """Check obstacles and turn them into triangle meshes in millimetres.

    The hook for the robot's environment: an obstacle is any object with a method
    ``surface()`` returning ``(vertices, triangles)``, the vertices an array (V, 3) [m]
    in the world frame and the triangles an integer array (M, 3) of vertex indices.

    Parameters
    ----------
    obstacles : sequence of objects with a surface() method
        The obstacles to draw (static).

    Returns
    -------
    tuple of dict
        ``{"vertices": [[x, y, z], ...] [mm], "triangles": [[i, j, k], ...]}``.
    """
    meshes = []
    for i, obstacle in enumerate(obstacles or ()):
        name = f"obstacles[{i}]"
        if not callable(getattr(obstacle, "surface", None)):
            raise ParameterError(
                f"{name} must have a surface() method returning (vertices, triangles), "
                f"got {type(obstacle).__name__}"
            )
        vertices, triangles = obstacle.surface()
        vertices = _points(f"{name} vertices", vertices)
        triangles = np.asarray(triangles)
        if (
            triangles.ndim != 2
            or triangles.shape[1] != 3
            or not np.issubdtype(triangles.dtype, np.integer)
            or triangles.min(initial=0) < 0
            or triangles.max(initial=0) >= len(vertices)
        ):
            raise ParameterError(
                f"{name} triangles must be integers of shape (M, 3) indexing the "
                f"{len(vertices)} vertices"
            )
        meshes.append(
            {
                "vertices": np.round(vertices * MM_PER_M, 4).tolist(),
                "triangles": triangles.astype(int).tolist(),
            }
        )
    return tuple(meshes)


def clip_mesh(vertices, triangles, low, high) -> tuple[np.ndarray, np.ndarray]:
    """The part of a triangle mesh inside the box ``[low, high]``: each triangle clipped
    against the box's six planes (Sutherland-Hodgman) and the polygon left fanned into
    triangles, so that an obstacle far larger than the robot is drawn where the robot
    is, not where it ends.

    Parameters
    ----------
    vertices : array_like, shape (V, 3)
        The mesh's points [any length unit].
    triangles : array_like of int, shape (M, 3)
        Vertex indices.
    low, high : array_like, shape (3,)
        The box's corners [the unit of ``vertices``].

    Returns
    -------
    vertices : ndarray, shape (V', 3)
    triangles : ndarray of int, shape (M', 3)
        The clipped mesh (both empty when nothing of it is inside the box).
    """
    vertices = np.asarray(vertices, dtype=np.float64)
    planes = [(k, sign, bound) for k in range(3) for sign, bound in ((1, low[k]), (-1, high[k]))]
    points, faces = [], []
    for triangle in np.asarray(triangles, dtype=int):
        polygon = [vertices[i] for i in triangle]
        for k, sign, bound in planes:  # keep sign * (x_k - bound) >= 0
            kept = []
            for a, b in zip(polygon, polygon[1:] + polygon[:1], strict=True):
                da, db = sign * (a[k] - bound), sign * (b[k] - bound)
                if da >= 0:
                    kept.append(a)
                if (da >= 0) != (db >= 0):  # the edge crosses the plane
                    kept.append(a + (b - a) * (da / (da - db)))
            polygon = kept
            if len(polygon) < 3:
                break
        if len(polygon) >= 3:
            first = len(points)
            points.extend(polygon)
            faces.extend((first, first + j, first + j + 1) for j in range(1, len(polygon) - 1))
    if not faces:
        return np.empty((0, 3)), np.empty((0, 3), dtype=int)
    return np.array(points), np.array(faces, dtype=int)


def build_scene(
    model,
    q,
    labels,
    *,
    times=None,
    tip_path=None,
    actuator=None,
    obstacles=(),
    rings: int = 16,
    title: str = "softcurve",
) -> Scene:
    """The scene of a robot at the configurations ``q``.

    Parameters
    ----------
    model : softcurve.Model
        The robot drawn.
    q : array_like, shape (F, n)
        One configuration per frame [m, 1/m, 1/m per segment].
    labels : sequence of str
        The caption of each frame.
    times : array_like, shape (F,), optional
        The instant of each frame [s], for playback; None for equilibria.
    tip_path : array_like, shape (P, 3), optional
        The tip's path [m] drawn as a line.
    actuator : softcurve.Actuator, optional
        Tendons are drawn when it is a :class:`~softcurve.TendonActuator`.
    obstacles : sequence
        Obstacles with a ``surface()`` method (:func:`drawable_obstacles`), drawn besides
        those of ``model.environment``.
    rings : int
        Rings along each segment [count], >= 2.
    title : str
        The page's heading.

    Returns
    -------
    Scene
    """
    rings = whole_number("rings", rings, 2)
    q = model_rows(model, q, "q")
    labels = tuple(str(label) for label in labels)
    if len(labels) != q.shape[0]:
        raise ParameterError(f"labels must have one entry per frame ({q.shape[0]})")
    if times is not None:
        times = real_array("times", times, (q.shape[0],))
    kinds = tuple("rigid" if s.kind == RIGID_KIND else "soft" for s in model.robot.segments)
    frames = bar_rings(ring_frames(model, q, rings), kinds, rings)
    radii = np.array([segment.radius for segment in model.robot.segments]) * MM_PER_M
    path = np.empty((0, 3))
    if tip_path is not None:
        path = _points("tip_path", tip_path) * MM_PER_M
        path = path[:: max(1, -(-len(path) // MAX_PATH_POINTS))]
    # the model's own obstacles, then any the caller adds
    reach = 1.5 * model.robot.rest_length
    meshes = drawable_obstacles((*environment_meshes(model, reach), *obstacles))
    base_axes = max(0.3 * model.robot.rest_length * MM_PER_M, 2.0 * radii.max())
    # framed on the robot's motion: obstacles are cut to that box, never widen it
    extent = [
        frames[..., :3].reshape(-1, 3) + radii.max(),
        frames[..., :3].reshape(-1, 3) - radii.max(),
        path,
        np.array([[base_axes] * 3, [-base_axes, -base_axes, 0.0]]),
    ]
    points = np.concatenate(extent)
    low, high = points.min(axis=0), points.max(axis=0)
    centre, half = (low + high) / 2, AXES_MARGIN * (high - low).max() / 2
    clipped = []
    for i, mesh in enumerate(meshes):
        vertices, triangles = clip_mesh(
            mesh["vertices"], mesh["triangles"], centre - half, centre + half
        )
        if len(triangles):
            clipped.append(
                {"vertices": np.round(vertices, 4).tolist(), "triangles": triangles.tolist()}
            )
        else:
            warnings.warn(
                f"obstacle {i + 1} lies wholly outside the space the robot moves in "
                f"({np.round(centre - half, 1).tolist()} .. {np.round(centre + half, 1).tolist()}"
                " mm) and is not drawn",
                UserWarning,
                stacklevel=3,
            )
    meshes = tuple(clipped)
    return Scene(
        labels=labels,
        times=times,
        rings=frames,
        rings_per_segment=rings,
        radii=radii,
        kinds=kinds,
        stripes=not model.robot.constant_curvature,
        tendons=tendon_paths(actuator, model, rings),
        tip_path=path,
        obstacles=meshes,
        base_axes=base_axes,
        bounds=np.stack([centre - half, centre + half], axis=1),
        title=title,
    )
