"""Identification of a whole robot from measured time series, with exact gradients.

Two fits share one description of what is free:

- :func:`fit_trajectory` simulates the equation of motion (16) with the creep
  states (19) and matches its outputs to the data; CVODES integrates the state
  together with its forward-sensitivity (variational) equations, compiled to C
  (:mod:`softcurve._sensitivity`), which gives the exact Jacobian of every output
  sample with respect to the free parameters and the initial state.
- :func:`fit_equilibria` treats each sample as a static equilibrium
  ``N(q) = tau(q, u)`` (inputs much slower than the robot), solved by Newton's
  method; the implicit function theorem gives the exact Jacobian.

What can be estimated: any entry of ``robot.parameter_names()`` (a *robot*
parameter), and any *named extra* parameter used by an output map, an input map,
the initial state or a ``bind`` rule that writes robot parameters as expressions of
extra ones (e.g. a well-posed re-parametrisation of the tanh law, see
:func:`tanh_parameters`). Sensor offsets, a bellows' mounting angle and pressure-map
gains are extra parameters of the output and input maps.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.compiled.model import Model
from softcurve.description.robot import Robot
from softcurve.identification.experiments import Experiment
from softcurve.identification.maps import (  # noqa: F401  (re-exported: one place to import fits from)
    InputMap,
    OutputMap,
    bellows_input_map,
    bending_angle,
    constant_input_map,
    curvatures,
    tip_position,
)
from softcurve.identification.stiffness import FitReport, solve_least_squares, summarise
from softcurve.simulation.sensitivity import trajectory_sensitivities


@dataclass(frozen=True)
class Free:
    """A parameter to estimate.

    Parameters
    ----------
    name : str or tuple of str
        A robot parameter (``"segments[0].damping[1,1]"``) or a named extra parameter;
        a tuple ties several robot parameters to one value (e.g. both bending dampings).
    lower, upper : float
        Bounds.
    initial : float, optional
        Starting value (default: the current value).
    scale : float, optional
        Typical magnitude, for conditioning (default: ``|initial|``, or 1 if zero).
    """

    name: str | tuple[str, ...]
    lower: float = -np.inf
    upper: float = np.inf
    initial: float | None = None
    scale: float | None = None

    @property
    def label(self) -> str:
        return self.name if isinstance(self.name, str) else "=".join(self.name)

    @property
    def targets(self) -> tuple[str, ...]:
        return (self.name,) if isinstance(self.name, str) else tuple(self.name)


def tanh_parameters(robot: Robot, law: str):
    """A well-posed re-parametrisation of a tanh stiffness law for fitting.

    ``k(0) = a1 - a2`` and ``k(inf) = a1`` are positive for every admissible law, so
    box bounds ``> 0`` on them keep the law well posed (``a1 > 0, a1 > a2``) throughout.

    Parameters
    ----------
    robot : Robot
    law : str
        Prefix of the law, e.g. ``"segments[0].bending_stiffness"`` (must be a tanh law).

    Returns
    -------
    values : dict
        Extra parameters ``law + ".k_zero"``, ``law + ".k_inf"``, ``law + ".rate"`` (= a3).
    bind : dict
        Rules writing ``a1, a2, a3`` from them, for the fits' ``bind`` argument.
    """
    current = dict(zip(robot.parameter_names(), robot.parameter_vector(), strict=True))
    if f"{law}.a2" not in current:
        raise ParameterError(f"{law!r} is not a tanh stiffness law of this robot")
    a1, a2, a3 = (current[f"{law}.{k}"] for k in ("a1", "a2", "a3"))
    zero, inf, rate = f"{law}.k_zero", f"{law}.k_inf", f"{law}.rate"
    values = {zero: a1 - a2, inf: a1, rate: a3}
    bind = {
        f"{law}.a1": lambda v: v[inf],
        f"{law}.a2": lambda v: v[inf] - v[zero],
        f"{law}.a3": lambda v: v[rate],
    }
    return values, bind


class _Parameters:
    """Maps the free vector ``theta`` to the robot vector ``p`` and the extra values."""

    def __init__(self, model: Model, free, extra: dict, bind: dict, p=None):
        self.robot_names = model.robot.parameter_names()
        self.p0 = model.parameters if p is None else np.asarray(p, dtype=np.float64)
        self.extra = {str(k): float(v) for k, v in extra.items()}
        self.bind = dict(bind)
        self.free = [f if isinstance(f, Free) else Free(f) for f in free]
        index = {n: i for i, n in enumerate(self.robot_names)}
        for name in self.bind:
            if name not in index:
                raise ParameterError(f"bind: {name!r} is not a robot parameter")
        seen = set()
        for f in self.free:
            for t in f.targets:
                if t in seen:
                    raise ParameterError(f"free: {t!r} is listed twice")
                seen.add(t)
                if t in self.bind:
                    raise ParameterError(f"free: {t!r} is bound by a rule; free its arguments")
                if t not in index and t not in self.extra:
                    raise ParameterError(
                        f"free: {t!r} is neither a robot parameter (robot.parameter_names()) "
                        f"nor an extra parameter ({sorted(self.extra)})"
                    )
            if len(f.targets) > 1 and any(t in self.extra for t in f.targets):
                raise ParameterError(f"free: only robot parameters can be tied, got {f.name}")
            if not f.lower < f.upper:
                raise ParameterError(f"free {f.label!r}: lower must be < upper")
        self.index = index
        current = {**dict(zip(self.robot_names, self.p0, strict=True)), **self.extra}
        self.theta0 = np.array(
            [current[f.targets[0]] if f.initial is None else f.initial for f in self.free]
        )
        bad = [
            f.label
            for f, v in zip(self.free, self.theta0, strict=True)
            if not f.lower <= v <= f.upper
        ]
        if bad:
            raise ParameterError(f"free: initial values outside their bounds: {bad}")
        given = [f.scale for f in self.free]
        self.scale = np.array(
            [
                s if s is not None else (abs(v) if v != 0 else 1.0)
                for s, v in zip(given, self.theta0, strict=True)
            ]
        )
        self.lower = np.array([f.lower for f in self.free]) / self.scale
        self.upper = np.array([f.upper for f in self.free]) / self.scale
        self.names = tuple(f.label for f in self.free)

    def expressions(self, theta):
        """``(p, values)`` as CasADi expressions of ``theta`` (MX)."""
        values = dict(self.extra)
        entries = [ca.MX(v) for v in self.p0]
        for i, f in enumerate(self.free):
            for t in f.targets:
                if t in self.index:
                    entries[self.index[t]] = theta[i]
                else:
                    values[t] = theta[i]
        for name, rule in self.bind.items():
            entries[self.index[name]] = rule(values)
        return ca.vertcat(*entries), values

    def evaluate(self, theta_value):
        """Numeric ``(p, values)`` at a numeric ``theta``."""
        theta = ca.MX.sym("theta", len(self.free))
        p, values = self.expressions(theta)
        keys = sorted(values)
        f = ca.Function("values", [theta], [p, *(ca.MX(values[k]) for k in keys)])
        out = f(np.asarray(theta_value, dtype=np.float64))
        out = out if isinstance(out, tuple | list) else [out]
        return np.array(out[0]).ravel(), {k: float(v) for k, v in zip(keys, out[1:], strict=True)}


def _signals(experiment: Experiment, output: OutputMap, signals):
    names = list(output.names) if signals is None else list(signals)
    if len(names) != len(output.names):
        raise ParameterError(
            f"signals: the output map gives {len(output.names)} outputs {output.names}, "
            f"got {len(names)} signal names {names}"
        )
    return names, experiment.signal_matrix(names)


def _weights(weights, k):
    w = np.ones(k) if weights is None else np.asarray(weights, dtype=np.float64).ravel()
    if w.shape != (k,) or not np.all(w > 0):
        raise ParameterError(f"weights must be {k} positive numbers (one per signal)")
    return w


class _Problem:
    """Free parameters + a predictor ``predict(theta MX) -> Y (k, T) MX``; fits or predicts."""

    def __init__(self, model, output, input_map, free, extra, bind, p):
        self.model = model
        self.output = output
        self.input_map = input_map
        extras = {**output.parameters, **(input_map.parameters if input_map else {})}
        extras.update(extra or {})
        self.parameters = _Parameters(model, free, extras, bind or {}, p)

    def forces(self, q, u, values):
        if self.input_map is None:
            return ca.MX.zeros(self.model.n)
        return self.input_map.function(q, u, values)

    def run(self, predictor, experiment, signals, weights, max_evaluations, confidence, kind):
        names, measured = _signals(experiment, self.output, signals)
        w = _weights(weights, len(names))
        P = self.parameters
        evaluate = predictor(experiment)  # theta -> (Y (k, T), dvec(Y)/dtheta (k T, P))

        def residual_and_jacobian(z):
            y, jac = evaluate(z * P.scale)
            r = ((y.T - measured) * w).ravel()
            return r, (jac * np.tile(w, experiment.t.size)[:, None]) * P.scale

        if len(P.free):
            z, *_, status, message, count = solve_least_squares(
                residual_and_jacobian, P.theta0 / P.scale, P.lower, P.upper, max_evaluations
            )
        else:
            z, status, message, count = np.zeros(0), "converged", "nothing to fit", 1
        theta_value = z * P.scale
        try:
            y_num, jac_num = evaluate(theta_value)
            r_num = ((y_num.T - measured) * w).ravel()
            jac_num = jac_num * np.tile(w, experiment.t.size)[:, None]
        except (RuntimeError, FloatingPointError) as exc:
            status, message = "failed", f"the model could not be evaluated: {exc}"
            y_num = np.full((len(names), experiment.t.size), np.nan)
            r_num, jac_num = np.zeros(0), np.zeros((0, len(P.free)))
        errors, corr, identifiable, message = summarise(
            P.names, theta_value, jac_num, r_num, status, message
        )
        at_bound = [
            name
            for name, v, lo, hi in zip(P.names, z, P.lower, P.upper, strict=True)
            if min(abs(v - lo), abs(v - hi)) <= 1e-8 * max(1.0, abs(v))
        ]
        if at_bound:
            message += f"; at a bound (interval not meaningful there): {at_bound}"
        p_value, extra_values = P.evaluate(theta_value)
        try:
            robot = self.model.robot.with_parameter_vector(p_value)
        except ParameterError as exc:
            robot, status = None, "failed"
            message += f"; the estimate is not an admissible robot: {exc}"
        return FitReport(
            status=status,
            message=f"{kind}: {message}",
            names=P.names,
            values=theta_value,
            standard_errors=errors,
            correlation=corr,
            abscissa=experiment.t,
            measured=measured,
            predicted=np.asarray(y_num).T,
            signals=tuple(names),
            units=tuple(
                experiment.units.get(n) or u for n, u in zip(names, self.output.units, strict=True)
            ),
            confidence=confidence,
            n_evaluations=count,
            identifiable=identifiable,
            extra={"robot": robot, "parameters": p_value, "values": extra_values},
        )


def _trajectory_predictor(problem: _Problem, x0, integrator_options):
    def predictor(experiment):
        return trajectory_sensitivities(
            problem.model,
            problem.parameters,
            problem.output,
            problem.input_map,
            x0,
            experiment,
            integrator_options,
        )

    return predictor


def fit_trajectory(
    model: Model,
    experiment: Experiment,
    *,
    output: OutputMap,
    x0,
    free,
    input_map: InputMap | None = None,
    extra: dict | None = None,
    bind: dict | None = None,
    signals=None,
    weights=None,
    parameters=None,
    max_evaluations: int = 60,
    confidence: float = 0.95,
    integrator_options: dict | None = None,
) -> FitReport:
    """Trajectory least squares: simulate the experiment and fit the free parameters.

    Parameters
    ----------
    model : Model
        The compiled model; its robot gives the values of everything not free.
    experiment : Experiment
        Time grid, measured signals and (for forced motion) inputs, held constant
        between samples.
    output : OutputMap
        Model outputs matched to the signals (:func:`bending_angle`, :func:`curvatures`,
        :func:`tip_position`).
    x0 : array_like, shape (n_state,), or callable
        Initial state ``(q, qd, lam)``; a callable receives the dict of extra
        parameters (CasADi expressions) and returns the state, so that initial creep
        states or angles can be estimated.
    free : list of Free or str
        What to estimate; a bare string is ``Free(name)`` without bounds.
    input_map : InputMap, optional
        Generalized forces from the experiment's inputs (all of them, in order).
    extra : dict, optional
        Named extra parameters and their values (used by ``x0`` or ``bind``).
    bind : dict, optional
        Robot parameter name -> ``rule(values)`` expression of extra parameters.
    signals : list of str, optional
        Experiment signals matched to the outputs, in order (default: output names).
    weights : array_like, optional
        One weight per signal (e.g. the inverse of its noise level).
    parameters : array_like, optional
        Robot parameter vector to start from (default ``model.parameters``).
    max_evaluations : int
        Budget of residual evaluations (each is one simulation with sensitivities).

    Returns
    -------
    FitReport
        With ``extra["robot"]`` the fitted robot, ``extra["parameters"]`` its
        vector, ``extra["values"]`` the extra parameters.
    """
    problem = _Problem(model, output, input_map, free, extra, bind, parameters)
    predictor = _trajectory_predictor(problem, x0, integrator_options)
    return problem.run(
        predictor, experiment, signals, weights, max_evaluations, confidence, "trajectory fit"
    )


def _equilibrium_predictor(problem: _Problem, guess):
    model = problem.model
    gravity, elastic = model.symbolic["gravity_force"], model.symbolic["elastic_force"]
    q = ca.MX.sym("q", model.n)

    def predictor(experiment):
        P = problem.parameters
        theta = ca.MX.sym("theta", len(P.free))
        p, values = P.expressions(theta)
        u_names = list(experiment.inputs)
        u = ca.MX.sym("u", len(u_names))
        keys = sorted(values)
        pv = ca.MX.sym("pv", p.shape[0] + len(keys))
        p_sym = pv[: p.shape[0]]
        v_sym = {k: pv[p.shape[0] + i] for i, k in enumerate(keys)}
        balance = gravity(q, p_sym) + elastic(q, p_sym) - problem.forces(q, u, v_sym)
        g = ca.Function("balance", [q, ca.vertcat(u, pv)], [balance])
        solver = ca.rootfinder(
            "equilibrium", "newton", g, {"abstol": 1e-12, "max_iter": 60, "error_on_fail": False}
        )
        t = experiment.t
        start = np.tile(np.asarray(guess, dtype=np.float64)[:, None], (1, t.size))
        pv_value = ca.vertcat(p, *(ca.MX(values[k]) for k in keys))
        u_data = experiment.input_matrix(u_names).T if u_names else np.zeros((0, t.size))
        columns = ca.repmat(pv_value, 1, t.size)
        q_all = solver.map(t.size)(start, ca.vertcat(u_data, columns))
        out = ca.Function(
            "out", [q, pv], [problem.output.function(q, ca.MX.zeros(model.n), v_sym, p_sym)]
        )
        y = out.map(t.size)(q_all, columns)
        imbalance = g.map(t.size)(q_all, ca.vertcat(u_data, columns))
        f = ca.Function(
            "equilibria", [theta], [y, ca.jacobian(ca.vec(y), theta), ca.mmax(ca.fabs(imbalance))]
        )
        force_scale = float(np.max(np.abs(model.gravity_force(guess)))) or 1.0

        def evaluate(theta_value):
            y_value, jac, worst = f(theta_value)
            if not float(worst) <= 1e-8 * force_scale:
                raise RuntimeError(
                    "Newton's method found no equilibrium for some samples (largest force "
                    f"imbalance {float(worst):.3g}): the robot may snap through or buckle there"
                )
            return np.array(y_value), np.array(jac)

        return evaluate

    return predictor


def fit_equilibria(
    model: Model,
    experiment: Experiment,
    *,
    output: OutputMap,
    input_map: InputMap,
    free,
    guess=None,
    extra: dict | None = None,
    bind: dict | None = None,
    signals=None,
    weights=None,
    parameters=None,
    max_evaluations: int = 100,
    confidence: float = 0.95,
) -> FitReport:
    """Quasi-static least squares: each sample is an equilibrium ``N(q) = tau(q, u)``.

    Valid when the inputs change much more slowly than the robot's lowest natural
    period (damping and creep then play no role). Arguments as in
    :func:`fit_trajectory`; ``guess`` (n,) starts Newton's method at every sample
    (default: the straight robot at rest length). With no free parameters this is
    a prediction.
    """
    if guess is None:
        guess = np.concatenate([[s.rest_length, 0.0, 0.0] for s in model.robot.segments])
    problem = _Problem(model, output, input_map, free, extra, bind, parameters)
    return problem.run(
        _equilibrium_predictor(problem, guess),
        experiment,
        signals,
        weights,
        max_evaluations,
        confidence,
        "equilibrium fit",
    )


def predict_trajectory(model: Model, experiment: Experiment, fit: FitReport, **problem):
    """Simulate ``experiment`` with the estimate of ``fit``, without refitting.

    ``problem`` holds the fit's ``output``, ``x0``, ``input_map``, ``bind`` (and
    optionally ``signals``, ``weights``); the fitted robot parameters and extra values
    are taken from ``fit``. Returns a :class:`FitReport` with no free parameters, whose
    ``rms`` and ``max_error`` are the prediction errors.
    """
    values = {**problem.pop("extra", {}), **fit.extra["values"]}
    return fit_trajectory(
        model, experiment, free=[], extra=values, parameters=fit.extra["parameters"], **problem
    )


def predict_equilibria(model: Model, experiment: Experiment, fit: FitReport, **problem):
    """Quasi-static prediction of ``experiment`` with the estimate of ``fit`` (see
    :func:`predict_trajectory`); ``problem`` holds ``output``, ``input_map``, ``bind``."""
    values = {**problem.pop("extra", {}), **fit.extra["values"]}
    return fit_equilibria(
        model, experiment, free=[], extra=values, parameters=fit.extra["parameters"], **problem
    )
