"""Lagrangian dynamics (section 2.2 of the paper) as CasADi expressions.

``D(q) qdd + C(q, qd) qd + N(q) + R qd = tau + K^T lambda`` (eq. 16), with the creep
states ``lambda' = -rate * lambda - gain * qd`` (eq. 19). The robot's numbers are a
symbolic parameter vector ``p`` (see :meth:`Robot.parameter_vector`), so the same
expressions serve every robot of one structure.

Backbone integrals use Gauss-Legendre quadrature in the material coordinate. The
integrands are entire functions of ``s`` whose highest frequency is twice the
segment's bending angle ``beta``; ``DEFAULT_QUADRATURE_NODES`` nodes integrate them
to machine precision for ``|beta| <= pi`` per segment (half a turn; the paper's
robot stays below 2 rad), see ``tests/test_dynamics.py::test_quadrature_converged``.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from .kinematics import segment_frames
from .materials import STIFFNESS_LAWS, Creep

DEFAULT_QUADRATURE_NODES = 12


@dataclass(frozen=True)
class SegmentSymbols:
    """The symbolic parameters of one segment, sliced from ``p``."""

    rest_length: ca.SX
    mass: ca.SX
    radius: ca.SX
    elongation: ca.SX
    bending: ca.SX
    damping: ca.SX  # (3, 3)
    creep_rate: ca.SX | None
    creep_gain: ca.SX | None
    creep_compliance: ca.SX | None  # (3, 3)


def parameter_count(structure: tuple) -> int:
    """Length of the parameter vector for a robot structure (see Robot.structure)."""
    count = 0
    for elongation_kind, bending_kind, has_creep in structure:
        count += 3 + STIFFNESS_LAWS[elongation_kind].n_parameters
        count += STIFFNESS_LAWS[bending_kind].n_parameters + 9
        count += Creep.n_parameters if has_creep else 0
    return count + 3 + 9


def unpack_parameters(p, structure: tuple):
    """Slice ``p`` into per-segment symbols, gravity (3,) and base rotation (3, 3)."""
    segments, k = [], 0

    def take(size):
        nonlocal k
        part = p[k : k + size]
        k += size
        return part

    for elongation_kind, bending_kind, has_creep in structure:
        l0, m, r = take(1), take(1), take(1)
        elongation = take(STIFFNESS_LAWS[elongation_kind].n_parameters)
        bending = take(STIFFNESS_LAWS[bending_kind].n_parameters)
        damping = ca.reshape(take(9), 3, 3).T
        rate = gain = compliance = None
        if has_creep:
            rate, gain, compliance = take(3), take(3), ca.reshape(take(9), 3, 3).T
        segments.append(
            SegmentSymbols(l0, m, r, elongation, bending, damping, rate, gain, compliance)
        )
    gravity = take(3)
    base_rotation = ca.reshape(take(9), 3, 3).T
    return segments, gravity, base_rotation


@dataclass(frozen=True)
class DynamicsExpressions:
    """Every term of the equation of motion, as SX expressions of the symbols below.

    Symbols: ``q, qd, qdd, tau`` (n,), ``lam`` (n_creep,), ``p`` (n_p,).
    """

    q: ca.SX
    qd: ca.SX
    qdd: ca.SX
    tau: ca.SX
    lam: ca.SX
    p: ca.SX
    n_segments: int
    base_rotation: ca.SX  # (3, 3), sliced from p
    mass_matrix: ca.SX
    coriolis_matrix: ca.SX
    coriolis_force: ca.SX  # C(q, qd) qd
    gravity_force: ca.SX
    elastic_force: ca.SX
    damping_force: ca.SX
    creep_force: ca.SX  # K^T lambda
    creep_rate: ca.SX  # lambda'
    kinetic_energy: ca.SX
    gravity_energy: ca.SX
    elastic_energy: ca.SX
    forward_dynamics: ca.SX  # qdd
    inverse_dynamics: ca.SX  # tau


def build_dynamics(
    structure: tuple, quadrature_nodes: int = DEFAULT_QUADRATURE_NODES
) -> DynamicsExpressions:
    """Assemble the equation of motion for a robot structure.

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
    p = ca.SX.sym("p", parameter_count(structure))
    segments, gravity, base_rotation = unpack_parameters(p, structure)

    nodes, weights = np.polynomial.legendre.leggauss(quadrature_nodes)
    nodes, weights = 0.5 * (nodes + 1.0), 0.5 * weights
    points = [(i, float(s)) for i in range(n_segments) for s in nodes]
    frames = segment_frames(q, n_segments, base_rotation, points)

    # Kane's form: generalized inertia forces of each slice, J^T (m a) and the body-frame
    # J_w^T (I w' + w x I w), with the accelerations' velocity-dependent parts taken by
    # forward-mode differentiation along qd. Equal to the Christoffel form of C qd.
    mass_matrix = ca.SX.zeros(n, n)
    coriolis_force = ca.SX.zeros(n)
    gravity_force = ca.SX.zeros(n)
    gravity_energy = 0
    for k, ((i, _), frame) in enumerate(zip(points, frames)):
        seg, w = segments[i], weights[k % quadrature_nodes]
        linear = ca.jacobian(frame.position, q)
        angular = frame.angular_jacobian
        r2 = seg.radius**2
        inertia = ca.vertcat(r2 / 4, r2 / 4, r2 / 2)
        velocity, omega = linear @ qd, angular @ qd
        linear_bias = ca.jtimes(velocity, q, qd)
        angular_bias = ca.jtimes(omega, q, qd)
        mass_matrix += w * seg.mass * (linear.T @ linear + angular.T @ (inertia * angular))
        coriolis_force += (
            w
            * seg.mass
            * (
                linear.T @ linear_bias
                + angular.T @ (inertia * angular_bias + ca.cross(omega, inertia * omega))
            )
        )
        gravity_force -= w * seg.mass * (linear.T @ gravity)
        gravity_energy -= w * seg.mass * ca.dot(gravity, frame.position)

    elastic_force, elastic_energy = _elastic(q, segments, structure)
    kinetic_energy = 0.5 * ca.dot(qd, mass_matrix @ qd)
    damping_force = ca.diagcat(*(seg.damping for seg in segments)) @ qd
    creep_force, creep_rate = _creep(qd, lam, segments, n)

    generalized = tau + creep_force - coriolis_force - gravity_force - elastic_force - damping_force
    forward = ca.solve(mass_matrix, generalized)
    inverse = (
        mass_matrix @ qdd
        + coriolis_force
        + gravity_force
        + elastic_force
        + damping_force
        - creep_force
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
        coriolis_matrix=_christoffel(mass_matrix, q, qd),
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


def _elastic(q, segments, structure):
    """Elastic forces ``k(x) x dx/dq`` and energy, from the squared strains.

    Bending: ``beta dbeta/dq = d(beta^2)/dq / 2 = (l kappa^2, l^2 kx, l^2 ky)``, which is
    smooth at zero curvature where ``beta`` itself is not.
    """
    forces, energy = [], 0
    for i, (seg, (elongation_kind, bending_kind, _)) in enumerate(zip(segments, structure)):
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


def _christoffel(mass_matrix, q, qd):
    """``C_ij = sum_k 1/2 (dD_ij/dq_k + dD_ik/dq_j - dD_jk/dq_i) qd_k``.

    The three sums are ``Ddot``, ``A = d(D qd)/dq`` and ``A^T``: ``C = (Ddot + A - A^T) / 2``.
    """
    a = ca.jacobian(mass_matrix @ qd, q)
    d_dot = ca.jtimes(mass_matrix, q, qd)
    return 0.5 * (d_dot + a - a.T)
