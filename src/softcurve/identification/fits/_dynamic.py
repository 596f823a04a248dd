"""Identification of a whole robot from measured time series, with exact gradients.

Two fits share one description of what is free
(``softcurve.identification.fits._parameters``):

- :func:`fit_trajectory` simulates the equation of motion (16) with the creep
  states (19) and matches its outputs to the data; CVODES integrates the state
  together with its forward-sensitivity (variational) equations, compiled to C
  (``softcurve.simulation.sensitivity._sensitivity``), which gives the exact Jacobian of every
  output sample with respect to the free parameters and the initial state.
- :func:`fit_equilibria` treats each sample as a static equilibrium
  ``N(q) = tau(q, u)`` (inputs much slower than the robot), solved by the package's
  equilibrium solver; the implicit function theorem gives the exact Jacobian
  (``softcurve.identification.fits._equilibria``).

What can be estimated: any entry of ``robot.layout`` (a *robot* parameter), and any
*named extra* parameter used by an output map, an input map, the initial state or a
``bind`` rule that writes robot parameters as expressions of extra ones (e.g. a
well-posed re-parametrization of the tanh law, see
:func:`~softcurve.identification.fits.tanh_parameters`). Sensor offsets, a
bellows' mounting angle and pressure-map gains are extra parameters of the output and
input maps (:mod:`softcurve.identification.maps`); entries of the initial state are
``x0.q[i]``, ``x0.qd[i]``, ``x0.lam[i]`` and, with an input lag, ``x0.u[i]``
(``softcurve.identification.fits._initial``).

Both fits take one experiment or a list of them: parameters are shared by all unless
declared ``Free(..., per_experiment=True)`` (``softcurve.identification.fits._joint``);
each experiment is simulated on its own, with its own sensitivities, in worker
processes. A trial point the model cannot evaluate is a rejected step, ``starts=K``
runs a seeded multi-start, ``progress=True`` shows a progress line
(``softcurve.identification.fits._problem``). Predicting from a failed fit raises
:class:`~softcurve.identification.fits.FitError`.
"""

from __future__ import annotations

import warnings
from dataclasses import replace

import numpy as np

from softcurve.analysis.loads import coordinate_scale, rest_configuration
from softcurve.base.docs import parameters_from
from softcurve.base.status import Status
from softcurve.base.validation import ParameterError, float_array, real_array, real_scalar
from softcurve.compiled import Model
from softcurve.identification.fits._equilibria import EquilibriumPredictor
from softcurve.identification.fits._initial import LAG, initial_state, start_values
from softcurve.identification.fits._initial_equilibrium import initial_equilibrium
from softcurve.identification.fits._joint import (
    experiment_list,
    outputs_alone,
    parallel_layout,
    split_extra,
)
from softcurve.identification.fits._parameters import Free
from softcurve.identification.fits._problem import Problem
from softcurve.identification.fits._report import FitError, FitReport, FitWarning, usable_fit
from softcurve.identification.fits._solve import EVALUATION_ERRORS
from softcurve.identification.fits._weights import WEIGHTS_DOC
from softcurve.identification.maps import InputMap, OutputMap
from softcurve.simulation.sensitivity import SENSITIVITY_CVODES, trajectory_sensitivities

PREDICTION_PARAMETERS = {
    "model": ("Model", "The compiled model the fit used."),
    "experiment": (
        "Experiment or list of Experiment",
        "The experiment(s) to predict (time grid, measured signals, inputs); one that "
        "the fit had gets its per-experiment values, another the nominal ones.",
    ),
    "fit": (
        "FitReport",
        "A report of :func:`fit_trajectory` or :func:`fit_equilibria`; its "
        "``extra['parameters']``, ``extra['values']`` and ``extra['per_experiment']`` "
        "give the estimate. A failed fit raises :class:`FitError`, one that ran out of "
        "evaluations warns (:class:`FitWarning`).",
    ),
}
"""The parameters ``predict_trajectory`` and ``predict_equilibria`` share."""

FIT_OPTIONS = {
    "experiment": (
        "Experiment or list of Experiment",
        "Time grid, measured signals and inputs (held constant between samples); a list "
        "is fitted jointly, each experiment simulated on its own.",
    ),
    "free": (
        "list of Free or str",
        "What to estimate; a bare string is ``Free(name)`` without bounds; "
        "``Free(..., per_experiment=True)`` gives one value per experiment.",
    ),
    "extra": (
        "dict, optional",
        "Named extra parameters and their values; a key ``name[experiment]`` sets the "
        "value for one experiment.",
    ),
    "bind": (
        "dict, optional",
        "Robot parameter name -> ``rule(values)`` expression of extra parameters.",
    ),
    "signals": (
        "list of str, optional",
        "Experiment signals matched to the outputs, in order (default: output names).",
    ),
    "weights": WEIGHTS_DOC,
    "parameters": (
        "array_like, shape (P,), optional",
        "Robot parameter vector to start from (default ``model.parameters``, or the "
        "estimate of ``start``).",
    ),
    "start": (
        "FitReport, optional",
        "An earlier fit to start from (one that ran out of evaluations, or of fewer "
        "experiments): every parameter it estimated starts at its estimate, whatever "
        "``Free(..., initial=)`` says (bounds and scales are kept), per-experiment values "
        "for the experiments it had; the robot starts at its ``extra['parameters']`` unless "
        "``parameters`` is given. A failed fit raises :class:`FitError`.",
    ),
    "confidence": (
        "float",
        "Confidence level of the report's intervals, a probability in (0, 1).",
    ),
    "starts": (
        "int",
        "Starting points of a multi-start (1: only the given start); the report keeps "
        "every optimum (``optima``) and its table their spread.",
    ),
    "seed": ("int, optional", "Seed of the multi-start's random starting points."),
    "progress": ("bool", "A progress line of the evaluations on stderr."),
}
"""The options ``fit_trajectory`` and ``fit_equilibria`` share, documented once."""

_fit_options = parameters_from(FIT_OPTIONS)


def _started(start, experiment, free, extra, parameters):
    """``(free, extra, parameters)`` of a fit that starts from the report ``start``: its
    estimates as the extra values and the robot vector, and no ``initial`` of the free
    parameters it estimated, so that they start there."""
    if start is None:
        return free, extra, parameters
    if not isinstance(start, FitReport):
        raise ParameterError(f"start must be a FitReport of an earlier fit, got {start!r}")
    with warnings.catch_warnings():  # resuming an unfinished fit is what start is for
        warnings.simplefilter("ignore", FitWarning)
        values = _fitted_values(start, experiment, dict(extra or {}))
    per = start.extra.get("per_experiment", {})
    estimated = set(start.names) | set(start.extra["values"]) | {n for v in per.values() for n in v}
    free = [Free(f) if isinstance(f, str) else f for f in free]
    free = [replace(f, initial=None) if f.label in estimated else f for f in free]
    if parameters is None:
        return free, values, start.extra["parameters"]
    # a given robot vector, with the report's estimates of the free robot parameters
    p, layout = np.array(parameters, dtype=np.float64), start.extra["robot"].layout
    for f in free:
        if f.label in start.names and all(t in layout for t in f.targets):
            for target in f.targets:
                p[layout.index(target)] = start.value(f.label)
    return free, values, p


def _per_experiment(name, value, experiments, is_one):
    """``value`` for each experiment: one shared, a list in order or a dict by name."""
    if isinstance(value, dict):
        missing = [e.name for e in experiments if e.name not in value]
        if missing:
            raise ParameterError(f"{name}: no entry for experiments {missing}")
        return [value[e.name] for e in experiments]
    if is_one(value):
        return [value] * len(experiments)
    values = list(value)
    if len(values) != len(experiments):
        raise ParameterError(
            f"{name}: one for all, or one per experiment ({len(experiments)}), got {len(values)}"
        )
    return values


def _finite_states(states, experiments) -> None:
    """Refuse an initial state given as numbers with an entry that is not finite (NaN, inf),
    naming the experiment and the entries (a callable gives CasADi expressions of the
    extra parameters: nothing to check before the integration)."""
    for e, state in zip(experiments, states, strict=True):
        if callable(state):
            continue
        name = "x0" if len(experiments) == 1 else f"x0 of experiment {e.name!r}"
        entries = float_array(name, state, "a real array of shape (n_state,)")
        bad = np.flatnonzero(~np.isfinite(entries.ravel()))
        if bad.size:
            raise ParameterError(
                f"{name} must be finite in every entry, got {entries.ravel()[bad].tolist()} "
                f"at entries {bad.tolist()}"
            )


def _one_state(value) -> bool:
    if isinstance(value, list | tuple) and value:  # a list of states or of callables?
        return not (callable(value[0]) or np.ndim(value[0]) == 1)
    return callable(value) or np.ndim(value) == 1


@_fit_options
def fit_trajectory(
    model: Model,
    experiment,
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
    start: FitReport | None = None,
    max_evaluations: int = 60,
    confidence: float = 0.95,
    integrator_options: dict | None = None,
    input_lag: float | None = None,
    input_hold: str = "constant",
    starts: int = 1,
    seed: int | None = None,
    progress: bool = False,
    processes: int | None = None,
    threads: int | None = None,
) -> FitReport:
    """Trajectory least squares: simulate the experiment(s) and fit the free parameters.

    Parameters
    ----------
    model : Model
        The compiled model; its robot gives the values of everything not free.
    %(experiment)s
    output : OutputMap
        Model outputs matched to the signals
        (:func:`~softcurve.identification.maps.bending_angle_map`,
        :func:`~softcurve.identification.maps.curvature_map`,
        :func:`~softcurve.identification.maps.tip_position_map`).
    x0 : array_like, shape (n_state,), or callable, or a list or dict of them
        Initial state ``(q, qd, lam)``; a callable receives the dict of extra
        parameters (CasADi expressions) and returns the state. One for all
        experiments, a list (in order) or a dict by experiment name. Its entries can be
        estimated by name (``"x0.lam[1]"``, ``softcurve.identification.fits._initial``).
    %(free)s
    input_map : InputMap, optional
        Generalized forces from the experiment's inputs (all of them, in order).
    %(extra)s
    %(bind)s
    %(signals)s
    %(weights)s
    %(parameters)s
    %(start)s
    max_evaluations : int
        Budget of residual evaluations per start (each is one simulation with
        sensitivities of every experiment).
    %(confidence)s
    integrator_options : dict, optional
        Extra CVODES options of the sensitivity integration (default tolerances: rtol
        1e-8, atol 1e-10 in the state's units), and ``"method"``: ``"auto"`` (default)
        chooses per experiment (Radau IIA where the inputs are held and change within
        ``softcurve.simulation.sensitivity.AUTO_WITHIN`` over the fastest rate, else
        Adams: ``softcurve.simulation.sensitivity.choose_method``); or CVODES's
        ``"adams"`` or ``"bdf"``, or ``"radau"``, Radau IIA with the sensitivities of its
        discrete scheme, whose Jacobian is its outputs' own derivative, far more
        accurate than CVODES's columns (outside its error test): at rtol 1e-6 it costs
        what Adams costs at the default 1e-8 (docs/performance.md, "Radau IIA");
        ``extra["method"]`` and ``extra["method_reason"]`` say which ran and why. With
        looser ``reltol`` or ``abstol`` the fit integrates its estimate once more at the
        default ones (the outputs alone) and reports the largest change of an output
        relative to the RMS of its signal's residuals as ``extra["integration_error"]``;
        above
        :data:`INTEGRATION_SHARE` (1e-2) the message says to tighten them.
    input_lag : float, optional
        Nominal time constant [s] of a first-order lag of every input before the input
        map (the extra parameter ``"input_lag"``, free like any other); the lagged
        inputs start at each experiment's first input sample (``"x0.u[i]"`` to fit
        them). None: no lag.
    input_hold : {"constant", "linear"}
        The inputs between two samples: the later sample (``"constant"``, a jump at
        every sample) or the line through both (``"linear"``: continuous inputs, which
        the integrator crosses without restarting: 4.9 times fewer steps and 4.9 times
        less time on the benchmark of ``benchmarks/bench_identification.py``).
    %(starts)s
    %(seed)s
    %(progress)s
    processes : int, optional
        Worker processes evaluating the experiments in parallel (default: one per
        experiment, at most the usable cores; 1 evaluates them here in turn).
    threads : int, optional
        Threads of each experiment's evaluation (default: the usable cores the processes
        leave, ``max(1, cores // processes)``); with 2 or more, the sensitivity
        equations are evaluated in two parts on two threads
        (``softcurve.simulation.sensitivity._sensitivity``).

    Returns
    -------
    FitReport
        With ``extra["robot"]`` the fitted robot, ``extra["parameters"]`` its vector,
        ``extra["values"]`` the shared extra parameters and ``extra["per_experiment"]``
        each experiment's own, ``extra["input_hold"]`` the hold of the inputs,
        ``extra["method"]`` and ``extra["method_reason"]`` each experiment's integration
        method and why, by experiment name (``integrator_options``; empty where none
        ran),
        ``extra["integration_error"]`` with looser tolerances (``integrator_options``);
        ``parts`` and :meth:`FitReport.part` give each experiment's rows.
    """
    free, extra, parameters = _started(start, experiment, free, extra, parameters)
    experiments, _ = experiment_list(experiment)
    states = _per_experiment("x0", x0, experiments, _one_state)
    _finite_states(states, experiments)
    lagged = input_lag is not None
    if lagged:
        if input_map is None or not (np.isfinite(input_lag) and input_lag > 0):
            raise ParameterError(
                f"input_lag must be a time constant > 0 [s] with an input_map, got {input_lag!r}"
            )
        extra = {LAG: float(input_lag), **(extra or {})}
    first = {e.name: e.input_matrix()[0] for e in experiments}
    index = {e.name: i for i, e in enumerate(experiments)}

    def starts_of(e, names):
        return start_values(model, states[index[e.name]], first[e.name], names, lagged)

    problem = Problem(
        model, output, input_map, free, extra, bind, parameters, experiment, starts_of
    )
    processes, threads = parallel_layout(len(experiments), processes, threads)
    evaluators = []
    tolerances = _looser_tolerances(integrator_options)
    # too few data values: not identifiable, reported without building the evaluators
    data = problem.data(signals, weights)
    built = [] if problem.too_few(data) else experiments
    for e, part, state in zip(built, problem.parameters.parts, states, strict=False):

        def start(values, state=state, u0=first[e.name]):
            return initial_state(model, state, values, u0, lagged)

        evaluators.append(trajectory_sensitivities(
            model, part, output, input_map, start, e, integrator_options,
            LAG if lagged else None, input_hold, threads,
        ))  # fmt: skip
    options = dict(starts=starts, seed=seed, progress=progress, processes=processes)
    report = problem.run(
        evaluators, data, max_evaluations, confidence, "trajectory fit", options=options
    )
    if tolerances is not None and evaluators:
        report = _integration_checked(report, evaluators, problem.parameters, tolerances)
    # the methods where the evaluators say them (any callable evaluates a fit)
    said = {e.name: v for e, v in zip(built, evaluators, strict=False) if hasattr(v, "method")}
    methods = {name: v.method for name, v in said.items()}
    reasons = {name: v.method_reason for name, v in said.items()}
    extra = {"input_hold": input_hold, "method": methods, "method_reason": reasons}
    return replace(report, extra={**report.extra, **extra})


INTEGRATION_SHARE = 0.01
"""Largest change of an output at the estimate, from the fit's integration tolerances to
the default ones, relative to the RMS of its signal's residuals, that a fit with looser
tolerances accepts silently; above it the message says to tighten them. An integration
error of a hundredth of the residuals moves the estimate by a small fraction of its
standard error."""


def _looser_tolerances(options) -> tuple[float, float] | None:
    """The tolerances ``(rtol, atol)`` that check a fit made with ``options``: each the
    tighter of the given and the default one, where ``options`` loosen either; else None.

    Parameters
    ----------
    options : dict or None
        The fit's ``integrator_options``.
    """
    default = (SENSITIVITY_CVODES["reltol"], SENSITIVITY_CVODES["abstol"])
    given = (options or {}).get("reltol", default[0]), (options or {}).get("abstol", default[1])
    if given[0] <= default[0] and given[1] <= default[1]:
        return None
    return min(given[0], default[0]), min(given[1], default[1])


def _integration_checked(report, evaluators, parameters, tolerances) -> FitReport:
    """``report`` with ``extra["integration_error"]``: the largest change of an output at
    the estimate when integrated at ``tolerances`` instead of the fit's, relative to the
    RMS of its signal's residuals (unweighted; the outputs alone, in this process, one
    experiment after another). Above :data:`INTEGRATION_SHARE` the message says to
    tighten the tolerances. None where it cannot be checked: no estimate, CasADi's
    route, or an integration that fails at those tolerances (the message says so).

    Parameters
    ----------
    report : FitReport
        The fit's.
    evaluators : list of SensitivityEvaluator
        The fit's, one per experiment.
    parameters : JointParameters
        The fit's free parameters.
    tolerances : tuple of float
        ``(rtol, atol)`` of the check (:func:`_looser_tolerances`).
    """
    unchecked = replace(report, extra={**report.extra, "integration_error": None})
    if not (np.all(np.isfinite(report.predicted)) and outputs_alone(evaluators)):
        return unchecked
    try:
        reference = np.vstack([
            np.asarray(evaluator.outputs(parameters.local(report.values, k), tolerances)).T
            for k, evaluator in enumerate(evaluators)
        ])  # fmt: skip
    except EVALUATION_ERRORS as exc:
        message = f"{report.message}; the integration at the estimate was not checked: {exc}"
        return replace(unchecked, message=message)
    residuals = report.measured - report.predicted
    seen = np.isfinite(residuals)
    ratios = []
    for j in np.flatnonzero(seen.any(axis=0)):  # signals with a measured sample
        spread = np.sqrt(np.mean(residuals[seen[:, j], j] ** 2))
        change = np.max(np.abs(reference[:, j] - report.predicted[:, j]))
        ratios.append(change / spread if spread > 0 else (0.0 if change == 0 else np.inf))
    error = float(max(ratios, default=0.0))
    message = report.message
    if error > INTEGRATION_SHARE:
        message += (
            f"; at the estimate the outputs change by {error:.2g} of the residuals' RMS "
            f"from these integrator_options to rtol {tolerances[0]:g}, atol "
            f"{tolerances[1]:g}: tighten them"
        )
    return replace(report, message=message, extra={**report.extra, "integration_error": error})


@_fit_options
def fit_equilibria(
    model: Model,
    experiment,
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
    start: FitReport | None = None,
    max_evaluations: int = 100,
    confidence: float = 0.95,
    starts: int = 1,
    seed: int | None = None,
    progress: bool = False,
) -> FitReport:
    """Quasi-static least squares: each sample is an equilibrium ``N(q) = tau(q, u)``.

    Valid when the inputs change much more slowly than the robot's lowest natural
    period (damping and creep then play no role). With no free parameters this is a
    prediction. The experiments are solved in this process, one after another (their
    samples are solved together, in compiled code).

    Parameters
    ----------
    model : Model
        The compiled model; its robot gives the values of everything not free.
    %(experiment)s
    output : OutputMap
        Model outputs matched to the signals.
    input_map : InputMap
        Generalized forces from the experiment's inputs (all of them, in order).
    %(free)s
    q0 : array_like, shape (n,), optional
        Initial guess of every sample's equilibrium [m, 1/m, 1/m] (default: the
        straight robot at rest length). At the first evaluation, a record of 256 samples
        or more solves about ``sqrt(T)`` samples from ``q0`` first and starts every
        sample from the solution of the one of nearest inputs; later evaluations start
        from the previous solutions (moved along their tangent where that move is
        small); ``q0`` is the last resort of every sample.
    %(extra)s
    %(bind)s
    %(signals)s
    %(weights)s
    %(parameters)s
    %(start)s
    max_evaluations : int
        Budget of residual evaluations per start.
    %(confidence)s
    %(starts)s
    %(seed)s
    %(progress)s

    Returns
    -------
    FitReport
        As :func:`fit_trajectory`'s.
    """
    q0 = rest_configuration(model.robot) if q0 is None else real_array("q0", q0, (model.n,))
    free, extra, parameters = _started(start, experiment, free, extra, parameters)
    if start is not None:
        extra.pop(LAG, None)  # a trajectory fit's input lag: no part of the statics
    problem = Problem(model, output, input_map, free, extra, bind, parameters, experiment)
    evaluators = [
        EquilibriumPredictor(model, part, output, input_map, q0)(e)
        for e, part in zip(problem.experiments, problem.parameters.parts, strict=True)
    ]
    options = dict(starts=starts, seed=seed, progress=progress, processes=1)
    return problem.run(
        evaluators,
        problem.data(signals, weights),
        max_evaluations,
        confidence,
        "equilibrium fit",
        options=options,
    )


def _fitted_values(fit: FitReport, experiment, given: dict) -> dict:
    """``fit``'s shared extra values, plus their own (``name[experiment]``) for the
    experiments it had; others keep the nominal per-experiment values, never another's."""
    usable_fit(fit)
    per = fit.extra.get("per_experiment", {})
    own = {name for values in per.values() for name in values}
    values = {**given, **{k: v for k, v in fit.extra["values"].items() if k not in own}}
    for e in experiment_list(experiment)[0]:
        for name, value in per.get(e.name, {}).items():
            values[f"{name}[{e.name}]"] = value
    return values


def _check_window(window, experiments) -> None:
    """A window of ``x0="window"`` shorter than every experiment: one as long as a record
    fits the initial state to all of it, and the prediction is then a fit."""
    window = real_scalar("window", window, positive=True)
    shortest = min(experiments, key=lambda e: e.duration)
    if not window < shortest.duration:
        raise ParameterError(
            f"window must be in (0, {shortest.duration:g}) s, shorter than every experiment "
            f"(the shortest, {shortest.name!r}, lasts {shortest.duration:g} s; a window "
            f"as long fits the initial state to the whole record, and the prediction is a "
            f"fit), got {window:g}"
        )


def _estimated_states(model, experiments, fit, values, how, window, problem) -> list:
    """Each experiment's initial state for a prediction: the equilibrium at its first
    input under the fit's estimate, then (``how == "window"``) the coordinates and rates
    fitted to its first ``window`` seconds with everything else held at the estimate."""
    if how not in ("equilibrium", "window"):
        raise ParameterError(
            f"x0 must be a state, a callable, a list or dict of them, 'equilibrium' or "
            f"'window', got {how!r}"
        )
    if how == "window" and not (
        isinstance(window, int | float) and np.isfinite(window) and window > 0
    ):
        raise ParameterError(
            f"x0='window' needs window, the seconds of each experiment's start to fit the "
            f"initial state to (> 0), got {window!r}"
        )
    shared, per = split_extra(values, [e.name for e in experiments])
    p = fit.extra["parameters"]
    states = []
    for e in experiments:
        own = {**shared, **per[e.name]}
        rest = initial_equilibrium(model, e, problem.get("input_map"), extra=own, parameters=p)
        if not rest.success:
            raise FitError(
                f"x0='{how}': no equilibrium at the first input of experiment {e.name!r} "
                f"({rest.message}); give x0 as a state"
            )
        if how == "equilibrium":
            states.append(rest.x0)
            continue
        # scales: a coordinate's natural size, and the rate that moves it that far in
        # the window (zero starting values give no scale of their own)
        size = coordinate_scale(model.robot)
        names = [
            Free(f"x0.{part}[{i}]", scale=size[i] / (window if part == "qd" else 1.0))
            for part in ("q", "qd")
            for i in range(model.n)
        ]
        start = e.trim(stop=e.t[0] + window)
        options = {k: v for k, v in problem.items() if k != "x0"}
        found = fit_trajectory(
            model, start, free=names, extra=own, parameters=p, x0=rest.x0, **options
        )
        # entries the window determines only together (a planar sensor's view of an
        # elongation and a bending rate) still give the outputs: enough to predict from
        if found.status not in (Status.SUCCESS, Status.NOT_IDENTIFIABLE) or not found.n_evaluations:
            raise FitError(
                f"x0='window': the initial state of experiment {e.name!r} could not be fitted "
                f"to its first {window:g} s ({found.status.value}: {found.message}); give a "
                "longer window, or x0 as a state"
            )
        states.append(np.concatenate([found.values, rest.x0[2 * model.n :]]))
    return states


@parameters_from(PREDICTION_PARAMETERS)
def predict_trajectory(
    model: Model, experiment, fit: FitReport, *, x0="equilibrium", window=None, **problem
):
    """Simulate ``experiment`` with the estimate of ``fit``, without refitting.

    Parameters
    ----------
    %(model)s
    %(experiment)s
    %(fit)s
    x0 : array_like, shape (n_state,), callable, list, dict, "equilibrium" or "window"
        Each experiment's initial state: given as in :func:`fit_trajectory`, or estimated
        under the fit's estimate. ``"equilibrium"`` (the default): at rest in the
        equilibrium of its first input (:func:`initial_equilibrium`; creep states zero),
        for a trial that starts at rest. ``"window"``: that equilibrium, then its
        coordinates and rates fitted to the experiment's first ``window`` seconds with
        everything else held at the estimate (one small trajectory fit per experiment;
        entries it determines only together are kept at its best fit, which reproduces
        the outputs), for a trial that starts in motion; the prediction covers the whole experiment,
        the window included.
    window : float, optional
        Seconds from each experiment's start that ``x0="window"`` fits to [s], shorter
        than every experiment: long enough for the outputs to show the motion (a few
        samples at least, and no longer than needed: its fit is a simulation of that
        window per evaluation).
    **problem
        The fit's keyword arguments ``output``, ``input_map``, ``bind``, ``input_lag``,
        ``input_hold`` (and optionally ``signals``, ``weights``, ``extra``,
        ``integrator_options``, ``processes``, ``threads``), passed on to
        :func:`fit_trajectory` with no free parameters. ``input_hold`` should be the
        fit's: another one predicts a different model of the same inputs (a warning,
        :class:`FitWarning`, says so). ``threads`` and ``processes`` change only the
        speed (and, for ``threads``, the last digits).

    Returns
    -------
    FitReport
        With no free parameters; its ``rms`` and ``max_error`` are the prediction errors,
        and ``extra["x0"]`` the initial states used, one per experiment.
    """
    values = _fitted_values(fit, experiment, problem.pop("extra", {}))
    hold, fitted_hold = problem.get("input_hold", "constant"), fit.extra.get("input_hold")
    if fitted_hold is not None and hold != fitted_hold:
        warnings.warn(
            f"predicting with input_hold={hold!r}, but the fit held its inputs "
            f"{fitted_hold!r}: the estimate belongs to the fit's model of the inputs; pass "
            f"input_hold={fitted_hold!r}",
            FitWarning,
            stacklevel=2,
        )
    experiments, _ = experiment_list(experiment)
    if window is not None:
        _check_window(window, experiments)
    if isinstance(x0, str):
        x0 = _estimated_states(model, experiments, fit, values, x0, window, problem)
    report = fit_trajectory(
        model, experiment, free=[], extra=values, parameters=fit.extra["parameters"], x0=x0,
        **problem,
    )  # fmt: skip
    states = _per_experiment("x0", x0, experiments, _one_state)
    return replace(report, extra={**report.extra, "x0": states})


@parameters_from(PREDICTION_PARAMETERS)
def predict_equilibria(model: Model, experiment, fit: FitReport, **problem):
    """Quasi-static prediction of ``experiment`` with the estimate of ``fit``, without
    refitting (see :func:`predict_trajectory`).

    Parameters
    ----------
    %(model)s
    %(experiment)s
    %(fit)s
    **problem
        The fit's keyword arguments ``output``, ``input_map``, ``bind`` (and optionally
        ``q0``, ``signals``, ``weights``, ``extra``), passed on to :func:`fit_equilibria`
        with no free parameters.

    Returns
    -------
    FitReport
        With no free parameters; its ``rms`` and ``max_error`` are the prediction errors.
    """
    values = _fitted_values(fit, experiment, problem.pop("extra", {}))
    values.pop(LAG, None)
    return fit_equilibria(
        model, experiment, free=[], extra=values, parameters=fit.extra["parameters"], **problem
    )
