"""Exact gradients of a scalar function of a simulated trajectory (:func:`gradient`, its
result :class:`RolloutGradient`).

The cost is written by the user in CasADi symbols of the whole trajectory
(:class:`RolloutSymbols`: the states and the tip at the output times, the input samples,
the parameters, and the running integrals of an integrand), so it is differentiated
exactly along with the integration, in the state scaled as ``simulate`` scales it. Its
derivative along the robot's parameters, the initial state and the input samples is
taken by one of :data:`GRADIENT_METHODS`: the discrete adjoint of the C driver's Radau
IIA (``softcurve.simulation.solvers``: the derivative of its discrete scheme, its step
sizes held; the running integrals integrated as states), the continuous adjoint on the
driver's CVODES (the adjoint equations integrated backward over the forward pass's taped
steps), or, through CasADi's
``integrator`` over the robot's actuated right-hand side
(:meth:`Transcription.compiled_rhs <softcurve.control.Transcription.compiled_rhs>`,
compiled with its first derivatives), CVODES's adjoint (one backward pass for every seed
at once, with the forward pass checkpointed) or its forward sensitivities (one column per
seed).

The inputs are held between samples, as ``simulate`` holds a grid of inputs: row ``k``
acts on ``[t_k, t_(k+1))``, so the last row acts on nothing and its gradient is zero.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from functools import cached_property

import casadi as ca
import numpy as np

from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError, float_array, real_array
from softcurve.compiled import NativeFunction, compile_functions, load_function
from softcurve.control._transcription import DERIVATIVE_FLAGS, Transcription
from softcurve.simulation import checked_rtol
from softcurve.simulation.sensitivity import SENSITIVITY_CVODES
from softcurve.simulation.solvers import (
    RESTART_INTERVAL,
    DriverProblem,
    RadauEngine,
    adams_backward,
    adams_forward,
    adjoint_backward,
    adjoint_forward,
    cvodes_options,
    cvodes_reason,
    driver_reason,
    driver_unavailable,
    grid_inputs,
    linearization_rates,
    nominal_scale,
    state_scale,
    vjp_function,
)

GRADIENT_METHODS = ("radau-adjoint", "adams-adjoint", "adjoint", "forward")
"""How :func:`gradient` differentiates; ``"auto"`` takes one of the first two where the C
driver runs (a compiled model and a C compiler; :data:`ADAMS_WITHIN` says which), else
``adjoint``. ``radau-adjoint``: the discrete adjoint of the driver's Radau IIA, one
forward pass that tapes its steps and one backward pass, at :data:`RADAU_TOLERANCE`.
``adams-adjoint``: the continuous adjoint on the driver's CVODES (Adams), the forward
pass's steps taped and the adjoint equations integrated backward over them, at
:data:`ADAMS_TOLERANCE`. ``adjoint``: CVODES's, one backward pass for
all seeds, through CasADi. ``forward``: CVODES's forward sensitivities, one column per
seed, and the right-hand side's second derivatives compiled besides the first. On the
paper robot's 10 s swing at 100 output intervals (a cost reading the tip at each) along
all 49 parameters and the initial state, ``radau-adjoint`` takes 0.042 s,
``adams-adjoint`` 0.071 s, ``adjoint`` 0.94 s and ``forward`` 10.3 s (along the initial
state alone 0.045, 0.077, 0.98 and 1.87 s; ``python benchmarks/bench_gradient.py
--methods``): the adjoints from the smallest group of seeds on, so the counts never
favour forward. The CVODES routes stay as the independent checks
of the discrete one (``tests/test_gradient.py``)."""

RADAU_TOLERANCE = 1e-6
"""The relative tolerance of ``radau-adjoint``, and the absolute one of the scaled state
(each state over its nominal size): ``simulate``'s defaults. There Radau IIA's states
are 20 times more accurate than ``simulate``'s (the paper robot's 10 s swing at 100
output intervals: 8.8e-7 of the states' scales against 2.0e-5), and the gradient lies
9e-6 from CVODES's at 1e-10 (``python benchmarks/bench_gradient.py --radau``). The
derivative holds the step sizes, which move with the start, inputs and parameters: at
this tolerance it lies 7e-6 from central differences of its own values, at 1e-4 1.3e-2
(``python benchmarks/bench_gradient.py --radau``), so a looser tolerance is a faster but
rougher gradient, of a less accurate trajectory."""

ADAMS_TOLERANCE = 1e-7
"""The relative tolerance of ``adams-adjoint``, and the absolute one of the scaled state:
ten times tighter than ``simulate``'s, because the continuous adjoint is the gradient of
the flow to about its tolerance. On the paper robot's 10 s swing (one output interval,
``python benchmarks/bench_gradient.py --adams``) it lies 1.8e-6 from CVODES's adjoint at
1e-10 at this tolerance in 17.1 ms, 4.8e-5 at 1e-6 in 13.2 ms and 9.1e-8 at 1e-8 in
19.9 ms (``radau-adjoint`` at its own: 9.1e-6 in 39.8 ms)."""

ADAMS_WITHIN = 200.0
"""``method="auto"`` takes ``adams-adjoint`` where the adjoint starts afresh on average no
more often than every ``ADAMS_WITHIN`` over the fastest rate of the linearization at the
start, else ``radau-adjoint``. The continuous adjoint starts afresh where the cost
depends on the state at an output time (the adjoint jumps there), where the input
changes and at least every ``RESTART_INTERVAL``, and each start costs the multistep
method's climb back to its order and step, where Radau IIA's steps go on through them.
Measured on the paper robot's 10 s swing (fastest rate 283 1/s) with the cost at every
output time, ``python benchmarks/bench_gradient.py --adams``: 1, 10, 30 and 100 output
intervals take 17.1, 35.5, 51.0 and 68.1 ms by ``adams-adjoint`` and 39.0 to 39.8 ms by
``radau-adjoint``: equal near 15 (0.67 s apart, 190 over the fastest rate, rounded up to
200). The choice does not foresee the continuous adjoint's second pass
(``softcurve.simulation.solvers.ADAMS_DECAYED``): where the cost is read only at the end
of a motion that damps out, it costs as much as the discrete adjoint or more (the tip's
height at the end of that swing: 44 against about 42 ms, ``--costs``; a one-segment
chain's after 1 s: 25.5 against 19.6 ms, ``--chain 1``)."""

WITH_RESPECT_TO = ("parameters", "x0", "inputs")
"""What :func:`gradient` differentiates along (its ``wrt``): the model's parameter vector
(``Model.parameters``, named by ``Robot.parameter_names()``), the initial state and the
input samples."""

GRADIENT_TOLERANCES = (1e-10, 1e-12)
"""CVODES's ``(rtol, atol)`` of :func:`gradient`, ``atol`` of the scaled state (each
state over its nominal size, ``softcurve.simulation.solvers.state_scale``). Tighter than
the fits' (``softcurve.simulation.sensitivity.SENSITIVITY_CVODES``, 1e-8 and 1e-10):
the adjoint is that of the continuous equations, integrated backward over an
interpolation of the forward pass, so it is the gradient of the integrated cost to about
the tolerance; at these the adjoint and forward sensitivities agree to 1e-6 and central
differences to 1e-5 (``tests/test_gradient.py``)."""

MAX_STEPS = SENSITIVITY_CVODES["max_num_steps"]
"""The steps allowed between two output times (CVODES's or Radau IIA's): the fits'
budget."""


@dataclass(frozen=True, eq=False)
class RolloutSymbols:
    """The trajectory that :func:`gradient`'s cost is written in, as CasADi symbols (MX):
    combine them with CasADi's operations into one scalar. Besides the attributes, the
    properties :attr:`q`, :attr:`qd`, :attr:`tip` and :attr:`integral`.

    Attributes
    ----------
    t : ndarray, shape (T,)
        The output times [s] (numbers).
    x : casadi.MX, shape (n_x, T)
        The state at every output time (``simulate``'s layout; the lagging inputs last).
    u : casadi.MX, shape (n_u, T)
        The input samples, column ``k`` the inputs held from ``t_k``.
    p : casadi.MX, shape (n_p,)
        The model's parameter vector.
    running_integral : casadi.MX, shape (k, T) or None
        What :attr:`integral` returns; None where :func:`gradient` got no ``running``.
    transcription : Transcription
        The robot's Functions (its :attr:`~Transcription.tip`, :attr:`~Transcription.domain`).
    """

    t: np.ndarray
    x: ca.MX
    u: ca.MX
    p: ca.MX
    running_integral: ca.MX | None = field(repr=False)
    transcription: Transcription = field(repr=False)

    @property
    def q(self) -> ca.MX:
        """The coordinates at every output time, shape (n, T)."""
        return self.x[: self.transcription.model.n, :]

    @property
    def qd(self) -> ca.MX:
        """The coordinates' rates at every output time, shape (n, T)."""
        n = self.transcription.model.n
        return self.x[n : 2 * n, :]

    @cached_property
    def tip(self) -> ca.MX:
        """The tip's position [m] at every output time, shape (3, T)."""
        return self.transcription.tip.map(self.t.size)(self.x, self.p)

    @property
    def integral(self) -> ca.MX:
        """The integrals of ``running`` from ``t_0`` to every output time (zero at
        ``t_0``), shape (k, T); an error where :func:`gradient` got no ``running``."""
        if self.running_integral is None:
            raise ParameterError("trajectory.integral needs gradient(..., running=...)")
        return self.running_integral


@dataclass(frozen=True)
class RolloutGradient(Result):
    """What :func:`gradient` computed.

    Attributes
    ----------
    status : Status
        SUCCESS; LEFT_DOMAIN where the trajectory leaves the model's or the actuator's
        domain at an output time (checked at the output times, as ``simulate`` checks
        its outputs: give times as dense as the check should be), with no gradient (NaN);
        INTEGRATION_FAILED where the integration or its derivative stopped, or a
        derivative is not finite.
    message : str
        What happened.
    value : float
        The cost [its unit].
    t : ndarray, shape (T,)
        The output times [s].
    x : ndarray, shape (T, n_x)
        The trajectory at them (``simulate``'s layout).
    parameters : ndarray, shape (n_p,) or None
        ``d value / d p`` [unit of the cost per unit of each parameter]; None where not
        asked (``wrt``).
    x0 : ndarray, shape (n_x,) or None
        ``d value / d x0`` [per unit of each state].
    inputs : ndarray, shape (T, n_u) or None
        ``d value / d u_k`` [per unit of each input], row ``k`` the sample held from
        ``t_k`` (the last row acts on the trajectory nowhere: zero unless the cost reads
        it).
    method : str
        One of :data:`GRADIENT_METHODS`.
    reason : str
        Why that method.
    names : tuple of str
        The parameters' names, in the order of :attr:`parameters`.
    at : ndarray, shape (n_p,)
        The parameter vector the gradient is at (``gradient``'s ``parameters``).
    solve_time : float
        Wall time [s] of the integration and its derivative (the build excluded).
    transcription : Transcription
        The model and actuator.
    stats : dict
        The counters of the driver's passes (empty for CVODES's routes through CasADi):
        the forward pass's (``steps``, ``rhs_evaluations``, ``jacobian_evaluations``,
        ``linear_solver_setups``, ``error_test_failures``, ``newton_failures``) and the
        backward pass's: ``radau-adjoint``'s ``ADJOINT_STATISTICS`` of
        ``softcurve.simulation.solvers`` (``vjp_evaluations``, ``iterations``,
        ``factorizations``, ``fresh_jacobians``), ``adams-adjoint``'s
        ``ADAMS_STATISTICS`` prefixed ``backward_`` (``backward_steps``,
        ``backward_vjp_evaluations``, ``backward_jacobians``, ``backward_factorizations``,
        ``backward_error_test_failures``, ``backward_starts``).
        Empty for CVODES's routes and wherever no gradient was computed.
    """

    status: Status
    message: str
    value: float
    t: np.ndarray
    x: np.ndarray
    parameters: np.ndarray | None
    x0: np.ndarray | None
    inputs: np.ndarray | None
    method: str
    reason: str
    names: tuple
    at: np.ndarray
    solve_time: float
    transcription: Transcription = field(repr=False, compare=False)
    stats: dict = field(default_factory=dict, compare=False)

    @property
    def by_name(self) -> dict:
        """``d value / d p`` by parameter name (empty where not asked)."""
        if self.parameters is None:
            return {}
        return dict(zip(self.names, self.parameters.tolist(), strict=True))

    def plot(self, ax=None, *, largest: int = 10, title: str | None = None):
        """The gradient along the input samples against time, and the largest relative
        sensitivities ``p_i d value / d p_i`` of the parameters.

        Parameters
        ----------
        ax : None or sequence of matplotlib.axes.Axes, shape (2,)
            Where to draw; None draws a new figure.
        largest : int
            Parameters drawn, the largest in magnitude first, >= 1.
        title : str, optional
            The figure's title.

        Returns
        -------
        matplotlib.figure.Figure
        """
        from softcurve.figures.gradients import gradient_figure

        relative = None if self.parameters is None else self.at * self.parameters
        return gradient_figure(
            self.t, self.inputs, relative, self.names, self.transcription.actuator,
            largest=largest, title=title, ax=ax,
        )  # fmt: skip


def _times(t) -> np.ndarray:
    t = float_array("t", t, "increasing output times [s]")
    if t.ndim != 1 or t.size < 2 or not np.all(np.isfinite(t)) or not np.all(np.diff(t) > 0):
        raise ParameterError(
            f"t must be increasing output times [s], at least two, got shape {t.shape}"
        )
    return t


def _samples(inputs, tr: Transcription, size: int) -> np.ndarray:
    """The input samples, (T, n_u), checked as ``simulate`` checks a grid of inputs
    (within the actuator's bounds)."""
    return grid_inputs("inputs", inputs, tr.n_u, size, tr.actuator)


def _integrand(running, tr: Transcription) -> ca.Function:
    """``running`` as an SX Function ``(x, u, p) -> l (k,)``, checked."""
    x, u, p = (ca.SX.sym(name, size) for name, size in
               (("x", tr.n_x), ("u", tr.n_u), ("p", tr.parameters.size)))  # fmt: skip
    try:
        value = ca.vec(ca.SX(running(x, u, p)))
    except (TypeError, NotImplementedError, RuntimeError) as error:
        raise ParameterError(
            f"running must be a CasADi expression of (x, u, p): {error}"
        ) from error
    return ca.Function("running", [x, u, p], [value])


AUTO_FALLBACK = "auto: CVODES's adjoint, since the C driver does not run here ({why})"
"""Why ``method="auto"`` takes ``adjoint`` where the driver does not run."""


def _method_name(method: str) -> str:
    if method != "auto" and method not in GRADIENT_METHODS:
        raise ParameterError(
            f"method must be 'auto' or one of {', '.join(GRADIENT_METHODS)}, got {method!r}"
        )
    return method


def _method(method: str, tr: Transcription) -> tuple[str, str]:
    """The method taken and why; where it needs the driver, after every other check (the
    driver may be built here)."""
    why = _driver_missing(tr) if method in ("auto", *DRIVER_METHODS) else None
    if method == "auto":
        if why is None:
            return GRADIENT_METHODS[0], "auto"  # which adjoint: _driver_choice, on the cost
        return "adjoint", AUTO_FALLBACK.format(why=why)
    if why is not None:
        raise ParameterError(f"method {method!r} needs the C driver, which does not run: {why}")
    return method, "asked"


def _driver_choice(of_states, tr: Transcription, x0, t, samples, p_value) -> tuple[str, str]:
    """``method="auto"``'s choice between the driver's adjoints (:data:`ADAMS_WITHIN`),
    and why: the output times whose states the cost reads (its derivative's pattern) and
    the input's changes count the continuous adjoint's starts, which come every
    ``RESTART_INTERVAL`` at least; the fastest rate is the linearization's at the start
    and the parameters differentiated at, or a lagging actuator's ``1 / time_constant``
    where that is faster."""
    n_x = tr.n_x
    read = np.zeros(t.size, bool)
    for index, size in ((3, n_x), (4, of_states.size1_in(4))):
        if size:  # the pattern of d cost / d X (column-major: output k's states in a row)
            columns = np.array(of_states.sparsity_jac(index, 0).get_col(), int)
            read[columns // size] = True
    starts = read[1:-1] | np.any(samples[1:-1] != samples[:-2], axis=1)
    spacing = min((t[-1] - t[0]) / (np.count_nonzero(starts) + 1), RESTART_INTERVAL)
    state = x0[None, : tr.model.n_state]
    nominal = nominal_scale(tr.model, state[0])
    try:
        with np.errstate(all="ignore"):  # a start the integration cannot take: said below
            rates = linearization_rates(tr.model, state, nominal=nominal, parameters=p_value[None])
        fastest = float(rates[1][0])
    except np.linalg.LinAlgError:  # not finite
        fastest = np.nan
    if not np.isfinite(fastest):
        return GRADIENT_METHODS[0], (
            "auto: the discrete adjoint of Radau IIA, as the linearization at the start is "
            "not finite"
        )
    if tr.inputs is not None and tr.inputs.time_constant:
        fastest = max(fastest, 1.0 / tr.inputs.time_constant)
    ratio = spacing * fastest
    if ratio >= ADAMS_WITHIN:
        return "adams-adjoint", (
            f"auto: CVODES's continuous adjoint, as it starts afresh every {spacing:.3g} s "
            f"on average, {ratio:.3g} over the fastest rate (ADAMS_WITHIN: {ADAMS_WITHIN:g})"
        )
    return GRADIENT_METHODS[0], (
        f"auto: the discrete adjoint of Radau IIA, as a continuous adjoint would start "
        f"afresh every {spacing:.3g} s on average, {ratio:.3g} over the fastest rate "
        f"(under ADAMS_WITHIN: {ADAMS_WITHIN:g})"
    )


def _driver_missing(tr: Transcription) -> str | None:
    """Why the driver cannot take this model, or None."""
    if tr.model.compiled_library is None:
        return "the model is not compiled"
    return driver_unavailable()


def _wrt(wrt) -> tuple:
    wrt = (wrt,) if isinstance(wrt, str) else tuple(wrt)
    unknown = [w for w in wrt if w not in WITH_RESPECT_TO]
    if unknown or not wrt:
        raise ParameterError(
            f"wrt must name one or more of {', '.join(WITH_RESPECT_TO)}, got {wrt!r}"
        )
    return wrt


def gradient(
    model,
    cost,
    q0,
    qd0=None,
    lam0=None,
    *,
    t,
    inputs=None,
    actuator=None,
    actuator_state=None,
    running=None,
    wrt=WITH_RESPECT_TO,
    method: str = "auto",
    parameters=None,
    rtol: float | None = None,
) -> RolloutGradient:
    """The exact gradient of a scalar function of a simulated trajectory.

    The robot is integrated from ``(q0, qd0, lam0)`` over the output times ``t`` with the
    input samples held, and ``cost(trajectory)`` is differentiated along the model's
    parameters, the initial state and the input samples.

    Parameters
    ----------
    model : Model
        The compiled model.
    cost : callable(RolloutSymbols) -> casadi.MX
        The scalar, written in the trajectory's symbols (:class:`RolloutSymbols`: its
        states, tip, inputs and parameters at the output times, and the integrals of
        ``running``), in any unit.
    q0 : array_like, shape (n,)
        Initial coordinates, in the model's domain.
    qd0 : array_like, shape (n,), optional
        Initial rates (default zero).
    lam0 : array_like, shape (n_creep,), optional
        Initial creep states (default zero).
    t : array_like, shape (T,)
        Output times [s], increasing, at least two; the first is the start.
    inputs : array_like, shape (n_u,) or (T, n_u), optional
        The actuator's inputs (its commands where it lags), else the generalized forces,
        row ``k`` held from ``t_k`` (default zero), within the actuator's bounds.
    actuator : Actuator, optional
        What the inputs drive (None: generalized forces).
    actuator_state : array_like, shape (m,), optional
        A lagging actuator's inputs at the start (default its rest inputs).
    running : callable(x, u, p) -> casadi.SX, optional
        An integrand of the state (n_x,), the inputs (n_u,) and the parameters (n_p,),
        shape (k,); its integrals are ``trajectory.integral``, integrated with the state
        and under its error test (not a sum over the output times). The tip is
        ``sc.Transcription(model).tip(x, p)``.
    wrt : str or sequence of str
        What to differentiate along, among :data:`WITH_RESPECT_TO` (default all).
    method : {"auto", "radau-adjoint", "adams-adjoint", "adjoint", "forward"}
        :data:`GRADIENT_METHODS`; "auto" takes ``adams-adjoint`` or ``radau-adjoint`` where
        the C driver runs (:data:`ADAMS_WITHIN`), else ``adjoint`` (the result's ``reason``
        says which and why).
    parameters : array_like, shape (n_p,), optional
        The parameter vector to integrate and differentiate at, each entry in its unit
        (``Robot.parameter_names()``; default ``model.parameters``): an optimizer's
        iterate, without a model built for it. Checked as a robot is built (every field
        in its range), and the domain checked with its rest lengths.
    rtol : float, optional
        The integration's relative tolerance, in ``[RTOL_MIN, 1)`` (2.2e-14,
        ``softcurve.simulation.RTOL_MIN``); the absolute one of the
        scaled state keeps the default's ratio to it. Default :data:`RADAU_TOLERANCE`
        for ``radau-adjoint``, :data:`ADAMS_TOLERANCE` for ``adams-adjoint``, the first of
        :data:`GRADIENT_TOLERANCES` for CVODES's routes through CasADi.

    Returns
    -------
    RolloutGradient

    Examples
    --------
    >>> import numpy as np
    >>> import softcurve as sc
    >>> model = sc.Model(sc.presets.ifac2020(), quadrature_nodes=3)
    >>> g = sc.gradient(model, lambda tr: tr.tip[2, -1], [0.064, 5.0, 0.0],
    ...                 t=np.linspace(0.0, 0.05, 6), wrt="x0")
    >>> g.success, g.x0.shape
    (True, (9,))
    """
    # everything checked before any work (the compile of the right-hand side)
    t = _times(t)
    tr = Transcription(model, actuator)
    x0 = tr.start(q0, qd0, lam0, actuator_state)
    samples = _samples(inputs, tr, t.size)
    wrt = _wrt(wrt)
    method = _method_name(method)
    rtol = _rtol(rtol)
    robot, p_value = _robot_at(tr, parameters, x0)
    integrand = None if running is None else _integrand(running, tr)
    if not callable(cost):
        raise ParameterError("cost must be a callable of the trajectory's symbols")
    chosen, reason = _method(method, tr)
    start, samples_sym, params = (ca.MX.sym(name, *shape) for name, shape in (
        ("x0", (tr.n_x,)), ("u", (tr.n_u, t.size)), ("p", (tr.parameters.size,))))  # fmt: skip
    arguments = [params, start, samples_sym]
    k = 0 if integrand is None else integrand.size1_out(0)

    def cost_of(states, integral):
        """The cost in the trajectory's symbols ``states`` (n_x, T), ``integral``."""
        value = cost(RolloutSymbols(t, states, samples_sym, params, integral, tr))
        if not isinstance(value, ca.MX | ca.DM | float | int) or ca.MX(value).numel() != 1:
            raise ParameterError(
                "cost must return one scalar: a CasADi expression of the trajectory's "
                f"symbols, shape (1, 1), got {type(value).__name__}"
            )
        return ca.MX(value)

    # the cost of given states (evaluated on the numbers of the integration), and through
    # the integration (differentiated)
    free = ca.MX.sym("X", tr.n_x, t.size), ca.MX.sym("Q", k, t.size)
    integrated = integrand is not None
    of_states = ca.Function(
        "rollout_cost", [*arguments, *free], [cost_of(free[0], free[1] if integrated else None)]
    )
    if method == "auto" and chosen in DRIVER_METHODS:
        chosen, reason = _driver_choice(of_states, tr, x0, t, samples, p_value)
    tolerances = _tolerances(rtol, chosen)
    names = tuple(model.robot.parameter_names())
    numbers = [p_value, x0, samples.T]
    failed = {"t": t, "tr": tr, "method": chosen, "reason": reason, "names": names,
              "at": p_value}  # fmt: skip
    if chosen in DRIVER_METHODS:
        return _driver_gradient(of_states, numbers, integrand, wrt, robot, failed, tolerances)
    held = "inputs" in wrt or not np.all(samples[:-1] == samples[0])
    states, integrals = _rollout(tr, x0, t, integrand, chosen, held, tolerances)(*arguments)
    trajectory = ca.Function("rollout", arguments, [states, integrals])
    value_only = ca.Function(
        "rollout_value", arguments, [cost_of(states, integrals if integrated else None)]
    )
    began = failed["began"] = time.perf_counter()
    try:
        x, quadratures = (np.array(a) for a in trajectory(*numbers))
    except RuntimeError as error:
        return _failed(Status.INTEGRATION_FAILED, _cvodes_failed(error), **failed)
    problem_text = tr.domain_exit(x.T, t, robot)
    if problem_text is not None:
        return _failed(Status.LEFT_DOMAIN, problem_text, x=x.T, **failed)
    cost_value = float(of_states(*numbers, x, quadratures))
    try:
        if chosen == "adjoint":
            seeds = value_only.reverse(1)(*numbers, cost_value, 1.0)
            d_p, d_x0, d_u = (np.array(s) for s in seeds)
        else:
            d_p, d_x0, d_u = _forward(value_only, numbers, cost_value, wrt)
    except RuntimeError as error:
        return _failed(Status.INTEGRATION_FAILED, _cvodes_failed(error), x=x.T, **failed)
    asked = dict(zip(WITH_RESPECT_TO, (d_p.ravel(), d_x0.ravel(), d_u.T), strict=True))
    return RolloutGradient(
        Status.SUCCESS, f"the gradient of the cost along {', '.join(wrt)}", cost_value,
        _frozen(t), _frozen(x.T), *(_frozen(asked[w]) if w in wrt else None
                                    for w in WITH_RESPECT_TO),
        chosen, reason, names, _frozen(p_value), time.perf_counter() - began, tr,
    )  # fmt: skip


def _driver_gradient(of_states, numbers, integrand, wrt, robot, failed, tolerances):
    """:func:`gradient` by one of the driver's adjoints (:data:`DRIVER_METHODS`): the
    forward pass tapes its steps, the cost's derivative along the states at the output
    times seeds the backward pass, and the cost's own derivatives along the parameters,
    the initial state and the inputs are added."""
    tr, t = failed["tr"], failed["t"]
    p_value, x0, inputs = numbers
    adjoint = _DRIVER_ADJOINTS[failed["method"]]
    problem, vjp = _driver_functions(tr, integrand)
    k = problem.struct.nx - tr.n_x  # the running integrals, integrated as states
    nominal = np.concatenate([state_scale(tr.model, x0[: tr.model.n_state], tr.inputs),
                              np.ones(k)])  # fmt: skip
    began = failed["began"] = time.perf_counter()
    # the steps end where the input changes, or at every sample where the adjoint needs
    # that for the gradient along them
    stops = np.ones(t.size, bool)
    if "inputs" not in wrt or not adjoint.stops_at_samples:
        stops[1:-1] = np.any(inputs[:, 1:-1] != inputs[:, :-2], axis=0)
    taped = adjoint.forward(problem, np.concatenate([x0, np.zeros(k)]), inputs.T, p_value,
                            nominal, t, *tolerances, MAX_STEPS, stops)  # fmt: skip
    x, quadratures = taped.states[:, : tr.n_x], taped.states[:, tr.n_x :].T
    if taped.flag:
        reached = taped.reached
        x = np.where(np.arange(t.size)[:, None] < reached, x, np.nan)
        outside = tr.domain_exit(x[:reached], t[:reached], robot)  # the cause, where it is
        if outside is not None:
            return _failed(Status.LEFT_DOMAIN, outside, x=x, **failed)
        reason = f"{adjoint.forward_reason(taped.flag)}, after {reached - 1} output interval(s)"
        return _failed(Status.INTEGRATION_FAILED, reason, x=x, **failed)
    problem_text = tr.domain_exit(x, t, robot)
    if problem_text is not None:
        return _failed(Status.LEFT_DOMAIN, problem_text, x=x, **failed)
    value = of_states(*numbers, x.T, quadratures)
    seeds = of_states.reverse(1)(*numbers, x.T, quadratures, value, 1.0)
    along_p, along_x0, along_u, along_x, along_q = (np.array(a) for a in seeds)
    along_states = np.vstack([along_x, along_q]).T
    if not np.all(np.isfinite(along_states)):
        when = t[np.flatnonzero(~np.all(np.isfinite(along_states), axis=1))[0]]
        return _failed(Status.INTEGRATION_FAILED, "the cost's derivative along the state at "
                       f"t = {when:g} s is not finite: no gradient", x=x, **failed)  # fmt: skip
    flag, lam, d_u, d_p, counts = adjoint.backward(taped, vjp, along_states)
    if flag:
        reason = f"{adjoint.backward_stopped}: {adjoint.backward_reason(driver_reason(flag))}"
        return _failed(Status.INTEGRATION_FAILED, reason, x=x, **failed)
    asked = {"parameters": along_p.ravel() + d_p, "x0": along_x0.ravel() + lam[: tr.n_x],
             "inputs": along_u.T + d_u}  # fmt: skip
    not_finite = [w for w in wrt if not np.all(np.isfinite(asked[w]))]
    if not_finite:  # the cost's own derivatives, or the sums
        return _failed(Status.INTEGRATION_FAILED, "the gradient is not finite along "
                       f"{', '.join(not_finite)}: no gradient", x=x, **failed)  # fmt: skip
    return RolloutGradient(
        Status.SUCCESS, f"the gradient of the cost along {', '.join(wrt)}", float(value),
        _frozen(t), _frozen(x), *(_frozen(asked[w]) if w in wrt else None
                                  for w in WITH_RESPECT_TO),
        failed["method"], failed["reason"], failed["names"], _frozen(p_value),
        time.perf_counter() - began, tr,
        {**taped.counts, **{adjoint.counts_prefix + name: n for name, n in counts.items()}},
    )  # fmt: skip


BACKWARD_FAILURES = {
    "CV_CONV_FAILURE": "a step's multipliers did not converge, on a fresh Jacobian either "
    "(the right-hand side's reverse mode not finite there?)",
    "CV_LSETUP_FAIL": "a step's transposed Newton matrices are singular",
    "CV_RHSFUNC_FAIL": "the right-hand side's reverse mode failed, or is not finite along "
    "the inputs or the parameters",
}
"""The backward pass's failures (the driver's flags by name) in words."""

ADAMS_FAILURES = {
    "CV_RHSFUNC_FAIL": "the right-hand side's reverse mode failed, or is not finite along "
    "the state, the inputs or the parameters",
}
"""The continuous adjoint's backward failures that CVODES's words would misname (its
right-hand side is the reverse mode)."""


@dataclass(frozen=True)
class _DriverAdjoint:
    """What differs between the driver's two adjoints (:func:`_driver_gradient`)."""

    forward: Callable  # adjoint_forward or adams_forward
    backward: Callable  # their backward passes
    tolerance: float  # the default rtol, and atol of the scaled state
    stops_at_samples: bool  # the steps end at every sample for the gradient along inputs
    forward_reason: Callable[[int], str]  # the forward pass's failure flag in a sentence
    backward_stopped: str  # how a backward failure's message begins
    backward_reason: Callable[[str], str]  # the backward pass's flag, by name, in words
    counts_prefix: str  # before the backward counters' names where they share the forward's


_DRIVER_ADJOINTS = {
    "radau-adjoint": _DriverAdjoint(
        adjoint_forward, adjoint_backward, RADAU_TOLERANCE, True,
        RadauEngine.failure_reason, "Radau IIA's adjoint stopped",
        lambda name: BACKWARD_FAILURES.get(name, name), "",
    ),
    "adams-adjoint": _DriverAdjoint(
        adams_forward, adams_backward, ADAMS_TOLERANCE, False,
        lambda flag: cvodes_reason(driver_reason(flag)),
        "the adjoint equations' integration stopped",
        lambda name: ADAMS_FAILURES.get(name, cvodes_reason(name)), "backward_",
    ),
}  # fmt: skip

DRIVER_METHODS = tuple(_DRIVER_ADJOINTS)
"""The methods of the C driver: the discrete adjoint of its Radau IIA and the continuous
adjoint on its CVODES (the first two of :data:`GRADIENT_METHODS`)."""


def _driver_functions(tr: Transcription, integrand) -> tuple:
    """``(DriverProblem, vjp)`` of the actuated right-hand side with the running
    integrals as states, compiled side by side under ``DERIVATIVE_FLAGS`` (cached on disk)
    and kept with the model: on the paper robot the first gradient then waits 3.8 s, the
    reverse mode compiling in 2.5 s against 22.7 s under the model's flags, for a
    gradient 15 % slower (55 ms against 46 ms on ``bench_gradient.py``'s 100
    intervals)."""

    def build():
        n_x, n_q = tr.n_x, 0 if integrand is None else integrand.size1_out(0)
        x = ca.SX.sym("x", n_x + n_q)
        u, p = ca.SX.sym("u", tr.n_u), ca.SX.sym("p", tr.parameters.size)
        rows = [tr.rhs_sx(x[:n_x], u, p)]
        if integrand is not None:
            rows.append(integrand(x[:n_x], u, p))
        rhs = ca.Function("softcurve_rollout_rhs", [x, u, p], [ca.densify(ca.vertcat(*rows))])
        built = compile_functions(
            [rhs, vjp_function(rhs)], flags=DERIVATIVE_FLAGS, load=load_function
        )
        if not all(isinstance(f, NativeFunction) for f in built):
            raise ParameterError(
                f"methods {', '.join(DRIVER_METHODS)} need their functions compiled, and they "
                "did not compile"
            )
        return DriverProblem(built[0], n_x + n_q, tr.n_u, tr.parameters.size), built[1]

    key = ("driver-adjoint", None if tr.actuator is None else tr.inputs.key,
           None if integrand is None else integrand.serialize())  # fmt: skip
    return tr.model.cached(key, build)


def _rtol(rtol) -> float | None:
    """``rtol`` checked as ``simulate``'s (:func:`softcurve.simulation.checked_rtol`), or
    None."""
    return None if rtol is None else checked_rtol(rtol)


def _tolerances(rtol: float | None, method: str) -> tuple[float, float]:
    """``(rtol, atol)`` of ``method``: its defaults, or ``rtol`` (checked) with the
    defaults' ratio."""
    adjoint = _DRIVER_ADJOINTS.get(method)
    default = GRADIENT_TOLERANCES if adjoint is None else (adjoint.tolerance,) * 2
    if rtol is None:
        return default
    return rtol, rtol * (default[1] / default[0])  # the defaults' own numbers at theirs


def _robot_at(tr: Transcription, parameters, x0) -> tuple:
    """``(robot, p)``: the robot of the parameter vector asked for (default the model's),
    checked as a robot is built (every field in its range), and the start inside its
    domain and the actuator laid along it."""
    robot, p_value = tr.model.robot, tr.parameters
    if parameters is None:
        return robot, p_value
    p_value = np.array(real_array("parameters", parameters, p_value.shape))
    try:
        robot = robot.with_parameter_vector(p_value)
        robot.check_configuration(x0[: robot.n], "q0")
        if tr.actuator is not None:
            tr.actuator.check_robot(robot)
    except ParameterError as error:
        raise ParameterError(f"parameters: {error}") from None
    return robot, p_value


def _cvodes_failed(error: RuntimeError) -> str:
    """What CVODES said, its last line (CasADi's traceback before it)."""
    lines = str(error).strip().splitlines()
    return f"CVODES failed: {lines[-1] if lines else 'no message'}"


def _frozen(array) -> np.ndarray:
    """A read-only copy of ``array``: the result's arrays are its own."""
    copy = np.array(array, dtype=np.float64)
    copy.setflags(write=False)
    return copy


def _rollout(tr: Transcription, x0, t, integrand, method, held: bool, tolerances) -> ca.Function:
    """``(p, x0, U) -> (X (n_x, T), Q (k, T))``: the states at the output times and the
    running integrals, integrated by CVODES.

    The state is scaled as ``simulate`` scales it (``state_scale``), so that one absolute
    tolerance fits every state. With ``held`` (inputs that change, or a gradient along
    them) each interval between output times is one integration over a unit of scaled
    time ``s = (t - t_k) / h_k``, its length ``h_k`` and its held inputs among the
    integrator's parameters, so one integrator serves every interval. Otherwise one
    integration runs through every output time, the inputs ``U[:, 0]`` among its
    parameters, without the restarts. The inputs are never the
    integrator's controls: CasADi 3.8.2's reverse mode of an integrator with controls and
    more than one output time crashes (``tests/test_gradient.py`` pins that)."""
    model, n_x, n_u, n_p = tr.model, tr.n_x, tr.n_u, tr.parameters.size
    n_q = 0 if integrand is None else integrand.size1_out(0)
    scale = ca.DM(state_scale(model, x0[: model.n_state], tr.inputs))
    rhs = tr.compiled_rhs(3 if method == "forward" else 1)
    z, w = ca.MX.sym("z", n_x), ca.MX.sym("w", n_u + n_p + 1)
    u, p, h = w[:n_u], w[n_u : n_u + n_p], w[-1]
    problem = {"x": z, "p": w, "ode": h * rhs(scale * z, u, p) / scale}
    options = cvodes_options("adams", *tolerances, MAX_STEPS, max_order=None)
    if integrand is not None:
        problem["quad"] = h * integrand(scale * z, u, p)
        options["quad_err_con"] = True  # the integral as accurate as the state
    start, samples, params = ca.MX.sym("x0", n_x), ca.MX.sym("u", n_u, t.size), ca.MX.sym("p", n_p)
    if held:
        one = ca.integrator("interval", "cvodes", problem, 0.0, 1.0, options)
        carried, w_k = ca.MX.sym("carried", n_x + n_q), ca.MX.sym("w", w.shape[0])
        ran = one(x0=carried[:n_x], p=w_k)
        interval = ca.Function(
            "interval", [carried, w_k], [ca.vertcat(ran["xf"], carried[n_x:] + ran["qf"])]
        )
        steps = ca.vertcat(samples[:, :-1], ca.repmat(params, 1, t.size - 1), ca.DM(np.diff(t)).T)
        carried0 = ca.vertcat(start / scale, ca.MX.zeros(n_q))
        after = interval.mapaccum("intervals", t.size - 1)(carried0, steps)
        final, integrals = after[:n_x, :], after[n_x:, :]
    else:  # time in units of 1 s from t_0 (h = 1): the output times as they are
        grid = t[1:] - t[0]
        through = ca.integrator("through", "cvodes", problem, 0.0, grid, options)
        ran = through(x0=start / scale, p=ca.vertcat(samples[:, 0], params, 1.0))
        final, integrals = ran["xf"], ran["qf"]
    states = ca.horzcat(start, scale * final)
    integrals = ca.horzcat(ca.MX.zeros(n_q, 1), integrals)
    return ca.Function("rollout", [params, start, samples], [states, integrals])


def _forward(function: ca.Function, numbers, value: float, wrt) -> tuple:
    """The gradient by forward sensitivities: one seed per entry of what ``wrt`` names
    (zero along the rest)."""
    sizes = [np.size(a) for a in numbers]
    chosen = [name in wrt for name in WITH_RESPECT_TO]
    total = sum(s for s, c in zip(sizes, chosen, strict=True) if c)
    seeds, offset = [], 0
    for array, size, on in zip(numbers, sizes, chosen, strict=True):
        block = np.zeros((size, total))
        if on:
            block[:, offset : offset + size] = np.eye(size)
            offset += size
        shape = np.shape(array) if np.ndim(array) == 2 else (size, 1)
        # CasADi takes the seeds of an input side by side, one input's shape each
        seeds.append(np.hstack([block[:, j].reshape(shape, order="F") for j in range(total)]))
    row = np.array(function.forward(total)(*numbers, value, *seeds)).ravel()
    parts, offset = [], 0
    for array, size, on in zip(numbers, sizes, chosen, strict=True):
        part = np.zeros(size)
        if on:
            part, offset = row[offset : offset + size], offset + size
        parts.append(part.reshape(np.shape(array), order="F") if np.ndim(array) == 2 else part)
    return tuple(parts)


def _failed(status, message, *, t, tr, method, reason, names, at, began, x=None):
    """A result without a gradient (NaN), its trajectory as far as it is known."""
    x = np.full((t.size, tr.n_x), np.nan) if x is None else x
    nan = [np.full(shape, np.nan) for shape in (at.size, tr.n_x, (t.size, tr.n_u))]
    return RolloutGradient(
        status, message, float("nan"), _frozen(t), _frozen(x), *map(_frozen, nan), method,
        reason, names, _frozen(at), time.perf_counter() - began, tr,
    )  # fmt: skip
