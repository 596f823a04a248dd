"""Trajectory optimization: the inputs that move a robot as asked, under its input
bounds, found by IPOPT over the robot's :class:`~softcurve.control.Transcription`
(:func:`optimize_trajectory`, its result :class:`TrajectoryPlan`), on the problem of
``softcurve.control._problem``.

Both transcriptions (:data:`PLAN_METHODS`) are the same discrete scheme, so both reach the
same optimum. IPOPT approximates the Hessian of the Lagrangian by L-BFGS, or takes it
exact (:data:`PLAN_HESSIANS`).
"""

from __future__ import annotations

import sys
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from softcurve.base.progress import on_terminal
from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError, whole_count
from softcurve.control._problem import (
    PLAN_ITERATIONS,
    VIOLATION_ALLOWED,
    Problem,
    TipTarget,
    checked_request,
    evaluation_timings,
    ipopt_options,
    solve_status,
)
from softcurve.control._transcription import Transcription
from softcurve.control.references import Reference
from softcurve.simulation.batch import default_threads

PLAN_HESSIANS = ("exact", "limited-memory")
"""The Hessians of the Lagrangian that :func:`optimize_trajectory` gives IPOPT; the first
is the default. Direct collocation runs on the compiled right-hand side
(:meth:`Transcription.compiled_collocation`): ``"exact"`` with its first and second
derivatives in C (the Hessian of the Lagrangian assembled stage by stage,
``Problem.lagrangian_hessian``), ``"limited-memory"`` with its first alone and IPOPT's
L-BFGS approximation of the Hessian (:data:`LBFGS_HISTORY` pairs). On the reach task of
docs/planning.md (15 intervals, the paper's robot, tolerance 1e-8; ``python
benchmarks/bench_planning.py --methods collocation --hessians exact limited-memory``):
exact 1.5 s and 44 iterations, limited-memory 2.1 s and 95, the same cost; the first
plan, its derivatives compiled, 19.4 s and 10.1 s. Exact is the default: its iterations
do not grow with the problem's conditioning and tolerance as L-BFGS's do
(``tests/test_planning.py``'s smaller reach needs a looser tolerance to converge with
the approximation), and a robot's second derivatives compile once (cached on disk)."""

PLAN_METHODS = ("collocation", "shooting")
"""The transcriptions of :func:`optimize_trajectory`; the first is the default. Both
reach the same plan: IPOPT sees the collocation equations and their exact second
derivatives, compiled (:data:`PLAN_HESSIANS`), where multiple shooting sees each step
through a Newton solve, solved and differentiated in CasADi's virtual machine at every
evaluation. On the reach task of docs/planning.md (15 intervals, the paper's robot):
collocation 0.5 s and 44 iterations, shooting 288 s and 58 (``python
benchmarks/bench_planning.py``, two threads)."""


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
    threads: int | None = None,
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
    threads : int, optional
        Threads that evaluate the stages' right-hand sides and their derivatives (with
        collocation and the exact Hessian), >= 1 (default: the cores this process may
        use). The results do not depend on it.

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
    threads = default_threads() if threads is None else whole_count("threads", threads)
    if hessian == "limited-memory" and method == "shooting":
        raise ParameterError(
            "hessian='limited-memory' needs method='collocation': shooting's Newton solves "
            "of its steps fail at the approximation's trial points"
        )
    request = checked_request(
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

    problem = Problem.build(tr, x0, request, rest_at_end=rest_at_end, method=method,
                             hessian=hessian, previous_inputs=False, threads=threads)  # fmt: skip
    options = ipopt_options(problem, max_iterations, tolerance, hessian,
                            warm=warm_start is not None)  # fmt: skip
    duals = {}
    if warm_start is not None:  # begin at the plan's primal and dual point, barrier small
        sizes = tuple(m.size for m in warm_start.multipliers)
        if sizes != problem.sizes:
            raise ParameterError(
                "warm_start must be a plan of the same problem (targets, tolerances, "
                f"clearance, tip bounds, rest at the end, horizon): {sizes} multipliers "
                f"against {problem.sizes}"
            )
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
    excess, violation = problem.excess(np.array(solution["g"]).ravel())
    # the input bounds are bounds of the unknowns: IPOPT keeps them, their multipliers say
    bound_multipliers = np.abs(np.array(solution["lam_x"]).ravel()[problem.u_rows])
    groups = [*problem.groups, *["input bounds"] * bound_multipliers.size]
    multipliers = np.concatenate([np.abs(np.array(solution["lam_g"]).ravel()), bound_multipliers])
    excess_all = np.concatenate([excess, np.zeros(bound_multipliers.size)])
    binding = _binding(groups, excess_all, multipliers)
    iterations = stats.get("iterations", {})
    optimality = float(iterations["inf_du"][-1]) if iterations.get("inf_du") else float("nan")
    status, words = solve_status(stats, violation)
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
        evaluation_timings(stats),
    )  # fmt: skip


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
