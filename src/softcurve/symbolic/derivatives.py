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
code. ``D`` is factored by CasADi's sparse ``LDL^T``. :class:`JacobianPasses` gives
its pieces, for code that runs the directions and the solve in loops of its own (the
stepper's vector lanes, ``softcurve.simulation.stepper._lanes``).

Against the forward differences the C driver takes otherwise (``n_state + 1`` right-hand
sides per Jacobian) it is exact, and at more than one segment cheaper
(``benchmarks/bench_jacobian.py``).
"""

from __future__ import annotations

import casadi as ca
import numpy as np

from softcurve.description.layout import ParameterLayout
from softcurve.symbolic import chain
from softcurve.symbolic.chain import SPATIAL
from softcurve.symbolic.dynamics import chain_elements, unpack_parameters
from softcurve.symbolic.segment import INERTIA_OUTPUTS, TERM_NAMES, nonzeros

_OPTIONS = {"never_inline": True, "cse": True}


def _from_nonzeros(vector, patterns) -> list:
    """``vector`` cut into matrices of ``patterns`` (``nonzeros`` undone)."""
    parts, start = [], 0
    for pattern in patterns:
        parts.append(ca.SX(pattern, vector[start : start + pattern.nnz()]))
        start += pattern.nnz()
    return parts


_MAPS = len(INERTIA_OUTPUTS)
DIRECTIONS = ("q", "qd", "qdd")
"""The kinds of direction of the Newton-Euler tangent, one mapped pass each: along a
coordinate the maps and the biases change, along a rate the biases alone, along an
acceleration neither."""


def _with_biases(values, biases) -> list:
    """An element's terms with its maps from ``values`` and ``biases`` (or, for None,
    zero biases of the same sparsity)."""
    if biases is None:
        biases = [ca.SX(*v.shape) for v in values[_MAPS:]]
    return [*values[:_MAPS], *biases]


def _tangent_pass(elements, patterns, shared, kind, direction):
    """``dID`` (n,) along ``direction`` (n,) of the coordinates, rates or accelerations
    (``kind``, one of :data:`DIRECTIONS`) at the passes ``shared``: the elements' terms'
    and local derivatives' nonzeros (their ``patterns``, per element the terms' and the
    derivatives'), ``qdd`` (n,), the base accelerations and tip wrenches (6 per
    element).

    The steps are bilinear: ``A_tip = X A + S qdd + c`` and the Newton-Euler relations
    are linear in the maps for given accelerations and wrenches, plus the biases. Their
    tangent is then the steps themselves: at the maps with the biases' tangents in place
    of the biases, on the accelerations' and wrenches' tangents, plus (along a
    coordinate, where the maps change) at the maps' tangents without biases on the
    accelerations and wrenches. Structural zeros of the other kinds drop out."""
    terms, local, qdd, accelerations, wrenches = shared
    zero = ca.SX(direction.shape[0], 1)
    dq, dqd, dqdd = (direction if kind == name else zero for name in DIRECTIONS)
    d_omega = ca.SX(3, 1)
    values, tangents, start, term_start = [], [], 0, 0
    for element, (pattern, local_pattern) in zip(elements, patterns, strict=True):
        k = element.coordinates
        size = sum(p.nnz() for p in pattern)
        values.append(_from_nonzeros(terms[term_start : term_start + size], pattern))
        term_start += size
        jacobian = ca.SX(local_pattern, local[start : start + local_pattern.nnz()])
        start += local_pattern.nnz()
        change = _from_nonzeros(jacobian @ ca.vertcat(dq[k], dqd[k], d_omega), pattern)
        d_omega = change[TERM_NAMES.index("omega_tip")]
        tangents.append(change)
    maps_change = kind == "q"
    d_acceleration, base_tangents = ca.SX(SPATIAL, 1), []
    for i, element in enumerate(elements):
        k, a = element.coordinates, accelerations[SPATIAL * i : SPATIAL * (i + 1)]
        base_tangents.append(d_acceleration)
        tip = element.steps.tip_acceleration
        moved = tip(*_with_biases(values[i], tangents[i][_MAPS:]), dqdd[k], d_acceleration)
        if maps_change:
            moved += tip(*_with_biases(tangents[i], None), qdd[k], a)
        d_acceleration = moved
    forces, d_wrench = [None] * len(elements), ca.SX(SPATIAL, 1)
    for i in reversed(range(len(elements))):
        element = elements[i]
        k, a = element.coordinates, accelerations[SPATIAL * i : SPATIAL * (i + 1)]
        newton_euler = element.steps.newton_euler
        force, wrench = newton_euler(
            *_with_biases(values[i], tangents[i][_MAPS:]), base_tangents[i], dqdd[k], d_wrench
        )
        if maps_change:
            w = wrenches[SPATIAL * i : SPATIAL * (i + 1)]
            more_force, more_wrench = newton_euler(*_with_biases(tangents[i], None), a, qdd[k], w)
            force, wrench = force + more_force, wrench + more_wrench
        forces[i], d_wrench = force, wrench
    return ca.vertcat(*forces)


class JacobianPasses:
    """The pieces of the exact Jacobian: the passes at the state and one tangent pass per
    kind of direction, as SX Functions of calls, for :func:`state_jacobian` and for code
    that runs the directions and the solve by itself (the stepper's vector lanes,
    ``softcurve.simulation.stepper._lanes``).

    Parameters
    ----------
    e : DynamicsExpressions
        The model's expressions.
    quadrature_nodes : int
        Gauss-Legendre nodes per segment, as the model's.

    Attributes
    ----------
    at_state : casadi.Function
        ``(x, tau, p) -> (*values, dF/dx, d creep rate/dx)``: the :attr:`n_shared` dense
        columns the tangents take, then the derivatives of the generalized force (n,
        n_x) and of the creep rates (n_lam, n_x).
    tangents : dict of str to casadi.Function
        Per kind of :data:`DIRECTIONS`, ``(*values, direction) -> dID`` (n,): the
        Newton-Euler algorithm's tangent along ``direction`` (n,) of the coordinates,
        rates or accelerations (the last gives a column of the mass matrix).
    inputs : list of casadi.SX
        The symbols ``x``, ``tau`` and ``p`` of :attr:`at_state`.
    n, n_lam, n_shared : int
        Coordinates, creep states and shared values.
    """

    def __init__(self, e, quadrature_nodes: int):
        structure, n = e.structure, e.q.shape[0]
        self.n, self.n_lam = n, e.lam.shape[0]
        x = ca.vertcat(e.q, e.qd, e.lam)
        parts, *_ = unpack_parameters(e.p, ParameterLayout.of_structure(structure))
        elements = chain_elements(structure, parts, quadrature_nodes, inline=False)
        force, falling = e.generalized_force, e.base_acceleration
        terms = chain.segment_motions(elements, e.q, e.qd, local=True)
        qdd = chain.forward_dynamics(terms, force, falling)
        carried = chain.newton_euler_passes(terms, qdd, falling)
        shared = [
            nonzeros([nonzeros(chain.arguments(t)) for t in terms]),
            nonzeros([t.local for t in terms]),
            qdd,
            ca.vertcat(*carried.accelerations),
            ca.vertcat(*carried.tip_wrenches),
        ]
        patterns = [([v.sparsity() for v in chain.arguments(t)], t.local.sparsity()) for t in terms]
        self.inputs = [x, e.tau, e.p]
        derivatives = [ca.jacobian(force, x), ca.jacobian(e.creep_rate, x)]
        self.at_state = ca.Function("state_passes", self.inputs, [*shared, *derivatives], _OPTIONS)
        self.n_shared = len(shared)
        symbols = [ca.SX.sym(f"shared{i}", v.sparsity()) for i, v in enumerate(shared)]
        direction = ca.SX.sym("direction", n)
        self.tangents = {
            kind: ca.Function(
                f"newton_euler_tangent_{kind}",
                [*symbols, direction],
                [_tangent_pass(elements, patterns, symbols, kind, direction)],
                _OPTIONS,
            )
            for kind in DIRECTIONS
        }

    def accelerations(self, values, force_x) -> tuple:
        """``(D^-1 (dF/dx - dID/dx), D)`` (MX): the accelerations' rows of the Jacobian
        and the mass matrix, the tangents mapped over the ``n`` directions of each kind
        (one pass of code, ``O(N^2)`` operations) and ``D`` factored once by CasADi's
        ``LDL^T``.

        Parameters
        ----------
        values : sequence of casadi.MX
            The :attr:`n_shared` values of :attr:`at_state` at the state.
        force_x : casadi.MX, shape (n, n_x)
            ``dF/dx`` along ``x = (q, qd, ...)``: columns after the first ``2 n`` (creep
            states, lagging inputs) have no inertial term.
        """
        n, shared = self.n, list(range(self.n_shared))
        mapped = {
            kind: tangent.map(f"newton_euler_tangents_{kind}", "serial", n, shared, [])
            for kind, tangent in self.tangents.items()
        }
        seeds = np.eye(n)
        d_inverse = ca.horzcat(
            mapped["q"](*values, seeds),
            mapped["qd"](*values, seeds),
            ca.MX(n, force_x.shape[1] - 2 * n),
        )
        mass = mapped["qdd"](*values, seeds)
        return ca.solve(mass, force_x - d_inverse, "ldl"), mass


def state_jacobian(passes: JacobianPasses) -> ca.Function:
    """The exact Jacobian of the state derivative ``rhs`` (see the module docstring).

    Parameters
    ----------
    passes : JacobianPasses
        The model's (``Model.jacobian_passes``), built on its expressions: with contact,
        :class:`ContactExpressions`, whose generalized force holds the contact force.

    Returns
    -------
    casadi.Function
        ``rhs_jacobian(x, tau, p) -> (J_x, D)``: ``J_x`` (n_x, n_x), the derivatives of
        ``xdot`` by the state ``x = (q, qd, lam)``; ``D`` (n, n), the mass matrix, whose
        inverse is the derivative of ``qdd`` by the generalized input force ``tau``.
    """
    n, n_lam = passes.n, passes.n_lam
    x_mx, tau_mx, p_mx = (
        ca.MX.sym(name, v.sparsity()) for name, v in zip("xtp", passes.inputs, strict=True)
    )
    *values, force_x, creep_x = passes.at_state(x_mx, tau_mx, p_mx)
    solved, mass = passes.accelerations(values, force_x)
    j_x = ca.vertcat(ca.horzcat(ca.MX(n, n), ca.MX.eye(n), ca.MX(n, n_lam)), solved, creep_x)
    return ca.Function(
        "rhs_jacobian", [x_mx, tau_mx, p_mx], [ca.densify(j_x), ca.densify(mass)],
        ["x", "tau", "p"], ["J_x", "D"],
    )  # fmt: skip
