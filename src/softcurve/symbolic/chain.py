"""Algorithms over the chain of elements: the mass matrix, inverse and forward dynamics,
each a recursion that calls one element's Functions (:mod:`softcurve.symbolic.segment`)
once per element. Element ``i`` owns the coordinates ``q[offset_i : offset_i + n_i]``
(Pinocchio's ``idx_q`` and ``nq``); a rigid body has ``n_i = 0`` and only carries
inertia and a fixed placement.

- :func:`mass_matrix`, the composite-body algorithm: each segment's momentum per unit
  rate, ``H_i + X_i^T I_(i+1) S_i``, carried to the base through the rigid transforms;
  ``O(N^2)`` 6 x n_i products on top of ``N`` segment calls.
- :func:`inverse_dynamics`, the recursive Newton-Euler algorithm: accelerations out
  from the base, wrenches back from the tip; ``O(N)``.
- :func:`forward_dynamics`, the articulated-body algorithm: the articulated inertia
  ``I_i = M_i + X_i^T I_(i+1) X_i - Y_i^T U_i^-1 Y_i`` of everything from segment ``i``
  on, back from the tip, each joint inertia ``U_i`` (n_i x n_i) factored on the way,
  then the accelerations out from the base, one solve with each factor; ``O(N)``, where
  solving with the mass matrix costs ``O(N^3)`` (``benchmarks/bench_chain.py`` measures
  both).

Accelerations ``A = (alpha, a)`` and wrenches ``W = (moment, force)`` are in the
coordinates of the frame they belong to; gravity enters as the base's acceleration
``(0, -g)``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import casadi as ca

from softcurve.base.docs import shared_parameters
from softcurve.symbolic.segment import TERM_NAMES, SegmentFunctions

SPATIAL = 6
"""Entries of a spatial acceleration or wrench, and columns of a coupling ``Y``;
``Z = L^-1 [Y, u]`` has one more."""


@dataclass(frozen=True)
class SegmentTerms:
    """The outputs of one element's ``motion`` Function at its symbols (shapes in
    :mod:`softcurve.symbolic.segment`), the steps of its kind and its coordinates' slice
    in ``q``; with ``segment_motions(..., local=True)``, also ``local``: the derivatives
    of the outputs' nonzeros by the element's coordinates, rates and base angular
    velocity (``SegmentFunctions.local``)."""

    X: ca.SX
    S: ca.SX
    M: ca.SX
    H: ca.SX
    D: ca.SX
    omega_tip: ca.SX
    c: ca.SX
    w: ca.SX
    b: ca.SX
    steps: ChainSteps | None = None
    coordinates: slice = field(default_factory=lambda: slice(0, 0))
    local: ca.SX | None = None

    @property
    def size(self) -> int:
        """``n_i``."""
        return self.coordinates.stop - self.coordinates.start


@dataclass(frozen=True)
class ChainElement:
    """What the chain algorithms need of one element: its kind's Functions and steps,
    its numbers and where its coordinates lie.

    Parameters
    ----------
    functions : SegmentFunctions
        The element kind's Functions.
    steps : ChainSteps
        The chain algorithms' steps for that kind.
    geometry : casadi.SX
        The element's numbers (its model's ``geometry``), sliced from ``p``.
    coordinates : slice
        Its coordinates in ``q``.
    """

    functions: SegmentFunctions
    steps: ChainSteps
    geometry: ca.SX
    coordinates: slice


def segment_motions(elements: list[ChainElement], q, qd, local: bool = False) -> list[SegmentTerms]:
    """Each element's linear maps and velocity terms at ``(q, qd)``: the angular
    velocities carried out from the base at rest.

    Parameters
    ----------
    elements : sequence of ChainElement
        The chain's elements.
    q, qd : casadi.SX, shape (n,)
        Coordinates and rates.
    local : bool
        Also each element's local derivatives (``SegmentTerms.local``), from the same
        call.
    """
    terms, omega = [], ca.SX.zeros(3)
    for element in elements:
        k = element.coordinates
        function = element.functions.local() if local else element.functions.motion
        out = function(q[k], qd[k], omega, element.geometry)
        term = SegmentTerms(
            **dict(zip(TERM_NAMES, out[: len(TERM_NAMES)], strict=True)),
            steps=element.steps,
            coordinates=k,
            local=out[len(TERM_NAMES)] if local else None,
        )
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
    inertia_s = t.S.T @ inertia
    coupling = t.H.T + inertia_s @ t.X
    joint = t.D + inertia_s @ t.S
    carried = inertia @ t.c + bias
    return joint, coupling, force_i - t.b - t.S.T @ carried, inertia_x, carried


def _articulated(t, force_i, inertia, bias):
    # With U = L diag(d) L^T and Z = L^-1 [Y, u], the inertia's update Y^T U^-1 Y is
    # Z^T diag(1/d) Z, one symmetric product; the solve with L^T waits for the outward
    # pass, where it takes one right-hand side instead of seven.
    joint, coupling, free, inertia_x, carried = _joint(t, force_i, inertia, bias)
    lower, reciprocal = ldl_factor(joint)
    projected = _forward_substitute(lower, ca.horzcat(coupling, free))
    scaled = _scaled_rows(projected, reciprocal)
    coupled, scaled_coupled = projected[:, :SPATIAL], scaled[:, :SPATIAL]
    inertia = _symmetric(t.M + t.X.T @ inertia_x - coupled.T @ scaled_coupled)
    bias = t.w + t.X.T @ carried + coupled.T @ scaled[:, SPATIAL]
    return inertia, bias, _packed(lower, reciprocal), projected


def _root_acceleration(t, force_i, inertia, bias, a):
    # the base's acceleration is known at the root: one right-hand side, not seven
    joint, coupling, free, *_ = _joint(t, force_i, inertia, bias)
    return solve_positive_definite(joint, free - coupling @ a)


def _articulated_acceleration(t, factor, projected, a):
    lower, reciprocal = _unpacked(factor, projected.shape[0])
    free = projected[:, SPATIAL] - projected[:, :SPATIAL] @ a
    qdd_i = _back_substitute(lower, _scaled_rows(free, reciprocal))
    return qdd_i, _tip_acceleration(t, qdd_i, a)


def _scaled_rows(rows, reciprocal):
    """``diag(1 / d) rows`` for the pivots' reciprocals ``1 / d``."""
    if not reciprocal:
        return rows
    return ca.vertcat(*(rows[i, :] * r for i, r in enumerate(reciprocal)))


def _symmetric(a):
    """``a`` from its lower triangle, so that the upper one is never computed."""
    return ca.tril2symm(ca.tril(a))


def _packed(lower, reciprocal):
    """The factor ``L diag(d) L^T`` as one vector: ``L``'s entries below the diagonal by
    rows, then ``1 / d``."""
    entries = [entry for row in lower for entry in row] + list(reciprocal)
    return ca.vertcat(*entries) if entries else ca.SX(0, 1)


def _unpacked(factor, k):
    entries = [factor[i] for i in range(factor.shape[0])]
    lower, start = [], 0
    for i in range(k):
        lower.append(entries[start : start + i])
        start += i
    return lower, entries[start : start + k]


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
        ``(terms, force_i, I_tip, p_tip) -> (I, p, factor, Z)``: the articulated
        inertia and bias of everything from the segment on, the joint inertia's factor
        ``U = L diag(d) L^T`` (packed, shape (n_i (n_i + 1) / 2,): ``L`` below its
        diagonal by rows, then ``1 / d``) and ``Z = L^-1 [Y, u]``, shape (n_i, 7).
    articulated_acceleration : casadi.Function
        ``(terms, factor, Z, A) -> (qdd_i, A_tip)``, ``qdd_i = U^-1 (u - Y A)``.
    root_acceleration : casadi.Function
        ``(terms, force_i, I_tip, p_tip, A) -> qdd_i``: the articulated step and the
        acceleration at once, for the segment whose base acceleration ``A`` is known.
    composite : casadi.Function
        ``(terms, I_tip) -> (D_ii, F_i, I)``: the diagonal block, the momentum of
        everything from the segment on per unit ``qd_i``, the composite inertia.
    carry : dict
        By the width ``n_i`` of ``F``: ``(terms of j, F) -> (D_ji, F carried to frame
        j)``, made on first use (:meth:`carry_of`).
    """

    tip_acceleration: ca.Function
    newton_euler: ca.Function
    articulated: ca.Function
    articulated_acceleration: ca.Function
    root_acceleration: ca.Function
    composite: ca.Function
    carry: dict

    def carry_of(self, width: int) -> ca.Function:
        """The ``carry`` step for a momentum ``F`` of ``width`` columns.

        Parameters
        ----------
        width : int
            ``n_i`` of the element whose momentum is carried.
        """
        if width not in self.carry:
            self.carry[width] = self.carry["make"](width)
        return self.carry[width]


def chain_steps(functions: SegmentFunctions, inline: bool = False, name: str = "") -> ChainSteps:
    """The steps of the chain algorithms for elements of ``functions``.

    Parameters
    ----------
    functions : SegmentFunctions
        The element kind's Functions; the steps take their outputs.
    inline : bool
        Whether the steps are inlined where they are called (see
        :func:`~softcurve.symbolic.segment.segment_functions`).
    name : str
        The steps' prefix, unique per kind within a model (generated C names them).
    """
    motion = functions.motion
    symbols = {name: ca.SX.sym(name, motion.sparsity_out(name)) for name in TERM_NAMES}
    t = SegmentTerms(**symbols)
    terms = [symbols[name] for name in TERM_NAMES]
    nq = motion.size1_out("D")
    a, wrench, bias = ca.SX.sym("A", 6), ca.SX.sym("W", 6), ca.SX.sym("p", 6)
    qdd_i, force_i = ca.SX.sym("qdd", nq), ca.SX.sym("force", nq)
    inertia = ca.SX.sym("I", 6, 6)
    factor = ca.SX.sym("factor", nq * (nq + 1) // 2)
    projected = ca.SX.sym("projected", nq, SPATIAL + 1)
    options = {"never_inline": not inline, "cse": True}

    def step(step_name, inputs, outputs):
        return ca.Function(name + step_name, [*terms, *inputs], list(outputs), options)

    def carry(width):
        momentum = ca.SX.sym("F", 6, width)
        return step(f"carry{width}", [momentum], _carry(t, momentum))

    return ChainSteps(
        tip_acceleration=step("tip_acceleration", [qdd_i, a], [_tip_acceleration(t, qdd_i, a)]),
        newton_euler=step("newton_euler", [a, qdd_i, wrench], _newton_euler(t, a, qdd_i, wrench)),
        articulated=step(
            "articulated", [force_i, inertia, bias], _articulated(t, force_i, inertia, bias)
        ),
        articulated_acceleration=step(
            "articulated_acceleration",
            [factor, projected, a],
            _articulated_acceleration(t, factor, projected, a),
        ),
        root_acceleration=step(
            "root_acceleration",
            [force_i, inertia, bias, a],
            [_root_acceleration(t, force_i, inertia, bias, a)],
        ),
        composite=step("composite", [inertia], _composite(t, inertia)),
        carry={"make": carry},
    )


def arguments(t: SegmentTerms) -> list:
    """The terms in the order the steps take them (the outputs of ``motion``).

    Parameters
    ----------
    t : SegmentTerms
        One element's terms.
    """
    return [getattr(t, name) for name in TERM_NAMES]


@shared_parameters
def mass_matrix(terms: list[SegmentTerms], n: int):
    """``D(q)``, shape (n, n), by the composite-body algorithm (of the terms, the maps
    alone are used).

    Parameters
    ----------
    %(terms)s
    n : int
        Number of coordinates.
    """
    d = ca.SX.zeros(n, n)
    composite = ca.SX.zeros(6, 6)  # of everything beyond the tip, tip coordinates
    for i in reversed(range(len(terms))):
        t = terms[i]
        block, momentum, composite = t.steps.composite(*arguments(t), composite)
        if not t.size:
            continue  # a rigid body: inertia carried, no coordinates of its own
        d[t.coordinates, t.coordinates] = block
        for j in reversed(range(i)):
            other = terms[j]
            block, momentum = other.steps.carry_of(t.size)(*arguments(other), momentum)
            if other.size:
                d[other.coordinates, t.coordinates] = block
                d[t.coordinates, other.coordinates] = block.T
    return 0.5 * (d + d.T)  # symmetric already; removes round-off


@shared_parameters
def inverse_dynamics(terms: list[SegmentTerms], qdd, base_acceleration):
    """``D qdd + C qd + G``, shape (n,), by the recursive Newton-Euler algorithm.

    Parameters
    ----------
    %(terms)s
    %(qdd)s
    %(base_acceleration)s
    """
    return ca.vertcat(*newton_euler_passes(terms, qdd, base_acceleration).forces)


@dataclass(frozen=True)
class NewtonEulerPasses:
    """What the recursive Newton-Euler algorithm carries: per element, the acceleration
    of its base frame (6,) and the wrench its tip frame exerts on what lies beyond
    (6,, zero at the last), both outward from the base; and its generalized force
    ``tau_i`` (n_i,)."""

    accelerations: list
    tip_wrenches: list
    forces: list


@shared_parameters
def newton_euler_passes(terms: list[SegmentTerms], qdd, base_acceleration) -> NewtonEulerPasses:
    """The two passes of :func:`inverse_dynamics` with what they carry between elements
    (:class:`NewtonEulerPasses`), for the algorithms that differentiate them.

    Parameters
    ----------
    %(terms)s
    %(qdd)s
    %(base_acceleration)s
    """
    accelerations, a = [], base_acceleration
    for t in terms:
        accelerations.append(a)
        a = t.steps.tip_acceleration(*arguments(t), qdd[t.coordinates], a)
    forces, tip_wrenches = [None] * len(terms), [None] * len(terms)
    wrench = ca.SX.zeros(6)
    for i in reversed(range(len(terms))):
        t = terms[i]
        tip_wrenches[i] = wrench
        forces[i], wrench = t.steps.newton_euler(
            *arguments(t), accelerations[i], qdd[t.coordinates], wrench
        )
    return NewtonEulerPasses(accelerations, tip_wrenches, forces)


@shared_parameters
def forward_dynamics(terms: list[SegmentTerms], force, base_acceleration):
    """``qdd`` for the generalized force ``force`` (all but the inertial terms), shape
    (n,), by the articulated-body algorithm.

    Parameters
    ----------
    %(terms)s
    force : casadi.SX, shape (n,)
        ``tau + K^T lambda - K(q) - R qd`` (e.g. [N, N m^2, N m^2] per segment).
    %(base_acceleration)s
    """
    factors = [None] * len(terms)
    inertia, bias = ca.SX.zeros(6, 6), ca.SX.zeros(6)  # articulated, beyond the tip
    for i in reversed(range(1, len(terms))):
        t = terms[i]
        inertia, bias, *factors[i] = t.steps.articulated(
            *arguments(t), force[t.coordinates], inertia, bias
        )
    root = terms[0]
    qdd = [
        root.steps.root_acceleration(
            *arguments(root), force[root.coordinates], inertia, bias, base_acceleration
        )
    ]
    a = root.steps.tip_acceleration(*arguments(root), qdd[0], base_acceleration)
    for t, (factor, projected) in zip(terms[1:], factors[1:], strict=True):
        qdd_i, a = t.steps.articulated_acceleration(*arguments(t), factor, projected, a)
        qdd.append(qdd_i)
    return ca.vertcat(*qdd)


def solve_positive_definite(a, b):
    """``a^-1 b`` for a symmetric positive definite ``a`` by the factorization
    ``a = L diag(d) L^T`` without pivoting (:func:`ldl_factor`), which is backward
    stable for such matrices.

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
    if a.shape[0] == 0:  # a rigid body's joint: nothing to solve
        return ca.SX(0, b.shape[1])
    lower, reciprocal = ldl_factor(a)
    return _back_substitute(lower, _scaled_rows(_forward_substitute(lower, b), reciprocal))


def ldl_factor(a):
    """``a = L diag(d) L^T`` for a symmetric positive definite ``a``, its lower triangle
    read, without pivoting.

    Parameters
    ----------
    a : casadi.SX, shape (k, k)
        The matrix.

    Returns
    -------
    lower : list of list of casadi.SX
        Row ``i`` holds ``L[i, :i]`` (the unit diagonal left out).
    reciprocal : list of casadi.SX
        ``1 / d``: one division per pivot, the solves then multiply.
    """
    k = a.shape[0]
    lower, d, reciprocal = [[None] * i for i in range(k)], [None] * k, [None] * k
    for j in range(k):
        scaled = [lower[j][m] * d[m] for m in range(j)]  # row j of L diag(d)
        d[j] = a[j, j] - sum(lower[j][m] * scaled[m] for m in range(j))
        reciprocal[j] = 1 / d[j]
        for i in range(j + 1, k):
            products = sum(lower[i][m] * scaled[m] for m in range(j))
            lower[i][j] = (a[i, j] - products) * reciprocal[j]
    return lower, reciprocal


def _forward_substitute(lower, b):
    """``L^-1 b`` for the unit lower triangular ``L`` of :func:`ldl_factor`, shape of
    ``b``."""
    y = []
    for i, row in enumerate(lower):
        y.append(b[i, :] - sum(row[m] * y[m] for m in range(i)))
    return ca.vertcat(*y) if y else ca.SX(0, b.shape[1])


def _back_substitute(lower, y):
    """``L^-T y`` for the unit lower triangular ``L`` of :func:`ldl_factor`, shape of
    ``y``."""
    k = len(lower)
    x = [None] * k
    for i in reversed(range(k)):
        x[i] = y[i, :] - sum(lower[m][i] * x[m] for m in range(i + 1, k))
    return ca.vertcat(*x) if k else ca.SX(0, y.shape[1])


def gravity_energy(elements: list[ChainElement], q, base_gravity, base_origin):
    """``V_g = -g . sum_k m_k x_k`` [J] over the elements' slices and bodies.

    Parameters
    ----------
    elements : sequence of ChainElement
        The chain's elements.
    q : casadi.SX, shape (n,)
        Coordinates.
    base_gravity : casadi.SX, shape (3,)
        Gravity [m/s^2] in base coordinates.
    base_origin : casadi.SX, shape (3,)
        The world's origin to the base's [m], in base coordinates.
    """
    rotation, origin, energy = ca.SX.eye(3), base_origin, 0
    for element in elements:
        tip_rotation, tip_position, moment, mass = element.functions.frame(
            q[element.coordinates], element.geometry
        )
        energy -= ca.dot(base_gravity, mass * origin + rotation @ moment)
        origin = origin + rotation @ tip_position
        rotation = rotation @ tip_rotation
    return energy
