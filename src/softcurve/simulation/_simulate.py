"""Simulation of eq. (16) with creep (eq. 19): :func:`simulate`, returning a :class:`Trajectory`.

The state is ``x = (q, qd, lam)``. Output is on a fixed grid ``t_k = k dt``; between
output times the integrator chooses its own steps under error control.

Integrators (``method``)
------------------------
``"cvodes"`` (default)
    SUNDIALS CVODES in compiled code (through CasADi), on the model's compiled
    right-hand side: a 10 s run of the paper's case never returns to Python. CVODES
    offers Adams-Moulton (orders 1-12, efficient on smooth non-stiff problems; capped at
    5 here, ``softcurve.simulation.solvers.MAX_ORDER``) and BDF (orders 1-5, stable on
    stiff ones); ``"cvodes"`` picks per problem from the linearization at the initial state:
    if the fastest decay rate exceeds the fastest oscillation frequency
    ``STIFFNESS_RATIO`` times (a decaying mode far faster than anything that must be
    resolved), BDF, otherwise Adams. The paper's case has its
    fastest decay (creep, 284 1/s) next to its fastest oscillation (247 rad/s): Adams.
    Where Adams was chosen, each restart segment after the first is integrated with BDF
    once the robot has settled (it moves a thousand times slower than its fastest mode,
    ``softcurve.simulation.solvers.SETTLED_RATIO``), and with Adams again if it moves; the method
    is then reported as ``"cvodes-adams+bdf"``. With actuator inputs, a controller or a
    callable input the family chosen at the start is kept.
``"auto"``
    Radau IIA (below) where the input given on the output grid changes on average within
    ``AUTO_INTERVAL`` over the fastest rate of the initial linearization (a slow input
    sampled often, where CVODES would restart at every sample), else ``"cvodes"``; the
    result says which and why in ``stats["method_reason"]``.
``"adams"``, ``"bdf"``
    CVODES with that family, no choice made.
``"radau"``
    Radau IIA of order 5 (three implicit stages), in softcurve's C driver: L-stable and of
    order 5 at any stiffness, a one-step method that restarts at a change of the input
    with nothing to rebuild, its two Newton matrices (one real, one complex) factored per
    step size and Jacobian and kept while the iteration converges. Cheaper than CVODES
    where fast modes die out while the motion is slow (after a transient, under slow
    inputs); dearer where the motion itself is fast (``docs/performance.md``). Where the
    driver cannot run, SciPy's Radau stepped from Python (route ``"scipy-radau"``).
``"rk45"``
    SciPy's explicit Runge-Kutta 4(5) of Dormand and Prince (the paper's ``ode45``)
    on the same compiled right-hand side, stepped from Python: 5-10x slower, for
    comparison and for robots where an explicit method is wanted.

How CVODES runs, measured on the paper's case (``benchmarks/bench_simulate.py``,
``docs/performance.md``): softcurve's C driver (``softcurve.simulation.solvers._driver``)
calls the library that :class:`~softcurve.Model` has already compiled, keeps the Newton
matrix's Jacobian while CVODES allows and integrates the whole output grid in one call:
about 3x faster than CasADi's CVODES integrator on the same library, which remains the
route where the driver cannot be built. With the right-hand side in CasADi's virtual
machine (``Model(robot, compile=False)``) the integration takes about 10x longer.
Multistep histories cannot cross a jump of the input, so the integrator restarts
wherever the input changes, and also every ``RESTART_INTERVAL`` (1 s) of simulated time:
after a transient, a method left at high order is stability-bound on the fast damped
modes of a robot at rest; a restart halves the steps of the paper's case (see
:data:`~softcurve.simulation.solvers.RESTART_INTERVAL`).

Inputs
------
``tau`` is None (zero), a constant (n,), an array (T, n) on the output grid (held
constant over ``[t_k, t_k+1)``), or a callable ``tau(t, state)`` with ``state`` a
:class:`State` (``q``, ``qd``, ``lam``, ``x``), evaluated at every output time and held
(zero-order hold). A ``controller`` (an object with ``sample_time`` [s] and
``__call__(t, q, qd, lam)``, optionally ``reset()``) is sampled every ``sample_time``
and its output held between samples. Give one of ``tau``, ``inputs`` or a ``controller``.

With an ``actuator`` (any :class:`~softcurve.Actuator`: pneumatic bellows, tendons, ...)
the robot is driven by the actuator's inputs ``u`` instead: ``inputs`` takes the forms
``tau`` takes, with ``m`` columns, and a controller returns ``u`` (m,). Every value is
checked against the actuator's bounds, and the force ``H(q) u`` is evaluated along the
trajectory inside the integrator (not held). With the actuator's ``time_constant`` the
given inputs are commands and the actuator's inputs are integrated states,
``u' = (command - u) / time_constant``, starting at ``actuator_state`` (default: zero
clipped into the bounds).
Inputs that need Python at run time integrate piece by piece and are slower.
"""

from __future__ import annotations

import time

import numpy as np

from softcurve.base.progress import ProgressLine
from softcurve.base.status import Status
from softcurve.base.validation import ParameterError, real_array
from softcurve.compiled import Model
from softcurve.description.actuator import Actuator
from softcurve.simulation._settings import SimulationSettings, sample_time, settings_with
from softcurve.simulation.results import Trajectory
from softcurve.simulation.solvers import (
    ActuatorInput,
    Domain,
    Problem,
    Stopped,
    actuator_exit,
    auto_method,
    change_interval,
    choose_route,
    failure_message,
    failure_status,
    grid_inputs,
    initial_state,
    input_changes,
    lag_scale,
    linearization_rates,
    multistep_family,
    run_on_grid,
    run_sampled,
    solver,
    state_scale,
    success_message,
)


# -- argument checks -----------------------------------------------------------------------
def _input_grid(name: str, value, n: int, grid: np.ndarray, actuator=None):
    """Constant / on-grid inputs as a (T, n) array, checked (:func:`grid_inputs`, within
    ``actuator``'s bounds where given); callables come back unchanged."""
    if callable(value):
        return value
    also = f" or a callable {name}(t, state)"
    return grid_inputs(name, value, n, grid.size, actuator, also)


def _drive(model: Model, grid, tau, controller, actuator, inputs):
    """``(values, actuator input or None, check)``: what drives the robot. ``values`` are
    the (T, width) inputs on the grid, a callable, or None under a controller; ``check``
    validates a value returned at run time."""
    drives = {"tau": tau, "inputs": inputs, "controller": controller}
    given = [name for name, value in drives.items() if value is not None]
    if len(given) > 1:
        raise ParameterError(f"give one of tau, inputs or a controller, got {' and '.join(given)}")
    if actuator is None:
        if inputs is not None:
            raise ParameterError("inputs are an actuator's: give actuator= too (an Actuator)")

        def check(value, source):
            return np.array(real_array(f"the {source}'s tau", value, (model.n,)))

        values = None if controller is not None else _input_grid("tau", tau, model.n, grid)
        return values, None, check
    if not isinstance(actuator, Actuator):
        raise ParameterError(
            f"actuator must be a softcurve.Actuator (e.g. PneumaticActuator), "
            f"got {type(actuator).__name__}"
        )
    if tau is not None or (inputs is None and controller is None):
        raise ParameterError(
            "with an actuator, give inputs= (the actuator's inputs) or a controller that "
            "returns them"
        )
    actuator.check_robot(model.robot)
    values = None
    if controller is None:
        values = _input_grid("inputs", inputs, actuator.n_inputs, grid, actuator)

    def check_inputs(value, source):
        return actuator.check_inputs(value, f"the {source}'s {actuator.input_name}")

    return values, ActuatorInput.of(actuator, model.n), check_inputs


def _constant(value, width: int) -> bool:
    """Whether an input given as ``value`` is one value on the whole grid (None or one
    row of ``width``): it has no changes to look for."""
    return value is None or (not callable(value) and np.shape(value) == (width,))


def _sample_time(controller, settings):
    if controller is None:
        return None
    if not callable(controller):
        raise ParameterError("controller must be callable as controller(t, q, qd, lam)")
    return sample_time("controller.sample_time", getattr(controller, "sample_time", None), settings)


# -- the simulation ------------------------------------------------------------------------
def simulate(
    model: Model,
    q0,
    qd0,
    lam0=None,
    *,
    tau=None,
    controller=None,
    actuator: Actuator | None = None,
    inputs=None,
    actuator_state=None,
    settings: SimulationSettings | None = None,
    progress: bool = False,
    **options,
) -> Trajectory:
    """Integrate the equation of motion from ``(q0, qd0, lam0)`` to ``t_final``.

    Parameters
    ----------
    model : Model
        The compiled model of the robot.
    q0 : array_like, shape (n,)
        Initial coordinates ``(l, kx, ky)`` per segment [m, 1/m, 1/m].
    qd0 : array_like, shape (n,)
        Initial rates [m/s, 1/(m s), 1/(m s)].
    lam0 : array_like, shape (n_creep,), optional
        Initial creep states (default zero).
    tau : None, array_like (n,) or (T, n), or callable
        Generalized input forces [N, N m^2, N m^2], see the module notes (default zero).
    controller : object, optional
        ``sample_time`` [s] and ``__call__(t, q, qd, lam)`` returning ``tau`` (n,), or with
        an ``actuator`` its inputs (m,), held between samples; ``reset()`` is called first
        if present.
    actuator : Actuator, optional
        Drive the robot by this actuator's inputs (``inputs`` or a controller's output)
        through the force ``H(q) u``.
    inputs : None, array_like (m,) or (T, m), or callable
        The actuator's inputs (e.g. pressures [Pa, gauge]) in the forms ``tau`` takes,
        within the actuator's bounds; commands when the actuator has a ``time_constant``.
    actuator_state : array_like, shape (m,), optional
        Initial inputs of an actuator with a ``time_constant`` (e.g. the chambers'
        pressures at the start [Pa]), within its bounds (default: zero clipped into
        them).
    settings : SimulationSettings, optional
        End time, output interval, integrator, tolerances, step budget (default
        :class:`SimulationSettings`).
    progress : bool
        Show a progress bar on stderr when the run takes longer than a second.
    **options : dict
        Fields of :class:`SimulationSettings` overriding ``settings``: ``t_final`` [s],
        ``dt`` [s], ``method``, ``rtol``, ``atol``, ``max_steps``.

    Returns
    -------
    Trajectory
        On failure, status ``INTEGRATION_FAILED``, or ``LEFT_DOMAIN`` where the state left
        the model's domain at an output time (a length ``l <= 0`` or beyond ``MAX_STRETCH``
        rest lengths, a bend beyond ``MAX_BEND``, a non-finite value; see
        :meth:`~softcurve.Robot.check_configuration`) or became non-finite, with a message
        naming the time, the coordinate and the likely cause; the trajectory is kept up to
        the last output inside the domain. With an actuator, its domain (every tendon
        length and chamber volume > 0, :meth:`Actuator.in_domain
        <softcurve.description.actuator.Actuator.in_domain>`) is checked at the output
        times: the trajectory stops before the first output outside it, ``LEFT_DOMAIN``
        naming the actuator element; ``q0`` outside it is refused.

    Examples
    --------
    >>> import softcurve as sc
    >>> model = sc.Model(sc.presets.ifac2020())
    >>> run = sc.simulate(model, [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0], t_final=0.2, dt=0.01)
    >>> run.success, run.q.shape
    (True, (21, 3))
    """
    if not isinstance(model, Model):
        raise ParameterError(f"model must be a softcurve.Model, got {type(model).__name__}")
    settings = settings_with(settings, options, "simulate")
    x0 = initial_state(model, q0, qd0, lam0)
    grid = settings.output_times()
    sample_time = _sample_time(controller, settings)
    values, actuated, check = _drive(model, grid, tau, controller, actuator, inputs)
    model_x0 = x0
    if actuator_state is not None and actuator is None:
        raise ParameterError("actuator_state is an actuator's initial state: give actuator= too")
    if actuator is not None:
        start = actuator.lag_start(actuator_state)
        problem = actuator.domain_problem(model_x0[: model.n])
        if problem is not None:
            raise ParameterError(f"q0: {problem}")
    nominal = state_scale(model, x0, actuated)
    atol = settings.atol_vector(nominal[: model.n_state])
    if actuated is not None and actuated.n_states:
        x0 = np.concatenate([x0, start])
        atol = np.concatenate([atol, settings.rtol * lag_scale(actuated)])

    method, rtol = settings.method, settings.rtol
    on_grid = controller is None and not callable(values)
    width = model.n if actuated is None else actuated.n_inputs
    # the output indices where an input on the grid changes, where known: none for one value
    constant = on_grid and _constant(tau if actuated is None else inputs, width)
    changes = np.empty(0, dtype=int) if constant else None
    rates, chosen = None, {}
    if method in ("cvodes", "auto"):
        tau0 = _initial_force(model, model_x0, x0, values, actuated)
        rates = linearization_rates(model, model_x0, tau0, nominal[: model.n_state])
    if method == "auto":
        if on_grid and changes is None:
            changes = input_changes(values)
        interval = change_interval(grid, changes) if on_grid else None
        method, chosen["method_reason"] = auto_method(rates[1], interval, not on_grid)
    route = choose_route(
        "simulate", method, model=model, inputs=actuated, jacobian=settings.jacobian
    )
    stats = {"method": method, "route": route.name, "route_reason": route.reason,
             "rtol": rtol, "atol": atol.tolist(), "dt": settings.dt, **chosen}  # fmt: skip
    fastest = None  # at a restart: BDF once the robot moves slower than this allows
    multistep = method
    if method == "cvodes":
        ratio, fastest = rates
        stats["stiffness_ratio"] = ratio
        multistep = multistep_family(ratio, model.environment is not None)
        if multistep != "adams" or actuated is not None:
            fastest = None
    described = Problem(model, actuated, nominal, atol, rtol, settings.max_steps, grid)
    engine = solver(route, described, multistep)

    states = np.empty((grid.size, x0.size))
    states[0] = x0
    # on the grid, the inputs applied are the values (an array of this run's own)
    applied = values if on_grid else np.zeros((grid.size, width))
    bar = ProgressLine(settings.t_final, unit="s simulated", delay=1.0) if progress else None
    start_time = time.perf_counter()
    try:
        if on_grid:
            domain = Domain(model, grid)
            reached = run_on_grid(engine, grid, states, values, bar, domain, fastest, changes)
        else:
            reached = run_sampled(
                engine, model, grid, states, applied, values, controller, sample_time, bar, check
            )
        failure = None
    except Stopped as stop:
        reached, failure = stop.reached, stop.reason
    finally:  # also on an error: its line outside a terminal stops
        if bar is not None:
            bar.close()
    wall = time.perf_counter() - start_time
    stats.update(engine.counts, method=engine.method, wall_time=wall)
    return _result(model, grid, states, applied, reached, failure, stats, actuated, actuator)


def _initial_force(model, model_x0, x0, values, actuated) -> np.ndarray:
    """The generalized force at the start, for the linearization that picks the method."""
    u0 = values[0] if isinstance(values, np.ndarray) else None
    if actuated is None:
        return np.zeros(model.n) if u0 is None else u0
    start = x0[model.n_state :] if actuated.n_states else u0
    start = np.zeros(actuated.n_inputs) if start is None else start
    return np.array(actuated.force(model_x0[: model.n], start)).ravel()


def _result(
    model, grid, states, applied, reached, failure, stats, actuated, actuator
) -> Trajectory:
    n = model.n
    left = actuator_exit(actuator, grid[:reached], states[:reached, :n])
    if left is not None:  # the recorded outputs left the actuator's domain first
        reached, failure = left
    # views, not copies: states, applied and the grid belong to this run alone (copying a
    # long run's columns cost a quarter of a millisecond per 10,000 outputs); a run that
    # stopped early is copied, so it does not hold the rows it never reached
    t = grid
    if reached < grid.size:
        states, applied, t = (a[:reached].copy() for a in (states, applied, grid))
    x = states[:reached]
    q, qd, lam = x[:, :n], x[:, n : 2 * n], x[:, 2 * n : model.n_state]
    if actuated is None:
        forces, inputs = applied[:reached], None
    else:
        inputs = x[:, model.n_state :] if actuated.n_states else applied[:reached]
        forces = actuated.forces(q, inputs) if reached else np.empty((0, n))
    if failure is None:
        status = Status.SUCCESS
        message = success_message(grid[-1], stats["method"]) + f" in {stats['steps']} steps"
    else:
        status = failure_status(failure)
        message = failure_message(failure, grid, reached, stats["method"])
    return Trajectory(
        t=t,
        q=q,
        qd=qd,
        lam=lam,
        tau=forces,
        inputs=inputs,
        stats=stats,
        status=status,
        message=message,
        model=model,
        actuator=actuator,
    )
