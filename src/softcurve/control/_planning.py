"""Trajectory optimization: the inputs that move a robot as asked, under its input
bounds, found by IPOPT over the robot's :class:`~softcurve.control.Transcription`
(:func:`optimize_trajectory`, its result :class:`TrajectoryPlan`), once or at every
sample of a receding horizon (:class:`PredictiveController`, on a Gauss-Newton Hessian by
default, :data:`PREDICTIVE_HESSIANS`).

The horizon ``[0, T]`` is split into ``intervals`` steps of ``h = T / intervals``, the
inputs held over each (as ``simulate`` holds inputs given on its grid). Two
transcriptions of the dynamics are built, one per ``method``:

- ``"collocation"`` (direct collocation): the states at the nodes and the three stage
  increments of each step are unknowns, tied by the Radau IIA collocation equations
  (:meth:`Transcription.compiled_collocation`);
- ``"shooting"`` (direct multiple shooting): the states at the nodes are unknowns, tied
  by ``x_(k+1) = step(x_k, u_k, p, h)`` (:attr:`Transcription.step`, its stages solved by
  Newton's method inside every evaluation).

Both are the same discrete scheme, so both reach the same optimum; :data:`PLAN_METHODS`
says which is the default and why. IPOPT approximates the Hessian of the Lagrangian by
L-BFGS, or takes it exact (:data:`PLAN_HESSIANS`).

The unknowns are scaled so that IPOPT sees entries of order one: the states by the
nominal scale of the start (``softcurve.simulation.solvers.nominal_scale``), the inputs
by their range, a free final time by its upper bound.
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field
from types import MappingProxyType

import casadi as ca
import numpy as np

from softcurve.base.progress import on_terminal
from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError, real_scalar
from softcurve.control._transcription import Transcription
from softcurve.control.controllers import SampledController
from softcurve.control.references import Reference
from softcurve.description.actuator import Actuator
from softcurve.simulation.solvers import (
    lag_scale,
    nominal_scale,
)

PLAN_HESSIANS = ("exact", "limited-memory")
"""The Hessians of the Lagrangian that :func:`optimize_trajectory` gives IPOPT; the first
is the default. Direct collocation runs on the compiled right-hand side
(:meth:`Transcription.compiled_collocation`): ``"exact"`` with its first and second
derivatives in C, ``"limited-memory"`` with its first alone and IPOPT's L-BFGS
approximation of the Hessian (:data:`LBFGS_HISTORY` pairs). On the reach task of
docs/planning.md (15 intervals, the paper's robot, tolerance 1e-8; ``python
benchmarks/bench_planning.py --methods collocation --hessians exact limited-memory``):
exact 2.8 s and 44 iterations, limited-memory 2.1 s and 95, the same cost; the first
plan, its derivatives compiled, 21.7 s and 10.1 s. Exact is the default: its iterations
do not grow with the problem's conditioning and tolerance as L-BFGS's do
(``tests/test_planning.py``'s smaller reach needs a looser tolerance to converge with
the approximation), and a robot's second derivatives compile once (cached on disk)."""

LBFGS_HISTORY = 20
"""Pairs of IPOPT's limited-memory Hessian (``limited_memory_max_history``): on the
reach task 6 pairs (IPOPT's default) ran out of its 300 iterations, 20 took 95 (1.9 s),
50 took 174 (4.8 s) (``python benchmarks/bench_planning.py --lbfgs-history 6 20 50``)."""

PLAN_ITERATIONS = 300
"""IPOPT's default iteration budget of a plan, and of a :class:`PredictiveController`'s
first solve: the reach tasks of docs/planning.md converge in 44 (exact Hessian) to 95
(limited-memory)."""

PREDICTIVE_HESSIANS = ("gauss-newton", "exact")
"""The Hessians of the Lagrangian of :class:`PredictiveController`'s solves; the first is
the default. ``"gauss-newton"``: the cost's own (constant: the cost is quadratic in the
unknowns), the constraints' curvature left out; ``"exact"``: with it, from the compiled
second derivatives. On the circle of docs/planning.md (the paper's robot, 25 steps of 20
ms; ``python benchmarks/bench_predictive.py``) a sample takes a median 100 ms with the
Gauss-Newton Hessian and 551 ms with the exact one, the tip 0.31 mm and 0.19 mm from the
circle; at 10 steps of 10 ms, 40 ms and 185 ms, the same 0.003 mm. Gauss-Newton is the
default. :func:`optimize_trajectory` keeps the exact Hessian: without the constraints'
curvature its iterations converge only linearly, and a plan's targets and rest at the end
add constraints whose curvature the controller's problem does not have."""

PLAN_METHODS = ("collocation", "shooting")
"""The transcriptions of :func:`optimize_trajectory`; the first is the default. Both
reach the same plan: IPOPT sees the collocation equations and their exact second
derivatives, compiled (:data:`PLAN_HESSIANS`), where multiple shooting sees each step
through a Newton solve, solved and differentiated in CasADi's virtual machine at every
evaluation. On the reach task of docs/planning.md (15 intervals, the paper's robot):
collocation 2.8 s and 44 iterations, shooting 375 s and 53 (``python
benchmarks/bench_planning.py``)."""


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


@dataclass(frozen=True)
class TrajectoryPlan(Result):
    """What :func:`optimize_trajectory` found.

    Attributes
    ----------
    status : Status
        SUCCESS where IPOPT converged to a point that meets every constraint; LEFT_DOMAIN
        where that point leaves the model's or the actuator's domain by the rules
        ``simulate`` applies; INFEASIBLE where IPOPT proved none exists (the message
        names the constraint that binds most);
        EVALUATION_LIMIT where ``max_iterations`` ran out; NOT_CONVERGED otherwise.
    message : str
        What happened, in IPOPT's words and ours.
    t : ndarray, shape (K + 1,)
        The nodes [s].
    x : ndarray, shape (K + 1, n_x)
        The planned state at the nodes (``simulate``'s layout).
    u : ndarray, shape (K, n_u)
        The inputs held over each step (commands where the actuator lags).
    tip : ndarray, shape (K + 1, 3)
        The planned tip positions [m].
    cost : float
        The objective at the plan (dimensionless, or [s] with a ``time_weight``).
    iterations : int
        IPOPT's iterations.
    violation : float
        The largest constraint violation at the plan, in the units IPOPT sees: the
        dynamics relative to the state's nominal size, a target relative to its
        tolerance, margins [their unit] and distances [m] in their own.
    optimality : float
        IPOPT's dual infeasibility at the plan (first-order optimality).
    solve_time : float
        Wall time of the solve [s] (the problem's construction excluded).
    method : str
        The transcription, one of :data:`PLAN_METHODS`.
    hessian : str
        The Hessian IPOPT used, one of :data:`PLAN_HESSIANS`.
    binding : str
        The constraint group that binds most (:func:`optimize_trajectory`'s message
        names it), e.g. ``"rest at the end"``; "" where none is active.
    transcription : Transcription
        The model and actuator the plan is for.
    stages : ndarray, shape (3 K, n_x)
        The stage increments of every step (direct collocation; empty for shooting).
    multipliers : tuple of ndarray
        IPOPT's multipliers of the bounds and the constraints at the plan (scaled),
        which a warm start from this plan begins with.
    timings : dict
        Wall time [s] of the solve by what IPOPT evaluated: ``"hessian"`` (of the
        Lagrangian), ``"jacobian"`` (of the constraints), ``"constraints"``, ``"cost"``,
        ``"gradient"`` (of the cost).
    """

    status: Status
    message: str
    t: np.ndarray
    x: np.ndarray
    u: np.ndarray
    tip: np.ndarray
    cost: float
    iterations: int
    violation: float
    optimality: float
    solve_time: float
    method: str
    hessian: str
    binding: str
    transcription: Transcription = field(repr=False, compare=False)
    stages: np.ndarray = field(repr=False, compare=False)
    multipliers: tuple = field(repr=False, compare=False)
    timings: dict = field(repr=False, compare=False)

    @property
    def horizon(self) -> float:
        """The plan's final time [s]."""
        return float(self.t[-1])

    @property
    def inputs(self) -> np.ndarray:
        """The inputs on the grid :attr:`t`, shape (K + 1, n_u): what ``simulate``'s
        ``inputs`` (or ``tau`` without an actuator) takes with ``dt`` the step; the last
        row repeats the last step's."""
        return np.vstack([self.u, self.u[-1:]])

    def input_function(self, t: float, state=None) -> np.ndarray:
        """The input held at time ``t`` [s], shape (n_u,): ``simulate``'s callable form.

        Parameters
        ----------
        t : float
            Time [s]; before 0 the first step's, after the horizon the last step's.
        state : object, optional
            Ignored (``simulate`` passes the state).
        """
        k = int(np.clip(np.searchsorted(self.t, t, side="right") - 1, 0, self.u.shape[0] - 1))
        return self.u[k].copy()

    def simulate(self, **settings):
        """The plan's inputs applied by ``simulate`` from the plan's start, on its grid.

        Parameters
        ----------
        **settings
            ``simulate``'s settings (``rtol``, ``atol``, ``method``, ...); ``dt`` and
            ``t_final`` are the plan's.

        Returns
        -------
        Trajectory
        """
        from softcurve.simulation import simulate

        tr = self.transcription
        model, n = tr.model, tr.model.n
        x0 = self.x[0]
        lam0 = x0[2 * n : model.n_state]
        drive = {"tau": self.inputs} if tr.actuator is None else {
            "actuator": tr.actuator, "inputs": self.inputs,
            **({"actuator_state": x0[model.n_state :]} if tr.n_x > model.n_state else {}),
        }  # fmt: skip
        step = float(self.t[1] - self.t[0])
        return simulate(model, x0[:n], x0[n : 2 * n], lam0, t_final=self.horizon, dt=step,
                        **drive, **settings)  # fmt: skip

    def plot(self, ax=None, *, targets=(), title: str | None = None):
        """The planned tip and inputs against time.

        Parameters
        ----------
        ax : None or sequence of matplotlib.axes.Axes, shape (2,)
            Panels for the tip and the inputs; None draws a new figure.
        targets : sequence of TipTarget
            Drawn as crosses at their times.
        title : str, optional
            The figure's title.

        Returns
        -------
        matplotlib.figure.Figure
        """
        from softcurve.figures.plans import plan_figure

        marks = [(self.horizon if g.time is None else g.time, g.position) for g in targets
                 if isinstance(g, TipTarget)]  # fmt: skip
        actuator = self.transcription.actuator
        return plan_figure(self.t, self.tip, self.u, actuator, marks, title, ax=ax)


class _Progress(ca.Callback):
    """IPOPT's iterations as a line: ``iteration k, cost f, violation v``."""

    def __init__(self, n_x: int, lower, upper, stream=None):
        ca.Callback.__init__(self)
        self.n_x, self.lower, self.upper = n_x, np.asarray(lower), np.asarray(upper)
        self.stream, self.count = stream, 0
        self.lines = not on_terminal(stream)
        self.construct("softcurve_plan_progress", {})

    def get_n_in(self):
        return ca.nlpsol_n_out()

    def get_n_out(self):
        return 1

    def get_name_in(self, i):
        return ca.nlpsol_out(i)

    def get_name_out(self, i):
        return "ret"

    def get_sparsity_in(self, i):
        name = ca.nlpsol_out(i)
        sizes = {"f": 1, "x": self.n_x, "lam_x": self.n_x, "g": self.lower.size,
                 "lam_g": self.lower.size}  # fmt: skip
        return ca.Sparsity.dense(sizes[name], 1) if name in sizes else ca.Sparsity(0, 0)

    def eval(self, arg):
        g = np.array(arg[2]).ravel()
        violation = max(0.0, float(np.max(np.concatenate(
            [self.lower - g, g - self.upper, [0.0]]))))  # fmt: skip
        stream = self.stream or sys.stderr
        text = (f"optimize_trajectory: iteration {self.count}, cost {float(arg[1]):.6g}, "
                f"violation {violation:.2g}")  # fmt: skip
        stream.write(f"{text}\n" if self.lines else f"\r{text}   ")
        stream.flush()
        self.count += 1
        return [0]


def _horizon(horizon) -> tuple[float, float, bool]:
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


class _Constraints:
    """The NLP's constraints by group: expressions, bounds and each group's rows."""

    def __init__(self):
        self.rows, self.lower, self.upper, self.groups = [], [], [], []
        self.blocks = []

    def add(self, group: str, expression, lower, upper) -> None:
        size = expression.numel()
        if size == 0:
            return
        self.blocks.append((len(self.groups), *expression.shape))
        self.rows.append(ca.vec(expression))
        # bounds in the order of ca.vec: column by column
        for bounds, value in ((self.lower, lower), (self.upper, upper)):
            flat = np.asarray(value, dtype=np.float64).ravel(order="F")
            bounds.append(np.broadcast_to(flat, (size,)))
        self.groups.extend([group] * size)

    def arrays(self):
        return ca.vertcat(*self.rows), np.concatenate(self.lower), np.concatenate(self.upper)


def optimize_trajectory(
    model,
    q0,
    qd0=None,
    lam0=None,
    *,
    actuator=None,
    actuator_state=None,
    horizon=1.0,
    intervals: int = 25,
    targets=(),
    reference: Reference | None = None,
    reference_weight: float = 1.0,
    effort_weight: float = 0.0,
    rate_weight: float = 0.0,
    time_weight: float = 0.0,
    rest_at_end: bool = False,
    clearance: float | None = None,
    tip_bounds=None,
    method: str = PLAN_METHODS[0],
    hessian: str = PLAN_HESSIANS[0],
    warm_start: TrajectoryPlan | None = None,
    max_iterations: int = PLAN_ITERATIONS,
    tolerance: float = 1e-8,
    progress: bool = False,
) -> TrajectoryPlan:
    """The inputs over a horizon that best meet the targets under the bounds.

    Minimizes, over the inputs held on ``intervals`` steps (and the final time where
    ``horizon`` is a range)::

        sum_targets weight |error|^2
          + reference_weight / T integral |(q - q_r(t)) / S|^2 dt
          + effort_weight / T integral |(u - u_rest) / span|^2 dt
          + rate_weight sum_k |(u_k - u_(k-1)) / span|^2  +  time_weight T

    subject to the dynamics (Radau IIA over each step, ``method``), the start, the
    actuator's input bounds, the model's and the actuator's domain at every node
    (lengths, bends, tendon lengths, chamber volumes), and as asked: hard target
    tolerances, clearance from the obstacles, tip bounds and rest at the end. ``S`` is the
    robot's coordinate scale, ``span`` the input range; the integrals are sums over the
    nodes times ``h``.

    Parameters
    ----------
    model : Model
        The compiled model; its environment's obstacles give the clearance constraints.
    q0 : array_like, shape (n,)
        Initial coordinates, in the model's domain.
    qd0 : array_like, shape (n,), optional
        Initial rates (default zero).
    lam0 : array_like, shape (n_creep,), optional
        Initial creep states (default zero).
    actuator : Actuator, optional
        The actuator whose inputs are planned; None: generalized forces (unbounded).
    actuator_state : array_like, shape (m,), optional
        Initial inputs of a lagging actuator (default its rest inputs).
    horizon : float or (float, float)
        The final time [s], or ``(shortest, longest)`` for a free final time.
    intervals : int
        Steps of the horizon, >= 1.
    targets : sequence of TipTarget or ConfigurationTarget
        Where the robot should be, when.
    reference : Reference, optional
        ``q_r(t)`` to track over the horizon.
    reference_weight : float
        Weight of the tracking term, >= 0, dimensionless.
    effort_weight : float
        Weight of the inputs' distance from rest, >= 0, dimensionless.
    rate_weight : float
        Weight of the inputs' changes between steps, >= 0, dimensionless.
    time_weight : float
        Weight of the final time, >= 0 [1/s]; with a free horizon, > 0 asks for the
        fastest plan.
    rest_at_end : bool
        Whether the robot ends at rest: zero rates and accelerations at the last node
        with the last inputs held (an equilibrium; creep may still move).
    clearance : float, optional
        Smallest signed distance [m] of the backbone at every contact point but the base
        (which no input moves) from every obstacle, at every node (needs an
        environment): the contact radius or more keeps the contact forces off.
    tip_bounds : tuple of array_like, optional
        ``(lower, upper)`` (3,) each: a box [m] the tip stays in at every node.
    method : {"collocation", "shooting"}
        The transcription (:data:`PLAN_METHODS`).
    hessian : {"exact", "limited-memory"}
        The Hessian of the Lagrangian IPOPT uses (:data:`PLAN_HESSIANS`); limited-memory
        with collocation alone.
    warm_start : TrajectoryPlan, optional
        A plan of the same problem size whose states, stages, inputs and final time start
        the iteration (default: the start held, the rest inputs).
    max_iterations : int
        IPOPT's iteration budget, >= 1.
    tolerance : float
        IPOPT's convergence tolerance (its scaled NLP error), > 0.
    progress : bool
        Write ``iteration k, cost f, violation v`` on stderr at each iteration.

    Returns
    -------
    TrajectoryPlan

    Examples
    --------
    >>> import numpy as np
    >>> import softcurve as sc
    >>> model = sc.Model(sc.presets.ifac2020(), quadrature_nodes=3)
    >>> bellows = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)
    >>> goal = sc.TipTarget([0.02, 0.0, 0.062], tolerance=2e-3)  # [m], at the end
    >>> plan = sc.optimize_trajectory(model, [0.064, 0.0, 0.0], actuator=bellows,
    ...                               horizon=0.2, intervals=8, targets=[goal],
    ...                               effort_weight=1e-3, rest_at_end=True)
    >>> plan.success, plan.u.shape
    (True, (8, 3))
    """
    if method not in PLAN_METHODS:
        raise ParameterError(f"method must be one of {', '.join(PLAN_METHODS)}, got {method!r}")
    if hessian not in PLAN_HESSIANS:
        raise ParameterError(f"hessian must be one of {', '.join(PLAN_HESSIANS)}, got {hessian!r}")
    if hessian == "limited-memory" and method == "shooting":
        raise ParameterError(
            "hessian='limited-memory' needs method='collocation': shooting's Newton solves "
            "of its steps fail at the approximation's trial points"
        )
    request = _checked_request(
        model, horizon=horizon, intervals=intervals, targets=targets, reference=reference,
        weights={"reference_weight": reference_weight, "effort_weight": effort_weight,
                 "rate_weight": rate_weight, "time_weight": time_weight},
        clearance=clearance, tip_bounds=tip_bounds, tolerance=tolerance,
        max_iterations=max_iterations,
    )  # fmt: skip
    tr = Transcription(model, actuator)
    x0 = tr.start(q0, qd0, lam0, actuator_state)
    K, n_x, n_u = request.intervals, tr.n_x, tr.n_u
    if warm_start is not None:
        if not isinstance(warm_start, TrajectoryPlan):
            raise ParameterError(
                f"warm_start must be a TrajectoryPlan, got {type(warm_start).__name__}"
            )
        shapes = (warm_start.x.shape, warm_start.u.shape, warm_start.method)
        if shapes != ((K + 1, n_x), (K, n_u), method):
            raise ParameterError(
                f"warm_start must be a plan of {K} intervals, {n_x} states, {n_u} inputs and "
                f"method {method!r}, got {shapes}"
            )

    problem = _Problem.build(tr, x0, request, rest_at_end=rest_at_end, method=method,
                             hessian=hessian, previous_inputs=False)  # fmt: skip
    options = _ipopt_options(problem, max_iterations, tolerance, hessian)
    duals = {}
    if warm_start is not None:  # begin at the plan's primal and dual point, barrier small
        sizes = tuple(m.size for m in warm_start.multipliers)
        if sizes != problem.sizes:
            raise ParameterError(
                "warm_start must be a plan of the same problem (targets, tolerances, "
                f"clearance, tip bounds, rest at the end, horizon): {sizes} multipliers "
                f"against {problem.sizes}"
            )
        options.update({f"ipopt.{name}": value for name, value in WARM_START.items()})
        duals = dict(zip(("lam_x0", "lam_g0"), warm_start.multipliers, strict=True))
        guess = problem.pack(warm_start.x, warm_start.u, warm_start.stages, warm_start.horizon)
    else:
        guess = problem.rest_guess(x0)
    if progress:
        options["iteration_callback"] = _Progress(problem.sizes[0], problem.lower_g,
                                                  problem.upper_g)  # fmt: skip
    solver = ca.nlpsol("optimize_trajectory", "ipopt", problem.nlp, options)
    lower_w, upper_w = problem.bounds(x0)
    began = time.perf_counter()
    solution = solver(x0=guess, lbx=lower_w, ubx=upper_w, lbg=problem.lower_g,
                      ubg=problem.upper_g, p=problem.parameters(0.0), **duals)  # fmt: skip
    solve_time = time.perf_counter() - began
    if progress and on_terminal():
        sys.stderr.write("\n")
    stats = solver.stats()

    # -- the result ----------------------------------------------------------------------
    x_plan, u_plan, z_plan, horizon_value = problem.unpack(np.array(solution["x"]).ravel())
    g_value = np.array(solution["g"]).ravel()
    excess = np.maximum(problem.lower_g - g_value, g_value - problem.upper_g)
    violation = float(max(0.0, excess.max(initial=0.0)))
    # the input bounds are bounds of the unknowns: IPOPT keeps them, their multipliers say
    bound_multipliers = np.abs(np.array(solution["lam_x"]).ravel()[problem.u_rows])
    groups = [*problem.groups, *["input bounds"] * bound_multipliers.size]
    multipliers = np.concatenate([np.abs(np.array(solution["lam_g"]).ravel()), bound_multipliers])
    excess_all = np.concatenate([excess, np.zeros(bound_multipliers.size)])
    binding = _binding(groups, excess_all, multipliers)
    iterations = stats.get("iterations", {})
    optimality = float(iterations["inf_du"][-1]) if iterations.get("inf_du") else float("nan")
    status, words = _status(stats, violation, tolerance)
    p = tr.parameters
    tip_plan = np.array(tr.tip.map(K + 1)(x_plan.T, p)).T
    message = f"{words} after {stats.get('iter_count', 0)} iterations"
    t_plan = np.linspace(0.0, horizon_value, K + 1)
    left = tr.domain_exit(x_plan, t_plan)
    if status is Status.SUCCESS and left:  # the margins are >= 0, the domain's strict
        status, message = Status.LEFT_DOMAIN, f"{message}, but {left}"
    if status is not Status.SUCCESS and binding:
        message += f"; the constraint that binds most: {binding}"
    return TrajectoryPlan(
        status, message, t_plan, x_plan, u_plan, tip_plan,
        float(solution["f"]), int(stats.get("iter_count", 0)), violation, optimality,
        solve_time, method, hessian, binding, tr, z_plan,
        (np.array(solution["lam_x"]).ravel(), np.array(solution["lam_g"]).ravel()),
        {name: float(stats.get(f"t_wall_nlp_{key}", 0.0)) for name, key in TIMED.items()},
    )  # fmt: skip


class PredictiveController(SampledController):
    """Nonlinear model-predictive control: :func:`optimize_trajectory`'s problem, solved
    again from the measured state at every sample over a horizon that recedes with time.

    At each sample the controller plans the inputs over ``[t, t + horizon]`` that track
    the reference under the actuator's bounds and the model's and actuator's domain (and,
    as asked, clearance and tip bounds), by direct collocation of the full nonlinear model,
    and returns the first step's inputs. The problem is built once, at the first sample
    (its states scaled by that sample's): the first solve runs to convergence from rest
    inputs, every later one starts from the previous plan moved one sample on (states,
    inputs, stages and multipliers, the last step repeated) and takes at most
    ``iterations`` iterations. Run it with ``simulate(..., actuator=..., controller=...)``.

    Logged per sample (:meth:`history`): ``t``, ``inputs``, ``tau`` (``H(q) u``),
    ``status`` (a :class:`~softcurve.base.status.Status`: SUCCESS where the solve
    converged, EVALUATION_LIMIT where the budget ended it first, INFEASIBLE or
    NOT_CONVERGED where the solver failed; the inputs of a failed solve are applied all
    the same, as far as they are finite, else the last plan's moved on), ``iterations``,
    ``solve_time`` [s] (the solver alone), ``cost``, ``violation`` and ``timings`` (the
    solve's wall time [s] by what it evaluated, as ``TrajectoryPlan.timings``).

    Parameters
    ----------
    model : Model
        The controller's model of the robot (may differ from the simulated one).
    actuator : Actuator
        The actuator whose inputs are chosen; where it lags, the controller follows its
        inputs by the lag's exact response to the commands it sent.
    reference : Reference
        ``q_r(t)`` to track (:func:`optimize_trajectory`'s ``reference``), of the model's
        ``n`` coordinates.
    horizon : float
        The horizon [s].
    intervals : int
        Steps of the horizon, >= 1.
    sample_time : float, optional
        Time between two samples [s], a whole number of steps and at most the horizon
        (default one step, ``horizon / intervals``).
    reference_weight, effort_weight, rate_weight : float
        :func:`optimize_trajectory`'s weights, >= 0 (dimensionless); the first step's rate
        is measured from the inputs last applied (at the first sample, the lagging
        inputs' start, else the rest inputs). The default rate weight, 1e-6, is the one
        docs/planning.md's circle is tracked with (``python
        benchmarks/bench_predictive.py``).
    clearance : float, optional
        :func:`optimize_trajectory`'s clearance [m] from the obstacles.
    tip_bounds : tuple of array_like, optional
        :func:`optimize_trajectory`'s box [m] for the tip, ``(lower (3,), upper (3,))``.
    hessian : {"gauss-newton", "exact"}
        The Hessian of the Lagrangian the solver takes (:data:`PREDICTIVE_HESSIANS`).
    iterations : int
        The iteration budget of every solve after the first, >= 1.
    tolerance : float
        IPOPT's convergence tolerance (its scaled NLP error, dimensionless), > 0.
    actuator_state : array_like, shape (m,), optional
        The lagging inputs at the first sample [the actuator's ``input_unit``] (default
        its rest inputs); only for an actuator with a ``time_constant``.

    Examples
    --------
    >>> import softcurve as sc
    >>> from softcurve.control.references import tip_circle
    >>> model = sc.Model(sc.presets.ifac2020(), quadrature_nodes=3, compile=False)
    >>> bellows = sc.PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4)
    >>> circle = tip_circle(center=(0.02, 0.0, 0.065), radius=0.01, period=2.0)
    >>> mpc = sc.PredictiveController(model, bellows, circle, horizon=0.1, intervals=5)
    >>> start = circle(0.0)
    >>> run = sc.simulate(model, start.q, start.qd, actuator=bellows, controller=mpc,
    ...                   t_final=0.06, dt=0.02)
    >>> run.success, len(mpc.log)
    (True, 3)
    """

    def __init__(
        self,
        model,
        actuator: Actuator,
        reference: Reference,
        *,
        horizon: float = 0.5,
        intervals: int = 25,
        sample_time: float | None = None,
        reference_weight: float = 1.0,
        effort_weight: float = 0.0,
        rate_weight: float = 1e-6,
        clearance: float | None = None,
        tip_bounds=None,
        hessian: str = PREDICTIVE_HESSIANS[0],
        iterations: int = 5,
        tolerance: float = 1e-8,
        actuator_state=None,
    ):
        if not isinstance(actuator, Actuator):
            raise ParameterError(f"actuator must be an Actuator, got {type(actuator).__name__}")
        if hessian not in PREDICTIVE_HESSIANS:
            raise ParameterError(
                f"hessian must be one of {', '.join(PREDICTIVE_HESSIANS)}, got {hessian!r}"
            )
        if not (isinstance(iterations, int | np.integer) and iterations >= 1):
            raise ParameterError(f"iterations must be an integer >= 1, got {iterations!r}")
        if not isinstance(reference, Reference):
            raise ParameterError(f"reference must be a Reference, got {type(reference).__name__}")
        request = _checked_request(
            model, horizon=horizon, intervals=intervals, targets=(), reference=reference,
            weights={"reference_weight": reference_weight, "effort_weight": effort_weight,
                     "rate_weight": rate_weight, "time_weight": 0.0},
            clearance=clearance, tip_bounds=tip_bounds, tolerance=tolerance,
            max_iterations=iterations,
        )  # fmt: skip
        if request.free:
            raise ParameterError(f"horizon must be a time [s], got {horizon!r}")
        step = request.t_high / request.intervals
        if sample_time is None:
            sample_time = step
        super().__init__(sample_time)
        steps = self.sample_time / step
        # a whole number, up to the rounding of horizon / intervals * steps
        if not (1 <= round(steps) <= request.intervals
                and abs(steps - round(steps)) <= 1e-9 * steps):  # fmt: skip
            raise ParameterError(
                f"sample_time must be a whole number of the horizon's steps of {step:g} s, "
                f"at most the horizon ({request.t_high:g} s), got {sample_time!r}"
            )
        self.transcription = Transcription(model, actuator)
        lagging = actuator.time_constant is not None or actuator_state is not None
        self.lag_start = actuator.lag_start(actuator_state) if lagging else None
        self.model, self.actuator, self.reference = model, actuator, reference
        self.request, self.iterations = request, int(iterations)
        self.hessian = hessian
        self.steps = int(round(steps))
        self._problem = None
        self._solvers = {}
        self.reset()

    def reset(self) -> None:
        """Forget the record, the last plan and the lag's inputs (the problem is kept)."""
        super().reset()
        lagging = self.lag_start is not None
        self._applied = self.lag_start.copy() if lagging else self.actuator.rest_inputs()
        self._lagging = self.lag_start.copy() if lagging else None
        self._last = None

    def _solve(self, warm: bool):
        """CasADi's solver of the problem: to convergence (cold) or on a budget (warm)."""
        if warm not in self._solvers:
            problem, request = self._problem, self.request
            budget = self.iterations if warm else PLAN_ITERATIONS
            options = _ipopt_options(problem, budget, request.tolerance, self.hessian)
            if warm:
                options.update({f"ipopt.{name}": value for name, value in WARM_START.items()})
            self._solvers[warm] = ca.nlpsol("predictive_controller", "ipopt", problem.nlp, options)
        return self._solvers[warm]

    def __call__(self, t, q, qd, lam=None) -> np.ndarray:
        model, tr = self.model, self.transcription
        lam = np.zeros(model.n_creep) if lam is None else np.asarray(lam, dtype=np.float64)
        x = np.concatenate([q, qd, lam, [] if self._lagging is None else self._lagging])
        if self._problem is None:
            self._problem = _Problem.build(tr, x, self.request, rest_at_end=False,
                                           method="collocation", hessian=self.hessian,
                                           previous_inputs=True)  # fmt: skip
        problem = self._problem
        lower_w, upper_w = problem.bounds(x)
        warm = self._last is not None
        if warm:
            guess, (lam_x, lam_g) = problem.shifted(*self._last, self.steps)
            duals = {"lam_x0": lam_x, "lam_g0": lam_g}
        else:
            guess, duals = problem.rest_guess(x), {}
        guess[: tr.n_x] = lower_w[: tr.n_x]
        solver = self._solve(warm)
        began = time.perf_counter()
        solution = solver(x0=guess, lbx=lower_w, ubx=upper_w, lbg=problem.lower_g,
                          ubg=problem.upper_g, p=problem.parameters(t, self._applied),
                          **duals)  # fmt: skip
        solve_time = time.perf_counter() - began
        stats = solver.stats()
        values = np.array(solution["x"]).ravel()
        g_value = np.array(solution["g"]).ravel()
        violation = float(max(0.0, np.max(np.maximum(problem.lower_g - g_value,
                                                     g_value - problem.upper_g),
                                          initial=0.0)))  # fmt: skip
        status, _ = _status(stats, violation, self.request.tolerance)
        if np.all(np.isfinite(values)):
            self._last = (values, (np.array(solution["lam_x"]).ravel(),
                                   np.array(solution["lam_g"]).ravel()))  # fmt: skip
            inputs = problem.unpack(values)[1][0]
        else:  # the next warm start is the plan before moved on again
            status = Status.NOT_CONVERGED
            if self._last is not None:
                self._last = problem.shifted(*self._last, self.steps)
            inputs = self._applied if self._last is None else problem.unpack(self._last[0])[1][0]
        inputs = self.actuator.clip(inputs)
        if self._lagging is not None:  # the lag's exact response to the held command
            decay = np.exp(-self.sample_time / self.actuator.time_constant)
            self._lagging = inputs + (self._lagging - inputs) * decay
        self._applied = inputs
        tau = self.actuator.input_matrix(q) @ inputs
        self.log.append(
            {"t": t, "inputs": inputs, "tau": tau, "status": status,
             "iterations": int(stats.get("iter_count", 0)), "solve_time": solve_time,
             "cost": float(solution["f"]), "violation": violation,
             "timings": {name: float(stats.get(f"t_wall_nlp_{key}", 0.0))
                         for name, key in TIMED.items()}}
        )  # fmt: skip
        return inputs.copy()


@dataclass(frozen=True)
class _Request:
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


def _checked_request(model, *, horizon, intervals, targets, reference, weights, clearance,
                     tip_bounds, tolerance, max_iterations) -> _Request:  # fmt: skip
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
    t_low, t_high, free = _horizon(horizon)
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
    if reference is not None and not (isinstance(reference, Reference) and reference.n == n):
        raise ParameterError(f"reference must be a Reference of {n} coordinates, got {reference!r}")
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
    return _Request(int(intervals), t_low, t_high, free, targets, reference,
                    MappingProxyType(checked), clearance, tip_box, float(tolerance),
                    int(max_iterations))  # fmt: skip


def _ipopt_options(problem, max_iterations: int, tolerance: float, hessian: str) -> dict:
    """CasADi's options of IPOPT for a problem: the budget, the tolerance, the Hessian,
    quiet."""
    options = {
        "ipopt.max_iter": int(max_iterations), "ipopt.tol": float(tolerance),
        "ipopt.print_level": 0, "ipopt.sb": "yes", "print_time": False,
    }  # fmt: skip
    if hessian == "limited-memory":
        options["ipopt.hessian_approximation"] = "limited-memory"
        options["ipopt.limited_memory_max_history"] = LBFGS_HISTORY
    elif hessian == "gauss-newton":
        options["hess_lag"] = problem.cost_hessian()
    return options


@dataclass(frozen=True, eq=False)
class _Problem:
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

    @classmethod
    def build(cls, tr, x0, request: _Request, *, rest_at_end, method, hessian,
              previous_inputs) -> _Problem:  # fmt: skip
        """The problem of a checked request, its states scaled by the start ``x0``."""
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

        constraints = _Constraints()
        if method == "collocation":
            Z = Zs * ca.DM(x_scale)
            mapped = tr.compiled_collocation(2 if hessian == "exact" else 1).map(K)
            residual, following = mapped(X[:, :K], Z, U, P, h)
            constraints.add("dynamics", residual / ca.DM(x_scale), 0.0, 0.0)
        else:
            following = tr.step.map(K)(X[:, :K], U, P, h)
        constraints.add("dynamics", (X[:, 1:] - following) / ca.DM(x_scale), 0.0, 0.0)
        margins = tr.domain.map(K)(X[:, 1:], P)
        constraints.add("model or actuator domain", margins, 0.0, np.inf)
        tips = tr.tip.map(K + 1)(X, P)
        if clearance is not None:
            # the base's rows (first) are fixed: no input moves them
            obstacles = len(model.environment.obstacles)
            gaps = tr.gaps.map(K)(X[:, 1:], P)[obstacles:, :]
            constraints.add("clearance", gaps, clearance, np.inf)
        if tip_box is not None:
            tip_low, tip_high = tip_box
            box = (np.tile(tip_low[:, None], K), np.tile(tip_high[:, None], K))
            constraints.add("tip bounds", tips[:, 1:], *box)
        if rest_at_end:
            xdot = tr.rhs(X[:, K], U[:, K - 1], P)
            # q and qd still, and a lagging actuator settled; creep may still move
            still = [*range(2 * n), *range(model.n_state, n_x)]
            constraints.add("rest at the end", xdot[still] / ca.DM(x_scale[still]), 0.0, 0.0)

        # -- cost ------------------------------------------------------------------------
        def node(time_value):
            return K if time_value is None else int(round(time_value / t_high * K))

        cost = 0
        for i, target in enumerate(targets):
            k = node(target.time)
            if isinstance(target, TipTarget):
                error = (tips[:, k] - ca.DM(target.position)) / length
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
        nlp = {"x": w, "f": cost, "g": g, "p": ca.vertcat(t0, u_before)}
        return cls(tr, nlp, lower_g, upper_g, tuple(constraints.groups), tuple(constraints.blocks),
                   x_scale, span, offset, rest_u, bounded, K, t_low, t_high, free,
                   previous_inputs)  # fmt: skip

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


def _status(stats: dict, violation: float, tolerance: float) -> tuple[Status, str]:
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


def _binding(groups, excess, multipliers) -> str:
    """The constraint group that binds most: of the groups other than the dynamics (which
    any inputs meet, by simulating them), the one violated most, else the one with the
    largest multiplier (a heuristic: the groups' units differ); the dynamics where no
    other group is violated or active."""
    others = [(e, m, g) for g, e, m in zip(groups, excess, multipliers, strict=True)
              if g != "dynamics"]  # fmt: skip
    if others:
        worst = max(others, key=lambda row: row[0])
        if worst[0] > VIOLATION_ALLOWED:
            return worst[2]
        active = max(others, key=lambda row: row[1])
        if active[1] > 0:
            return active[2]
    return "dynamics" if excess.size and excess.max() > VIOLATION_ALLOWED else ""
