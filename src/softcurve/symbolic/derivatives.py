"""The exact Jacobian of the state derivative, by the derivatives of the chain algorithms.

The accelerations solve ``ID(q, qd, qdd) = F(x, tau)``, with ``ID`` the inertial inverse
dynamics (:func:`softcurve.symbolic.chain.inverse_dynamics`: ``D qdd + C qd + G``) and
``F`` every other generalized force (inputs, contact, creep, minus the elastic and
damping forces). Differentiated at the solution, holding ``qdd``:

    d qdd / dx = D^-1 (dF/dx - dID/dx),        d qdd / d tau = D^-1,

the derivatives of the forward dynamics from those of the inverse dynamics (Carpentier
and Mansard, "Analytical derivatives of rigid body dynamics algorithms", RSS 2018, as
Pinocchio's ``computeABADerivatives``). ``dID/dx`` is the recursive Newton-Euler
algorithm's tangent: along one direction of ``(q, qd, qdd)`` the segment terms change by
their local Jacobian (each element's outputs by its own coordinates, rates and base
angular velocity, one call per element) and the tangent runs through the steps' forward
derivatives, outward and back, a pass of ``O(N)``; its columns along ``qdd`` are the mass
matrix ``D``. The passes of the ``3 n`` directions are one mapped Function, so that the
generated code holds one pass however many directions: ``O(N^2)`` operations, ``O(N)``
code. ``D`` is factored by CasADi's sparse ``LDL^T``.

Against the forward differences the C driver takes otherwise (``n_state + 1`` right-hand
sides per Jacobian) it is exact, and at more than one segment cheaper
(``benchmarks/bench_jacobian.py``).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from softcurve.description.layout import ParameterLayout
from softcurve.symbolic import chain
from softcurve.symbolic.dynamics import chain_elements, unpack_parameters
from softcurve.symbolic.segment import BIAS_OUTPUTS, INERTIA_OUTPUTS

_NAMES = (*INERTIA_OUTPUTS, *BIAS_OUTPUTS)
_OPTIONS = {"never_inline": True, "cse": True}


def _nonzeros(parts) -> ca.SX:
    """The nonzeros of ``parts`` in one column."""
    columns = [part.nz[:] for part in parts if part.nnz()]
    return ca.vertcat(*columns) if columns else ca.SX(0, 1)


def _from_nonzeros(vector, patterns) -> list:
    """``vector`` cut into matrices of ``patterns`` (:func:`_nonzeros` undone)."""
    parts, start = [], 0
    for pattern in patterns:
        parts.append(ca.SX(pattern, vector[start : start + pattern.nnz()]))
        start += pattern.nnz()
    return parts


def local_jacobian(motion: ca.Function) -> ca.Function:
    """``(q_i, qd_i, omega, g) -> (the outputs of motion..., L)``: an element kind's terms
    and ``L``, the derivatives of their nonzeros (column by column of each output) by
    ``(q_i, qd_i, omega)``, shape (nnz, 2 n_i + 3).

    Parameters
    ----------
    motion : casadi.Function
        The kind's ``SegmentFunctions.motion``.
    """
    inputs = [ca.SX.sym(name, motion.sparsity_in(k)) for k, name in enumerate(motion.name_in())]
    q, qd, omega, _ = inputs
    outputs = motion(*inputs)
    local = ca.jacobian(_nonzeros(outputs), ca.vertcat(q, qd, omega))
    return ca.Function(
        f"{motion.name()}_local",
        inputs,
        [*outputs, local],
        list(motion.name_in()),
        [*_NAMES, "L"],
        _OPTIONS,
    )


def _tangent_pass(elements, patterns, shared, direction):
    """``dID`` (n,) along ``direction = (dq, dqd, dqdd)`` at the passes ``shared``."""
    terms, local, qdd, accelerations, wrenches = shared
    dq, dqd, dqdd = direction
    d_omega, d_acceleration = ca.SX.zeros(3), ca.SX.zeros(6)
    segment_terms, tangents, start = [], [], 0
    term_start = 0
    for element, (pattern, local_pattern) in zip(elements, patterns, strict=True):
        k = element.coordinates
        size = sum(p.nnz() for p in pattern)
        values = _from_nonzeros(terms[term_start : term_start + size], pattern)
        term_start += size
        jacobian = ca.SX(local_pattern, local[start : start + local_pattern.nnz()])
        start += local_pattern.nnz()
        change = _from_nonzeros(jacobian @ ca.vertcat(dq[k], dqd[k], d_omega), pattern)
        d_omega = change[_NAMES.index("omega_tip")]
        segment_terms.append(values)
        tangents.append(change)
    base_tangents = []
    for i, element in enumerate(elements):
        k = element.coordinates
        a = accelerations[6 * i : 6 * i + 6]
        base_tangents.append(d_acceleration)
        tip = element.steps.tip_acceleration(*segment_terms[i], qdd[k], a)
        d_acceleration = ca.jtimes(
            tip,
            ca.vertcat(_nonzeros(segment_terms[i]), qdd[k], a),
            ca.vertcat(_nonzeros(tangents[i]), dqdd[k], d_acceleration),
        )
    forces, d_wrench = [None] * len(elements), ca.SX.zeros(6)
    for i in reversed(range(len(elements))):
        element = elements[i]
        k = element.coordinates
        a, w = accelerations[6 * i : 6 * i + 6], wrenches[6 * i : 6 * i + 6]
        force, wrench = element.steps.newton_euler(*segment_terms[i], a, qdd[k], w)
        wrt = ca.vertcat(_nonzeros(segment_terms[i]), a, qdd[k], w)
        seeds = ca.vertcat(_nonzeros(tangents[i]), base_tangents[i], dqdd[k], d_wrench)
        forces[i] = ca.jtimes(force, wrt, seeds)
        d_wrench = ca.jtimes(wrench, wrt, seeds)
    return ca.vertcat(*forces)


def state_jacobian(e, quadrature_nodes: int) -> ca.Function:
    """``(x, tau, p) -> (J_x, D)``: the Jacobian of the state derivative ``rhs`` by the
    state ``x = (q, qd, lam)`` (n_x, n_x), exact (see the module docstring), and the mass
    matrix ``D`` (n, n), whose inverse is the accelerations' derivative by the
    generalized input force ``tau``.

    Parameters
    ----------
    e : DynamicsExpressions
        The model's expressions (with contact, :class:`ContactExpressions`, whose
        contact force enters ``F``).
    quadrature_nodes : int
        Gauss-Legendre nodes per segment, as the model's.
    """
    structure, n = e.structure, e.q.shape[0]
    x = ca.vertcat(e.q, e.qd, e.lam)
    parts, gravity, base_rotation, _ = unpack_parameters(
        e.p, ParameterLayout.of_structure(structure)
    )
    elements = chain_elements(structure, parts, quadrature_nodes, inline=False)
    falling = ca.vertcat(ca.SX.zeros(3), -(base_rotation.T @ gravity))
    contact = getattr(e, "contact_force", 0)
    force = e.tau + contact + e.creep_force - e.elastic_force - e.damping_force

    locals_, terms, jacobians, patterns = {}, [], [], []
    omega = ca.SX.zeros(3)
    for element in elements:
        k, motion = element.coordinates, element.functions.motion
        if motion.name() not in locals_:
            locals_[motion.name()] = local_jacobian(motion)
        *outputs, local = locals_[motion.name()](e.q[k], e.qd[k], omega, element.geometry)
        terms.append(
            chain.SegmentTerms(**dict(zip(_NAMES, outputs, strict=True)), steps=element.steps,
                               coordinates=k)
        )  # fmt: skip
        jacobians.append(local)
        patterns.append(([o.sparsity() for o in outputs], local.sparsity()))
        omega = outputs[_NAMES.index("omega_tip")]
    qdd = chain.forward_dynamics(terms, force, falling)
    passes = chain.newton_euler_passes(terms, qdd, falling)
    shared = [
        _nonzeros([_nonzeros(chain.arguments(t)) for t in terms]),
        _nonzeros(jacobians),
        qdd,
        ca.vertcat(*passes.accelerations),
        ca.vertcat(*passes.tip_wrenches),
    ]
    inputs = [x, e.tau, e.p]
    derivatives = [ca.jacobian(force, x), ca.jacobian(e.creep_rate, x)]
    at_state = ca.Function("state_passes", inputs, [*shared, *derivatives], _OPTIONS)

    symbols = [ca.SX.sym(f"shared{i}", s.sparsity()) for i, s in enumerate(shared)]
    direction = [ca.SX.sym(name, n) for name in ("dq", "dqd", "dqdd")]
    tangent = ca.Function(
        "newton_euler_tangent",
        [*symbols, *direction],
        [_tangent_pass(elements, patterns, symbols, direction)],
        _OPTIONS,
    )
    mapped = tangent.map("newton_euler_tangents", "serial", 3 * n, list(range(len(shared))), [])

    x_mx, tau_mx, p_mx = (
        ca.MX.sym(name, v.sparsity()) for name, v in zip("xtp", inputs, strict=True)
    )
    *values, force_x, creep_x = at_state(x_mx, tau_mx, p_mx)
    seeds = np.eye(3 * n)
    columns = mapped(*values, seeds[:n], seeds[n : 2 * n], seeds[2 * n :])
    d_inverse, mass = columns[:, : 2 * n], columns[:, 2 * n :]
    n_lam = e.lam.shape[0]
    rhs = force_x - ca.horzcat(d_inverse, ca.MX(n, n_lam))
    solved = ca.solve(mass, rhs, "ldl")
    j_x = ca.vertcat(ca.horzcat(ca.MX(n, n), ca.MX.eye(n), ca.MX(n, n_lam)), solved, creep_x)
    return ca.Function(
        "rhs_jacobian", [x_mx, tau_mx, p_mx], [ca.densify(j_x), ca.densify(mass)],
        ["x", "tau", "p"], ["J_x", "D"],
    )  # fmt: skip
