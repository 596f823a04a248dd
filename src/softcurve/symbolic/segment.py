"""What one element contributes to the dynamics of the chain, written once as CasADi
Functions of the element's own coordinates, for every element kind.

An element (a segment of coordinates ``q_i``, e.g. ``(l, kx, ky)``, or a rigid body of
none; :mod:`softcurve.description.elements`) is a body between two frames:
its base frame ``i`` and its tip frame ``i + 1`` (the next segment's base). Its
quadrature slices (``DEFAULT_QUADRATURE_NODES`` of :mod:`softcurve.symbolic.dynamics`,
Gauss-Legendre nodes in the material coordinate) move with the base frame and with
``q_i``, and everything downstream moves rigidly with its tip frame. The chain
algorithms (:mod:`softcurve.symbolic.chain`) need of each segment only the linear maps
between these quantities, all in the coordinates of the frame they belong to:

- accelerations ``A = (alpha, a)`` of a frame: angular acceleration and acceleration of
  its origin (classical, not spatial: the velocity terms are in the biases);
- wrenches ``W = (moment about the origin, force)``;
- the tip frame's acceleration ``A_tip = X A + S qdd_i + c``;
- the wrench the base must exert on the segment and all it carries,
  ``W = M A + H qdd_i + X^T W_tip + w``;
- the segment's generalized force ``tau_i = H^T A + D_i qdd_i + S^T W_tip + b``.

``X`` (6x6) is the rigid transform from the base to the tip frame, ``S`` (6 x n_i) the
tip's acceleration per unit ``qdd_i``, ``M`` (6x6) the element's spatial inertia about
its base, ``H`` (6 x n_i) its momentum per unit ``qd_i``, ``D_i`` (n_i x n_i) its own
mass matrix; the
biases ``c``, ``w``, ``b`` hold the velocity terms and depend on ``qd_i`` and on the base
frame's angular velocity. They are derived from one Newton-Euler pass over the slices
(:func:`segment_newton_euler`), the maps as its exact derivatives, so that the chain's
mass matrix, Coriolis terms and forward dynamics are one algebra.

Each quantity is an SX Function (:func:`segment_functions`), called once per element:
the generated code holds one copy of an element kind's work however many elements of
that kind the robot has. A robot of one structure calls the same Functions with each
element's numbers (its model's ``geometry``: mass, radius, rest strains ...).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from softcurve.description.elements import ElementModel


@dataclass(frozen=True)
class _Point:
    """A material point or rigid body of an element, in the element's base frame:
    rotation, position, their Jacobians w.r.t. the element's coordinates (linear
    ``dp/dq_i``; angular in the point's own frame), its mass and rotational inertia (3x3,
    its own frame)."""

    rotation: ca.SX
    position: ca.SX
    linear: ca.SX
    angular: ca.SX
    mass: ca.SX
    inertia: ca.SX


def _point(model: ElementModel, q_i, g, s, mass=0.0, inertia=None) -> _Point:
    rotation, position = model.point_pose(q_i, s, g) if s != 1.0 else model.tip_pose(q_i, g)
    inertia = ca.SX.zeros(3, 3) if inertia is None else inertia
    return _Point(
        rotation,
        position,
        ca.jacobian(position, q_i),
        model.angular_jacobian(q_i, s, g),
        mass,
        inertia,
    )


def _fixed(q_i, body) -> _Point:
    zero = ca.SX(3, q_i.shape[0])
    return _Point(ca.SX.eye(3), body.centre, zero, zero, body.mass, body.inertia)


def _velocity_bias(point, q_i, qd_i):
    """``(d/dt J) qd`` and ``(d/dt A) qd`` at fixed ``qd``: the point's relative
    acceleration and angular acceleration when ``qdd = 0``.

    Computed as derivatives along the line ``q + t qd`` in the scalar ``t`` (second
    derivative of the position, first of ``A qd``): one derivative direction instead of
    the three of ``jtimes(J qd, q, qd)``, which differentiates the Jacobian itself. On the
    paper's robot this cuts the compiled right-hand side by a third; both forms agree to
    round-off (``tests/test_dynamics.py`` checks the dynamics against energy and
    finite-difference identities).
    """
    t = ca.SX.sym("t")
    line = q_i + t * qd_i
    position = ca.substitute(point.position, q_i, line)
    linear_bias = ca.substitute(ca.jacobian(ca.jacobian(position, t), t), t, 0)
    relative_omega = ca.substitute(point.angular @ qd_i, q_i, line)
    angular_bias = ca.substitute(ca.jacobian(relative_omega, t), t, 0)
    return linear_bias, angular_bias


def _point_motion(point, q_i, qd_i, qdd_i, omega, alpha, accel):
    """Acceleration of a material point (segment-frame coordinates), and the angular
    velocity and acceleration of its slice (slice coordinates), given the segment frame's
    angular velocity ``omega``, angular acceleration ``alpha`` and origin acceleration
    ``accel`` (segment-frame coordinates)."""
    rate = point.linear @ qd_i  # velocity relative to the segment frame
    relative_omega = point.angular @ qd_i
    linear_bias, angular_bias = _velocity_bias(point, q_i, qd_i)
    r = point.position
    linear_accel = (
        accel
        + ca.cross(alpha, r)
        + ca.cross(omega, ca.cross(omega, r))
        + 2 * ca.cross(omega, rate)
        + point.linear @ qdd_i
        + linear_bias
    )
    frame_omega = point.rotation.T @ omega
    body_omega = frame_omega + relative_omega
    body_alpha = (
        point.rotation.T @ alpha
        - ca.cross(relative_omega, frame_omega)
        + point.angular @ qdd_i
        + angular_bias
    )
    return linear_accel, body_omega, body_alpha


@dataclass(frozen=True)
class SegmentNewtonEuler:
    """One segment's Newton-Euler relations as SX expressions of its symbols.

    Parameters
    ----------
    q, qd, qdd : casadi.SX, shape (n_i,)
        The element's coordinates, rates and accelerations.
    omega : casadi.SX, shape (3,)
        Angular velocity of the base frame [rad/s], base coordinates.
    acceleration : casadi.SX, shape (6,)
        ``A = (alpha, a)`` of the base frame [rad/s^2, m/s^2], base coordinates.
    tip_wrench : casadi.SX, shape (6,)
        ``W_tip`` [N m, N], the wrench the segment exerts on what it carries, tip
        coordinates.
    geometry : casadi.SX, shape (n_g,)
        The element's numbers (its model's ``geometry``).
    tip_omega : casadi.SX, shape (3,)
        Angular velocity of the tip frame, tip coordinates.
    tip_acceleration : casadi.SX, shape (6,)
        ``A_tip``, tip coordinates.
    base_wrench : casadi.SX, shape (6,)
        ``W``, the wrench on the segment and all it carries, base coordinates.
    force : casadi.SX, shape (n_i,)
        ``tau_i``, conjugate to ``q_i`` (e.g. [N, N m^2, N m^2]).
    tip_rotation : casadi.SX, shape (3, 3)
        Orientation of the tip frame in the base frame.
    tip_position : casadi.SX, shape (3,)
        Position [m] of the tip frame's origin, base coordinates.
    moment : casadi.SX, shape (3,)
        The element's first moment of mass ``sum m_k p_k`` [kg m], base coordinates.
    mass : casadi.SX
        The element's mass [kg].
    """

    q: ca.SX
    qd: ca.SX
    qdd: ca.SX
    omega: ca.SX
    acceleration: ca.SX
    tip_wrench: ca.SX
    geometry: ca.SX
    tip_omega: ca.SX
    tip_acceleration: ca.SX
    base_wrench: ca.SX
    force: ca.SX
    tip_rotation: ca.SX
    tip_position: ca.SX
    moment: ca.SX
    mass: ca.SX


def segment_newton_euler(model: ElementModel, quadrature_nodes: int) -> SegmentNewtonEuler:
    """The Newton-Euler pass over one element's slices (or its rigid body), forward (tip
    motion) and backward (base wrench and generalized force).

    Parameters
    ----------
    model : ElementModel
        The element kind's model.
    quadrature_nodes : int
        Gauss-Legendre nodes along a segment.
    """
    nq = model.nq
    q, qd, qdd = (ca.SX.sym(name, nq) for name in ("q", "qd", "qdd"))
    omega = ca.SX.sym("omega", 3)
    acceleration, tip_wrench = ca.SX.sym("A", 6), ca.SX.sym("W_tip", 6)
    geometry = ca.SX.sym("g", model.geometry_size())
    alpha, accel = acceleration[:3], acceleration[3:]
    points = [
        _fixed(q, body) if body.s is None else _point(model, q, geometry, body.s, body.mass,
                                                      body.inertia)
        for body in model.bodies(geometry, quadrature_nodes)
    ]  # fmt: skip
    tip = _point(model, q, geometry, 1.0)
    tip_accel, tip_omega, tip_alpha = _point_motion(tip, q, qd, qdd, omega, alpha, accel)

    tip_moment, tip_force = tip_wrench[:3], tip_wrench[3:]
    force_at_tip = tip.rotation @ tip_force
    generalized = tip.linear.T @ force_at_tip + tip.angular.T @ tip_moment
    total_force = force_at_tip
    total_moment = tip.rotation @ tip_moment + ca.cross(tip.position, force_at_tip)
    moment, mass = ca.SX.zeros(3), 0
    for point in points:
        linear_accel, body_omega, body_alpha = _point_motion(point, q, qd, qdd, omega, alpha, accel)
        slice_force = point.mass * linear_accel
        slice_moment = point.inertia @ body_alpha + ca.cross(body_omega, point.inertia @ body_omega)
        generalized += point.linear.T @ slice_force + point.angular.T @ slice_moment
        total_force += slice_force
        total_moment += ca.cross(point.position, slice_force) + point.rotation @ slice_moment
        moment += point.mass * point.position
        mass += point.mass
    return SegmentNewtonEuler(
        q=q,
        qd=qd,
        qdd=qdd,
        omega=omega,
        acceleration=acceleration,
        tip_wrench=tip_wrench,
        geometry=geometry,
        tip_omega=tip_omega,
        tip_acceleration=ca.vertcat(tip_alpha, tip.rotation.T @ tip_accel),
        base_wrench=ca.vertcat(total_moment, total_force),
        force=generalized,
        tip_rotation=tip.rotation,
        tip_position=tip.position,
        moment=moment,
        mass=mass,
    )


@dataclass(frozen=True)
class SegmentFunctions:
    """One segment's terms as CasADi Functions (see the module's docstring for the
    symbols).

    Parameters
    ----------
    frame : casadi.Function
        ``(q_i, g) -> (R_tip (3, 3), r_tip (3,), moment (3,), mass)``: the tip frame's
        pose [m] and the first moment of mass [kg m] in the base frame, and the mass [kg].
    motion : casadi.Function
        ``(q_i, qd_i, omega, g) -> (X, S, M, H, D_i, omega_tip, c, w, b)``:
        the configuration's linear maps and the velocity terms. One Function for both:
        the maps and the velocity terms share the slices' poses and Jacobians, and a
        library holding a second Function of the maps alone compiles for as long again
        (the maps of a configuration alone are ``motion`` at ``qd_i = 0``).
    """

    frame: ca.Function
    motion: ca.Function


INERTIA_OUTPUTS = ("X", "S", "M", "H", "D")
"""Names of the linear maps of a segment, the first outputs of
``SegmentFunctions.motion``."""

BIAS_OUTPUTS = ("omega_tip", "c", "w", "b")
"""Names of the velocity terms, the last outputs of ``SegmentFunctions.motion``."""


def segment_functions(
    model: ElementModel, quadrature_nodes: int, inline: bool = False, name: str = "segment"
) -> SegmentFunctions:
    """The Functions of an element kind (segments of ``quadrature_nodes`` slices).

    Parameters
    ----------
    model : ElementModel
        The element kind's model.
    quadrature_nodes : int
        Gauss-Legendre nodes along the segment.
    name : str
        The Functions' prefix, unique per kind within a model (generated C names them).
    inline : bool
        Whether the Functions are inlined where they are called (False: they stay calls,
        so generated code and derivatives hold one copy per Function). Inlined, a model's
        Functions count every operation in ``n_instructions()``.

    Notes
    -----
    Built anew for each model: CasADi keeps the derivatives it makes of a Function, and
    a shared Function would make a model's generated code (and so its round-off) depend
    on what the process built before.
    """
    e = segment_newton_euler(model, quadrature_nodes)
    accelerations = ca.vertcat(e.qdd, e.acceleration, e.tip_wrench)

    def at_rest(expression):
        return ca.substitute(expression, accelerations, ca.SX.zeros(accelerations.shape[0]))

    maps = [
        ca.jacobian(e.tip_acceleration, e.acceleration),
        ca.jacobian(e.tip_acceleration, e.qdd),
        ca.jacobian(e.base_wrench, e.acceleration),
        ca.jacobian(e.base_wrench, e.qdd),
        ca.jacobian(e.force, e.qdd),
    ]
    maps[-1] = 0.5 * (maps[-1] + maps[-1].T)  # symmetric already; removes round-off
    # the relations are linear in the accelerations and W_tip: their derivatives are the
    # maps, free of those symbols once they are set to zero
    maps = [at_rest(m) for m in maps]
    biases = [e.tip_omega, *(at_rest(v) for v in (e.tip_acceleration, e.base_wrench, e.force))]
    options = {"never_inline": not inline, "cse": True}
    return SegmentFunctions(
        frame=ca.Function(
            f"{name}_frame",
            [e.q, e.geometry],
            [e.tip_rotation, e.tip_position, e.moment, e.mass],
            ["q", "g"],
            ["R_tip", "r_tip", "moment", "mass"],
            options,
        ),
        motion=ca.Function(
            f"{name}_motion",
            [e.q, e.qd, e.omega, e.geometry],
            [*maps, *biases],
            ["q", "qd", "omega", "g"],
            [*INERTIA_OUTPUTS, *BIAS_OUTPUTS],
            options,
        ),
    )
