"""Simulation of eq. (16) with creep (eq. 19): :func:`simulate` and its :class:`Trajectory`.

The state is ``x = (q, qd, lam)``. Output is on a fixed grid ``t_k = k dt``; between
output times the integrator chooses its own steps under error control.

Integrators (``method``)
------------------------
``"cvodes"`` (default)
    SUNDIALS CVODES in compiled code (through CasADi), on the model's compiled
    right-hand side: a 10 s run of the paper's case never returns to Python. CVODES
    offers Adams-Moulton (orders 1-12, efficient on smooth non-stiff problems; capped at
    5 here, ``softcurve._engines.MAX_ORDER``) and BDF (orders 1-5, stable on stiff
    ones); ``"cvodes"`` picks per problem from the linearisation at the initial state:
    if the fastest decay rate exceeds the fastest oscillation frequency
    ``STIFFNESS_RATIO`` times (a decaying mode far faster than anything that must be
    resolved), BDF, otherwise Adams. The paper's case has its
    fastest decay (creep, 284 1/s) next to its fastest oscillation (247 rad/s): Adams.
    Where Adams was chosen, each restart segment after the first is integrated with BDF
    once the robot has settled (it moves a thousand times slower than its fastest mode,
    ``softcurve._engines.SETTLED_RATIO``), and with Adams again if it moves; the method
    is then reported as ``"cvodes-adams+bdf"``. With pressure inputs, a controller or a
    callable input the family chosen at the start is kept.
``"adams"``, ``"bdf"``
    CVODES with that family, no choice made.
``"rk45"``
    SciPy's explicit Runge-Kutta 4(5) of Dormand and Prince (the paper's ``ode45``)
    on the same compiled right-hand side, stepped from Python: 5-10x slower, for
    comparison and for robots where an explicit method is wanted.

How CVODES gets compiled code, measured on the paper's case
(``benchmarks/bench_simulate.py``): the library that :class:`~softcurve.Model` has
already compiled is loaded as a CasADi ``external`` (numbers in
``docs/paper-reproduction.md``); the same integration with the right-hand side in CasADi's
virtual machine takes about 6x longer; CasADi's ``jit`` would compile the right-hand
side and its exact Jacobian again for every new integrator (about 50 s with gcc -O2).
Multistep histories cannot cross a jump of the input, so the integrator restarts
wherever the input changes, and also every ``RESTART_INTERVAL`` (1 s) of simulated time:
after a transient, a method left at high order is stability-bound on the fast damped
modes of a robot at rest; a restart halves the steps of the paper's case (see
``softcurve._engines.RESTART_INTERVAL``).

Inputs
------
``tau`` is None (zero), a constant (n,), an array (T, n) on the output grid (held
constant over ``[t_k, t_k+1)``), or a callable ``tau(t, state)`` with ``state`` a
:class:`State` (``q``, ``qd``, ``lam``, ``x``), evaluated at every output time and held
(zero-order hold). A ``controller`` (an object with ``sample_time`` [s] and
``__call__(t, q, qd, lam) -> tau``, optionally ``reset()``) is sampled every
``sample_time`` and its output held between samples; give either ``tau`` or a
``controller``. Inputs that need Python at run time integrate piece by piece and are
slower.
"""

from __future__ import annotations

import dataclasses
import math
import sys
import time
from collections.abc import Callable

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError, real_array, real_scalar
from softcurve.compiled.model import Model
from softcurve.simulation.engine import (
    RESTART_INTERVAL,
    STIFFNESS_RATIO,
    CvodesEngine,
    IntegrationFailure,
    PressureInput,
    ScipyEngine,
    linearisation_rates,
    nominal_scale,
    restart_segments,
    settled,
    stiffness_ratio,  # noqa: F401 (softcurve.simulate.stiffness_ratio, as in the examples)
)
from softcurve.simulation.trajectory import State, Trajectory

METHODS = ("cvodes", "adams", "bdf", "rk45")


# -- argument checks -----------------------------------------------------------------------
def _finite_vector(name: str, value, size: int) -> np.ndarray:
    return np.array(real_array(name, value, (size,)))  # a writable copy


def _positive(name: str, value) -> float:
    return real_scalar(name, value, positive=True)


def _grid(t_final: float, dt: float) -> np.ndarray:
    """Times ``0, dt, 2 dt, ...``; the last one is ``t_final`` if it is not a multiple."""
    count = t_final / dt
    steps = round(count)
    if abs(count - steps) > 1e-9 * max(count, 1.0):  # not a multiple: a shorter last step
        steps = math.ceil(count)
    grid = np.arange(steps + 1) * dt
    grid[-1] = t_final
    return grid


def _input_grid(name: str, value, n: int, grid: np.ndarray):
    """Constant / on-grid inputs as a (T, n) array; callables come back unchanged."""
    if value is None:
        return np.zeros((grid.size, n))
    if callable(value):
        return value
    a = np.asarray(value, dtype=np.float64) if not isinstance(value, str) else None
    if a is not None and a.shape == (n,):
        a = np.broadcast_to(a, (grid.size, n))
    if a is None or a.shape != (grid.size, n):
        raise ParameterError(
            f"{name} must be None, shape ({n},), shape ({grid.size}, {n}) (one row per output "
            f"time) or a callable {name}(t, state), got {getattr(a, 'shape', value)!r}"
        )
    if not np.all(np.isfinite(a)):
        raise ParameterError(f"{name} must be finite")
    return np.array(a)


def _pressure_input(model: Model, actuator, pressures, grid, tau, controller):
    """``(inputs, PressureInput, check)`` for ``simulate(pressures=..., actuator=...)``."""
    from softcurve.description.actuators import Actuator

    if not isinstance(actuator, Actuator):
        raise ParameterError(
            "pressures need actuator= a softcurve.Actuator (e.g. PneumaticActuator), "
            f"got {type(actuator).__name__}"
        )
    if tau is not None or controller is not None:
        raise ParameterError("give one of tau, pressures or a controller")
    actuator.check_robot(model.robot)
    inputs = _input_grid("pressures", pressures, actuator.n_inputs, grid)
    if not callable(inputs):
        for row in np.unique(inputs, axis=0):
            actuator.check_inputs(row)
    q, p = ca.SX.sym("q", model.n), ca.SX.sym("p", actuator.n_inputs)
    force = ca.Function("pressure_force", [q, p], [ca.mtimes(actuator.input_matrix_symbolic(q), p)])
    description = PressureInput(
        force, actuator.lower.copy(), actuator.upper.copy(), actuator.time_constant
    )
    return inputs, description, lambda value: actuator.check_inputs(value, "pressures returned")


def check_settings(t_final, dt, rtol, method, max_steps, methods=METHODS):
    """``(t_final, dt, rtol)`` as floats after the checks shared by :func:`simulate` and
    :func:`softcurve.batch.simulate_batch`; :class:`ParameterError` names a bad one."""
    t_final, dt = _positive("t_final", t_final), _positive("dt", dt)
    if dt > t_final:
        raise ParameterError(f"dt must be <= t_final, got dt={dt!r} > t_final={t_final!r}")
    rtol = _positive("rtol", rtol)
    if not rtol < 1:
        raise ParameterError(f"rtol must be < 1, got {rtol!r}")
    if method not in methods:
        raise ParameterError(f"method must be one of {', '.join(methods)}, got {method!r}")
    if isinstance(max_steps, bool) or not isinstance(max_steps, int | np.integer) or max_steps < 1:
        raise ParameterError(f"max_steps must be an integer >= 1, got {max_steps!r}")
    return t_final, dt, rtol


def _controller(controller):
    if controller is None:
        return None
    if not callable(controller):
        raise ParameterError("controller must be callable as controller(t, q, qd, lam) -> tau")
    return _positive("controller.sample_time", getattr(controller, "sample_time", None))


# -- the simulation ------------------------------------------------------------------------
def simulate(
    model: Model,
    t_final: float,
    q0,
    qd0,
    lam0=None,
    tau=None,
    dt: float = 1e-3,
    *,
    method: str = "cvodes",
    rtol: float = 1e-6,
    atol=None,
    controller=None,
    pressures=None,
    actuator=None,
    max_steps: int = 50_000,
    progress: bool = False,
) -> Trajectory:
    """Integrate the equation of motion from ``(q0, qd0, lam0)`` to ``t_final``.

    Parameters
    ----------
    model : Model
    t_final : float
        End time [s], > 0.
    q0, qd0 : array_like (n,)
        Initial coordinates and rates.
    lam0 : array_like (n_creep,), optional
        Initial creep states (default zero).
    tau : None, array_like (n,) or (T, n), or callable
        Input forces, see the module notes (default zero).
    dt : float
        Output interval [s], default 1 ms; ``dt <= t_final``. Integration steps are
        chosen by error control, independently of ``dt``.
    method : {"cvodes", "adams", "bdf", "rk45"}
        See the module notes.
    rtol : float
        Relative tolerance (default 1e-6).
    atol : float or array_like (n_state,), optional
        Absolute tolerance per state; default ``rtol * nominal_scale(model, x0)``, i.e.
        errors are relative to ``max(|x|, the state's natural scale)``.
    controller : object, optional
        ``sample_time`` [s] and ``__call__(t, q, qd, lam) -> tau`` (zero-order hold);
        ``reset()`` is called first if present. Replaces ``tau``.
    pressures : array_like (m,) or (T, m), or callable, optional
        Pressures [Pa, gauge] instead of ``tau``, in the forms ``tau`` takes, within the
        actuator's bounds. The input force is ``H(q) p`` with ``H`` of ``actuator``,
        evaluated along the trajectory inside the integrator (not held). Without a
        ``time_constant`` they are the chamber pressures; with one they are commands and
        the chamber pressures are integrated states, ``p' = (command - p) /
        time_constant``, starting at zero gauge pressure.
    actuator : Actuator, optional
        The pressure map for ``pressures`` (required with them).
    max_steps : int
        Internal steps allowed between two output times.
    progress : bool
        Show a progress bar on stderr when the run takes longer than a second.

    Returns
    -------
    Trajectory
        With ``status`` "failed" and the trajectory up to the failure if the integrator stops.
    """
    if not isinstance(model, Model):
        raise ParameterError(f"model must be a softcurve.Model, got {type(model).__name__}")
    t_final, dt, rtol = check_settings(t_final, dt, rtol, method, max_steps)
    x0 = np.concatenate(
        [
            _finite_vector("q0", q0, model.n),
            _finite_vector("qd0", qd0, model.n),
            np.zeros(model.n_creep)
            if lam0 is None
            else _finite_vector("lam0", lam0, model.n_creep),
        ]
    )
    grid = _grid(t_final, dt)
    sample_time = _controller(controller)
    if controller is not None and tau is not None:
        raise ParameterError("give either tau or a controller, not both")
    pressure = check = None
    if pressures is not None or actuator is not None:
        if pressures is None:
            raise ParameterError("actuator is given without pressures: give pressures= too")
        inputs, pressure, check = _pressure_input(model, actuator, pressures, grid, tau, controller)
    else:
        inputs = _input_grid("tau", tau, model.n, grid) if controller is None else None
    nominal = nominal_scale(model, x0)
    if atol is None:
        atol_vector = rtol * nominal
    elif np.ndim(atol) == 0:
        atol_vector = np.full(model.n_state, _positive("atol", atol))
    else:
        atol_vector = _finite_vector("atol", atol, model.n_state)
        if not np.all(atol_vector > 0):
            raise ParameterError("atol must be > 0 in every entry")
    model_x0 = x0
    if pressure is not None and pressure.n_states:
        # lagging chamber pressures start at zero gauge (clipped into the bounds)
        p_start = np.clip(0.0, pressure.lower, pressure.upper)
        p_scale = np.maximum(np.abs(pressure.lower), np.abs(pressure.upper))
        x0 = np.concatenate([x0, p_start])
        nominal = np.concatenate([nominal, p_scale])
        atol_vector = np.concatenate([atol_vector, rtol * p_scale])

    stats = {"method": method, "rtol": rtol, "atol": atol_vector.tolist(), "dt": dt}
    settle = None  # at a restart: True once the robot has settled (then BDF)
    if method == "rk45":
        engine = ScipyEngine(model, rtol, atol_vector, max_steps, pressure)
    else:
        multistep = method
        if method == "cvodes":
            u0 = inputs[0] if isinstance(inputs, np.ndarray) else None
            if pressure is None:
                tau0 = np.zeros(model.n) if u0 is None else u0
            else:
                p0 = x0[model.n_state :] if pressure.n_states else u0
                p0 = np.zeros(pressure.n_inputs) if p0 is None else p0
                tau0 = np.array(pressure.force(model_x0[: model.n], p0)).ravel()
            ratio, fastest = linearisation_rates(model, model_x0, tau0, nominal[: model.n_state])
            stats["stiffness_ratio"] = ratio
            multistep = "bdf" if ratio > STIFFNESS_RATIO else "adams"
            if multistep == "adams" and pressure is None:

                def settle(x, tau):
                    return settled(model.state_derivative(x, tau), nominal, fastest)

        engine = CvodesEngine(model, multistep, rtol, atol_vector, nominal, max_steps, pressure)

    states = np.empty((grid.size, x0.size))
    states[0] = x0
    applied = np.zeros((grid.size, model.n if pressure is None else pressure.n_inputs))
    bar = _Progress(t_final) if progress else None
    start = time.perf_counter()
    try:
        if controller is None and not callable(inputs):
            applied[:] = inputs
            reached = _run_on_grid(engine, grid, states, inputs, bar, settle)
        else:
            reached = _run_sampled(
                engine, model, grid, states, applied, inputs, controller, sample_time, bar, check
            )
        failure = None
    except _Stopped as stop:
        reached, failure = stop.reached, stop.reason
    wall = time.perf_counter() - start
    if bar is not None:
        bar.close()
    stats.update(engine.counts, method=engine.method, wall_time=wall)
    if pressure is None:
        return _result(model, grid, states, applied, reached, failure, stats, method)
    q = states[:reached, : model.n]
    chamber = states[:reached, model.n_state :] if pressure.n_states else applied[:reached]
    forces = np.array(pressure.force.map(reached)(q.T, chamber.T)).T
    model_states = states[:, : model.n_state]
    trajectory = _result(model, grid, model_states, forces, reached, failure, stats, method)
    return dataclasses.replace(trajectory, pressures=chamber.copy())


class _Stopped(Exception):
    def __init__(self, reached: int, reason: str):
        self.reached, self.reason = reached, reason


def _run_on_grid(engine, grid, states, inputs, bar, settle=None) -> int:
    """All outputs in one call per restart segment (see ``RESTART_INTERVAL``), split
    further only to report progress; with ``settle``, each segment after the first is
    integrated with BDF when ``settle(x, tau)`` at its start, else Adams
    (``SETTLED_RATIO``)."""
    chunk = grid.size if bar is None else max(1, math.ceil((grid.size - 1) / 50))
    for k0, k1 in restart_segments(grid, RESTART_INTERVAL):
        if settle is not None and k0 > 0:
            engine.use("bdf" if settle(states[k0], inputs[k0]) else "adams")
        k = k0
        while k < k1:
            m = min(chunk, k1 - k)
            _advance(engine, grid, states, inputs, k, m)
            k += m
            if bar is not None:
                bar.update(grid[k])
    return grid.size


def _advance(engine, grid, states, inputs, k, m) -> None:
    """Fill states[k+1 : k+m+1] from states[k]; on failure retry point by point to keep
    every output reached, then raise _Stopped."""
    h = grid[k + m] - grid[k]
    tout = (grid[k + 1 : k + m + 1] - grid[k]) / h
    try:
        states[k + 1 : k + m + 1] = engine.advance(states[k], h, tout, inputs[k : k + m])
        _check_finite(states, k + 1, k + m + 1)
        return
    except IntegrationFailure as failure:
        reason, partial = failure.reason, failure.states
    done = k + partial.shape[0]
    states[k + 1 : done + 1] = partial
    if m > 1 and partial.shape[0] == 0 and engine.name == "cvodes":
        for j in range(k, k + m):
            _advance(engine, grid, states, inputs, j, 1)
        return
    raise _Stopped(done + 1, reason)


def _check_finite(states, a, b) -> None:
    bad = ~np.all(np.isfinite(states[a:b]), axis=1)
    if np.any(bad):
        first = a + int(np.argmax(bad))
        raise _Stopped(first, "the state became non-finite")


def _run_sampled(
    engine, model, grid, states, applied, inputs, controller, sample_time, bar, check=None
):
    """Piece by piece between output times and controller samples, input held; ``check``
    validates a value of a callable input (pressures within their bounds)."""
    n, n_state, width = model.n, model.n_state, applied.shape[1]
    if controller is not None:
        if callable(getattr(controller, "reset", None)):
            controller.reset()
        samples = np.arange(0.0, grid[-1], sample_time)
    else:
        samples = grid[:-1]
    tolerance = 1e-9 * min(grid[1] - grid[0], sample_time or np.inf)
    times = np.unique(np.concatenate([grid, samples]))
    times = times[np.concatenate([[True], np.diff(times) > tolerance])]
    sample_index = np.searchsorted(times, samples - tolerance)
    is_sample = np.zeros(times.size, bool)
    is_sample[sample_index] = True
    grid_index = np.searchsorted(times, grid - tolerance)
    current = np.zeros(width)
    x = states[0].copy()
    output = 0
    for i in range(times.size - 1):
        if is_sample[i]:
            q, qd, lam = x[:n], x[n : 2 * n], x[2 * n : n_state]
            if controller is not None:
                value = controller(times[i], q.copy(), qd.copy(), lam.copy())
            else:
                value = inputs(times[i], State(q.copy(), qd.copy(), lam.copy(), x[:n_state].copy()))
            current = _finite_vector("the input returned by the callable", value, width)
            if check is not None:
                current = check(current)
        while output < grid.size and grid_index[output] <= i:
            applied[output] = current
            output += 1
        h = times[i + 1] - times[i]
        try:
            x_next = engine.advance(x, h, np.ones(1), current[None, :])[0]
        except IntegrationFailure as failure:
            raise _Stopped(output, f"{failure.reason} (near t = {times[i]:.6g} s)") from None
        if not np.all(np.isfinite(x_next)):
            raise _Stopped(output, f"the state became non-finite near t = {times[i]:.6g} s")
        x = x_next
        if grid_index[output] == i + 1:
            states[output] = x
            if bar is not None:
                bar.update(times[i + 1])
    applied[output:] = current
    return grid.size


def _result(model, grid, states, applied, reached, failure, stats, method) -> Trajectory:
    n = model.n
    x = states[:reached]
    q, qd, lam = x[:, :n], x[:, n : 2 * n], x[:, 2 * n :]
    if failure is None:
        status = "success"
        message = (
            f"integrated to t = {grid[-1]:.6g} s with {stats['method']} in {stats['steps']} steps"
        )
    else:
        status = "failed"
        t_stop = grid[reached - 1]
        advice = ["loosen rtol/atol", "raise max_steps"]
        if stats["method"] != "cvodes-bdf":
            advice.insert(0, "method='bdf' if the problem is stiff")
        advice.append("check that the initial state and inputs are physical")
        message = (
            f"{failure}; the trajectory stops at t = {t_stop:.6g} s "
            f"(output {reached - 1} of {grid.size - 1}). What to try: " + "; ".join(advice)
        )
    return Trajectory(
        t=grid[:reached].copy(),
        q=q.copy(),
        qd=qd.copy(),
        lam=lam.copy(),
        tau=applied[:reached].copy(),
        stats=stats,
        status=status,
        message=message,
        model=model,
    )


class _Progress:
    """A one-line progress bar on stderr that appears once a run has taken a second."""

    def __init__(self, total: float, delay: float = 1.0, stream=None):
        self.total, self.delay = total, delay
        self.stream = stream or sys.stderr
        self.start = time.perf_counter()
        self.shown = False

    def update(self, t: float) -> None:
        elapsed = time.perf_counter() - self.start
        if elapsed < self.delay:
            return
        fraction = min(1.0, t / self.total)
        filled = int(30 * fraction)
        eta = elapsed * (1 - fraction) / max(fraction, 1e-12)
        self.stream.write(
            f"\r[{'#' * filled}{'.' * (30 - filled)}] {100 * fraction:5.1f}% "
            f"t = {t:.3g} s, {elapsed:.1f} s elapsed, ~{eta:.0f} s left "
        )
        self.stream.flush()
        self.shown = True

    def close(self) -> None:
        if self.shown:
            self.stream.write("\n")
            self.stream.flush()


TauCallable = Callable[[float, State], np.ndarray]
