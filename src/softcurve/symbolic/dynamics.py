"""Lagrangian dynamics (section 2.2 of the paper) as CasADi expressions.

``D(q) qdd + C(q, qd) qd + N(q) + R qd = tau + K^T lambda`` (eq. 16), with the creep
states ``lambda' = -rate * lambda - gain * qd`` (eq. 19). The robot's numbers are a
symbolic parameter vector ``p`` (see :meth:`Robot.parameter_vector`), so the same
expressions serve every robot of one structure.

Backbone integrals use Gauss-Legendre quadrature in the material coordinate. The
integrands are entire functions of ``s`` whose highest frequency is twice the
segment's bending angle ``beta``; ``DEFAULT_QUADRATURE_NODES`` nodes integrate them
to round-off for ``|beta| <= pi`` per segment (half a turn; the paper's robot stays
below 2 rad; measurements in docs/model.md), see
``tests/test_dynamics.py::test_quadrature_converged``.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.description.layout import ParameterLayout
from softcurve.description.materials import STIFFNESS_LAWS
from softcurve.symbolic.kinematics import segment_angular_jacobian, segment_pose

DEFAULT_QUADRATURE_NODES = 11


@dataclass(frozen=True)
class SegmentSymbols:
    """The symbolic parameters of one segment, sliced from ``p``.

    Parameters
    ----------
    rest_length, mass, radius : casadi.SX
        ``l0`` [m], ``m`` [kg] and ``r`` [m].
    elongation, bending : casadi.SX, shape (n_parameters,)
        The stiffness laws' parameters.
    damping : casadi.SX, shape (3, 3)
        ``R``.
    creep_rate, creep_gain : casadi.SX, shape (3,), or None
        Creep decay rates [1/s] and gains; None without creep.
    creep_compliance : casadi.SX, shape (3, 3), or None
        ``K`` of the creep force ``K^T lambda``; None without creep.
    """

    rest_length: ca.SX
    mass: ca.SX
    radius: ca.SX
    elongation: ca.SX
    bending: ca.SX
    damping: ca.SX
    creep_rate: ca.SX | None
    creep_gain: ca.SX | None
    creep_compliance: ca.SX | None


def unpack_parameters(p, layout: ParameterLayout):
    """Slice ``p`` into per-segment symbols, gravity (3,) and base rotation (3, 3).

    Parameters
    ----------
    p : casadi.SX, shape (layout.size,)
        The symbolic parameter vector.
    layout : ParameterLayout
        Where each field lies in ``p``.
    """
    part = layout.split(p)
    segments = []
    for k, (_, _, has_creep) in enumerate(layout.structure):
        head = f"segments[{k}]."
        fields = {name: part[head + name] for name in ("rest_length", "mass", "radius", "damping")}
        fields["elongation"] = part[head + "elongation_stiffness"]
        fields["bending"] = part[head + "bending_stiffness"]
        for name in ("rate", "gain", "compliance"):
            fields[f"creep_{name}"] = part[f"{head}creep.{name}"] if has_creep else None
        segments.append(SegmentSymbols(**fields))
    return segments, part["gravity"], part["base_rotation"]


@dataclass(frozen=True)
class DynamicsExpressions:
    """Every term of the equation of motion, as SX expressions of the symbols below.

    Parameters
    ----------
    q, qd, qdd, tau : casadi.SX, shape (n,)
        Symbols of the coordinates, their rates and accelerations, the input forces.
    lam : casadi.SX, shape (n_creep,)
        Symbol of the creep states.
    p : casadi.SX, shape (n_p,)
        Symbol of the parameter vector.
    n_segments : int
        Number of segments N.
    base_rotation : casadi.SX, shape (3, 3)
        The base frame's orientation, sliced from ``p``.
    mass_matrix, coriolis_matrix : casadi.SX, shape (n, n)
        ``D(q)`` and ``C(q, qd)``.
    coriolis_force, gravity_force, elastic_force, damping_force, creep_force : casadi.SX, (n,)
        ``C(q, qd) qd``, ``G(q)``, ``K(q)``, ``R qd`` and ``K^T lambda``.
    creep_rate : casadi.SX, shape (n_creep,)
        ``lambda'``.
    kinetic_energy, gravity_energy, elastic_energy : casadi.SX
        ``T``, ``V_g`` and ``V_e`` [J].
    forward_dynamics, inverse_dynamics : casadi.SX, shape (n,)
        ``qdd`` for given ``tau``, and ``tau`` for given ``qdd``.
    """

    q: ca.SX
    qd: ca.SX
    qdd: ca.SX
    tau: ca.SX
    lam: ca.SX
    p: ca.SX
    n_segments: int
    base_rotation: ca.SX
    mass_matrix: ca.SX
    coriolis_matrix: ca.SX
    coriolis_force: ca.SX
    gravity_force: ca.SX
    elastic_force: ca.SX
    damping_force: ca.SX
    creep_force: ca.SX
    creep_rate: ca.SX
    kinetic_energy: ca.SX
    gravity_energy: ca.SX
    elastic_energy: ca.SX
    forward_dynamics: ca.SX
    inverse_dynamics: ca.SX


def build_dynamics(
    structure: tuple, quadrature_nodes: int = DEFAULT_QUADRATURE_NODES
) -> DynamicsExpressions:
    """Assemble the equation of motion for a robot structure.

    The inertial and gravitational forces come from a recursive Newton-Euler pass over
    the segments (:func:`_newton_euler`), which costs O(N K) for N segments of K
    quadrature nodes: ``D`` column by column with ``qd = 0``, ``C qd`` with ``qdd = 0``
    and gravity with ``qd = qdd = 0``. The Christoffel matrix is
    ``C = d(C qd)/d(qd) / 2``, since the Christoffel symbols are symmetric in the two
    velocity indices.

    Parameters
    ----------
    structure : tuple
        ``Robot.structure()``: per segment (elongation law kind, bending law kind, has creep).
    quadrature_nodes : int
        Gauss-Legendre nodes per segment for the backbone integrals.
    """
    n_segments = len(structure)
    n = 3 * n_segments
    n_creep = 3 * sum(has_creep for *_, has_creep in structure)
    q, qd, qdd, tau = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd", "tau"))
    lam = ca.SX.sym("lam", n_creep)
    layout = ParameterLayout.of_structure(structure)
    p = ca.SX.sym("p", layout.size)
    segments, gravity, base_rotation = unpack_parameters(p, layout)
    chain = _SegmentChain(q, segments, quadrature_nodes)
    base_gravity = base_rotation.T @ gravity
    zero = ca.SX.zeros(n)

    mass_matrix = ca.horzcat(
        *(chain.newton_euler(zero, ca.SX(ca.DM.eye(n)[:, j]), ca.SX.zeros(3)) for j in range(n))
    )
    mass_matrix = 0.5 * (mass_matrix + mass_matrix.T)  # exact already; removes round-off
    coriolis_force = chain.newton_euler(qd, zero, ca.SX.zeros(3))
    bias_force = chain.newton_euler(qd, zero, base_gravity)  # C qd + G in one pass
    gravity_energy = chain.gravity_energy(base_gravity)
    # G alone as the gradient of V_g rather than a Newton-Euler pass with qd = qdd = 0:
    # the same force (tests/test_dynamics.py checks one against the other), in 40 % fewer
    # operations, and its Jacobian is the symmetric Hessian of V_g, which CasADi builds in
    # half the operations of the pass's Jacobian on three segments (the statics' Newton
    # matrix; benchmarks/bench_identification.py, section 2)
    gravity_force = ca.gradient(gravity_energy, q)

    elastic_force, elastic_energy = _elastic(q, segments, structure)
    kinetic_energy = 0.5 * ca.dot(qd, mass_matrix @ qd)
    damping_force = ca.diagcat(*(seg.damping for seg in segments)) @ qd
    creep_force, creep_rate = _creep(qd, lam, segments, n)

    generalized = tau + creep_force - bias_force - elastic_force - damping_force
    forward = ca.solve(mass_matrix, generalized)
    inverse = (
        chain.newton_euler(qd, qdd, base_gravity) + elastic_force + damping_force - creep_force
    )
    return DynamicsExpressions(
        q=q,
        qd=qd,
        qdd=qdd,
        tau=tau,
        lam=lam,
        p=p,
        n_segments=n_segments,
        base_rotation=base_rotation,
        mass_matrix=mass_matrix,
        coriolis_matrix=0.5 * ca.jacobian(coriolis_force, qd),
        coriolis_force=coriolis_force,
        gravity_force=gravity_force,
        elastic_force=elastic_force,
        damping_force=damping_force,
        creep_force=creep_force,
        creep_rate=creep_rate,
        kinetic_energy=kinetic_energy,
        gravity_energy=gravity_energy,
        elastic_energy=elastic_energy,
        forward_dynamics=forward,
        inverse_dynamics=inverse,
    )


@dataclass(frozen=True)
class _Point:
    """A material point of a segment, in the segment's base frame: rotation, position,
    their Jacobians w.r.t. the segment's coordinates (linear ``dp/dq_i``; angular in the
    point's own frame) and the quadrature weight times the segment mass."""

    rotation: ca.SX
    position: ca.SX
    linear: ca.SX
    angular: ca.SX
    mass: ca.SX


class _SegmentChain:
    """The robot's segments with their quadrature points, for Newton-Euler passes."""

    def __init__(self, q, segments, quadrature_nodes: int):
        nodes, weights = np.polynomial.legendre.leggauss(quadrature_nodes)
        self.q, self.segments = q, segments
        self.points, self.tips = [], []
        for i, seg in enumerate(segments):
            q_i = q[3 * i : 3 * i + 3]
            self.points.append(
                [
                    self._point(q_i, 0.5 * (x + 1.0), 0.5 * w * seg.mass)
                    for x, w in zip(nodes, weights, strict=True)
                ]
            )
            self.tips.append(self._point(q_i, 1.0, 0.0))

    @staticmethod
    def _point(q_i, s, mass) -> _Point:
        rotation, position = segment_pose(q_i, s)
        return _Point(
            rotation, position, ca.jacobian(position, q_i), segment_angular_jacobian(q_i, s), mass
        )

    def _coordinates(self, i):
        return self.q[3 * i : 3 * i + 3]

    def newton_euler(self, qd, qdd, base_gravity):
        """Generalized inertial plus gravitational forces ``D qdd + C qd + G``, shape (n,).

        Gravity enters as an upward acceleration ``-g`` of the base. Frame quantities are
        in the frame's own coordinates: angular velocity ``omega``, angular acceleration
        ``alpha`` and origin acceleration ``accel``.
        """
        n_segments = len(self.segments)
        omega, alpha, accel = ca.SX.zeros(3), ca.SX.zeros(3), -base_gravity
        frames = []
        for i in range(n_segments):
            frames.append((omega, alpha, accel))
            q_i, qd_i, qdd_i = self._coordinates(i), qd[3 * i : 3 * i + 3], qdd[3 * i : 3 * i + 3]
            # the tip slice's frame is the next segment's frame
            tip_accel, omega, alpha = _point_motion(
                self.tips[i], q_i, qd_i, qdd_i, omega, alpha, accel
            )
            accel = self.tips[i].rotation.T @ tip_accel
        forces = [None] * n_segments
        wrench_force, wrench_moment = ca.SX.zeros(3), ca.SX.zeros(3)  # from downstream
        for i in reversed(range(n_segments)):
            q_i, qd_i, qdd_i = self._coordinates(i), qd[3 * i : 3 * i + 3], qdd[3 * i : 3 * i + 3]
            omega, alpha, accel = frames[i]
            tip = self.tips[i]
            force_at_tip = tip.rotation @ wrench_force
            generalized = tip.linear.T @ force_at_tip + tip.angular.T @ wrench_moment
            total_force = force_at_tip
            total_moment = tip.rotation @ wrench_moment + ca.cross(tip.position, force_at_tip)
            for point in self.points[i]:
                linear_accel, body_omega, body_alpha = _point_motion(
                    point, q_i, qd_i, qdd_i, omega, alpha, accel
                )
                inertia = self.segments[i].radius ** 2 * ca.DM([0.25, 0.25, 0.5])
                force = point.mass * linear_accel
                moment = point.mass * (
                    inertia * body_alpha + ca.cross(body_omega, inertia * body_omega)
                )
                generalized += point.linear.T @ force + point.angular.T @ moment
                total_force += force
                total_moment += ca.cross(point.position, force) + point.rotation @ moment
            forces[i] = generalized
            wrench_force, wrench_moment = total_force, total_moment
        return ca.vertcat(*forces)

    def gravity_energy(self, base_gravity):
        """``-sum m g . x`` over the quadrature points, in base-frame coordinates."""
        rotation, origin, energy = ca.SX.eye(3), ca.SX.zeros(3), 0
        for points, tip in zip(self.points, self.tips, strict=True):
            for point in points:
                energy -= point.mass * ca.dot(base_gravity, origin + rotation @ point.position)
            origin = origin + rotation @ tip.position
            rotation = rotation @ tip.rotation
        return energy


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


def _elastic(q, segments, structure):
    """Elastic forces ``k(x) x dx/dq`` and energy, from the squared strains.

    Bending: ``beta dbeta/dq = d(beta^2)/dq / 2 = (l kappa^2, l^2 kx, l^2 ky)``, which is
    smooth at zero curvature where ``beta`` itself is not.
    """
    forces, energy = [], 0
    for i, (seg, (elongation_kind, bending_kind, _)) in enumerate(
        zip(segments, structure, strict=True)
    ):
        length, kx, ky = q[3 * i], q[3 * i + 1], q[3 * i + 2]
        eps = length - seg.rest_length
        kappa2 = kx**2 + ky**2
        beta2 = length**2 * kappa2
        k_e = STIFFNESS_LAWS[elongation_kind]
        k_b = STIFFNESS_LAWS[bending_kind]
        kb = k_b.coefficient(beta2, seg.bending)
        forces.append(
            ca.vertcat(
                k_e.coefficient(eps**2, seg.elongation) * eps + kb * length * kappa2,
                kb * length**2 * kx,
                kb * length**2 * ky,
            )
        )
        energy += k_e.energy(eps**2, seg.elongation) + k_b.energy(beta2, seg.bending)
    return ca.vertcat(*forces), energy


def _creep(qd, lam, segments, n):
    force = ca.SX.zeros(n)
    rates = []
    k = 0
    for i, seg in enumerate(segments):
        if seg.creep_rate is None:
            continue
        lam_i = lam[k : k + 3]
        force[3 * i : 3 * i + 3] = seg.creep_compliance.T @ lam_i
        rates.append(-seg.creep_rate * lam_i - seg.creep_gain * qd[3 * i : 3 * i + 3])
        k += 3
    rate = ca.vertcat(*rates) if rates else ca.SX(0, 1)
    return force, rate
