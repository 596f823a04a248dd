"""Nonlinear model-predictive control: the problem of :func:`~softcurve.control.
optimize_trajectory` solved again at every sample over a receding horizon
(:class:`PredictiveController`), on a Gauss-Newton Hessian by default
(:data:`PREDICTIVE_HESSIANS`).
"""

from __future__ import annotations

import time

import casadi as ca
import numpy as np

from softcurve.base.status import Status
from softcurve.base.validation import ParameterError
from softcurve.control._problem import (
    PLAN_ITERATIONS,
    Problem,
    checked_request,
    evaluation_timings,
    ipopt_options,
    solve_status,
)
from softcurve.control._transcription import Transcription
from softcurve.control.controllers import SampledController
from softcurve.control.references import Reference, checked_reference
from softcurve.description.actuator import Actuator

PREDICTIVE_HESSIANS = ("gauss-newton", "exact")
"""The Hessians of the Lagrangian of :class:`PredictiveController`'s solves; the first is
the default. ``"gauss-newton"``: the cost's own (constant: the cost is quadratic in the
unknowns), the constraints' curvature left out; ``"exact"``: with it, from the compiled
second derivatives, stage by stage (``Problem.lagrangian_hessian``). On the circle of
docs/planning.md (the paper's robot, 25 steps of 20 ms, one iteration a sample; ``python
benchmarks/bench_predictive.py``) a sample takes a median 12 ms with the Gauss-Newton
Hessian (the constraints' Jacobian by stages, ``Problem.constraint_jacobian``, and
:data:`REAL_TIME_OPTIONS`) and 81 ms with the exact one, the tip 0.14 mm and
0.15 mm from the circle; at 10 steps of 10 ms, 5 ms and 38 ms, the same 0.022 mm.
Gauss-Newton is the default. :func:`optimize_trajectory` keeps the exact Hessian: without
the constraints' curvature its iterations converge only linearly, and a plan's targets
and rest at the end add constraints whose curvature the controller's problem does not
have."""


REAL_TIME_OPTIONS = {
    "nlp_scaling_method": "none",
    "mumps_pivot_order": 0,
    "mumps_permuting_scaling": 0,
    "mumps_scaling": 0,
}
"""IPOPT's options of every solve of a Gauss-Newton :class:`PredictiveController`, for its
time a sample. The problem's unknowns and constraints are scaled to order one when it is
built, and the Gauss-Newton Hessian is positive semi-definite, so IPOPT's gradient-based
scaling (a Jacobian at the start of every solve) and MUMPS's weighted matching and
scaling of the KKT system are left out, and MUMPS orders it by approximate minimum
degree, its analysis redone at every solve. On the paper's robot at 25 steps of 20 ms and
one iteration a sample (``python benchmarks/bench_predictive.py``, each option added in
turn): 21.1 ms a sample with IPOPT's defaults, 18.7 ms without its scaling, 18.1 ms
ordered by minimum degree, 11.8 ms without MUMPS's matching and scaling; the tip's error
the same (0.1385 mm) throughout. Without the matching but with MUMPS's scaling the tip
went 0.170 mm off, so both are left out. With the exact Hessian, whose KKT system is
indefinite, these options took the tip 2.1 mm off (14.6 mm at worst): it keeps IPOPT's
defaults."""


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
        The iteration budget of every solve after the first, >= 1 (default 1: one
        Newton step of the interior-point method a sample from the moved plan, a
        real-time iteration; more iterations cost about 6 ms each on the paper's robot,
        docs/planning.md).
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
        iterations: int = 1,
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
        checked_reference(reference, model.robot)  # required here, optional in a plan
        request = checked_request(
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
            options = ipopt_options(problem, budget, request.tolerance, self.hessian, warm)
            if self.hessian == "gauss-newton":
                options.update({f"ipopt.{key}": value for key, value in REAL_TIME_OPTIONS.items()})
            self._solvers[warm] = ca.nlpsol("predictive_controller", "ipopt", problem.nlp, options)
        return self._solvers[warm]

    def __call__(self, t, q, qd, lam=None) -> np.ndarray:
        model, tr = self.model, self.transcription
        lam = np.zeros(model.n_creep) if lam is None else np.asarray(lam, dtype=np.float64)
        x = np.concatenate([q, qd, lam, [] if self._lagging is None else self._lagging])
        if self._problem is None:
            self._problem = Problem.build(tr, x, self.request, rest_at_end=False,
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
        _, violation = problem.excess(np.array(solution["g"]).ravel())
        status, _ = solve_status(stats, violation)
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
            self._lagging = self.actuator.input_step(self._lagging, inputs, self.sample_time)
        self._applied = inputs
        tau = self.actuator.input_matrix(q) @ inputs
        self.log.append(
            {"t": t, "inputs": inputs, "tau": tau, "status": status,
             "iterations": int(stats.get("iter_count", 0)), "solve_time": solve_time,
             "cost": float(solution["f"]), "violation": violation,
             "timings": evaluation_timings(stats)}
        )  # fmt: skip
        return inputs.copy()
