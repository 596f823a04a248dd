"""Identification of a whole robot from measured time series, with exact gradients.

Two fits share one description of what is free
(:mod:`softcurve.identification.parameters`):

- :func:`fit_trajectory` simulates the equation of motion (16) with the creep
  states (19) and matches its outputs to the data; CVODES integrates the state
  together with its forward-sensitivity (variational) equations, compiled to C
  (:mod:`softcurve.simulation.sensitivity`), which gives the exact Jacobian of every
  output sample with respect to the free parameters and the initial state.
- :func:`fit_equilibria` treats each sample as a static equilibrium
  ``N(q) = tau(q, u)`` (inputs much slower than the robot), solved by the package's
  equilibrium solver; the implicit function theorem gives the exact Jacobian
  (:mod:`softcurve.identification.equilibria`).

What can be estimated: any entry of ``robot.layout`` (a *robot* parameter), and any
*named extra* parameter used by an output map, an input map, the initial state or a
``bind`` rule that writes robot parameters as expressions of extra ones (e.g. a
well-posed re-parametrization of the tanh law, see
:func:`~softcurve.identification.parameters.tanh_parameters`). Sensor offsets, a
bellows' mounting angle and pressure-map gains are extra parameters of the output and
input maps (:mod:`softcurve.identification.maps`).
"""

from __future__ import annotations

import numpy as np

from softcurve.analysis.loads import rest_configuration
from softcurve.base.docs import parameters_from
from softcurve.base.status import Status
from softcurve.base.validation import ParameterError, real_array
from softcurve.compiled.model import Model
from softcurve.identification.equilibria import EquilibriumPredictor
from softcurve.identification.experiments import Experiment
from softcurve.identification.maps import InputMap, OutputMap
from softcurve.identification.parameters import FreeParameters
from softcurve.identification.report import FitReport, solve_least_squares, summarize
from softcurve.simulation.sensitivity import trajectory_sensitivities


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
        self.parameters = FreeParameters(model, free, extras, bind or {}, p)

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
            z, status, message, count = np.zeros(0), Status.SUCCESS, "nothing to fit", 1
        theta_value = z * P.scale
        try:
            y_num, jac_num = evaluate(theta_value)
            r_num = ((y_num.T - measured) * w).ravel()
            jac_num = jac_num * np.tile(w, experiment.t.size)[:, None]
        except (RuntimeError, FloatingPointError) as exc:
            status, message = Status.NOT_CONVERGED, f"the model could not be evaluated: {exc}"
            y_num = np.full((len(names), experiment.t.size), np.nan)
            r_num, jac_num = np.zeros(0), np.zeros((0, len(P.free)))
        errors, corr, identifiable, status, message = summarize(
            P.names, jac_num, r_num, status, message
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
            robot, status = None, Status.INFEASIBLE
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


PREDICTION_PARAMETERS = {
    "model": ("Model", "The compiled model the fit used."),
    "experiment": (
        "Experiment",
        "The experiment to predict (time grid, measured signals, inputs).",
    ),
}
"""The parameters ``predict_trajectory`` and ``predict_equilibria`` share."""

FIT_OPTIONS = {
    "bind": (
        "dict, optional",
        "Robot parameter name -> ``rule(values)`` expression of extra parameters.",
    ),
    "signals": (
        "list of str, optional",
        "Experiment signals matched to the outputs, in order (default: output names).",
    ),
    "weights": (
        "array_like, shape (k,), optional",
        "One weight per signal (e.g. the inverse of its noise level) [1/signal unit].",
    ),
    "parameters": (
        "array_like, shape (P,), optional",
        "Robot parameter vector to start from (default ``model.parameters``).",
    ),
    "confidence": (
        "float",
        "Confidence level of the report's intervals, a probability in (0, 1).",
    ),
}
"""The options ``fit_trajectory`` and ``fit_equilibria`` share, documented once."""

_fit_options = parameters_from(FIT_OPTIONS)


@_fit_options
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
    %(bind)s
    %(signals)s
    %(weights)s
    %(parameters)s
    max_evaluations : int
        Budget of residual evaluations (each is one simulation with sensitivities).
    %(confidence)s
    integrator_options : dict, optional
        Extra CVODES options of the sensitivity integration.

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


@_fit_options
def fit_equilibria(
    model: Model,
    experiment: Experiment,
    *,
    output: OutputMap,
    input_map: InputMap,
    free,
    q0=None,
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
    period (damping and creep then play no role). With no free parameters this is a
    prediction.

    Parameters
    ----------
    model : Model
        The compiled model; its robot gives the values of everything not free.
    experiment : Experiment
        Time grid, measured signals and inputs.
    output : OutputMap
        Model outputs matched to the signals.
    input_map : InputMap
        Generalized forces from the experiment's inputs (all of them, in order).
    free : list of Free or str
        What to estimate.
    q0 : array_like, shape (n,), optional
        Initial guess of every sample's equilibrium [m, 1/m, 1/m] (default: the
        straight robot at rest length); later evaluations start from the previous
        solutions.
    extra : dict, optional
        Named extra parameters and their values.
    %(bind)s
    %(signals)s
    %(weights)s
    %(parameters)s
    max_evaluations : int
        Budget of residual evaluations.
    %(confidence)s
    """
    q0 = rest_configuration(model.robot) if q0 is None else real_array("q0", q0, (model.n,))
    problem = _Problem(model, output, input_map, free, extra, bind, parameters)
    predictor = EquilibriumPredictor(model, problem.parameters, output, input_map, q0)
    return problem.run(
        predictor,
        experiment,
        signals,
        weights,
        max_evaluations,
        confidence,
        "equilibrium fit",
    )


@parameters_from(PREDICTION_PARAMETERS)
def predict_trajectory(model: Model, experiment: Experiment, fit: FitReport, **problem):
    """Simulate ``experiment`` with the estimate of ``fit``, without refitting.

    The fitted robot parameters and extra values are taken from ``fit``.

    Parameters
    ----------
    %(model)s
    %(experiment)s
    fit : FitReport
        A report of :func:`fit_trajectory` or :func:`fit_equilibria`; its
        ``extra["parameters"]`` and ``extra["values"]`` give the estimate.
    **problem
        The fit's keyword arguments ``output``, ``x0``, ``input_map``, ``bind`` (and
        optionally ``signals``, ``weights``, ``extra``), passed on to
        :func:`fit_trajectory` with no free parameters.

    Returns
    -------
    FitReport
        With no free parameters; its ``rms`` and ``max_error`` are the prediction errors.
    """
    values = {**problem.pop("extra", {}), **fit.extra["values"]}
    return fit_trajectory(
        model, experiment, free=[], extra=values, parameters=fit.extra["parameters"], **problem
    )


@parameters_from(PREDICTION_PARAMETERS)
def predict_equilibria(model: Model, experiment: Experiment, fit: FitReport, **problem):
    """Quasi-static prediction of ``experiment`` with the estimate of ``fit``, without
    refitting (see :func:`predict_trajectory`).

    Parameters
    ----------
    %(model)s
    %(experiment)s
    fit : FitReport
        A report of :func:`fit_equilibria` or :func:`fit_trajectory`; its
        ``extra["parameters"]`` and ``extra["values"]`` give the estimate.
    **problem
        The fit's keyword arguments ``output``, ``input_map``, ``bind`` (and optionally
        ``q0``, ``signals``, ``weights``, ``extra``), passed on to :func:`fit_equilibria`
        with no free parameters.

    Returns
    -------
    FitReport
        With no free parameters; its ``rms`` and ``max_error`` are the prediction errors.
    """
    values = {**problem.pop("extra", {}), **fit.extra["values"]}
    return fit_equilibria(
        model, experiment, free=[], extra=values, parameters=fit.extra["parameters"], **problem
    )
