"""The optimal control problem over a robot's transcription, which
:func:`~softcurve.control.optimize_trajectory` solves once and
:class:`~softcurve.control.PredictiveController` at every sample: the request checked
(targets, horizon, weights, constraints), the nonlinear program built as CasADi
expressions with the layout of its unknowns (:class:`Problem`), and IPOPT's options and
statuses.

The horizon ``[0, T]`` is split into ``intervals`` steps of ``h = T / intervals``, the
inputs held over each (as ``simulate`` holds inputs given on its grid). Two
transcriptions of the dynamics are built, one per ``method``:

- ``"collocation"`` (direct collocation): the states at the nodes and the three stage
  increments of each step are unknowns, tied by the Radau IIA collocation equations
  (:meth:`Transcription.compiled_collocation`);
- ``"shooting"`` (direct multiple shooting): the states at the nodes are unknowns, tied
  by ``x_(k+1) = step(x_k, u_k, p, h)`` (:attr:`Transcription.step`, its stages solved by
  Newton's method inside every evaluation).

The unknowns are scaled so that IPOPT sees entries of order one: the states by the
nominal scale of the start (``softcurve.simulation.solvers.nominal_scale``), the inputs
by their range, a free final time by its upper bound.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import cached_property
from types import MappingProxyType

import casadi as ca
import numpy as np

from softcurve.base.status import Status
from softcurve.base.validation import ParameterError, real_scalar
from softcurve.control._transcription import Transcription
from softcurve.control.references import Reference, checked_reference
from softcurve.simulation.solvers import lag_scale, mapped, nominal_scale

LBFGS_HISTORY = 20
"""Pairs of IPOPT's limited-memory Hessian (``limited_memory_max_history``): on the
reach task 6 pairs (IPOPT's default) took 218 iterations (1.8 s), 20 took 98 (1.2 s),
50 took 122 (2.7 s) (``python benchmarks/bench_planning.py --lbfgs-history 6 20 50``)."""

PLAN_ITERATIONS = 300
"""IPOPT's default iteration budget of a plan, and of a :class:`PredictiveController`'s
first solve: the reach tasks of docs/planning.md converge in 44 (exact Hessian) to 95
(limited-memory)."""


@dataclass(frozen=True)
class TipTarget:
    """The tip at ``position`` at ``time``.

    Parameters
    ----------
    position : array_like, shape (3,)
        Where the tip should be [m], in the world frame.
    time : float, optional
        When [s], from the start; None: at the end of the horizon. Taken at the node
        nearest to it.
    weight : float
        Weight of ``|tip - position|^2 / L^2`` in the cost (``L`` the robot's rest
        length), >= 0, dimensionless.
    tolerance : float, optional
        A hard constraint ``|tip - position| <= tolerance`` [m] instead of (or besides)
        the cost; None: the cost alone.
    """

    position: np.ndarray
    time: float | None = None
    weight: float = 1.0
    tolerance: float | None = None

    def __post_init__(self):
        position = np.asarray(self.position, dtype=np.float64)
        if position.shape != (3,) or not np.all(np.isfinite(position)):
            raise ParameterError(
                f"TipTarget.position must be 3 finite values [m], got {position!r}"
            )
        object.__setattr__(self, "position", position)
        _check_common(self, "TipTarget")


@dataclass(frozen=True)
class ConfigurationTarget:
    """The coordinates at ``q`` at ``time``.

    Parameters
    ----------
    q : array_like, shape (n,)
        The coordinates, in the model's units (per segment ``(l, kx, ky)`` [m, 1/m,
        1/m]).
    time : float, optional
        When [s]; None: at the end of the horizon. Taken at the node nearest to it.
    weight : float
        Weight of ``|(q_k - q) / S|^2`` in the cost (``S`` the robot's coordinate
        scale: a bend of one radian is 1), >= 0, dimensionless.
    tolerance : float, optional
        A hard constraint ``|(q_k - q) / S| <= tolerance`` (dimensionless) besides the
        cost; None: the cost alone.
    """

    q: np.ndarray
    time: float | None = None
    weight: float = 1.0
    tolerance: float | None = None

    def __post_init__(self):
        q = np.asarray(self.q, dtype=np.float64)
        if q.ndim != 1 or not np.all(np.isfinite(q)):
            raise ParameterError(f"ConfigurationTarget.q must be finite values, got {q!r}")
        object.__setattr__(self, "q", q)
        _check_common(self, "ConfigurationTarget")


def _check_common(target, name: str) -> None:
    """The weight, time and tolerance of a target, checked once."""
    weight = real_scalar(f"{name}.weight", target.weight)
    if weight < 0:
        raise ParameterError(f"{name}.weight must be >= 0, got {target.weight!r}")
    if target.time is not None and not real_scalar(f"{name}.time", target.time) >= 0:
        raise ParameterError(f"{name}.time must be >= 0 [s], got {target.time!r}")
    if target.tolerance is not None and not real_scalar(f"{name}.tolerance", target.tolerance) > 0:
        raise ParameterError(f"{name}.tolerance must be > 0, got {target.tolerance!r}")


def horizon_bounds(horizon) -> tuple[float, float, bool]:
    """``(lower, upper, free)`` of the final time [s]."""
    if np.ndim(horizon) == 0:
        value = real_scalar("horizon", horizon)
        if not value > 0:
            raise ParameterError(f"horizon must be > 0 [s], got {horizon!r}")
        return value, value, False
    bounds = tuple(horizon)
    if len(bounds) != 2:
        raise ParameterError(f"horizon must be a time or (shortest, longest), got {horizon!r}")
    low, high = (real_scalar("horizon", b) for b in bounds)
    if not 0 < low < high:
        raise ParameterError(f"horizon must be 0 < shortest < longest [s], got {horizon!r}")
    return low, high, True


class Constraints:
    """The NLP's constraints by group: expressions, bounds and each group's rows."""

    def __init__(self):
        self.rows, self.lower, self.upper, self.groups = [], [], [], []
        self.blocks = []

    def add(self, group: str, expression, lower, upper) -> int | None:
        """Add the rows of ``expression`` (bounds broadcast to it) as ``group``; return
        the index of its block in :attr:`rows`, None where it has no rows (not added)."""
        size = expression.numel()
        if size == 0:
            return None
        self.blocks.append((len(self.groups), *expression.shape))
        self.rows.append(ca.vec(expression))
        # bounds in the order of ca.vec: column by column
        for bounds, value in ((self.lower, lower), (self.upper, upper)):
            flat = np.asarray(value, dtype=np.float64).ravel(order="F")
            bounds.append(np.broadcast_to(flat, (size,)))
        self.groups.extend([group] * size)
        return len(self.rows) - 1

    def arrays(self):
        return ca.vertcat(*self.rows), np.concatenate(self.lower), np.concatenate(self.upper)


@dataclass(frozen=True)
class Request:
    """A plan's request, checked: the horizon, the objective and the constraints."""

    intervals: int
    t_low: float
    t_high: float
    free: bool
    targets: tuple
    reference: Reference | None
    weights: MappingProxyType
    clearance: float | None
    tip_box: tuple | None
    tolerance: float
    max_iterations: int


def checked_request(model, *, horizon, intervals, targets, reference, weights, clearance,
                     tip_bounds, tolerance, max_iterations) -> Request:  # fmt: skip
    """The arguments that :func:`optimize_trajectory` and :class:`PredictiveController`
    share, checked (naming the argument) before anything is built."""
    if not (isinstance(intervals, int | np.integer) and intervals >= 1):
        raise ParameterError(f"intervals must be an integer >= 1, got {intervals!r}")
    if not (isinstance(max_iterations, int | np.integer) and max_iterations >= 1):
        raise ParameterError(f"max_iterations must be an integer >= 1, got {max_iterations!r}")
    if not real_scalar("tolerance", tolerance) > 0:
        raise ParameterError(f"tolerance must be > 0, got {tolerance!r}")
    checked = {}
    for name, value in weights.items():
        checked[name] = real_scalar(name, value)
        if checked[name] < 0:
            raise ParameterError(f"{name} must be >= 0, got {value!r}")
    t_low, t_high, free = horizon_bounds(horizon)
    n = model.n
    targets = tuple(targets)
    for target in targets:
        if not isinstance(target, TipTarget | ConfigurationTarget):
            raise ParameterError(
                f"targets must be TipTarget or ConfigurationTarget, got {type(target).__name__}"
            )
        if isinstance(target, ConfigurationTarget) and target.q.shape != (n,):
            raise ParameterError(
                f"ConfigurationTarget.q must have {n} entries, got {target.q.shape}"
            )
        if target.time is not None and (free or target.time > t_high):
            raise ParameterError(
                f"a target's time ({target.time!r} s) must lie in a fixed horizon of "
                f"{t_high:g} s (with a free final time, targets are at the end: time=None)"
            )
    if reference is not None:
        checked_reference(reference, model.robot)
    if clearance is not None:
        clearance = real_scalar("clearance", clearance)
        if model.environment is None:
            raise ParameterError("clearance needs a model with an environment (obstacles)")
    if tip_bounds is not None:
        pair = tuple(tip_bounds) if np.ndim(tip_bounds) == 2 else ()
        tip_low, tip_high = (np.asarray(b, dtype=np.float64) for b in pair) if len(pair) == 2 else (
            np.zeros(0), np.zeros(0))  # fmt: skip
        if tip_low.shape != (3,) or tip_high.shape != (3,) or not np.all(tip_low < tip_high):
            raise ParameterError(
                "tip_bounds must be (lower (3,), upper (3,)) with lower < upper [m], "
                f"got {tip_bounds!r}"
            )
    tip_box = None if tip_bounds is None else (tip_low, tip_high)
    return Request(int(intervals), t_low, t_high, free, targets, reference,
                    MappingProxyType(checked), clearance, tip_box, float(tolerance),
                    int(max_iterations))  # fmt: skip


STAGED = ("exact", "gauss-newton")
"""The Hessians of the Lagrangian whose collocation problems are differentiated stage by
stage: ``"exact"``'s Hessian (:attr:`Problem.lagrangian_hessian`; CasADi's own took 2.6
times as long an evaluation on docs/planning.md's 2 s plan, one thread), and the
constraints' Jacobian (:attr:`Problem.constraint_jacobian`) where
:func:`jacobian_by_stages` says. The
limited-memory Hessian keeps CasADi's Jacobian: the same matrix to rounding, but its
L-BFGS iterations on the reach task of ``tests/test_planning.py`` ran out of their 300
where CasADi's converged in 125, the rounding apart."""


def jacobian_by_stages(tr: Transcription, hessian: str) -> bool:
    """Whether a collocation problem's constraint Jacobian is assembled stage by stage
    (:attr:`Problem.constraint_jacobian`, on :attr:`Transcription.stage_jacobian`) rather
    than CasADi's through the compiled collocation: with the Gauss-Newton Hessian, whose
    constraints' values come from the right-hand side without derivatives; with the exact
    Hessian where the model keeps its elements' calls (``Model.inlined`` false), where
    CasADi's sweeps every stage in every direction (ten iterations of the ten-segment
    tendon robot's plan: 0.5 s of Jacobians by stages, 13.9 s through CasADi's); not for
    a robot of one element, where the stage Jacobian's compile delays the first plan more
    than it saves (the reach task's: 18.5 s against 12.9 s, its solve 0.5 s against
    0.6 s). ``python benchmarks/bench_planning.py --jacobian-route`` prints both.

    Parameters
    ----------
    tr : Transcription
        The robot's.
    hessian : str
        The Hessian of the Lagrangian (:data:`STAGED`, or ``"limited-memory"``).

    Returns
    -------
    bool
        True: by stages (:attr:`Problem.constraint_jacobian`, given to IPOPT as
        ``jac_g``); False: CasADi's.
    """
    return hessian == "gauss-newton" or (hessian == "exact" and not tr.model.inlined)


def dynamics_rows(X, residual, following, x_scale) -> tuple:
    """The dynamics' blocks of constraints, scaled as the states: the collocation
    equations' ``residual`` (n_x, 3 K; None with shooting, which has none) and the nodes
    ``X`` (n_x, K + 1) against the states ``following`` (n_x, K) the steps end in."""
    scale = ca.DM(x_scale)
    continuity = (X[:, 1:] - following) / scale
    return (continuity,) if residual is None else (residual / scale, continuity)


@dataclass(frozen=True, eq=False)
class _Stages:
    """A collocation problem's stages, for the derivatives assembled stage by stage: the
    slopes as a ``symbol`` (n_x, 3 K) and their ``value`` (the right-hand side ``rhs`` at
    the stages, :meth:`Transcription.compiled_rhs` with its second derivatives where
    ``hessian`` is ``"exact"``, else without derivatives), their ``jacobians`` (n_x,
    (n_x + n_u) 3 K) from :attr:`Transcription.stage_jacobian` where
    :func:`jacobian_by_stages` says (else None), each map of a stage's function on
    ``threads`` threads; the stages' states ``x`` and inputs ``u`` as expressions of the
    unknowns; the ``dynamics``' rows (the collocation equations and the continuity of the
    states, scaled as the problem's) on the slopes' value and on their symbol; the
    constraints' ``equations`` on the symbol."""

    hessian: str
    threads: int
    rhs: ca.Function
    symbol: ca.MX
    value: ca.MX
    jacobians: ca.MX | None
    x: ca.MX
    u: ca.MX
    dynamics: tuple
    dynamics_held: tuple
    equations: ca.MX | None = None

    @classmethod
    def build(cls, tr, X, Z, U, h, x_scale, hessian: str, threads: int) -> _Stages:
        """The stages of the steps between the nodes ``X`` (n_x, K + 1) with increments
        ``Z`` (n_x, 3 K), inputs ``U`` (n_u, K) and step ``h``; ``x_scale`` scales the
        dynamics' rows; the stages' functions run on ``threads`` threads."""
        n_x, (stages, K) = tr.n_x, (tr.stages, U.shape[1])
        repeat = ca.sparsify(ca.DM(np.kron(np.eye(K), np.ones((1, stages)))))
        x, u = ca.mtimes(X[:, :K], repeat) + Z, ca.mtimes(U, repeat)
        P = ca.DM(tr.parameters)
        # the values from the right-hand side alone: the stages' Jacobians cost four
        # times as much, and IPOPT evaluates the constraints at every trial point
        count = stages * K
        rhs = tr.compiled_rhs(2 if hessian == "exact" else 0)
        value = mapped(rhs, count, threads)(x, u, P)
        jacobians = None
        if jacobian_by_stages(tr, hessian):
            jacobians = mapped(tr.stage_jacobian, count, threads)(x, u, P)[1]
        symbol = ca.MX.sym("slopes", n_x, stages * K)
        x1, z, s, step = (ca.MX.sym(name, *shape) for name, shape in
                          (("x", (n_x, 1)), ("z", (n_x, stages)), ("s", (n_x, stages)),
                           ("h", (1, 1))))  # fmt: skip
        equations = ca.Function("equations", [x1, z, s, step],
                                list(tr.collocation_equations(x1, z, s, step))).map(K)  # fmt: skip

        def rows(slopes):
            return dynamics_rows(X, *equations(X[:, :K], Z, slopes, h), x_scale)

        return cls(hessian, threads, rhs, symbol, value, jacobians, x, u, rows(value),
                   rows(symbol))  # fmt: skip

    def with_equations(self, g) -> _Stages:
        """These stages with the constraints' ``equations`` on the slopes' symbol."""
        return replace(self, equations=g)

    def carry(self, w) -> ca.DM:
        """The constant Jacobian (n_v 3 K, n_w) of the stages' states and inputs, stage by
        stage (``n_v = n_x + n_u`` rows each), along the unknowns ``w`` (n_w,)."""
        at_stages = ca.vec(ca.vertcat(self.x, self.u))  # affine in the unknowns
        return ca.DM(ca.Function("carry", [w], [ca.jacobian(at_stages, w)])(np.zeros(w.numel())))


def ipopt_options(problem, max_iterations: int, tolerance: float, hessian: str,
                  warm: bool = False) -> dict:  # fmt: skip
    """CasADi's options of IPOPT for a problem: the budget, the tolerance, the Hessian,
    quiet, and with ``warm`` those of a start from another solution (:data:`WARM_START`)."""
    options = {
        "ipopt.max_iter": int(max_iterations), "ipopt.tol": float(tolerance),
        "ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False,
    }  # fmt: skip
    if hessian == "limited-memory":
        options["ipopt.hessian_approximation"] = "limited-memory"
        options["ipopt.limited_memory_max_history"] = LBFGS_HISTORY
    elif hessian == "gauss-newton":
        options["hess_lag"] = problem.cost_hessian
    elif problem.stages is not None:
        options["hess_lag"] = problem.lagrangian_hessian
    if problem.stages is not None and problem.stages.jacobians is not None:
        # with the Gauss-Newton Hessian the constraints' values come from the right-hand
        # side compiled without derivatives, which CasADi would take by differences:
        # nothing may differentiate them, and the multipliers of p would (CasADi builds
        # their function, unevaluated); with the exact one nothing needs them either
        options.update(jac_g=problem.constraint_jacobian, calc_lam_p=False)
    if warm:
        options.update({f"ipopt.{name}": value for name, value in WARM_START.items()})
    return options


@dataclass(frozen=True, eq=False)
class Problem:
    """The nonlinear program of a plan, built once: CasADi's ``nlp`` (unknowns, cost,
    constraints, parameters), its bounds, and the layout of its scaled unknowns.

    The unknowns are ``(vec X, vec U, vec Z, T)``, scaled: the states at the ``K + 1``
    nodes column by column, the inputs of the ``K`` steps, the stages (collocation) and
    the free final time. ``groups`` names each constraint's group, row by row; ``blocks``
    gives each expression added, ``(first row, rows, columns)``. The parameters are
    ``(t0, u_before)``: the time the horizon begins at (the reference is read from it on)
    and, with ``previous_inputs``, the inputs applied before it (the first step's rate is
    measured from them).
    """

    transcription: Transcription
    nlp: dict
    lower_g: np.ndarray
    upper_g: np.ndarray
    groups: tuple
    blocks: tuple
    x_scale: np.ndarray
    span: np.ndarray
    offset: np.ndarray
    rest_u: np.ndarray
    bounded: np.ndarray
    K: int
    t_low: float
    t_high: float
    free: bool
    previous_inputs: bool
    stages: _Stages | None = None

    @classmethod
    def build(cls, tr, x0, request: Request, *, rest_at_end, method, hessian,
              previous_inputs, threads: int = 1) -> Problem:  # fmt: skip
        """The problem of a checked request, its states scaled by the start ``x0``; the
        stages' derivatives (collocation) evaluated on ``threads`` threads."""
        model = tr.model
        K, t_low, t_high, free = request.intervals, request.t_low, request.t_high, request.free
        targets, reference, weights = request.targets, request.reference, request.weights
        clearance, tip_box = request.clearance, request.tip_box
        n, n_x, n_u = model.n, tr.n_x, tr.n_u
        lower_u, upper_u = tr.input_bounds
        bounded = np.isfinite(lower_u) & np.isfinite(upper_u)
        span = np.where(bounded, upper_u - lower_u, 1.0 if tr.actuator else _force_scale(model, x0))
        offset = np.where(bounded, lower_u, 0.0)
        x_scale = np.ones(n_x)
        x_scale[: model.n_state] = nominal_scale(model, x0[: model.n_state])
        if n_x > model.n_state:
            x_scale[model.n_state :] = lag_scale(tr.inputs)
        rest_u = offset if tr.actuator is None else tr.actuator.rest_inputs()
        length = float(model.robot.rest_length)
        q_scale = model.robot.coordinate_scale()

        # -- unknowns (scaled) and parameters ------------------------------------------
        stages = tr.stages
        Xs = ca.MX.sym("X", n_x, K + 1)
        Us = ca.MX.sym("U", n_u, K)
        Zs = ca.MX.sym("Z", n_x, stages * K) if method == "collocation" else ca.MX(n_x, 0)
        Ts = ca.MX.sym("T") if free else ca.MX(0, 1)
        t0 = ca.MX.sym("t0")
        u_before = ca.MX.sym("u_before", n_u) if previous_inputs else ca.MX(0, 1)
        X = Xs * ca.DM(x_scale)
        U = Us * ca.DM(span) + ca.DM(offset)
        T = Ts * t_high if free else ca.MX(t_high)
        h = T / K
        P = ca.DM(tr.parameters)

        constraints = Constraints()
        stages_of = None
        if method == "collocation":
            Z = Zs * ca.DM(x_scale)
            if hessian in STAGED:
                stages_of = _Stages.build(tr, X, Z, U, h, x_scale, hessian, threads)
            if jacobian_by_stages(tr, hessian):  # on the stages' compiled Jacobians
                dynamics = stages_of.dynamics
            else:  # CasADi's Jacobian through the compiled collocation
                order = 2 if hessian == "exact" else 1
                steps = tr.compiled_collocation(order).map(K)(X[:, :K], Z, U, P, h)
                dynamics = dynamics_rows(X, *steps, x_scale)
        else:
            dynamics = dynamics_rows(X, None, tr.step.map(K)(X[:, :K], U, P, h), x_scale)
        for rows in dynamics:
            constraints.add("dynamics", rows, 0.0, 0.0)
        margins = tr.domain.map(K)(X[:, 1:], P)
        constraints.add("model or actuator domain", margins, 0.0, np.inf)
        if clearance is not None:
            # the base's rows (first) are fixed: no input moves them
            obstacles = len(model.environment.obstacles)
            gaps = tr.gaps.map(K)(X[:, 1:], P)[obstacles:, :]
            constraints.add("clearance", gaps, clearance, np.inf)
        if tip_box is not None:
            tip_low, tip_high = tip_box
            box = (np.tile(tip_low[:, None], K), np.tile(tip_high[:, None], K))
            constraints.add("tip bounds", tr.tip.map(K)(X[:, 1:], P), *box)
        rest_block = None
        if rest_at_end:
            # q and qd still, and a lagging actuator settled; creep may still move
            still = [*range(2 * n), *range(model.n_state, n_x)]

            def rest(xdot):
                return xdot[still] / ca.DM(x_scale[still])

            if stages_of is not None:
                # at the last step's last stage, which is the last node where the
                # dynamics hold (Radau IIA's c = 1): the stages' derivatives carry its
                # slope, where the symbolic right-hand side's would run in CasADi's
                # virtual machine (0.64 s of the 2.7 s of an evaluation of the Hessian
                # of the ten-segment tendon plan); one call, which CasADi's Jacobian
                # differentiates where the stages' is not used
                xdot = stages_of.rhs(stages_of.x[:, -1], stages_of.u[:, -1], P)
            elif method == "collocation":
                # the compiled collocation's right-hand side, whose first derivatives the
                # limited-memory Hessian's Jacobian compiles anyway: the symbolic one's run
                # in CasADi's virtual machine
                xdot = tr.compiled_rhs(1)(X[:, K], U[:, K - 1], P)
            else:
                xdot = tr.rhs(X[:, K], U[:, K - 1], P)
            rest_block = constraints.add("rest at the end", rest(xdot), 0.0, 0.0)

        # -- cost ------------------------------------------------------------------------
        def node(time_value):
            return K if time_value is None else int(round(time_value / t_high * K))

        cost = 0
        for i, target in enumerate(targets):
            k = node(target.time)
            if isinstance(target, TipTarget):
                # the node's own tip: CasADi's derivatives of a map sweep all its nodes
                error = (tr.tip(X[:, k], P) - ca.DM(target.position)) / length
                scale = length
            else:
                error = (X[:n, k] - ca.DM(target.q)) / ca.DM(q_scale)
                scale = 1.0
            cost = cost + target.weight * ca.sumsqr(error)
            if target.tolerance is not None:  # relative to the tolerance: |e| <= tolerance
                name = f"target {i} ({type(target).__name__} at {k * t_high / K:g} s)"
                bound = ca.sumsqr(error) / (target.tolerance / scale) ** 2
                constraints.add(name, bound, -np.inf, 1.0)
        if reference is not None and weights["reference_weight"] > 0:
            t_nodes = t0 + ca.linspace(ca.MX(0), T, K + 1)[1:]
            t_sym = ca.SX.sym("t")
            q_r = ca.Function("q_r", [t_sym], [reference.symbolic(t_sym).q]).map(K)(t_nodes.T)
            tracking = ca.sumsqr((X[:n, 1:] - q_r) / ca.DM(q_scale)) / K
            cost = cost + weights["reference_weight"] * tracking
        if weights["effort_weight"] > 0:
            effort = ca.sumsqr((U - ca.DM(rest_u)) / ca.DM(span)) / K
            cost = cost + weights["effort_weight"] * effort
        if weights["rate_weight"] > 0:
            applied = ca.horzcat(u_before, U) if previous_inputs else U
            if applied.shape[1] > 1:
                changes = (applied[:, 1:] - applied[:, :-1]) / ca.DM(span)
                cost = cost + weights["rate_weight"] * ca.sumsqr(changes)
        if weights["time_weight"] > 0:
            cost = cost + weights["time_weight"] * T

        w = ca.vertcat(ca.vec(Xs), ca.vec(Us), ca.vec(Zs), Ts)
        g, lower_g, upper_g = constraints.arrays()
        if stages_of is not None:  # the dynamics' blocks first: on the slopes' symbol
            rows = list(constraints.rows)
            rows[: len(stages_of.dynamics_held)] = map(ca.vec, stages_of.dynamics_held)
            if rest_block is not None:
                rows[rest_block] = ca.vec(rest(stages_of.symbol[:, -1]))
            stages_of = stages_of.with_equations(ca.vertcat(*rows))
        nlp = {"x": w, "f": cost, "g": g, "p": ca.vertcat(t0, u_before)}
        return cls(tr, nlp, lower_g, upper_g, tuple(constraints.groups), tuple(constraints.blocks),
                   x_scale, span, offset, rest_u, bounded, K, t_low, t_high, free,
                   previous_inputs, stages_of)  # fmt: skip

    @cached_property
    def lagrangian_hessian(self) -> ca.Function:
        """The exact Hessian of the Lagrangian of a collocation problem, as CasADi's
        ``hess_lag`` option of IPOPT takes it: ``(x, p, lam_f, lam_g) -> triu(H)``.

        The collocation equations are linear in the slopes at the stages, so the
        Lagrangian's curvature is (i) that of the cost and of the other constraints with
        the slopes held, (ii) per stage, the right-hand side's Hessian weighted by the
        slopes' multipliers ``mu`` (:attr:`Transcription.stage_hessian`, twelve
        directions a stage on the paper's robot), carried to the unknowns by the constant
        map from them to the stage's state and input, and (iii) with a free final time,
        the slopes' gradient along the unknowns times the step's share of ``mu``. CasADi's
        own Hessian sweeps every stage in every direction its colouring needs.
        """
        if self.stages is None or self.stages.hessian != "exact":
            raise ValueError("lagrangian_hessian needs a collocation problem built with "
                             "hessian='exact'")  # fmt: skip
        stages, tr = self.stages, self.transcription
        w, p = self.nlp["x"], self.nlp["p"]
        lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", self.sizes[1])
        lagrangian = lam_f * self.nlp["f"] + ca.dot(lam_g, stages.equations)
        held = ca.hessian(lagrangian, w)[0]  # (i)
        shape = stages.symbol.shape
        mu = ca.reshape(ca.jacobian(lagrangian, ca.vec(stages.symbol)).T, *shape)
        P = ca.DM(tr.parameters)
        blocks = mapped(tr.stage_hessian, shape[1], stages.threads)(stages.x, stages.u, mu, P)
        carry = stages.carry(w)
        each = ca.horzsplit(blocks, blocks.shape[0])
        hessian = held + ca.mtimes([carry.T, ca.diagcat(*each), carry])  # (ii)
        slopes = stages.value
        if self.free:  # (iii): mu is linear in h = T / K, T (scaled) the last unknown
            along = ca.vec(ca.jacobian(ca.vec(mu), w[-1]))
            pull = ca.gradient(ca.dot(along, ca.vec(slopes)), w)
            # sparse: a dense column's structural zeros would fill the whole Hessian
            # (examples/flick.py's plan: 320,361 entries of IPOPT's Hessian, 0.34 s an
            # iteration in its factorizations, against 11,536 and 3 ms)
            last = ca.DM(ca.Sparsity.triplet(w.numel(), 1, [w.numel() - 1], [0]), 1.0)
            hessian = hessian + ca.mtimes(pull, last.T) + ca.mtimes(last, pull.T)
        hessian = ca.substitute(hessian, stages.symbol, slopes)
        return ca.Function("nlp_hess_l", [w, p, lam_f, lam_g], [ca.triu(hessian)],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])  # fmt: skip

    @cached_property
    def constraint_jacobian(self) -> ca.Function:
        """The constraints and their Jacobian, as CasADi's ``jac_g`` option of IPOPT takes
        it: ``(x, p) -> (g, jac_g_x)``, for a collocation problem whose Jacobian is by
        stages (:func:`jacobian_by_stages`).

        The collocation equations are linear in the slopes at the stages, so their
        Jacobian is theirs with the slopes held plus their slopes' coefficients times each
        stage's Jacobian of the right-hand side (:attr:`Transcription.stage_jacobian`, one
        compiled call a stage) carried to the unknowns; the other constraints' is CasADi's.
        CasADi's own Jacobian of the whole problem sweeps every stage in every direction
        its colouring needs, each sweep a forward derivative of the right-hand side.
        """
        if self.stages is None or self.stages.jacobians is None:
            raise ValueError("constraint_jacobian needs a collocation problem whose "
                             "Jacobian is by stages (jacobian_by_stages)")  # fmt: skip
        stages = self.stages
        w, p = self.nlp["x"], self.nlp["p"]
        equations, slopes = stages.equations, ca.vec(stages.symbol)
        each = ca.horzsplit(stages.jacobians, stages.jacobians.shape[1] // stages.symbol.shape[1])
        along = ca.mtimes(ca.diagcat(*each), stages.carry(w))  # d slopes / d unknowns
        jacobian = ca.jacobian(equations, w) + ca.mtimes(ca.jacobian(equations, slopes), along)
        jacobian = ca.substitute(jacobian, stages.symbol, stages.value)
        return ca.Function("nlp_jac_g", [w, p], [self.nlp["g"], jacobian],
                           ["x", "p"], ["g", "jac_g_x"])  # fmt: skip

    @cached_property
    def cost_hessian(self) -> ca.Function:
        """The Hessian of the Lagrangian without the constraints' curvature, as CasADi's
        ``hess_lag`` option of IPOPT takes it: ``(x, p, lam_f, lam_g) -> triu(lam_f
        d2f/dx2)``. With the tracking, effort and rate terms alone the cost is quadratic
        in the unknowns, so this is constant and positive semi-definite: a Gauss-Newton
        Hessian of the problem (tip targets add their own curvature)."""
        w, p = self.nlp["x"], self.nlp["p"]
        lam_f, lam_g = ca.MX.sym("lam_f"), ca.MX.sym("lam_g", self.sizes[1])
        hessian = lam_f * ca.hessian(self.nlp["f"], w)[0]
        return ca.Function("nlp_hess_l", [w, p, lam_f, lam_g],
                           [ca.triu(hessian)],
                           ["x", "p", "lam_f", "lam_g"], ["triu_hess_gamma_x_x"])  # fmt: skip

    # -- the layout of the unknowns ---------------------------------------------------
    @property
    def sizes(self) -> tuple[int, int]:
        """Unknowns and constraints."""
        return self.nlp["x"].numel(), self.lower_g.size

    @property
    def u_rows(self) -> slice:
        """The inputs' rows among the unknowns."""
        first = self.transcription.n_x * (self.K + 1)
        return slice(first, first + self.transcription.n_u * self.K)

    @property
    def z_count(self) -> int:
        """Entries of the stages among the unknowns (0 with shooting)."""
        free = 1 if self.free else 0
        return self.sizes[0] - self.u_rows.stop - free

    def excess(self, g: np.ndarray) -> tuple[np.ndarray, float]:
        """How far each constraint's value ``g`` lies outside its bounds (<= 0 inside),
        and the largest of them, 0 where all hold: the violation, in the units IPOPT
        sees."""
        excess = np.maximum(self.lower_g - g, g - self.upper_g)
        return excess, float(max(0.0, excess.max(initial=0.0)))

    def parameters(self, t0: float, u_before=None) -> np.ndarray:
        """The NLP's parameters: the horizon's start [s] and the inputs before it."""
        before = [] if not self.previous_inputs else u_before
        return np.concatenate([[float(t0)], np.asarray(before, dtype=np.float64)])

    def bounds(self, x0: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Bounds of the (scaled) unknowns, the start fixed at ``x0``."""
        n_x, K = self.transcription.n_x, self.K
        lower = np.full(self.sizes[0], -np.inf)
        upper = np.full(self.sizes[0], np.inf)
        lower[:n_x] = upper[:n_x] = x0 / self.x_scale
        lower[self.u_rows] = np.tile(np.where(self.bounded, 0.0, -np.inf), K)
        upper[self.u_rows] = np.tile(np.where(self.bounded, 1.0, np.inf), K)
        if self.free:
            lower[-1], upper[-1] = self.t_low / self.t_high, 1.0
        return lower, upper

    def rest_guess(self, x0: np.ndarray) -> np.ndarray:
        """The start held, the rest inputs, no stage increments, the longest horizon."""
        start = x0 / self.x_scale
        return np.concatenate([
            np.tile(start, self.K + 1), np.tile((self.rest_u - self.offset) / self.span, self.K),
            np.zeros(self.z_count), [1.0] if self.free else [],
        ])  # fmt: skip

    def pack(self, x, u, stages, horizon) -> np.ndarray:
        """Scaled unknowns of a plan's states, inputs, stages and final time."""
        return np.concatenate([
            (x / self.x_scale).ravel(), ((u - self.offset) / self.span).ravel(),
            (stages / self.x_scale).ravel(), [horizon / self.t_high] if self.free else [],
        ])  # fmt: skip

    def unpack(self, values: np.ndarray):
        """``(x (K+1, n_x), u (K, n_u), stages (3K, n_x), horizon [s])`` of the scaled
        unknowns; the inputs put back inside their bounds."""
        n_x, n_u, K = self.transcription.n_x, self.transcription.n_u, self.K
        lower_u, upper_u = self.transcription.input_bounds
        x = values[: n_x * (K + 1)].reshape(K + 1, n_x) * self.x_scale
        # IPOPT relaxes its bounds by 1e-8 of their size (bound_relax_factor): the inputs
        # are put back inside, where simulate takes them
        u = np.clip(values[self.u_rows].reshape(K, n_u) * self.span + self.offset,
                    lower_u, upper_u)  # fmt: skip
        z = values[self.u_rows.stop : self.u_rows.stop + self.z_count].reshape(-1, n_x)
        horizon = values[-1] * self.t_high if self.free else self.t_high
        return x, u, z * self.x_scale, horizon

    def shifted(self, values: np.ndarray, multipliers: tuple, steps: int):
        """The unknowns and multipliers (``lam_x``, ``lam_g``) moved ``steps`` steps on,
        the last step's repeated: a receding horizon's warm start."""
        n_x, n_u, K = self.transcription.n_x, self.transcription.n_u, self.K
        stages = self.z_count // (n_x * K)

        def along(array, first, rows, columns, per_step):
            """A block of ``columns`` of ``rows`` entries, ``per_step`` columns a step (0:
            not along the horizon), moved on; the last step's columns repeated."""
            block = array[first : first + rows * columns].reshape(columns, rows)
            if per_step == 0:
                return block.ravel()
            repeated = [block[-per_step:]] * steps
            return np.concatenate([block[steps * per_step :], *repeated]).ravel()

        def unknowns(array):
            parts = [along(array, 0, n_x, K + 1, 1),  # the nodes: the last one repeated
                     along(array, self.u_rows.start, n_u, K, 1)]  # fmt: skip
            if self.z_count:
                parts.append(along(array, self.u_rows.stop, n_x, stages * K, stages))
            return np.concatenate([*parts, array[self.u_rows.stop + self.z_count :]])

        def per_step(columns):
            return {K: 1, stages * K: stages}.get(columns, 0) if stages else int(columns == K)

        lam_x, lam_g = multipliers
        rows = [along(lam_g, first, size, columns, per_step(columns))
                for first, size, columns in self.blocks]  # fmt: skip
        return unknowns(values), (unknowns(lam_x), np.concatenate(rows) if rows else lam_g)


def _force_scale(model, x0) -> np.ndarray:
    """A generalized force per coordinate, of the size that holds it one coordinate scale
    from the start (the change of the potential force along it, plus the force at the
    start): what unbounded force inputs are scaled by, so that IPOPT sees entries of order
    one [N, N m^2 per coordinate]."""
    n, scale = model.n, model.robot.coordinate_scale()
    q0 = x0[:n]
    at_start = model.potential_force(q0)
    moved = [model.potential_force(q0 + scale[i] * np.eye(n)[i])[i] for i in range(n)]
    return np.maximum(np.abs(np.array(moved) - at_start) + np.abs(at_start), 1e-9)


TIMED = {"hessian": "hess_l", "jacobian": "jac_g", "constraints": "g", "cost": "f",
         "gradient": "grad_f"}  # fmt: skip
""":attr:`TrajectoryPlan.timings`' names for IPOPT's evaluations in CasADi's statistics."""


def evaluation_timings(stats: dict) -> dict:
    """Wall time [s] of a solve by what IPOPT evaluated (:data:`TIMED`'s names), from
    CasADi's statistics."""
    return {name: float(stats.get(f"t_wall_nlp_{key}", 0.0)) for name, key in TIMED.items()}


WARM_START = {
    "warm_start_init_point": "yes",
    "mu_init": 1e-6,
    "warm_start_bound_push": 1e-9,
    "warm_start_bound_frac": 1e-9,
    "warm_start_slack_bound_push": 1e-9,
    "warm_start_slack_bound_frac": 1e-9,
    "warm_start_mult_bound_push": 1e-9,
}
"""IPOPT's options where a plan starts from another (``warm_start``): its primal and
dual point kept as given (pushed off the bounds by 1e-9 rather than IPOPT's 1e-2, which
would move an optimum with active bounds far from itself) and a barrier parameter
near the one the first plan ended with, so that an unchanged problem converges in a
few iterations."""

VIOLATION_ALLOWED = 1e-6
"""The largest constraint violation (scaled) at which a converged plan is a SUCCESS:
IPOPT's own ``constr_viol_tol`` default is 1e-4; the dynamics' rows are scaled by the
state's nominal size, so 1e-6 is a relative defect of the step well below ``simulate``'s
default rtol 1e-6 times the state's scale."""


def solve_status(stats: dict, violation: float) -> tuple[Status, str]:
    """The plan's status and IPOPT's words."""
    words = str(stats.get("return_status", "unknown"))
    if words == "Solve_Succeeded" and violation <= VIOLATION_ALLOWED:
        return Status.SUCCESS, f"IPOPT: {words}"
    if words == "Infeasible_Problem_Detected":
        return Status.INFEASIBLE, f"IPOPT: {words}"
    if words in ("Maximum_Iterations_Exceeded", "Maximum_CpuTime_Exceeded"):
        return Status.EVALUATION_LIMIT, f"IPOPT: {words}"
    if words == "Solve_Succeeded":
        return Status.NOT_CONVERGED, f"IPOPT: {words}, but a constraint is off by {violation:.2g}"
    return Status.NOT_CONVERGED, f"IPOPT: {words}"
