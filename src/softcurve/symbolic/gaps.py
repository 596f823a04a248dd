"""Where a configuration stands with respect to the obstacles: the check that a robot
does not start inside one (docs/contact.md, "Starting states").

A start is refused when the backbone itself is inside an obstacle at one of the points
the contact is measured at (the base included): there the penalty law no longer
describes a contact (a body pressed into a surface) but a robot passed through the
obstacle, and a sphere's or capsule's normal would point the wrong way. A body that
only touches, as at a contact equilibrium (penetration less than its contact radius),
is a valid start.
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.symbolic.contact import contact_points, signed_distance
from softcurve.symbolic.kinematics import segment_frames


@lru_cache(maxsize=16)
def _distances(environment, structure: tuple):
    """``(Function q -> signed distances (points, obstacles), [(segment, s)])``."""
    n_segments = len(structure)
    points = [(0, 0.0)] + [(i, s) for i, s, _ in contact_points(structure, environment)]
    q = ca.SX.sym("q", 3 * n_segments)
    frames = segment_frames(q, n_segments, ca.SX.eye(3), points)
    rows = [
        ca.horzcat(*[signed_distance(o, f.position) for o in environment.obstacles]) for f in frames
    ]
    return ca.Function("distances", [q], [ca.vertcat(*rows)]), points


def start_problem(environment, robot, q, name: str = "q0") -> str | None:
    """Why the configuration ``q`` puts the robot inside an obstacle, or None.

    Parameters
    ----------
    environment : Environment or None
        The obstacles (None: nothing to check).
    robot : Robot
        The robot.
    q : array_like, shape (n,)
        Coordinates [m, 1/m, 1/m], in the robot's domain.
    name : str
        How ``q`` is called in the message.

    Returns
    -------
    str or None
        A message naming the obstacle, how deep [mm] the backbone is inside it and where
        (material coordinate), or None when the backbone is outside every obstacle.
    """
    if environment is None:
        return None
    function, points = _distances(environment, robot.structure())
    distances = np.array(function(np.asarray(q, dtype=np.float64)), dtype=np.float64)
    row, column = np.unravel_index(np.argmin(distances), distances.shape)
    depth = -distances[row, column]
    if not depth > 0:
        return None
    obstacle = environment.obstacles[column]
    segment, s = points[row]
    where = (segment + s) / robot.n_segments
    return (
        f"{name} starts the robot inside obstacle {column} ({type(obstacle).__name__}): "
        f"its backbone is {1e3 * depth:.4g} mm deep in it at s = {where:.4g} "
        f"(segment {segment + 1}); start it outside every obstacle (a body that only "
        f"touches, penetrating less than its contact radius, is allowed)"
    )


def check_start(environment, robot, q, name: str = "q0") -> None:
    """Raise :class:`ParameterError` when ``q`` puts the robot inside an obstacle
    (:func:`start_problem`).

    Parameters
    ----------
    environment : Environment or None
        The obstacles (None: nothing to check).
    robot : Robot
        The robot.
    q : array_like, shape (n,)
        Coordinates [m, 1/m, 1/m], in the robot's domain.
    name : str
        How ``q`` is called in the message.
    """
    problem = start_problem(environment, robot, q, name)
    if problem is not None:
        raise ParameterError(problem)
