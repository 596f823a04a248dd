"""Forward sensitivities of a simulated experiment, compiled, for trajectory least squares.

The equation of motion ``x' = f(x, tau(q, u, v), p)`` is augmented with the
variational equations ``S' = f_x S + f_d`` for the columns of ``d = (p, v, x0)``
that depend on the free parameters (``S(0)`` selects the free entries of ``x0``).
The augmented right-hand side is generated as C by CasADi, compiled once by
:func:`softcurve.compiled.compile_function` (same compiler and cache as the model),
loaded and integrated by CVODES, so an evaluation of the residuals and their exact
Jacobian never returns to Python. The chain rule from ``d`` to the free parameters
``theta`` (ties, re-parametrizations, initial states) and from the state to the outputs
is applied afterwards, sample by sample.

Two routes integrate it (the route is chosen by the solvers' ``choose_route`` and
recorded in the statistics). Where softcurve's CVODES driver is available, the state is
integrated by Adams-Newton (or BDF) on its own Newton matrix and the sensitivity
columns by CVODES's staggered corrector (outside the error test), or both by Radau IIA
with the sensitivities of its discrete scheme (:data:`SENSITIVITY_METHODS`), all in C
(``softcurve_sensitivities`` of the driver's ``sensitivity.c``), without a restart at
the samples of a linear hold; what an evaluator carries into worker
processes for that route is a :class:`DriverRoute`. Otherwise (no driver, or CVODES
options other than :data:`NATIVE_OPTIONS`) CasADi's CVODES integrates the augmented
system with :data:`SENSITIVITY_CVODES`. Both agree to the tolerances
(``tests/test_sensitivity_driver.py``). With the columns in its error test the driver was
1.5x (inputs held) to 2.8x (linear hold) faster on ``bench_identification.py``'s case,
without them 1.34x more (``benchmarks/study_sensitivity_driver.py`` compares).

With two threads, the sensitivity columns' right-hand side is split in two parts.

``S' = f_x S + f_d`` is, by the Jacobian's column blocks, the sum of
``f_x[:, A] S[A, :] + f_d`` and ``f_x[:, B] S[B, :]`` for any split of the states into
``A`` and ``B``. Each part is compiled on its own; softcurve's CVODES driver evaluates the
first on its own thread and the second on a helper thread
(the driver's ``parts.c``), so that an evaluation takes about as long
as the larger part instead of the whole.

:func:`assembled` joins the compiled parts into the augmented system of CasADi's CVODES,
the route of a process without the driver.

Almost all of the work is the Jacobian's columns of the coordinates ``q`` (the
kinematics' higher derivatives at every quadrature node): on the paper robot
(``benchmarks/bench_identification.py``'s case, 75,024 operations in all) the columns of
``q`` take 64,801 operations with ``f``, those of the rates and creep states with
``f_d`` 20,973, and a single coordinate's column about 29,000-30,600. The split gives
``B`` the last two thirds of the coordinates and ``A`` the rest with every other state
and ``f_d``: 42,480 and 45,912 operations there (the rest of the operations shared by
both parts, computed twice). Other splits of that robot are less even (``A`` = the first
two coordinates and ``f_d``: 48,095 and 40,723).
"""

from __future__ import annotations

import ctypes
import pickle
import uuid
from typing import NamedTuple

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.compiled import (
    compile_function,
    compile_functions,
    load_external,
    load_function,
    load_with_path,
)
from softcurve.simulation.solvers import (
    DRIVER_FAMILIES,
    DriverProblem,
    auto_method,
    change_interval,
    choose_route,
    cvodes_options,
    driver,
    driver_library,
    driver_options,
    driver_reason,
    input_changes,
    linear_rates,
    radau_constants,
)
from softcurve.symbolic.functions import common_subexpressions

SENSITIVITY_CVODES = cvodes_options(
    "adams", 1e-8, 1e-10, 100_000, max_order=None, nonlinear_solver_iteration="functional"
)
"""CVODES on the augmented, unscaled system, as the trajectory fits were validated with
(``tests/test_identify.py``): tolerances tighter than a simulation's, Adams with
functional iteration (no Newton matrix of the augmented system) at CVODES's own order
cap; ``options`` of :func:`trajectory_sensitivities` override them. The driver's route
takes the same tolerances and step limit."""

NATIVE_OPTIONS = frozenset({"reltol", "abstol", "max_num_steps", "fsens_err_con"})
"""The CVODES options the driver's route understands; others select CasADi's route.
``fsens_err_con`` (default False, CVODES's own) puts the sensitivity columns in the
error test: 1.6 times the steps for Jacobian columns within 4e-9 instead of 6e-8 to
3e-7 of a reference, which no fit resolves (docs/validation.md). CasADi's route always has
them in it (it integrates ``(x, S)`` as one system)."""

FAMILY_NAMES = {family: name for name, family in DRIVER_FAMILIES.items()}
"""The driver's families by number (``DriverSettings.family``)."""

METHOD_OPTION = "method"
"""The option of :func:`trajectory_sensitivities` (a fit's ``integrator_options``) that
picks the driver's method: ``"auto"`` (the default: :func:`choose_method`) or one of
:data:`SENSITIVITY_METHODS`; the other options are CVODES's."""

SENSITIVITY_METHODS = ("adams", "bdf", "radau")
"""The driver's methods of the sensitivities: CVODES's Adams (the default: on the 30 s
benchmark case of ``benchmarks/study_sensitivity_driver.py`` 9,032 steps in 0.37 s at
rtol 1e-8 against BDF's 11,286 steps in 0.46 s, the paper robot's lightly damped modes
favouring Adams's higher orders) or BDF with the staggered corrector, or Radau IIA with the
sensitivities of its discrete scheme (the driver's ``sensitivity.c``: the converged
stages differentiated, solved on the step's own factors). CasADi's route, without the
driver, takes Adams; the evaluator's ``stats["method"]`` says which ran. Radau IIA is
not the default: on the 30 s case of ``benchmarks/study_sensitivity_driver.py`` it takes
0.18 to 0.84 times Adams's steps at the same tolerance, each with 7 to 8 right-hand sides
and 6 to 7 evaluations of the columns against Adams's 2.3 and 1.4; at rtol 1e-6 it costs
what Adams costs at 1e-8, with states as accurate and far more accurate columns
(docs/performance.md)."""


AUTO_WITHIN = 0.35
"""``integrator_options={"method": "auto"}`` (the default) integrates with Radau IIA where
the inputs are held between samples and change on average within ``AUTO_WITHIN`` over the
fastest rate of the linearization at the start (seconds), else with Adams
(:func:`choose_method`). Below 10 (a simulation's ``AUTO_INTERVAL``) because Radau's
columns cost six to seven evaluations a step, and both methods run at the fit's one
tolerance. Measured at the default rtol 1e-8 on ``bench_identification.py``'s case over 3 s
with the pressures sampled at each rate and held (fastest rate 282 1/s; ``python
benchmarks/study_sensitivity_driver.py --rates 12 100 300 500 1000``): a change every
1 ms (0.28 over the fastest rate) Radau IIA 1.09 times Adams's speed, every 2 ms (0.56)
0.83 times, every 3.3 ms (0.94) 0.58 times, every 10 ms 0.32 times, at 12 Hz 0.14
times; Radau's own error is 100 to 1,000 times smaller there. The speeds are equal near
0.35, interpolated in the logarithms between 0.28 and 0.56. Inputs joined linearly are
integrated through without restarts, and there Adams is faster at every tolerance
measured (docs/performance.md, "Radau IIA")."""


class SensitivityEvaluator:
    """``theta -> (Y (k, T), dvec(Y)/dtheta (k T, P))`` for one experiment.

    Holds only CasADi functions and arrays, so it can be pickled into a worker process
    (CasADi serializes its functions; a compiled ``external`` is reloaded from its
    library on disk, and so are the driver's functions, at the first call in a process).
    """

    def __init__(
        self, direct, integrator, out, u_data, seed, scale, active, sizes, driven, reason=""
    ):
        self.direct, self.integrator, self.out = direct, integrator, out
        self.u_data, self.seed, self.scale, self.active = u_data, seed, scale, active
        self.n_p, self.n_v, self.n_x = sizes
        self.driven: DriverRoute | None = driven
        self.method_reason: str = reason
        """Why :attr:`method` was chosen (``integrator_options``, :func:`choose_method`)."""
        self.token, self._blob, self._native = uuid.uuid4().hex, None, None
        self.stats: dict = {}
        """The last evaluation's route and counters (steps, right-hand sides, ...), in the
        process that evaluated it (a worker's, under a parallel fit)."""
        self.variational: ca.Function | None = None
        """``fs(x;vec(S), u, d;scale) -> f;vec(S')``, the SX function of the sensitivity
        equations (in the process that built the evaluator; for studies of its cost). Both
        routes compile it, unless the evaluator splits it in parts for two threads."""

    def __reduce__(self):
        # Serialized once; a worker that has loaded this evaluator before reuses it
        # (deserializing builds the CVODES memory again).
        if self._blob is None:
            state = (self.direct, self.integrator, self.out, self.u_data, self.seed)
            state += (self.scale, self.active, (self.n_p, self.n_v, self.n_x), self.driven)
            state += (self.method_reason,)
            self._blob = pickle.dumps(state)
        return (_restore, (self.token, self._blob))

    def __call__(self, theta_value):
        """Outputs and their Jacobian at ``theta_value``.

        Parameters
        ----------
        theta_value : array_like, shape (P,)
            The free parameters, in the units of each.
        """
        n_x, start = self.n_x, self.n_p + self.n_v
        d_value, jac = (np.array(a) for a in self.direct(theta_value))
        d_value = d_value.ravel()
        x_start = np.concatenate([d_value[start:], self.seed.ravel(order="F")])
        parameters = np.concatenate([d_value, self.scale])
        states = self._integrate(x_start, d_value, parameters)
        size = states.shape[1]
        y_value, y_x, y_d = (
            np.array(a) for a in self.out(states[:n_x], np.tile(d_value[:, None], size))
        )
        k, m = y_value.shape[0], len(self.active)
        s_all = states[n_x:].reshape(m, n_x, size).transpose(2, 1, 0) / self.scale
        y_x = y_x.reshape(k, size, n_x).transpose(1, 0, 2)  # (T, k, n_x)
        y_d = y_d.reshape(k, size, -1).transpose(1, 0, 2)  # (T, k, n_d)
        total = np.einsum("tkx,txm,mp->tkp", y_x, s_all, jac[self.active]) + y_d @ jac
        return y_value, total.reshape(size * k, -1)

    @property
    def method(self) -> str:
        """The method of the integration, one of :data:`SENSITIVITY_METHODS`: the
        driver's as asked (``integrator_options``), Adams on CasADi's route."""
        return "adams" if self._route() is None else FAMILY_NAMES[self.driven.settings.family]

    @property
    def outputs_alone(self) -> bool:
        """Whether :meth:`outputs` integrates the state alone (the driver's route, as
        built in the process that made the evaluator): on the paper robot about a seventh
        of the cost of the outputs with their Jacobian (``python
        benchmarks/study_sensitivity_driver.py`` prints both); on CasADi's route it
        costs as much as a call."""
        return self.driven is not None

    def outputs(self, theta_value, tolerances=None) -> np.ndarray:
        """The outputs alone at ``theta_value``, ``Y (k, T)``: the state integrated
        without the sensitivity columns (the same steps as a call's but for the
        columns' corrector, so the same outputs to the integration's tolerance).

        Parameters
        ----------
        theta_value : array_like, shape (P,)
            The free parameters, in the units of each.
        tolerances : tuple of float, optional
            ``(rtol, atol)`` instead of the evaluator's, on the driver's route only
            (:attr:`outputs_alone`; CasADi's route refuses them with ValueError).

        Returns
        -------
        ndarray, shape (k, T)
            The outputs at every sample, in the output map's units.
        """
        route = self._route()
        if route is None:
            if tolerances is not None:
                raise ValueError("other tolerances need softcurve's CVODES driver")
            return self(theta_value)[0]
        start = self.n_p + self.n_v
        d_value = np.array(self.direct(theta_value)[0]).ravel()
        parameters = np.concatenate([d_value, self.scale])
        states = self._integrate(d_value[start:], d_value, parameters, tolerances)
        return np.array(self.out(states, np.tile(d_value[:, None], states.shape[1]))[0])

    def _integrate(self, start, d_value, d_scaled, tolerances=None) -> np.ndarray:
        """``(x, vec(S))`` at every sample, (W, T), by the driver or CasADi's CVODES; by
        the driver, ``x`` alone for a ``start`` of the state alone, and with
        ``tolerances`` ``(rtol, atol)`` instead of its own."""
        route = self._route()
        if route is None:
            states = np.array(self.integrator(x0=start, p=d_scaled, u=self.u_data)["xf"])
            counts = self.integrator.stats()
            self.stats = {"route": "sensitivity-casadi", "method": "adams",
                          "steps": counts.get("nsteps"),
                          "rhs_evaluations": counts.get("nfevals"),
                          "error_test_failures": counts.get("netfails")}  # fmt: skip
            return states
        problem, columns = route
        driven = self.driven
        settings = driven.settings
        if tolerances is not None:
            settings = DriverSettings(
                float(tolerances[0]), float(tolerances[1]), settings.max_steps, settings.family,
                settings.columns_tested,
            )  # fmt: skip
        out, reached, flag, counts = integrate_sensitivities(
            problem, columns, start, d_value, d_scaled, driven.times, driven.table,
            driven.linear, settings, driven.helper,
        )  # fmt: skip
        split = len(driven.columns) > 1
        self.stats = {"route": "sensitivity-driver-split" if split else "sensitivity-driver",
                      "method": self.method, **counts}  # fmt: skip
        if flag:
            solver = "Radau IIA" if self.method == "radau" else "CVODES"
            raise RuntimeError(
                f"{solver} failed after t = {driven.times[reached - 1]:g} s: {driver_reason(flag)}"
            )
        return out.T

    def _route(self):
        """(problem, column functions) of the driver, loaded once per process, or None."""
        if self.driven is None or driver() is None:
            return None
        if self._native is None:  # a worker process: load the libraries the parent built
            driven = self.driven
            try:
                route = (DriverProblem(load_function(*driven.state), *driven.sizes),
                         [load_function(*c) for c in driven.columns])  # fmt: skip
            except (OSError, RuntimeError, AttributeError):  # not loadable: CasADi's route
                route = False
            self._native = route
        return self._native or None


_LOADED: dict = {}
LOADED_KEPT = 16
"""Evaluators a worker process keeps loaded (the experiments of the current fits)."""


def _restore(token: str, blob: bytes) -> SensitivityEvaluator:
    """The evaluator ``token``, loaded from ``blob`` unless this process has it."""
    if token not in _LOADED:
        if len(_LOADED) >= LOADED_KEPT:
            _LOADED.pop(next(iter(_LOADED)))
        evaluator = SensitivityEvaluator(*pickle.loads(blob))
        evaluator.token, evaluator._blob = token, blob
        _LOADED[token] = evaluator
    return _LOADED[token]


def hold_inputs(t: np.ndarray, u: np.ndarray, hold: str) -> np.ndarray:
    """The integrator's input columns for inputs sampled at ``t``.

    CasADi applies column ``k`` on ``(t[k-1], t[k]]``. ``"constant"``: the sample at the
    start of each interval, ``u_(k-1)``, held until the next one (a zero-order hold, as
    :func:`~softcurve.simulation.simulate` applies a grid of inputs: an input
    never acts before it was sampled). ``"linear"``: the line through both samples,
    ``a_k + b_k t`` with rows ``(a, b)``, so the inputs are continuous in time (no jump
    for the integrator to restart at).

    Parameters
    ----------
    t : ndarray, shape (T,)
        Sample times [s].
    u : ndarray, shape (m, T)
        Input samples [unit of each input].
    hold : {"constant", "linear"}
        How the inputs go between samples.
    """
    if u.shape[0] == 0:
        return u
    before = np.concatenate([u[:, :1], u[:, :-1]], axis=1)
    if hold == "constant":
        return before
    if hold != "linear":
        raise ValueError(f"hold must be 'constant' or 'linear', got {hold!r}")
    slope = np.zeros_like(u)
    slope[:, 1:] = np.diff(u, axis=1) / np.diff(t)
    start = np.concatenate([t[:1], t[:-1]])
    return np.vstack([before - slope * start, slope])


def _casadi_integrator(rhs, n_u: int, hold: str, t, options) -> ca.Function:
    """CasADi's CVODES on the augmented system ``rhs(x;vec(S), u, d;scale)`` over the
    sample times ``t``, the inputs per interval (``hold``) as its controls."""
    xa, ua, da = (
        ca.MX.sym("x", rhs.size1_in(0)),
        ca.MX.sym("u", n_u * (2 if hold == "linear" else 1)),
        ca.MX.sym("d", rhs.size1_in(2)),
    )
    time = ca.MX.sym("t")
    applied_u = ua[:n_u] + ua[n_u:] * time if hold == "linear" else ua
    problem = {"x": xa, "u": ua, "p": da, "t": time, "ode": rhs(xa, applied_u, da)}
    return ca.integrator("sensitivity", "cvodes", problem, float(t[0]), t, options)


def _method_of(options) -> tuple[str, dict]:
    """``(method, the CVODES options)`` of ``options`` (a fit's ``integrator_options``),
    checked: :data:`METHOD_OPTION` ``"auto"`` (the default, resolved by
    :func:`choose_method`) or one of :data:`SENSITIVITY_METHODS`; a method other than Adams
    only with the options the driver takes (CasADi's route has Adams alone), Radau IIA
    without ``fsens_err_con`` (its columns are its scheme's derivative, never in its error
    test)."""
    options = dict(options or {})
    method = options.pop(METHOD_OPTION, "auto")
    field = f"integrator_options['{METHOD_OPTION}']"
    if method != "auto" and method not in SENSITIVITY_METHODS:
        raise ParameterError(
            f"{field} must be 'auto' or one of {', '.join(SENSITIVITY_METHODS)}, got {method!r}"
        )
    foreign = sorted(set(options) - NATIVE_OPTIONS)
    if method not in ("auto", SENSITIVITY_METHODS[0]) and foreign:
        raise ParameterError(
            f"{field} = {method!r} runs in softcurve's driver, which does not take "
            f"{', '.join(foreign)} (CasADi's CVODES, which does, runs Adams alone)"
        )
    if method == "radau" and options.get("fsens_err_con"):
        raise ParameterError(
            f"{field} = 'radau' takes no fsens_err_con: its columns are the derivative of "
            "its discrete scheme, outside its error test"
        )
    return method, options


def choose_method(options, hold, t, samples, fastest) -> tuple[str, str]:
    """What ``integrator_options={"method": "auto"}`` integrates a fit's sensitivities
    with, and why: ``(method, reason)``, the method one of :data:`SENSITIVITY_METHODS`.

    Radau IIA where the inputs are held and change at half of the samples or more, on
    average within :data:`AUTO_WITHIN` over the fastest rate; Adams otherwise, and always
    with options that keep Radau out (CVODES's own, ``fsens_err_con``).

    Parameters
    ----------
    options : dict
        The CVODES options (without the method).
    hold : {"constant", "linear"}
        The inputs between samples (:func:`hold_inputs`).
    t : ndarray, shape (T,)
        Sample times [s].
    samples : ndarray, shape (m, T)
        The input samples [unit of each input].
    fastest : callable() -> float
        The fastest rate of the linearization at the start [1/s], computed only where the
        rule needs it.
    """
    if set(options) - NATIVE_OPTIONS:
        return "adams", "auto: options only CasADi's CVODES takes, which runs Adams alone"
    if options.get("fsens_err_con"):
        return "adams", "auto: fsens_err_con puts the columns in CVODES's error test"
    if hold == "linear":
        return "adams", "auto: inputs joined linearly, integrated through without restarts"
    # held, sample k acts on the interval after t_k, as simulate's grid rows do
    interval = change_interval(t, input_changes(samples.T)) if samples.shape[0] else None
    rule, why = auto_method(fastest() if interval is not None else 0.0, interval,
                            within=AUTO_WITHIN)  # fmt: skip
    return ("radau" if rule == "radau" else "adams"), why


def trajectory_sensitivities(
    model,
    parameters,
    output,
    input_map,
    x0,
    experiment,
    options,
    lag=None,
    hold="constant",
    threads=1,
) -> SensitivityEvaluator:
    """An evaluator ``theta -> (Y (k, T), dvec(Y)/dtheta (k T, P))`` for one experiment.

    Parameters
    ----------
    model : Model
        The compiled model.
    parameters : softcurve.identification.fits._parameters.FreeParameters
        The free parameters and how they enter ``p`` and the extra values.
    output : OutputMap
        The measured signals as functions of the state.
    input_map : InputMap or None
        Generalized forces from the inputs.
    x0 : array_like (n_state [+ m],) or callable(values) -> initial state
        With ``lag``, the state ends with the ``m`` lagged inputs.
    experiment : Experiment
        Time grid and inputs.
    options : dict or None
        Extra CVODES options, and :data:`METHOD_OPTION`: ``"auto"`` (default,
        :func:`choose_method`) or one of :data:`SENSITIVITY_METHODS`, checked by
        ``_method_of``'s rules.
    lag : str, optional
        Name of the extra parameter holding the time constant [s] of a first-order lag
        ``u_a' = (u - u_a) / T`` of every input before the input map (None: no lag).
    hold : {"constant", "linear"}
        Inputs between samples (:func:`hold_inputs`).
    threads : int
        Threads of an evaluation in the driver's route, >= 1: with 2 or more the
        columns' right-hand side is evaluated in two parts on two threads
        (``softcurve.simulation.sensitivity._sensitivity``).
    """
    method, options = _method_of(options)
    P = parameters
    u_names = list(experiment.inputs)
    n_model, n_p = model.n_state, P.p0.size
    n_x = n_model + (len(u_names) if lag else 0)
    keys = sorted(P.extra)
    n_v = len(keys)
    theta = ca.MX.sym("theta", len(P.free))
    p, values = P.expressions(theta)
    start = x0(values) if callable(x0) else ca.DM(np.asarray(x0, dtype=np.float64))
    start = ca.MX(start) if not isinstance(start, ca.MX) else start
    if start.shape != (n_x, 1):
        raise ValueError(f"x0 must have {n_x} entries (q, qd, lam[, u]), got {start.shape}")
    d = ca.vertcat(p, *(ca.MX(values[k]) for k in keys), start)
    jac_d = ca.jacobian(d, theta)
    active = sorted(set(jac_d.sparsity().get_triplet()[0]))
    direct = ca.Function("direct", [theta], [d, ca.densify(jac_d)])

    xs, us = ca.SX.sym("x", n_x), ca.SX.sym("u", len(u_names))
    ds = ca.SX.sym("d", n_p + n_v + n_x)
    v_s = {k: ds[n_p + i] for i, k in enumerate(keys)}
    q, qd = xs[: model.n], xs[model.n : 2 * model.n]
    applied = xs[n_model:] if lag else us
    tau = input_map.function(q, applied, v_s) if input_map is not None else ca.SX.zeros(model.n)
    f = model.casadi_rhs()(xs[:n_model], tau, ds[:n_p])
    if lag:
        f = ca.vertcat(f, (us - applied) / v_s[lag])
    d0 = np.array(direct(P.theta0)[0]).ravel()
    scale = np.array([abs(d0[i]) if d0[i] != 0 else 1.0 for i in active])
    m = len(active)
    # The column scales are an input (not constants of the code), so that experiments
    # and fits of one structure share one compiled library.
    split = threads > 1 and m > 0
    state = ca.Function("f", [xs, us, ds], [f])
    # keyed by the state's expression (serialized, as the equilibrium fit's functions):
    # the fits of one structure (any data, parameter values and scales) build their
    # sensitivity functions once per model
    functions = model.cached(
        ("sensitivity-functions", state.serialize(), tuple(active), split),
        lambda: sensitivity_functions(state, active, model.n, model.robot.n_segments, split),
    )
    augmented = functions.augmented
    t = experiment.t
    settings = {**SENSITIVITY_CVODES, **options}
    y = output.function(q, qd, v_s, ds[:n_p])
    out = ca.Function("out", [xs, ds], [y, ca.jacobian(y, xs), ca.jacobian(y, ds)]).map(t.size)
    samples = experiment.input_matrix(u_names).T if u_names else np.zeros((0, t.size))
    u_data = hold_inputs(t, samples, hold)
    reason = f"integrator_options['{METHOD_OPTION}'] = {method!r}"
    if method == "auto":

        def fastest():
            """The fastest rate [1/s] of the linearization at the start and first input."""
            jacobian = ca.Function("jacobian", [xs, us, ds], [ca.jacobian(f, xs)])
            at_start = np.array(jacobian(d0[n_p + n_v :], u_data[:, 0], d0))
            return float(linear_rates(np.linalg.eigvals(at_start))[1])

        method, reason = choose_method(options, hold, t, samples, fastest)
    seed = np.zeros((n_x, m))
    for j, i in enumerate(active):
        if i >= n_p + n_v:
            seed[i - n_p - n_v, j] = scale[j]

    def build_driver():
        """The driver's route of this evaluator, ``(DriverRoute, loaded)``, or None."""
        plain = functions.plain
        libraries = compile_functions([plain, *functions.columns], load=load_with_path)
        if not all(isinstance(entry, tuple) for entry in libraries):
            return None
        driver_settings = DriverSettings(
            float(settings["reltol"]), float(settings["abstol"]),
            int(settings["max_num_steps"]), DRIVER_FAMILIES[method],
            bool(settings.get("fsens_err_con", False)),
        )  # fmt: skip
        table = np.ascontiguousarray(u_data.T)
        sizes = (n_x, plain.size1_in(1), plain.size1_in(2))
        paths = tuple(entry[:2] for entry in libraries)
        route = DriverRoute(paths[0], paths[1:], sizes, t, table, hold == "linear",
                            driver_settings, "shared" if split else "none")  # fmt: skip
        return route, (DriverProblem(libraries[0][2], *sizes), [e[2] for e in libraries[1:]])

    chosen = choose_route("sensitivity", options_known=set(options) <= NATIVE_OPTIONS,
                          threads=2 if split else 1,
                          builders={"sensitivity-driver": build_driver})  # fmt: skip
    driven, loaded = chosen.built or (None, None)
    # CasADi's route: on the libraries the driver's route just built, loaded by path
    if driven is None:
        rhs = compile_function(augmented)
    elif len(driven.columns) > 1:
        externals = [load_external(*path) for path in driven.columns]
        rhs = assembled(load_external(*driven.state), externals, ds.shape[0])
    else:
        rhs = load_external(*driven.columns[0])
    integrator = _casadi_integrator(rhs, len(u_names), hold, t, settings)
    evaluator = SensitivityEvaluator(
        direct, integrator, out, u_data, seed, scale, active, (n_p, n_v, n_x), driven, reason
    )
    evaluator._native = loaded
    evaluator.variational = augmented
    return evaluator


class SensitivityFunctions(NamedTuple):
    """The compiled sensitivities' SX functions of one state derivative
    (:func:`sensitivity_functions`)."""

    augmented: ca.Function
    """``(x;vec(S), u, d;scale) -> f;vec(S')``, the state and its columns."""
    plain: ca.Function
    """``(x, u, d) -> f``, the state alone."""
    columns: tuple
    """What the driver evaluates for the columns: ``(augmented,)``, or the two parts of
    :func:`column_parts` where an evaluation is split over two threads."""


def sensitivity_functions(
    state: ca.Function, active, n_coordinates: int, n_segments: int, split: bool
) -> SensitivityFunctions:
    """The SX functions of the forward sensitivities of ``x' = f(x, u, d)`` along the
    parameters ``active`` (one scaled column each), with CasADi's common-subexpression
    elimination where the expression is inlined (``common_subexpressions``: most of the
    build's time at one segment, 1.7 s of a fit's 2.3 s, measured by cProfile).

    Parameters
    ----------
    state : casadi.Function
        ``(x (n_x,), u (n_u,), d (n_d,)) -> f (n_x,)``, SX.
    active : sequence of int
        The parameters of the columns, entries of ``d``.
    n_coordinates : int
        Coordinates ``q`` among the states.
    n_segments : int
        Segments of the robot (``common_subexpressions``).
    split : bool
        The columns in two parts (:func:`column_parts`).

    Returns
    -------
    SensitivityFunctions
    """
    xs, us, ds = (ca.SX.sym(name, state.sparsity_in(k)) for k, name in enumerate("xud"))
    f = state(xs, us, ds)
    n_x, m = xs.shape[0], len(active)
    sens, sc_s = ca.SX.sym("S", n_x, m), ca.SX.sym("scale", m)
    seeds = parameter_seeds(ds.shape[0], active, sc_s)
    through_calls = bool(state.get_function())
    s_dot = tangents(f, xs, sens, ds, seeds, through_calls)
    augmented = ca.Function(
        "softcurve_sensitivity",
        [ca.vertcat(xs, ca.vec(sens)), us, ca.vertcat(ds, sc_s)],
        [ca.densify(common_subexpressions(ca.vertcat(f, ca.vec(s_dot)), n_segments))],
    )
    f_state = augmented(ca.vertcat(xs, ca.SX.zeros(n_x * m)), us, ca.vertcat(ds, np.ones(m)))
    plain = ca.Function("softcurve_state", [xs, us, ds], [ca.densify(f_state[:n_x])])
    columns = (
        tuple(column_parts(f, xs, us, ds, sens, sc_s, seeds, n_coordinates, through_calls))
        if split
        else (augmented,)
    )
    return SensitivityFunctions(augmented, plain, columns)


class DriverSettings(NamedTuple):
    """How the driver integrates (CVODES's settings of :func:`integrate_sensitivities`)."""

    rtol: float
    """Relative tolerance."""
    atol: float
    """Absolute tolerance, in the state's units."""
    max_steps: int
    """Steps allowed per output interval."""
    family: int
    """1 Adams, 2 BDF, 3 Radau IIA (``softcurve.simulation.solvers.DRIVER_FAMILIES``)."""
    columns_tested: bool
    """The sensitivity columns in the error test too (``fsens_err_con``)."""


HELPER_MODES = ("none", "shared")
"""Who evaluates the second of two parts (:func:`integrate_sensitivities`): ``"none"``
the driver's own thread; ``"shared"`` whichever of the driver and a helper thread claims
it first (the driver never waits for a helper that has not started). Which thread wins
is the scheduler's choice."""


class DriverRoute(NamedTuple):
    """What a sensitivity evaluator needs for the driver's route, and carries into worker
    processes: the compiled libraries by ``(path, name)``, not their functions."""

    state: tuple[str, str]
    """``f(x, u, d)``: its library's absolute path and the function's name."""
    columns: tuple[tuple[str, str], ...]
    """The columns' right-hand side by path and name: ``fs(x;vec(S), u, d;scale) ->
    f;vec(S')``, or its two parts (:func:`integrate_sensitivities`)."""
    sizes: tuple[int, int, int]
    """``(nx, nu, n_d)`` of ``f``."""
    times: np.ndarray
    """Output times [s], shape (T,)."""
    table: np.ndarray
    """The inputs per interval, shape (T, k) or (T, 2 k) (:func:`integrate_sensitivities`)."""
    linear: bool
    """The inputs are linear between samples (else held)."""
    settings: DriverSettings
    """CVODES's settings."""
    helper: str
    """Who evaluates the second of two parts, one of :data:`HELPER_MODES`."""


SENSITIVITY_STATISTICS = ("steps", "rhs_evaluations", "jacobian_evaluations",
                          "linear_solver_setups", "error_test_failures",
                          "sensitivity_evaluations", "helper_evaluations")  # fmt: skip
"""The counters :func:`integrate_sensitivities` returns, in the driver's order: CVODES's
steps, right-hand sides (not those of the finite-difference Newton matrices), Newton
matrices, linear-solver setups and error-test failures, the evaluations of the columns'
right-hand side, and of those the second parts the helper thread evaluated (the driver
evaluates the others itself)."""


def integrate_sensitivities(
    problem,
    columns,
    start,
    d,
    d_scaled,
    times,
    table,
    linear,
    settings,
    helper="none",
    library=None,
):
    """States and forward sensitivities over ``times`` in one call into the driver.

    Parameters
    ----------
    problem : softcurve.simulation.solvers.DriverProblem
        ``f(x, u, d)`` of the state (no actuator).
    columns : sequence of NativeFunction
        ``[fs]``, ``fs(x;vec(S), u, d;scale) -> f;vec(S')`` for ``m`` columns, or two
        parts of the same arguments whose outputs sum to ``vec(S')``
        (``softcurve.simulation.sensitivity._sensitivity.column_parts``).
    start : ndarray, shape (W,)
        ``(x0, vec(S0))`` with ``W = nx (1 + m)``, at ``times[0]``.
    d : ndarray, shape (n_d,)
        The parameters of ``f``.
    d_scaled : ndarray, shape (n_d + m,)
        ``(d, scale)``: the parameters of ``fs`` with its column scales.
    times : ndarray, shape (T,)
        Output times [s], increasing.
    table : ndarray, shape (T, k) or (T, 2 k)
        Row ``i``: the inputs on ``(times[i-1], times[i]]``, or the line ``(a, b)`` of
        ``u = a + b t`` there with ``linear``.
    linear : bool
        Inputs continuous (integrated through) or held (a restart at every sample).
    settings : DriverSettings
        CVODES's settings.
    helper : {"none", "shared"}
        With two parts, who evaluates the second (:data:`HELPER_MODES`).
    library : ctypes.CDLL, optional
        A build of the driver (:func:`softcurve.simulation.solvers.driver_library`; default the
        product's, without defines).

    Returns
    -------
    tuple
        ``(out (T, W), reached, flag, counts)``: the outputs (rows after ``reached`` are
        zero), how many were computed (``start`` included), 0 or CVODES's negative flag
        (``softcurve.simulation.solvers._driver.FLAGS``) and the counters of
        :data:`SENSITIVITY_STATISTICS`.
    """
    if helper not in HELPER_MODES:
        raise ValueError(f"helper must be one of {HELPER_MODES}, got {helper!r}")
    out = np.zeros((times.size, start.size))
    out[0] = start
    arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (d, d_scaled, times, table)]
    sizes = np.array([c.work_sizes for c in columns], np.int64)
    pointers = (ctypes.c_void_p * len(columns))(*(c.address for c in columns))
    counts = np.zeros(len(SENSITIVITY_STATISTICS), dtype=np.int64)
    reached = ctypes.c_int(0)
    n_x = problem.struct.nx
    m = start.size // n_x - 1
    leading = n_x if len(columns) == 1 else 0  # fs's f before vec(S'); the parts have none
    call = (library or driver_library()).softcurve_sensitivities
    chosen = driver_options(
        settings.rtol, settings.atol, settings.max_steps, family=settings.family,
        columns_tested=settings.columns_tested, helper=helper == "shared",
        radau=radau_constants(),
    )  # fmt: skip
    flag = call(
        ctypes.byref(problem.struct), ctypes.byref(chosen), pointers, sizes.ctypes.data,
        len(columns), leading, m, arrays[0].ctypes.data, arrays[1].ctypes.data,
        arrays[2].ctypes.data, times.size, arrays[3].ctypes.data, int(linear), out.ctypes.data,
        counts.ctypes.data, ctypes.byref(reached),
    )  # fmt: skip
    return out, reached.value, flag, dict(zip(SENSITIVITY_STATISTICS, counts.tolist(), strict=True))


SPLIT_OF_COORDINATES = 3
"""``B`` holds the coordinates from ``n // SPLIT_OF_COORDINATES`` on (at least the last
one): the paper robot's two bending curvatures, ``A`` its length and the rest."""


def split_states(n_coordinates: int, n_states: int) -> tuple[list[int], list[int]]:
    """``(A, B)``: the states of the two parts (``A`` gets ``f_d`` too).

    Parameters
    ----------
    n_coordinates : int
        Coordinates ``q`` (the first states), >= 1.
    n_states : int
        All states (``q``, rates, creep states, lagged inputs).
    """
    first = max(1, n_coordinates // SPLIT_OF_COORDINATES) if n_coordinates > 1 else 0
    second = list(range(first, n_coordinates))
    return [i for i in range(n_states) if i not in second], second


def parameter_seeds(n_d: int, active, scales) -> ca.SX:
    """``E`` (n_d, m): column ``j`` is ``scales[j]`` at parameter ``active[j]``, else
    zero, so that ``f_d E`` are the scaled columns' derivatives along the parameters.

    Parameters
    ----------
    n_d : int
        Entries of the parameter vector ``d``.
    active : sequence of int
        The parameter of each column.
    scales : casadi.SX, shape (m, 1)
        The columns' scales.

    Returns
    -------
    casadi.SX
        The seeds, structurally zero but at ``(active[j], j)``.
    """
    seeds = ca.SX(n_d, len(active))
    for j, i in enumerate(active):
        seeds[i, j] = scales[j]
    return seeds


def tangents(f, x, v, d=None, seeds=None, through_calls=False):
    """``f_x v + f_d seeds`` (SX): the state's derivative along the sensitivity columns.

    Through the calls of a chain's segment functions it is CasADi's forward derivative
    (``jtimes``: one forward call of each segment function for all the columns), where
    the Jacobian's product takes one reverse call per output: at eight segments and eight
    columns 3.3 million operations against 19.3 million, and 16,854 instructions to
    compile against 105,022. On the inlined expression of one segment the Jacobian's
    product shares more (88,388 operations against 190,207). Both measured by
    ``python benchmarks/bench_chain.py --sensitivity``.

    Parameters
    ----------
    f : casadi.SX, shape (n_x, 1)
        The state's right-hand side.
    x : casadi.SX
        Symbols of (some of) the state.
    v : casadi.SX, shape (x.numel(), m)
        The columns' entries along ``x``.
    d, seeds : casadi.SX, optional
        Symbols of the parameters and the columns' entries along them (n_d, m).
    through_calls : bool
        Whether ``f`` calls functions.

    Returns
    -------
    casadi.SX, shape (n_x, m)
        The derivative along each column.
    """
    if d is not None and through_calls:
        x, v = ca.vertcat(x, d), ca.vertcat(v, seeds)
    product = ca.jtimes(f, x, v) if through_calls else ca.jacobian(f, x) @ v
    if d is not None and not through_calls:
        product = product + ca.jacobian(f, d) @ seeds
    return product


def column_parts(
    f, xs, us, ds, sens, scales, seeds, n_coordinates: int, through_calls: bool
) -> list[ca.Function]:
    """The two parts ``(x;vec(S), u, d;scale) -> vec(part)`` that sum to ``vec(f_x S + f_d)``.

    Parameters
    ----------
    f : casadi.SX, shape (n_x, 1)
        The state's right-hand side in ``xs``, ``us`` and ``ds``.
    xs, us, ds : casadi.SX
        Symbols of the state, the inputs and the parameters ``d``.
    sens : casadi.SX, shape (n_x, m)
        Symbols of the sensitivity columns.
    scales : casadi.SX, shape (m, 1)
        Symbols of the column scales.
    seeds : casadi.SX, shape (n_d, m)
        The columns' entries along ``d`` (the scales at their parameters).
    n_coordinates : int
        Coordinates ``q`` among the states.
    through_calls : bool
        Whether ``f`` calls functions (:func:`tangents`).

    Returns
    -------
    list of casadi.Function
        The parts ``A`` (with ``f_d``) and ``B``, dense outputs of ``n_x m`` entries.
    """
    inputs = [ca.vertcat(xs, ca.vec(sens)), us, ca.vertcat(ds, scales)]
    parts = []
    for k, states in enumerate(split_states(n_coordinates, xs.shape[0])):
        along = (ds, seeds) if k == 0 else (None, None)
        part = tangents(f, xs[states], sens[states, :], *along, through_calls)
        parts.append(
            ca.Function(
                f"softcurve_sensitivity_part{k}",
                inputs,
                [ca.densify(common_subexpressions(ca.vec(part), n_coordinates // 3))],
            )
        )
    return parts


def assembled(state: ca.Function, parts, n_parameters: int) -> ca.Function:
    """``(x;vec(S), u, d;scale) -> f;vec(S')`` from the compiled state function
    ``f(x, u, d)`` and the parts: the augmented system for CasADi's CVODES, referring to
    the compiled libraries by path (so it pickles small), for a process that evaluates
    a split evaluator without softcurve's driver.

    Parameters
    ----------
    state : casadi.Function
        ``f(x, u, d)``, compiled (an ``external``).
    parts : sequence of casadi.Function
        The parts of :func:`column_parts`, compiled.
    n_parameters : int
        Entries of ``d`` (the scales follow them in the third argument).
    """
    n_x = state.size1_in(0)
    width = parts[0].size1_in(0)
    x, u = ca.MX.sym("x", width), ca.MX.sym("u", state.size1_in(1))
    d = ca.MX.sym("d", parts[0].size1_in(2))
    columns = sum(part(x, u, d) for part in parts)
    rhs = ca.vertcat(state(x[:n_x], u, d[:n_parameters]), columns)
    return ca.Function("softcurve_sensitivity_assembled", [x, u, d], [rhs])
