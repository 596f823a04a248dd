"""Algorithms over the chain of segments: the mass matrix, inverse and forward dynamics,
each a recursion that calls one segment's Functions (:mod:`softcurve.symbolic.segment`)
once per segment.

- :func:`mass_matrix`, the composite-body algorithm: each segment's momentum per unit
  rate, ``H_i + X_i^T I_(i+1) S_i``, carried to the base through the rigid transforms;
  ``O(N^2)`` 6x3 products on top of ``N`` segment calls.
- :func:`inverse_dynamics`, the recursive Newton-Euler algorithm: accelerations out
  from the base, wrenches back from the tip; ``O(N)``.
- :func:`forward_dynamics`, the articulated-body algorithm: the articulated inertia
  ``I_i = M_i + X_i^T I_(i+1) X_i - Y_i^T U_i^-1 Y_i`` of everything from segment ``i``
  on, back from the tip, then the accelerations out from the base, one 3x3 solve per
  segment; ``O(N)``, where solving with the mass matrix costs ``O(N^3)``
  (``benchmarks/bench_chain.py`` measures both).

Accelerations ``A = (alpha, a)`` and wrenches ``W = (moment, force)`` are in the
coordinates of the frame they belong to; gravity enters as the base's acceleration
``(0, -g)``.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca

from softcurve.base.docs import shared_parameters
from softcurve.symbolic.segment import BIAS_OUTPUTS, INERTIA_OUTPUTS, SegmentFunctions


@dataclass(frozen=True)
class SegmentTerms:
    """The outputs of one segment's ``motion`` Function at its symbols (shapes in
    :mod:`softcurve.symbolic.segment`)."""

    X: ca.SX
    S: ca.SX
    M: ca.SX
    H: ca.SX
    D: ca.SX
    omega_tip: ca.SX
    c: ca.SX
    w: ca.SX
    b: ca.SX


def _coordinates(v, i):
    return v[3 * i : 3 * i + 3]


def segment_motions(functions: SegmentFunctions, q, qd, segments) -> list[SegmentTerms]:
    """Each segment's linear maps and velocity terms at ``(q, qd)``: the angular
    velocities carried out from the base at rest.

    Parameters
    ----------
    functions : SegmentFunctions
        The segment's Functions.
    q, qd : casadi.SX, shape (3N,)
        Coordinates and rates.
    segments : sequence of SegmentSymbols
        Each segment's parameters (mass and radius are used).
    """
    terms, omega = [], ca.SX.zeros(3)
    names = (*INERTIA_OUTPUTS, *BIAS_OUTPUTS)
    for i, seg in enumerate(segments):
        out = functions.motion(_coordinates(q, i), _coordinates(qd, i), omega, seg.mass, seg.radius)
        term = SegmentTerms(**dict(zip(names, out, strict=True)))
        terms.append(term)
        omega = term.omega_tip
    return terms


def _tip_acceleration(t, qdd_i, a):
    return t.X @ a + t.S @ qdd_i + t.c


def _newton_euler(t, a, qdd_i, wrench):
    force = t.H.T @ a + t.D @ qdd_i + t.S.T @ wrench + t.b
    return force, t.M @ a + t.H @ qdd_i + t.X.T @ wrench + t.w


def _joint(t, force_i, inertia, bias):
    """The articulated terms of a segment: its joint inertia ``U``, the coupling ``Y``
    of its coordinates to the base frame's acceleration, the force ``u`` left at zero
    base acceleration, and the products that carry them to the base."""
    inertia_x = inertia @ t.X
    coupling = t.H.T + t.S.T @ inertia_x
    joint = t.D + t.S.T @ inertia @ t.S
    carried = inertia @ t.c + bias
    return joint, coupling, force_i - t.b - t.S.T @ carried, inertia_x, carried


def _articulated(t, force_i, inertia, bias):
    joint, coupling, free, inertia_x, carried = _joint(t, force_i, inertia, bias)
    solved = solve_positive_definite(joint, ca.horzcat(coupling, free))
    gain, offset = solved[:, :6], solved[:, 6]
    inertia = t.M + t.X.T @ inertia_x - coupling.T @ gain
    return inertia, t.w + t.X.T @ carried + coupling.T @ offset, gain, offset


def _root_acceleration(t, force_i, inertia, bias, a):
    # the base's acceleration is known at the root: one right-hand side, not seven
    joint, coupling, free, *_ = _joint(t, force_i, inertia, bias)
    return solve_positive_definite(joint, free - coupling @ a)


def _articulated_acceleration(t, gain, offset, a):
    qdd_i = offset - gain @ a
    return qdd_i, _tip_acceleration(t, qdd_i, a)


def _composite(t, composite):
    carried = composite @ t.S
    block = t.D + t.S.T @ carried
    return block, t.H + t.X.T @ carried, t.M + t.X.T @ composite @ t.X


def _carry(t, momentum):
    return t.S.T @ momentum, t.X.T @ momentum


@dataclass(frozen=True)
class ChainSteps:
    """One step of each algorithm over the chain as a CasADi Function, called once per
    segment (:func:`carry`: once per pair of segments), so that the generated code holds
    one copy of each step however many segments. Each takes a segment's terms (the
    outputs of ``SegmentFunctions.motion``, their sparsity kept) followed by the
    quantities it carries.

    Parameters
    ----------
    tip_acceleration : casadi.Function
        ``(terms, qdd_i, A) -> A_tip``.
    newton_euler : casadi.Function
        ``(terms, A, qdd_i, W_tip) -> (tau_i, W)``.
    articulated : casadi.Function
        ``(terms, force_i, I_tip, p_tip) -> (I, p, U^-1 Y, U^-1 u)``: the articulated
        inertia and bias of everything from the segment on.
    articulated_acceleration : casadi.Function
        ``(terms, U^-1 Y, U^-1 u, A) -> (qdd_i, A_tip)``.
    root_acceleration : casadi.Function
        ``(terms, force_i, I_tip, p_tip, A) -> qdd_i``: the articulated step and the
        acceleration at once, for the segment whose base acceleration ``A`` is known.
    composite : casadi.Function
        ``(terms, I_tip) -> (D_ii, F_i, I)``: the diagonal block, the momentum of
        everything from the segment on per unit ``qd_i``, the composite inertia.
    carry : casadi.Function
        ``(terms of j, F) -> (D_ji, F carried to frame j)``.
    """

    tip_acceleration: ca.Function
    newton_euler: ca.Function
    articulated: ca.Function
    articulated_acceleration: ca.Function
    root_acceleration: ca.Function
    composite: ca.Function
    carry: ca.Function


def chain_steps(functions: SegmentFunctions, inline: bool = False) -> ChainSteps:
    """The steps of the chain algorithms for segments of ``functions``.

    Parameters
    ----------
    functions : SegmentFunctions
        The segment's Functions; the steps take their outputs.
    inline : bool
        Whether the steps are inlined where they are called (see
        :func:`~softcurve.symbolic.segment.segment_functions`).
    """
    motion = functions.motion
    names = (*INERTIA_OUTPUTS, *BIAS_OUTPUTS)
    symbols = {name: ca.SX.sym(name, motion.sparsity_out(name)) for name in names}
    t = SegmentTerms(**symbols)
    terms = [symbols[name] for name in names]
    a, wrench, bias = ca.SX.sym("A", 6), ca.SX.sym("W", 6), ca.SX.sym("p", 6)
    qdd_i, force_i = ca.SX.sym("qdd", 3), ca.SX.sym("force", 3)
    inertia, gain, offset = ca.SX.sym("I", 6, 6), ca.SX.sym("gain", 3, 6), ca.SX.sym("offset", 3)
    momentum = ca.SX.sym("F", 6, 3)
    options = {"never_inline": not inline, "cse": True}

    def step(name, inputs, outputs):
        return ca.Function(name, [*terms, *inputs], list(outputs), options)

    return ChainSteps(
        tip_acceleration=step("tip_acceleration", [qdd_i, a], [_tip_acceleration(t, qdd_i, a)]),
        newton_euler=step("newton_euler", [a, qdd_i, wrench], _newton_euler(t, a, qdd_i, wrench)),
        articulated=step(
            "articulated", [force_i, inertia, bias], _articulated(t, force_i, inertia, bias)
        ),
        articulated_acceleration=step(
            "articulated_acceleration",
            [gain, offset, a],
            _articulated_acceleration(t, gain, offset, a),
        ),
        root_acceleration=step(
            "root_acceleration",
            [force_i, inertia, bias, a],
            [_root_acceleration(t, force_i, inertia, bias, a)],
        ),
        composite=step("composite", [inertia], _composite(t, inertia)),
        carry=step("carry", [momentum], _carry(t, momentum)),
    )


def _arguments(t: SegmentTerms) -> list:
    return [getattr(t, name) for name in (*INERTIA_OUTPUTS, *BIAS_OUTPUTS)]


@shared_parameters
def mass_matrix(steps: ChainSteps, terms: list[SegmentTerms]):
    """``D(q)``, shape (3N, 3N), by the composite-body algorithm (of the terms, the maps
    alone are used).

    Parameters
    ----------
    %(steps)s
    %(terms)s
    """
    n_segments = len(terms)
    blocks = [[None] * n_segments for _ in range(n_segments)]
    composite = ca.SX.zeros(6, 6)  # of everything beyond the tip, tip coordinates
    for i in reversed(range(n_segments)):
        blocks[i][i], momentum, composite = steps.composite(*_arguments(terms[i]), composite)
        for j in reversed(range(i)):
            blocks[j][i], momentum = steps.carry(*_arguments(terms[j]), momentum)
            blocks[i][j] = blocks[j][i].T
    d = ca.blockcat(blocks)
    return 0.5 * (d + d.T)  # symmetric already; removes round-off


@shared_parameters
def inverse_dynamics(steps: ChainSteps, terms: list[SegmentTerms], qdd, base_acceleration):
    """``D qdd + C qd + G``, shape (3N,), by the recursive Newton-Euler algorithm.

    Parameters
    ----------
    %(steps)s
    %(terms)s
    qdd : casadi.SX, shape (3N,)
        Accelerations.
    %(base_acceleration)s
    """
    accelerations, a = [], base_acceleration
    for i, t in enumerate(terms):
        accelerations.append(a)
        a = steps.tip_acceleration(*_arguments(t), _coordinates(qdd, i), a)
    forces, wrench = [None] * len(terms), ca.SX.zeros(6)
    for i in reversed(range(len(terms))):
        forces[i], wrench = steps.newton_euler(
            *_arguments(terms[i]), accelerations[i], _coordinates(qdd, i), wrench
        )
    return ca.vertcat(*forces)


@shared_parameters
def forward_dynamics(steps: ChainSteps, terms: list[SegmentTerms], force, base_acceleration):
    """``qdd`` for the generalized force ``force`` (all but the inertial terms), shape
    (3N,), by the articulated-body algorithm.

    Parameters
    ----------
    %(steps)s
    %(terms)s
    force : casadi.SX, shape (3N,)
        ``tau + K^T lambda - K(q) - R qd`` [N, N m^2, N m^2].
    %(base_acceleration)s
    """
    gains = [None] * len(terms)
    inertia, bias = ca.SX.zeros(6, 6), ca.SX.zeros(6)  # articulated, beyond the tip
    for i in reversed(range(1, len(terms))):
        inertia, bias, *gains[i] = steps.articulated(
            *_arguments(terms[i]), _coordinates(force, i), inertia, bias
        )
    root = _arguments(terms[0])
    qdd = [steps.root_acceleration(*root, _coordinates(force, 0), inertia, bias, base_acceleration)]
    a = steps.tip_acceleration(*root, qdd[0], base_acceleration)
    for t, (gain, offset) in zip(terms[1:], gains[1:], strict=True):
        qdd_i, a = steps.articulated_acceleration(*_arguments(t), gain, offset, a)
        qdd.append(qdd_i)
    return ca.vertcat(*qdd)


def solve_positive_definite(a, b):
    """``a^-1 b`` for a symmetric positive definite ``a`` by the factorization
    ``a = L diag(d) L^T`` without pivoting, which is backward stable for such matrices.

    CasADi's ``solve`` of an SX matrix orthogonalizes its columns by Gram-Schmidt, whose
    error grows with the square of the condition number: on a segment's joint inertia
    (elongation and bending rows differ by ``l^2``, 1e-9 for a segment of a few
    millimetres) the forward dynamics of 20 segments then lost five digits
    (``tests/test_chain.py``).

    Parameters
    ----------
    a : casadi.SX, shape (k, k)
        Symmetric positive definite; its lower triangle is read.
    b : casadi.SX, shape (k, m)
        Right-hand sides.
    """
    k = a.shape[0]
    lower, d = [[None] * k for _ in range(k)], [None] * k
    for j in range(k):
        d[j] = a[j, j] - sum(lower[j][m] ** 2 * d[m] for m in range(j))
        for i in range(j + 1, k):
            lower[i][j] = (a[i, j] - sum(lower[i][m] * lower[j][m] * d[m] for m in range(j))) / d[j]
    y = [None] * k
    for i in range(k):
        y[i] = b[i, :] - sum(lower[i][m] * y[m] for m in range(i))
    x = [None] * k
    for i in reversed(range(k)):
        x[i] = y[i] / d[i] - sum(lower[m][i] * x[m] for m in range(i + 1, k))
    return ca.vertcat(*x)


def gravity_energy(functions: SegmentFunctions, q, segments, base_gravity):
    """``V_g = -sum_i m_i g . x_i`` [J] over the segments' centres of mass.

    Parameters
    ----------
    functions : SegmentFunctions
        The segment's Functions.
    q : casadi.SX, shape (3N,)
        Coordinates.
    segments : sequence of SegmentSymbols
        Each segment's parameters (mass is used).
    base_gravity : casadi.SX, shape (3,)
        Gravity [m/s^2] in base coordinates.
    """
    rotation, origin, energy = ca.SX.eye(3), ca.SX.zeros(3), 0
    for i, seg in enumerate(segments):
        tip_rotation, tip_position, centre = functions.frame(_coordinates(q, i))
        energy -= seg.mass * ca.dot(base_gravity, origin + rotation @ centre)
        origin = origin + rotation @ tip_position
        rotation = rotation @ tip_rotation
    return energy
