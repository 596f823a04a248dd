"""Stepping a simulation along its output grid: on the grid (whole restart segments in
compiled code) and sampled (inputs computed in Python at output times or
controller samples, held in between), with the progress bar of long runs; both stop at
the first output outside the model's domain (:func:`outside_domain`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from softcurve.base.validation import ParameterError, float_array
from softcurve.simulation.solvers._policy import (
    LEFT_DOMAIN,
    RESTART_INTERVAL,
    IntegrationFailure,
    restart_segments,
    settled,
)


@dataclass(frozen=True)
class State:
    """The state passed to a ``tau(t, state)`` or ``inputs(t, state)`` callable.

    Parameters
    ----------
    q : ndarray, shape (n,)
        Coordinates [m, 1/m, 1/m].
    qd : ndarray, shape (n,)
        Rates [m/s, 1/(m s), 1/(m s)].
    lam : ndarray, shape (n_creep,)
        Creep states, three per segment with creep [unit of the coordinate times that
        of ``Creep.gain``].
    x : ndarray, shape (n_state,)
        ``(q, qd, lam)`` stacked.
    """

    q: np.ndarray
    qd: np.ndarray
    lam: np.ndarray
    x: np.ndarray


class Stopped(Exception):
    """The run stopped at output ``reached`` (exclusive) for ``reason``."""

    def __init__(self, reached: int, reason: str):
        self.reached, self.reason = reached, reason


def outside_domain(x: np.ndarray, robot, rest_lengths=None) -> np.ndarray:
    """Which states lie outside the model's domain: a configuration outside it
    (:meth:`Robot.inside <softcurve.description.robot.Robot.inside>`: e.g. ``0 < l <=
    MAX_STRETCH l0``, ``|kappa| l <= MAX_BEND``) or any entry non-finite. Vectorized over
    leading axes: the check of a simulation's outputs, once per call of the integrator.

    Parameters
    ----------
    x : ndarray, shape (..., n_state)
        States ``(q, qd, lam, ...)``.
    robot : Robot
        The robot.
    rest_lengths : array_like, shape (N,) or (..., N), optional
        Rest length ``l0`` [m] of each element where it differs from the robot's (per
        state).
    """
    inside = robot.inside(x[..., : robot.n], rest_lengths)
    return ~(inside & np.all(np.isfinite(x), axis=-1))


def domain_reason(x: np.ndarray, robot, t: float, rest_lengths=None) -> str:
    """Why the state ``x`` at time ``t`` [s] is outside the domain, naming the coordinate
    and its value (a run's failure reason, starting with :data:`LEFT_DOMAIN`).

    Parameters
    ----------
    x : ndarray, shape (n_state,)
        The state.
    robot : Robot
        The robot.
    t : float
        Its time [s].
    rest_lengths : array_like, shape (N,), optional
        Rest length ``l0`` [m] of each element where it differs from the robot's.
    """
    n = robot.n
    problem = robot.domain_problem(x[:n], entry="q", rest_lengths=rest_lengths)
    if problem is None:
        bad = int(np.argmax(~np.isfinite(x)))
        names = ("qd", bad - n) if bad < 2 * n else ("lam", bad - 2 * n)
        problem = f"{names[0]}[{names[1]}] = {x[bad]} is not finite"
    return f"{LEFT_DOMAIN} at t = {t:.6g} s: {problem}"


def actuator_exit(actuator, t: np.ndarray, q: np.ndarray) -> tuple[int, str] | None:
    """The first output at which the recorded configurations leave the actuator's domain
    (a tendon length or chamber volume <= 0, :meth:`Actuator.in_domain
    <softcurve.description.actuator.Actuator.in_domain>`), as ``(index, reason)``, the
    reason starting with :data:`LEFT_DOMAIN` and naming the actuator element; None when
    every output lies inside. The actuator's domain is checked at the output times, once
    per run, where its result is assembled (every integration route).

    Parameters
    ----------
    actuator : Actuator or None
        The actuator driving the run (None: nothing to check).
    t : ndarray, shape (T,)
        Output times [s].
    q : ndarray, shape (T, n)
        Configurations at them [m, 1/m, 1/m].
    """
    if actuator is None or not len(q):
        return None
    outside = ~actuator.in_domain(q) & np.all(np.isfinite(q), axis=-1)
    if not outside.any():
        return None
    k = int(np.argmax(outside))
    return k, f"{LEFT_DOMAIN} at t = {t[k]:.6g} s: {actuator.domain_problem(q[k])}"


class Domain:
    """The check of a run's outputs against the model's domain
    (:func:`outside_domain`), vectorized over the outputs
    of one call of the integrator.

    Parameters
    ----------
    model : Model
        The compiled model (its robot's rest lengths).
    grid : ndarray, shape (T,)
        Output times [s].
    """

    def __init__(self, model, grid):
        self.n, self.robot, self.grid = model.n, model.robot, grid

    def check(self, states, a: int, b: int) -> None:
        """Raise :class:`Stopped` at the first of ``states[a:b]`` outside the domain."""
        bad = outside_domain(states[a:b], self.robot)
        if np.any(bad):
            first = a + int(np.argmax(bad))
            reason = domain_reason(states[first], self.robot, self.grid[first])
            raise Stopped(first, reason)


def run_on_grid(engine, grid, states, inputs, bar, domain, fastest=None, changes=None) -> int:
    """All outputs in one call per restart segment (see ``RESTART_INTERVAL``), or with
    CVODES's C driver the whole grid in one call; with ``fastest``, each segment after the
    first is integrated with BDF once the robot has settled, else Adams
    (``SETTLED_RATIO``).

    A progress bar is drawn between restart segments: the C driver then runs one call per
    segment, choosing the family of each in Python by the rule the driver applies inside
    its one call (:func:`~softcurve.simulation.solvers.settled`), so the route and the
    trajectory are those without the bar, bit for bit (``tests/test_routes.py``); the
    driver reports no progress from inside a call. Radau IIA's calls each start afresh
    (a first step size and Jacobian), so its trajectory with the bar is the one without
    it to the tolerance, not bit for bit (``tests/test_radau.py``).

    Parameters
    ----------
    engine : Solver
        The integrator (:class:`~softcurve.simulation.solvers.Solver`).
    grid : ndarray, shape (T,)
        Output times [s].
    states : ndarray, shape (T, n_state [+ m])
        Filled in place from row 0.
    inputs : ndarray, shape (T, width)
        Input per output interval.
    bar : ProgressLine or None
        The progress bar, counting simulated seconds.
    domain : Domain
        The check of every output against the model's domain.
    fastest : float, optional
        Fastest rate of the initial linearization [1/s]: switch to BDF at a restart once
        settled (:func:`~softcurve.simulation.solvers.settled`).
    changes : ndarray of int, optional
        The output indices where the input changes (:func:`input_changes`), where the
        caller knows them (empty: one value on every row); None: found here where the
        route needs them.
    """
    segments = restart_segments(grid, RESTART_INTERVAL)
    on_driver = getattr(engine, "native", None) is not None
    if on_driver:
        changes = input_changes(inputs) if changes is None else changes
        if bar is None:
            return _run_native(engine, grid, states, inputs, domain, segments, fastest, changes)
    model, nominal = getattr(engine, "model", None), getattr(engine, "nominal", None)
    for k0, k1 in segments:
        if fastest is not None and k0 > 0:
            rates = model.state_derivative(states[k0], inputs[k0])
            engine.use("bdf" if settled(rates, nominal, fastest) else "adams")
        if on_driver:
            _run_native(engine, grid, states, inputs, domain, [(k0, k1)], None, changes)
        else:
            _advance(engine, grid, states, inputs, k0, k1 - k0, domain)
        if bar is not None:
            bar.update(grid[k1])
    return grid.size


def _run_native(engine, grid, states, inputs, domain, segments, fastest, changes) -> int:
    """Outputs ``segments[0][0]`` to ``segments[-1][1]`` of :func:`run_on_grid` in one call
    of the C driver: segments end at the restarts and at the ``changes`` of the input
    (:func:`input_changes`); the driver stops at the first output outside the domain,
    which :class:`Domain` then words."""
    ends, restart = [], []
    bounds = np.array(segments).T
    # the changes strictly inside each segment, found for all segments in two searches
    first = changes.searchsorted(bounds[0], "right").tolist()
    stop = changes.searchsorted(bounds[1]).tolist()
    cuts = changes.tolist()
    for (_, k1), a, b in zip(segments, first, stop, strict=True):
        ends.extend(cuts[a:b])
        ends.append(k1)
        restart.append(True)
        restart.extend([False] * (b - a))
    start, last = segments[0][0], segments[-1][1]
    starts = np.array([start, *ends[:-1]], dtype=int)
    # the driver writes into the run's own array: no copy of the outputs
    span = states[start : last + 1]
    _, reached, flags = engine.run_native(
        span[:1], inputs[starts][None], grid[start : last + 1], np.array(ends) - start,
        restart, fastest, True, span[None],
    )  # fmt: skip
    done = start + int(reached[0])
    if flags[0] == 0:
        return last + 1
    domain.check(states, start + 1, done)
    if flags[0] == 1:  # outside by the driver's test, inside by Python's: stop there
        raise Stopped(done - 1, f"{LEFT_DOMAIN} at t = {grid[done - 1]:.6g} s")
    raise Stopped(done, engine.failure_reason(flags[0]))


def grid_inputs(name: str, value, n: int, size: int, actuator=None, also: str = ""):
    """Inputs given on an output grid, as a (size, n) array, checked: None is zero, one
    row (n,) is held at every output, (size, n) is a row per output time; finite, and
    within ``actuator``'s bounds where it is given (each distinct row checked once, by
    :meth:`Actuator.check_inputs <softcurve.description.actuator.Actuator.check_inputs>`).

    Parameters
    ----------
    name : str
        The argument's name, for the messages.
    value : None or array_like, shape (n,) or (size, n)
        The inputs, in each one's unit.
    n : int
        Inputs per output time.
    size : int
        Output times.
    actuator : Actuator, optional
        Whose bounds the rows must lie within (None: unbounded forces).
    also : str
        What else the caller accepts, appended to the shape message (e.g. ``" or a
        callable tau(t, state)"``).
    """
    held = value is None or np.shape(value) == (n,)
    if value is None:
        values = np.zeros((size, n))
    else:
        expected = f"shape ({n},) or ({size}, {n}) (one row per output time)"
        a = float_array(name, value, expected) if not isinstance(value, str) else None
        if a is not None and a.shape == (n,):
            a = np.broadcast_to(a, (size, n))
        if a is None or a.shape != (size, n):
            raise ParameterError(
                f"{name} must be None, shape ({n},), shape ({size}, {n}) (one row per output "
                f"time){also}, got {getattr(a, 'shape', value)!r}"
            )
        if not np.all(np.isfinite(a)):
            raise ParameterError(f"{name} must be finite")
        values = np.array(a)
    if actuator is not None:
        for row in values[:1] if held else np.unique(values, axis=0):
            actuator.check_inputs(row, name)
    return values


def input_changes(inputs: np.ndarray) -> np.ndarray:
    """The output indices ``k`` (ascending) where the input of interval ``k`` differs from
    that of interval ``k - 1``. Rows 1..T-2 and rows 0..T-3 are each one contiguous block
    of a C-ordered array, so one elementwise comparison of the blocks finds the differing
    entries: about three times faster than column by column on a 10,000-row grid, and
    NumPy's ``any(axis=1)`` over a few columns is slower still.

    Parameters
    ----------
    inputs : ndarray, shape (T, width)
        One row per output interval (the last row is unused).
    """
    rows, width = inputs.shape
    if rows < 3 or width == 0:
        return np.empty(0, dtype=int)
    flat = np.ascontiguousarray(inputs).ravel()
    changed = np.flatnonzero(flat[width:-width] != flat[: -2 * width]) // width + 1
    if changed.size < 2:
        return changed
    first = np.empty(changed.size, dtype=bool)  # the first differing entry of each row
    first[0] = True
    np.not_equal(changed[1:], changed[:-1], out=first[1:])
    return changed[first]


def change_interval(grid: np.ndarray, changes: np.ndarray) -> float | None:
    """The mean time [s] between changes of an input given on the output grid, where it
    changes at half of the output intervals or more, else None: what ``method="auto"``
    weighs (:func:`~softcurve.simulation.solvers.auto_method`).

    Parameters
    ----------
    grid : ndarray, shape (T,)
        Output times [s].
    changes : ndarray of int
        The output indices where the input changes (:func:`input_changes`).
    """
    count = changes.size
    return (grid[-1] - grid[0]) / (count + 1) if 2 * count >= grid.size - 1 else None


def _advance(engine, grid, states, inputs, k, m, domain) -> None:
    """Fill states[k+1 : k+m+1] from states[k], stopping at the first output outside the
    domain; on failure retry point by point to keep every output reached, then raise
    Stopped."""
    h = grid[k + m] - grid[k]
    tout = (grid[k + 1 : k + m + 1] - grid[k]) / h
    try:
        states[k + 1 : k + m + 1] = engine.advance(states[k], h, tout, inputs[k : k + m])
        domain.check(states, k + 1, k + m + 1)
        return
    except IntegrationFailure as failure:
        reason, partial = failure.reason, failure.states
    done = k + partial.shape[0]
    states[k + 1 : done + 1] = partial
    domain.check(states, k + 1, done + 1)
    if m > 1 and partial.shape[0] == 0 and engine.name == "cvodes":
        for j in range(k, k + m):
            _advance(engine, grid, states, inputs, j, 1, domain)
        return
    raise Stopped(done + 1, reason)


def run_sampled(engine, model, grid, states, applied, inputs, controller, sample_time, bar, check):
    """Piece by piece between output times and controller samples, input held;
    ``check(value, source)`` validates each value the callable or the controller returns
    (its shape, and the actuator's bounds). The run stops at the first output or sample
    whose state is outside the model's domain, before the controller sees it.

    Parameters
    ----------
    engine : CvodesEngine or ScipyEngine
        The integrator.
    model : Model
        The compiled model.
    grid : ndarray, shape (T,)
        Output times [s].
    states : ndarray, shape (T, n_state [+ m])
        Filled in place from row 0.
    applied : ndarray, shape (T, width)
        Filled with the input held at each output.
    inputs : callable or None
        ``inputs(t, state)``, or None under a controller.
    controller : object or None
        The controller.
    sample_time : float or None
        The controller's sample time [s].
    bar : ProgressLine or None
        The progress bar, counting simulated seconds.
    check : callable
        ``check(value, source) -> ndarray``, ``source`` "controller" or "callable" (for
        the message).
    """
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
                source = "controller"
            else:
                value = inputs(times[i], State(q.copy(), qd.copy(), lam.copy(), x[:n_state].copy()))
                source = "callable"
            try:
                current = check(value, source)
            except ParameterError as exc:
                raise ParameterError(f"{exc} (at t = {times[i]:.6g} s)") from None
        while output < grid.size and grid_index[output] <= i:
            applied[output] = current
            output += 1
        h = times[i + 1] - times[i]
        try:
            x_next = engine.advance(x, h, np.ones(1), current[None, :])[0]
        except IntegrationFailure as failure:
            raise Stopped(output, f"{failure.reason} (near t = {times[i]:.6g} s)") from None
        if outside_domain(x_next, model.robot):  # before a callable sees it
            reason = domain_reason(x_next, model.robot, times[i + 1])
            raise Stopped(output, reason)
        x = x_next
        if grid_index[output] == i + 1:
            states[output] = x
            if bar is not None:
                bar.update(times[i + 1])
    applied[output:] = current
    return grid.size
