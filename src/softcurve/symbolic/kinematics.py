"""Kinematics of the chain, symbolic: frames of material points and their Jacobians.

Each element kind's pose of a material point (:mod:`softcurve.description.elements`:
the constant-curvature segment's arc, the constant-strain segment's SE(3) exponential,
the rigid body's fixed placement) is one CasADi Function a chain calls per element
(:func:`segment_point_function`); the functions here compose them from the base.

Functions here take and return CasADi expressions; masses and forces live in
:mod:`softcurve.symbolic.dynamics`.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from softcurve.description.elements import ElementModel, coordinate_slices, element_model
from softcurve.description.layout import ParameterLayout


@dataclass(frozen=True)
class KinematicElement:
    """What the kinematics need of one element.

    Parameters
    ----------
    point : casadi.Function
        Its kind's :func:`segment_point_function`.
    geometry : casadi.SX
        Its numbers (its model's ``geometry``).
    coordinates : slice
        Its coordinates in ``q``.
    """

    point: ca.Function
    geometry: ca.SX
    coordinates: slice


def kinematic_chain(structure: tuple, p, inline: bool | None = None) -> list[KinematicElement]:
    """The chain's elements for its kinematics, one point Function per distinct kind.

    Parameters
    ----------
    structure : tuple
        ``Robot.structure()``.
    p : casadi.SX, shape (n_p,)
        The parameter vector (:meth:`Robot.parameter_vector`), symbolic.
    inline : bool or None
        Whether the point Functions are inlined (None: :func:`inline_calls`).
    """
    inline = inline_calls(len(structure)) if inline is None else inline
    parts = ParameterLayout.of_structure(structure).element_parts(p)
    points: dict[tuple, tuple] = {}
    elements = []
    slices = coordinate_slices(structure)
    for signature, part, coordinates in zip(structure, parts, slices, strict=True):
        if signature not in points:
            model = element_model(signature)
            name = f"{signature[0]}{len(points)}_point" if len(set(structure)) > 1 else ""
            points[signature] = (model, segment_point_function(model, inline, name or None))
        model, point = points[signature]
        elements.append(KinematicElement(point, model.geometry(part), coordinates))
    return elements


@dataclass(frozen=True)
class Frame:
    """Pose of a material point and its body angular-velocity Jacobian (symbolic).

    Parameters
    ----------
    rotation : casadi.SX, shape (3, 3)
        World-frame orientation.
    position : casadi.SX, shape (3,)
        World-frame position [m].
    angular_jacobian : casadi.SX, shape (3, n)
        Body-frame angular velocity per unit ``qd``.
    """

    rotation: ca.SX
    position: ca.SX
    angular_jacobian: ca.SX


def segment_frames(q, elements: list[KinematicElement], base_rotation, points, base_position=None):
    """Frames of a serial chain at the given material points.

    Parameters
    ----------
    q : SX, shape (n,)
        Generalized coordinates.
    elements : list of KinematicElement
        :func:`kinematic_chain` of the robot.
    base_rotation : SX or DM, shape (3, 3)
        World orientation of the base frame.
    points : sequence of (element index, local s)
        Points at which frames are wanted; ``s`` may be a number or an expression.
    base_position : SX or DM, shape (3,), optional
        World position of the base frame [m]; default zero.

    Returns
    -------
    list of Frame
        One per point, in the order given.
    """
    n = q.shape[0]
    wanted: dict[int, list[tuple[int, object]]] = {}
    for k, (i, s) in enumerate(points):
        wanted.setdefault(i, []).append((k, s))
    frames: list[Frame | None] = [None] * len(points)

    position = ca.SX.zeros(3) if base_position is None else base_position
    rotation, angular = base_rotation, ca.SX.zeros(3, n)
    for i, element in enumerate(elements):
        for k, s in wanted.get(i, []):
            frames[k] = _chain_step(element, q, s, rotation, position, angular)
        tip = _chain_step(element, q, 1.0, rotation, position, angular)
        rotation, position, angular = tip.rotation, tip.position, tip.angular_jacobian
    return frames


def _chain_step(element: KinematicElement, q, s, rotation, position, angular) -> Frame:
    k = element.coordinates
    local_rotation, local_position, _, element_angular = element.point(q[k], s, element.geometry)
    local_angular = ca.SX.zeros(3, q.shape[0])
    local_angular[:, k] = element_angular
    return Frame(
        rotation=rotation @ local_rotation,
        position=position + rotation @ local_position,
        angular_jacobian=local_rotation.T @ angular + local_angular,
    )


def inline_calls(n_segments: int) -> bool:
    """Whether a robot of ``n_segments`` inlines its segments' Functions: for one segment,
    where there is nothing to share and inlining drops the terms the robot does not use
    (a third of the forward dynamics' operations, ``benchmarks/bench_chain.py``);
    otherwise they stay calls, one copy of a segment's work however many segments.

    Parameters
    ----------
    n_segments : int
        Number of segments N.
    """
    return n_segments == 1


@dataclass(frozen=True)
class MaterialPoint:
    """Pose of a material point of the robot and its world-frame Jacobian (symbolic).

    Parameters
    ----------
    rotation : casadi.SX, shape (3, 3)
        World-frame orientation.
    position : casadi.SX, shape (3,)
        World-frame position [m].
    jacobian : casadi.SX, shape (6, n)
        Linear velocity [m/s] above, angular velocity [rad/s] below, world frame, per
        unit ``qd``.
    """

    rotation: ca.SX
    position: ca.SX
    jacobian: ca.SX


def segment_point_function(
    model: ElementModel, inline: bool = False, name: str | None = None
) -> ca.Function:
    """``(q_i, s, g) -> (rotation, position, linear Jacobian, body angular Jacobian)`` of
    material point ``s`` of an element, in its base frame: one Function a chain calls per
    element of the kind.

    Parameters
    ----------
    model : ElementModel
        The element kind's model.
    inline : bool
        Whether it is inlined where it is called (False: it stays a call).
    name : str, optional
        Its name (default ``"segment_point"``), unique per kind within a model.
    """
    q_i, s = ca.SX.sym("q", model.nq), ca.SX.sym("s")
    g = ca.SX.sym("g", model.geometry_size())
    rotation, position = model.point_pose(q_i, s, g)
    return ca.Function(
        name or "segment_point",
        [q_i, s, g],
        [rotation, position, ca.jacobian(position, q_i), model.angular_jacobian(q_i, s, g)],
        ["q", "s", "g"],
        ["rotation", "position", "linear", "angular"],
        {"never_inline": not inline, "cse": True},
    )


def point_at(
    q, elements: list[KinematicElement], base_rotation, s, base_position=None, bounds=None
):
    """The material point at coordinate ``s`` in [0, 1] of the whole robot (symbolic
    ``s``), by one pass over the elements.

    Element ``i`` covers ``[c_i, c_(i+1)]`` (``bounds``; by default ``[i/N, (i+1)/N]``);
    ``s = 1`` is the tip. Element ``j`` moves the point rigidly with its tip frame when
    the point lies beyond it, through its own slice when the point lies in it (the local
    coordinate ``clamp((s - c_j) / (c_(j+1) - c_j), 0, 1)``), and not at all when the
    point lies before it (the slice at ``0`` has zero Jacobian): each element's block of
    the Jacobian is one of two expressions, so the pass costs O(N).

    Parameters
    ----------
    q : casadi.SX, shape (n,)
        Generalized coordinates.
    elements : list of KinematicElement
        :func:`kinematic_chain` of the robot.
    base_rotation : casadi.SX or casadi.DM, shape (3, 3)
        World orientation of the base frame.
    s : casadi.SX
        Material coordinate of the whole robot, in [0, 1].
    base_position : casadi.SX or casadi.DM, shape (3,), optional
        World position of the base frame [m]; default zero.
    bounds : casadi.SX or sequence of float, shape (N + 1,), optional
        Where each element begins and ends in ``s`` (``Robot.span_bounds``, symbolic from
        the parameter vector); default equal spans.
    """
    n_segments = len(elements)
    if bounds is None:
        bounds = [i / n_segments for i in range(n_segments + 1)]
    rotation = base_rotation
    origin = ca.SX.zeros(3) if base_position is None else base_position
    candidates, blocks = [], []
    for j, element in enumerate(elements):
        q_j, g = q[element.coordinates], element.geometry
        local = ca.fmin(ca.fmax((s - bounds[j]) / (bounds[j + 1] - bounds[j]), 0.0), 1.0)
        r_local, p_local, linear, angular = element.point(q_j, local, g)
        r_tip, p_tip, linear_tip, angular_tip = element.point(q_j, 1.0, g)
        frame_rotation = rotation @ r_local
        candidates.append((frame_rotation, origin + rotation @ p_local))
        inside = ca.vertcat(rotation @ linear, frame_rotation @ angular)
        tip_origin, tip_rotation = origin + rotation @ p_tip, rotation @ r_tip
        # beyond the element: the tip frame's twist per unit qd_j, moved to the point below
        blocks.append((j, inside, rotation @ linear_tip, tip_rotation @ angular_tip, tip_origin))
        rotation, origin = tip_rotation, tip_origin
    chosen_rotation, chosen_position = candidates[-1]
    for i in reversed(range(n_segments - 1)):
        before = s < bounds[i + 1]
        chosen_rotation = ca.if_else(before, candidates[i][0], chosen_rotation)
        chosen_position = ca.if_else(before, candidates[i][1], chosen_position)
    columns = []
    for j, inside, linear_tip, angular_tip, tip_origin in blocks:
        moved = linear_tip - ca.skew(chosen_position - tip_origin) @ angular_tip
        beyond = s >= bounds[j + 1]
        columns.append(ca.if_else(beyond, ca.vertcat(moved, angular_tip), inside))
    jacobian = ca.horzcat(*columns) if columns else ca.SX(6, 0)
    return MaterialPoint(chosen_rotation, chosen_position, jacobian)
