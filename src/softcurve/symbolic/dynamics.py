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

from softcurve.description.layout import ParameterLayout
from softcurve.description.materials import STIFFNESS_LAWS
from softcurve.symbolic import chain
from softcurve.symbolic.kinematics import inline_calls
from softcurve.symbolic.segment import segment_functions

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
    structure: tuple,
    quadrature_nodes: int = DEFAULT_QUADRATURE_NODES,
    inline: bool | None = None,
) -> DynamicsExpressions:
    """Assemble the equation of motion for a robot structure.

    The inertial and gravitational terms come from the algorithms over the chain
    (:mod:`softcurve.symbolic.chain`), each calling one segment's Functions
    (:mod:`softcurve.symbolic.segment`) once per segment: the mass matrix by the
    composite-body algorithm, ``C qd`` and the inverse dynamics by the recursive
    Newton-Euler algorithm, the forward dynamics by the articulated-body algorithm. The
    Christoffel matrix is ``C = d(C qd)/d(qd) / 2``, since the Christoffel symbols are
    symmetric in the two velocity indices.

    Parameters
    ----------
    structure : tuple
        ``Robot.structure()``: per segment (elongation law kind, bending law kind, has creep).
    quadrature_nodes : int
        Gauss-Legendre nodes per segment for the backbone integrals.
    inline : bool or None
        Whether the segment's Functions are inlined (True: the expressions hold every
        operation, as :meth:`casadi.Function.n_instructions` then counts them) or stay
        calls (False: one copy of a segment's work, however many segments). None: as
        :func:`~softcurve.symbolic.kinematics.inline_calls` says.
    """
    n_segments = len(structure)
    n = 3 * n_segments
    n_creep = 3 * sum(has_creep for *_, has_creep in structure)
    q, qd, qdd, tau = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd", "tau"))
    lam = ca.SX.sym("lam", n_creep)
    layout = ParameterLayout.of_structure(structure)
    p = ca.SX.sym("p", layout.size)
    segments, gravity, base_rotation = unpack_parameters(p, layout)
    inline = inline_calls(n_segments) if inline is None else inline
    functions = segment_functions(quadrature_nodes, inline)
    steps = chain.chain_steps(functions, inline)
    base_gravity = base_rotation.T @ gravity
    at_rest, falling = ca.SX.zeros(6), ca.vertcat(ca.SX.zeros(3), -base_gravity)

    motions = chain.segment_motions(functions, q, qd, segments)
    # of q alone, though built from the Functions that take qd too (see
    # SegmentFunctions.motion): a Function of q alone takes it at qd = 0
    mass_matrix = chain.mass_matrix(steps, motions)
    coriolis_force = chain.inverse_dynamics(steps, motions, ca.SX.zeros(n), at_rest)
    gravity_energy = chain.gravity_energy(functions, q, segments, base_gravity)
    # G as the gradient of V_g rather than a Newton-Euler pass with qd = qdd = 0: the same
    # force (tests/test_dynamics.py checks one against the other), and its Jacobian is the
    # symmetric Hessian of V_g (the statics' Newton matrix)
    gravity_force = ca.gradient(gravity_energy, q)

    elastic_force, elastic_energy = _elastic(q, segments, structure)
    kinetic_energy = 0.5 * ca.dot(qd, mass_matrix @ qd)
    damping_force = ca.diagcat(*(seg.damping for seg in segments)) @ qd
    creep_force, creep_rate = _creep(qd, lam, segments, n)

    generalized = tau + creep_force - elastic_force - damping_force
    forward = chain.forward_dynamics(steps, motions, generalized, falling)
    inertial = chain.inverse_dynamics(steps, motions, qdd, falling)
    inverse = inertial + elastic_force + damping_force - creep_force
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
