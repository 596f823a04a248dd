"""Piecewise-constant-curvature kinematics (section 2.1 of the paper), symbolic.

Segment coordinates ``q_i = (l, kx, ky)``. At material coordinate ``s`` in [0, 1] of
a segment the frame is the rotation ``exp([w]x)`` with rotation vector
``w = s l (-ky, kx, 0)`` (eq. 3), and the position is ``s l Jl(w) e_z`` (eq. 4) with
``Jl`` the left Jacobian of SO(3), since ``int_0^1 exp(t [w]x) dt = Jl(w)``. The body
angular velocity is ``Jr(w) dw/dt``, ``Jr`` the right Jacobian: that is the exact
time derivative of the pose at fixed material point (docs/model.md, "Kinematics"), not the paper's
eq. (10). All trigonometric factors are smooth functions of ``|w|^2`` from
:mod:`softcurve.base.smooth`, exact at zero curvature.

Functions here take and return CasADi expressions; masses and forces live in
:mod:`softcurve.symbolic.dynamics`.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from softcurve.base import smooth as _smooth
from softcurve.base.docs import shared_parameters

E_Z = ca.DM([0.0, 0.0, 1.0])


@shared_parameters
def rotation_vector(q_i, s):
    """``w = s l (-ky, kx, 0)``: the rotation from the segment base to material point ``s``.

    Parameters
    ----------
    %(q_i)s
    %(s)s
    """
    length, kx, ky = q_i[0], q_i[1], q_i[2]
    return s * length * ca.vertcat(-ky, kx, 0)


def _so3_terms(q_i, s):
    """``(w, [w]x, |w|^2)`` of the rotation vector of point ``s``
    (:func:`rotation_vector`), the arguments of the SO(3) series."""
    w = rotation_vector(q_i, s)
    z = ca.dot(w, w)
    return w, ca.skew(w), z


@shared_parameters
def segment_pose(q_i, s):
    """Rotation (3x3) and position (3,) [m] of material point ``s`` in the segment's
    base frame.

    Parameters
    ----------
    %(q_i)s
    %(s)s
    """
    _, wx, z = _so3_terms(q_i, s)
    wx2 = wx @ wx
    rotation = ca.SX.eye(3) + _smooth.sinc(z) * wx + _smooth.cosc(z) * wx2
    left_jacobian = ca.SX.eye(3) + _smooth.cosc(z) * wx + _smooth.sinc3(z) * wx2
    position = s * q_i[0] * (left_jacobian @ E_Z)
    return rotation, position


@shared_parameters
def segment_angular_jacobian(q_i, s):
    """Body-frame angular velocity Jacobian (3x3) of point ``s`` w.r.t. ``q_i``.

    ``omega_body = Jr(w) dw/dq qd`` with ``Jr(w) = I - cosc [w]x + sinc3 [w]x^2``.

    Parameters
    ----------
    %(q_i)s
    %(s)s
    """
    w, wx, z = _so3_terms(q_i, s)
    right_jacobian = ca.SX.eye(3) - _smooth.cosc(z) * wx + _smooth.sinc3(z) * (wx @ wx)
    return right_jacobian @ ca.jacobian(w, q_i)


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


def segment_frames(q, n_segments: int, base_rotation, points, point=None):
    """Frames of a serial chain at the given material points.

    Parameters
    ----------
    q : SX, shape (3N,)
        Generalized coordinates.
    n_segments : int
        Number of segments N.
    base_rotation : SX or DM, shape (3, 3)
        World orientation of the base frame.
    points : sequence of (segment index, local s)
        Points at which frames are wanted; ``s`` may be a number or an expression.
    point : casadi.Function, optional
        :func:`segment_point_function` (default: a new one, inlined as
        :func:`inline_calls` says).

    Returns
    -------
    list of Frame
        One per point, in the order given.
    """
    if point is None:
        point = segment_point_function(inline_calls(n_segments))
    n = 3 * n_segments
    wanted: dict[int, list[tuple[int, object]]] = {}
    for k, (i, s) in enumerate(points):
        wanted.setdefault(i, []).append((k, s))
    frames: list[Frame | None] = [None] * len(points)

    rotation, position, angular = base_rotation, ca.SX.zeros(3), ca.SX.zeros(3, n)
    for i in range(n_segments):
        q_i = q[3 * i : 3 * i + 3]
        for k, s in wanted.get(i, []):
            frames[k] = _chain_step(point, q_i, i, s, n, rotation, position, angular)
        tip = _chain_step(point, q_i, i, 1.0, n, rotation, position, angular)
        rotation, position, angular = tip.rotation, tip.position, tip.angular_jacobian
    return frames


def _chain_step(point, q_i, i, s, n, rotation, position, angular) -> Frame:
    local_rotation, local_position, _, segment_angular = point(q_i, s)
    local_angular = ca.SX.zeros(3, n)
    local_angular[:, 3 * i : 3 * i + 3] = segment_angular
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


def segment_point_function(inline: bool = False) -> ca.Function:
    """``(q_i, s) -> (rotation, position, linear Jacobian, body angular Jacobian)`` of
    material point ``s`` of a segment, in its base frame: one Function a chain calls per
    segment.

    Parameters
    ----------
    inline : bool
        Whether it is inlined where it is called (False: it stays a call).
    """
    q_i, s = ca.SX.sym("q", 3), ca.SX.sym("s")
    rotation, position = segment_pose(q_i, s)
    return ca.Function(
        "segment_point",
        [q_i, s],
        [rotation, position, ca.jacobian(position, q_i), segment_angular_jacobian(q_i, s)],
        ["q", "s"],
        ["rotation", "position", "linear", "angular"],
        {"never_inline": not inline, "cse": True},
    )


def point_at(q, n_segments: int, base_rotation, s, point: ca.Function | None = None):
    """The material point at coordinate ``s`` in [0, 1] of the whole robot (symbolic
    ``s``), by one pass over the segments.

    Segment ``i`` covers ``[i/N, (i+1)/N]``; ``s = 1`` is the tip. Segment ``j`` moves the
    point rigidly with its tip frame when the point lies beyond it, through its own
    slice when the point lies in it (the local coordinate ``clamp(s N - j, 0, 1)``), and
    not at all when the point lies before it (the slice at ``0`` has zero Jacobian): each
    segment's block of the Jacobian is one of two expressions, so the pass costs O(N).

    Parameters
    ----------
    q : casadi.SX, shape (3N,)
        Generalized coordinates.
    n_segments : int
        Number of segments N.
    base_rotation : casadi.SX or casadi.DM, shape (3, 3)
        World orientation of the base frame.
    s : casadi.SX
        Material coordinate of the whole robot, in [0, 1].
    point : casadi.Function, optional
        :func:`segment_point_function` (default: a new one, kept as calls).
    """
    point = segment_point_function() if point is None else point
    rotation, origin = base_rotation, ca.SX.zeros(3)
    candidates, blocks = [], []
    for j in range(n_segments):
        q_j = q[3 * j : 3 * j + 3]
        local = ca.fmin(ca.fmax(s * n_segments - j, 0.0), 1.0)
        r_local, p_local, linear, angular = point(q_j, local)
        r_tip, p_tip, linear_tip, angular_tip = point(q_j, 1.0)
        frame_rotation = rotation @ r_local
        candidates.append((frame_rotation, origin + rotation @ p_local))
        inside = ca.vertcat(rotation @ linear, frame_rotation @ angular)
        tip_origin, tip_rotation = origin + rotation @ p_tip, rotation @ r_tip
        # beyond the segment: the tip frame's twist per unit qd_j, moved to the point below
        blocks.append((j, inside, rotation @ linear_tip, tip_rotation @ angular_tip, tip_origin))
        rotation, origin = tip_rotation, tip_origin
    chosen_rotation, chosen_position = candidates[-1]
    for i in reversed(range(n_segments - 1)):
        before = s * n_segments < i + 1
        chosen_rotation = ca.if_else(before, candidates[i][0], chosen_rotation)
        chosen_position = ca.if_else(before, candidates[i][1], chosen_position)
    columns = []
    for j, inside, linear_tip, angular_tip, tip_origin in blocks:
        moved = linear_tip - ca.skew(chosen_position - tip_origin) @ angular_tip
        beyond = s * n_segments >= j + 1
        columns.append(ca.if_else(beyond, ca.vertcat(moved, angular_tip), inside))
    return MaterialPoint(chosen_rotation, chosen_position, ca.horzcat(*columns))
