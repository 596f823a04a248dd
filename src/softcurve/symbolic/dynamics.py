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

from softcurve.description.elements import coordinate_slices, element_model
from softcurve.description.layout import ParameterLayout
from softcurve.symbolic import chain
from softcurve.symbolic.kinematics import inline_calls
from softcurve.symbolic.segment import segment_functions

DEFAULT_QUADRATURE_NODES = 11


def unpack_parameters(p, layout: ParameterLayout):
    """Slice ``p`` into each element's fields (field name -> SX, matrices as matrices),
    gravity (3,), base rotation (3, 3) and base position (3,).

    Parameters
    ----------
    p : casadi.SX, shape (layout.size,)
        The symbolic parameter vector.
    layout : ParameterLayout
        Where each field lies in ``p``.
    """
    part = layout.split(p)
    elements = layout.element_parts(p)
    return elements, part["gravity"], part["base_rotation"], part["base_position"]


def chain_elements(structure: tuple, parts: list[dict], quadrature_nodes: int, inline: bool):
    """The chain's elements (:class:`~softcurve.symbolic.chain.ChainElement`) of a
    structure: one set of Functions and steps per distinct signature, shared by every
    element of it.

    Parameters
    ----------
    structure : tuple
        ``Robot.structure()``.
    parts : list of dict
        Each element's fields (:func:`unpack_parameters`).
    quadrature_nodes : int
        Gauss-Legendre nodes per segment.
    inline : bool
        Whether the Functions are inlined.
    """
    kinds: dict[tuple, tuple] = {}
    elements = []
    for signature, part, k in zip(structure, parts, coordinate_slices(structure), strict=True):
        if signature not in kinds:
            model = element_model(signature)
            name = f"{signature[0]}{len(kinds)}_" if len(set(structure)) > 1 else "segment_"
            functions = segment_functions(model, quadrature_nodes, inline, name=name.rstrip("_"))
            kinds[signature] = (model, functions, chain.chain_steps(functions, inline, name))
        model, functions, steps = kinds[signature]
        elements.append(chain.ChainElement(functions, steps, model.geometry(part), k))
    return elements


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
        Number of elements N.
    structure : tuple
        ``Robot.structure()``.
    base_rotation : casadi.SX, shape (3, 3)
        The base frame's orientation, sliced from ``p``.
    base_position : casadi.SX, shape (3,)
        The base frame's origin [m], sliced from ``p``.
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
    generalized_force : casadi.SX, shape (n,)
        Every generalized force but the inertial and gravitational ones, which
        ``forward_dynamics`` balances: ``tau + K^T lambda - K(q) - R qd`` (and the
        contact force, :func:`~softcurve.symbolic.contact.with_contact`).
    base_acceleration : casadi.SX, shape (6,)
        The base frame's ``(alpha, a)`` that carries gravity: ``(0, -g)`` in base
        coordinates.
    """

    q: ca.SX
    qd: ca.SX
    qdd: ca.SX
    tau: ca.SX
    lam: ca.SX
    p: ca.SX
    n_segments: int
    structure: tuple
    base_rotation: ca.SX
    base_position: ca.SX
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
    generalized_force: ca.SX
    base_acceleration: ca.SX


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
        ``Robot.structure()``: each element's signature.
    quadrature_nodes : int
        Gauss-Legendre nodes per segment for the backbone integrals.
    inline : bool or None
        Whether the segment's Functions are inlined (True: the expressions hold every
        operation, as :meth:`casadi.Function.n_instructions` then counts them) or stay
        calls (False: one copy of a segment's work, however many segments). None: as
        :func:`~softcurve.symbolic.kinematics.inline_calls` says.
    """
    n_segments = len(structure)
    models = [element_model(signature) for signature in structure]
    n = coordinate_slices(structure)[-1].stop
    n_creep = sum(m.n_creep for m in models)
    q, qd, qdd, tau = (ca.SX.sym(name, n) for name in ("q", "qd", "qdd", "tau"))
    lam = ca.SX.sym("lam", n_creep)
    layout = ParameterLayout.of_structure(structure)
    p = ca.SX.sym("p", layout.size)
    parts, gravity, base_rotation, base_position = unpack_parameters(p, layout)
    inline = inline_calls(n_segments) if inline is None else inline
    elements = chain_elements(structure, parts, quadrature_nodes, inline)
    base_gravity = base_rotation.T @ gravity
    at_rest, falling = ca.SX.zeros(6), ca.vertcat(ca.SX.zeros(3), -base_gravity)

    motions = chain.segment_motions(elements, q, qd)
    # of q alone, though built from the Functions that take qd too (see
    # SegmentFunctions.motion): a Function of q alone takes it at qd = 0
    mass_matrix = chain.mass_matrix(motions, n)
    coriolis_force = chain.inverse_dynamics(motions, ca.SX.zeros(n), at_rest)
    base_origin = base_rotation.T @ base_position
    gravity_energy = chain.gravity_energy(elements, q, base_gravity, base_origin)
    # G as the gradient of V_g rather than a Newton-Euler pass with qd = qdd = 0: the same
    # force (tests/test_dynamics.py checks one against the other), and its Jacobian is the
    # symmetric Hessian of V_g (the statics' Newton matrix)
    gravity_force = ca.gradient(gravity_energy, q)

    elastic_force, elastic_energy = _elastic(q, models, parts, elements)
    kinetic_energy = 0.5 * ca.dot(qd, mass_matrix @ qd)
    damping_force = ca.diagcat(*(m.damping(part) for m, part in zip(models, parts, strict=True)))
    damping_force = damping_force @ qd
    creep_force, creep_rate = _creep(qd, lam, models, parts, elements, n)

    generalized = tau + creep_force - elastic_force - damping_force
    forward = chain.forward_dynamics(motions, generalized, falling)
    inertial = chain.inverse_dynamics(motions, qdd, falling)
    inverse = inertial + elastic_force + damping_force - creep_force
    return DynamicsExpressions(
        q=q,
        qd=qd,
        qdd=qdd,
        tau=tau,
        lam=lam,
        p=p,
        n_segments=n_segments,
        structure=structure,
        base_rotation=base_rotation,
        base_position=base_position,
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
        generalized_force=generalized,
        base_acceleration=falling,
    )


def _elastic(q, models, parts, elements):
    """Elastic forces and energy, each element's model's."""
    forces, energy = [], 0
    for model, part, element in zip(models, parts, elements, strict=True):
        if not model.nq:
            continue
        element_energy, force = model.elastic(q[element.coordinates], part)
        forces.append(force)
        energy += element_energy
    return ca.vertcat(*forces), energy


def _creep(qd, lam, models, parts, elements, n):
    force = ca.SX.zeros(n)
    rates = []
    k = 0
    for model, part, element in zip(models, parts, elements, strict=True):
        creep = model.creep(part)
        if creep is None:
            continue
        rate, gain, compliance = creep
        lam_i = lam[k : k + model.n_creep]
        force[element.coordinates] = compliance.T @ lam_i
        rates.append(-rate * lam_i - gain * qd[element.coordinates])
        k += model.n_creep
    rate = ca.vertcat(*rates) if rates else ca.SX(0, 1)
    return force, rate
