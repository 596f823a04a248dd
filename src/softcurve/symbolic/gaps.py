"""Where a configuration stands with respect to the obstacles: the check that a robot
does not start inside one (docs/contact.md, "Starting states").

A start is refused when, at one of the points the contact is measured at (the base
included), the body is entirely inside an obstacle: its backbone lies deeper below the
obstacle's surface than the contact radius (or than half the radius of a sphere or
capsule, whose normal would otherwise soon point the wrong way). There the penalty law
no longer describes a body pressed into a surface but a robot that passed through the
obstacle. A body pressed in, as at a contact equilibrium (where a thin body's backbone
may be slightly below the surface), is a valid start.
"""

from __future__ import annotations

from functools import lru_cache

import casadi as ca
import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.base.validation import ParameterError
from softcurve.description.elements import coordinate_slices
from softcurve.description.layout import ParameterLayout
from softcurve.symbolic.contact import contact_points, signed_distance
from softcurve.symbolic.kinematics import kinematic_chain, segment_frames


@lru_cache(maxsize=16)
def obstacle_distances(environment, structure: tuple):
    """The signed distances of the contact points from the obstacles, and the points.

    Parameters
    ----------
    environment : Environment
        The obstacles.
    structure : tuple
        ``Robot.structure()``.

    Returns
    -------
    tuple
        ``(distances, points)``: ``distances(q, p)`` a CasADi SX Function of the
        coordinates and the parameter vector, (points, obstacles) [m], positive outside;
        ``points`` the ``(element, s)`` of each row, the base ``(0, 0.0)`` first.
    """
    layout = ParameterLayout.of_structure(structure)
    points = [(0, 0.0)] + [(i, s) for i, s, _ in contact_points(structure, environment)]
    q = ca.SX.sym("q", coordinate_slices(structure)[-1].stop)
    p = ca.SX.sym("p", layout.size)
    frames = segment_frames(q, kinematic_chain(structure, p), ca.SX.eye(3), points)
    rows = [
        ca.horzcat(*[signed_distance(o, f.position) for o in environment.obstacles]) for f in frames
    ]
    return ca.Function("distances", [q, p], [ca.vertcat(*rows)]), points


def _allowed_depths(environment, robot, points) -> np.ndarray:
    """How deep [m] the backbone may lie below each obstacle's surface, (points, obstacles)."""
    radii = environment.radii([segment.radius for segment in robot.segments])
    halves = [getattr(o, "radius", np.inf) / 2 for o in environment.obstacles]
    return np.array([[min(radii[i], half) for half in halves] for i, _ in points])


_start_parameters = parameters_from(
    {
        "environment": ("Environment or None", "The obstacles (None: nothing to check)."),
        "robot": ("Robot", "The robot."),
        "q": ("array_like, shape (n,)", "Coordinates [m, 1/m, 1/m], in the robot's domain."),
        "name": ("str", "How ``q`` is called in the message."),
    }
)


@_start_parameters
def start_problem(environment, robot, q, name: str = "q0") -> str | None:
    """Why the configuration ``q`` puts the robot inside an obstacle, or None.

    Parameters
    ----------
    %(environment)s
    %(robot)s
    %(q)s
    %(name)s

    Returns
    -------
    str or None
        A message naming the obstacle and how deep [mm] the backbone is inside it and
        where (material coordinate), or the penalty force [N] the start would put on the
        robot when it exceeds the force that squeezes a segment to zero length; None when
        the start is outside every obstacle or pressed into one as a robot at rest can be.
    """
    if environment is None:
        return None
    function, points = obstacle_distances(environment, robot.structure())
    q = np.asarray(q, dtype=np.float64)
    depths = -np.array(function(q, robot.parameter_vector()), dtype=np.float64)

    problem = _depth_problem(environment, robot, points, depths, name)
    return problem or _force_problem(environment, robot, points, depths, name)


def _depth_problem(environment, robot, points, depths, name) -> str | None:
    """A body point entirely inside an obstacle: its backbone deeper than allowed."""
    excess = depths - _allowed_depths(environment, robot, points)
    row, column = np.unravel_index(np.argmax(excess), excess.shape)
    if not excess[row, column] > 0:
        return None
    obstacle = environment.obstacles[column]
    segment, s = points[row]
    where = (segment + s) / robot.n_segments
    allowed = depths[row, column] - excess[row, column]
    return (
        f"{name} starts the robot inside obstacle {column} ({type(obstacle).__name__}): "
        f"its backbone is {1e3 * depths[row, column]:.4g} mm deep in it at s = {where:.4g} "
        f"(segment {segment + 1}), more than the {1e3 * allowed:.4g} mm of a body pressed "
        f"in; start it outside every obstacle"
    )


def _force_problem(environment, robot, points, depths, name) -> str | None:
    """A start pressed so deep into an obstacle that its penalty force (the law without
    the rounding, summed with the points' weights) exceeds the force that would squeeze
    the softest segment to zero length, ``k_e(0) l0``: no robot rests there, and the
    integrator would throw it off with an unphysical force."""
    law = environment.law
    radii = environment.radii([segment.radius for segment in robot.segments])
    weights = [0.0] + [w for _, _, w in contact_points(robot.structure(), environment)]
    forces = np.zeros(depths.shape[1])
    for (segment, _), weight, row in zip(points, weights, depths, strict=True):
        penetration = np.maximum(radii[segment] + row, 0.0)
        length = robot.segments[segment].rest_length
        forces += weight * length * law.stiffness * penetration**law.exponent
    squeeze = min(_squeeze_force(element) for element in robot.segments)
    worst = int(np.argmax(forces))
    if not forces[worst] > squeeze:
        return None
    obstacle = environment.obstacles[worst]
    return (
        f"{name} starts the robot pressed into obstacle {worst} ({type(obstacle).__name__}) "
        f"with a penalty force of {forces[worst]:.4g} N, more than the {squeeze:.4g} N that "
        f"would squeeze a segment to zero length; start it outside every obstacle"
    )


def _squeeze_force(element) -> float:
    """The axial force [N] that squeezes an element to zero length at its rest stiffness:
    ``k_e(0) l0`` of a constant-curvature segment, ``k(0)`` of a constant-strain segment's
    stretch law (its strain from 1 to 0); infinite for a rigid body or a segment that does
    not stretch."""
    law = getattr(element, "elongation_stiffness", None)
    if law is not None:
        return float(law.stiffness(0.0)) * element.rest_length
    law = getattr(element, "stretch_stiffness", None)
    return np.inf if law is None else float(law.stiffness(0.0))


@_start_parameters
def check_start(environment, robot, q, name: str = "q0") -> None:
    """Raise :class:`ParameterError` when ``q`` puts the robot inside an obstacle
    (:func:`start_problem`).

    Parameters
    ----------
    %(environment)s
    %(robot)s
    %(q)s
    %(name)s
    """
    problem = start_problem(environment, robot, q, name)
    if problem is not None:
        raise ParameterError(problem)
