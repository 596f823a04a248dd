"""Many simulations in one call: :func:`simulate_batch`, returning a
:class:`~softcurve.simulation.results.BatchTrajectory`.

A batch is ``B`` robots of one structure (one compiled model) that differ in their
initial states, constant inputs (forces, or an actuator's inputs and parameters:
``softcurve.simulation.batch._inputs``) and parameter values. The robot's parameter
vector is a run-time input of the compiled functions, so the whole batch is integrated by
one call of softcurve's C driver of CVODES (``softcurve.simulation.solvers._driver``) on the
compiled right-hand side (as :func:`~softcurve.simulation.simulate` does), the
members split over threads: the integration never returns to Python between members
(members driven by an actuator: one call per distinct set of actuator parameters). Where
the driver cannot be built, one CasADi CVODES integrator mapped over the members does the
same work about 3x slower (``docs/performance.md``).

Each member is integrated exactly as :func:`~softcurve.simulation.simulate`
would integrate it: the same scaled state (``nominal_scale`` of the member's own robot
and initial state), the same tolerances and, for ``method="cvodes"``, the same choice
between Adams and BDF per member. Results therefore agree with single simulations to
round-off (see ``tests/test_batch.py``). One difference: with an explicit ``atol``,
CVODES's one absolute tolerance of the scaled state is the tightest over the members
integrated together, so each member meets at least its own tolerance.
"""

from __future__ import annotations

import math
import time

import numpy as np

from softcurve.base.validation import ParameterError, whole_count
from softcurve.compiled import LANE_WIDTH, Model
from softcurve.description.actuator import Actuator
from softcurve.description.robot import Robot
from softcurve.simulation._settings import SimulationSettings, settings_with
from softcurve.simulation.batch._inputs import Drives, drive_arrays, member_rows
from softcurve.simulation.batch._members import MemberRun, integrate_native
from softcurve.simulation.batch._workers import (
    default_threads,
    model_description,
    run_in_processes,
    worker_model,
)
from softcurve.simulation.results import BatchTrajectory, batch_status, stop_at_actuator_domain
from softcurve.simulation.solvers import (
    Problem,
    Route,
    auto_method,
    batch_route,
    blocks,
    choose_route,
    chunks,
    linearization_rates,
    method_name,
    multistep_family,
    nominal_scale,
    restart_segments,
    rhs_along,
    settled,
    success_message,
)
from softcurve.symbolic.gaps import check_start

CHUNKS_PER_PROCESS = 4
"""Chunks of members per worker process: members differ in their cost (a violent
transient takes more steps), so smaller chunks handed out as workers finish balance the
load; each chunk costs one call across processes."""


class _RobotView:
    """What :func:`~softcurve.simulation.solvers.nominal_scale` reads of a model: its robot."""

    def __init__(self, robot: Robot):
        self.robot = robot


def _count(name: str, value, default: int) -> int:
    return whole_count(name, default if value is None else value)


def simulate_batch(
    model: Model,
    q0,
    qd0,
    lam0=None,
    *,
    tau=None,
    parameters=None,
    actuator: Actuator | None = None,
    inputs=None,
    actuator_parameters=None,
    actuator_state=None,
    settings: SimulationSettings | None = None,
    threads: int | None = None,
    processes: int | None = None,
    lanes: bool = True,
    **options,
) -> BatchTrajectory:
    """Integrate ``B`` robots of the structure of ``model`` from their initial states.

    Every array argument is per member, shape (B, k), or shared, shape (k,); ``B`` is
    the common first dimension of the per-member ones.

    Parameters
    ----------
    model : Model
        The compiled model; its robot gives the structure and the default parameters.
    q0 : array_like, shape (B, n) or (n,)
        Initial coordinates [m, 1/m, 1/m].
    qd0 : array_like, shape (B, n) or (n,)
        Initial rates [m/s, 1/(m s), 1/(m s)].
    lam0 : array_like, shape (B, n_creep) or (n_creep,), optional
        Initial creep states (default zero).
    tau : array_like, shape (B, n) or (n,), optional
        Constant input forces [N, N m^2, N m^2] (default zero).
    parameters : array_like, shape (B, n_p) or (n_p,), optional
        Parameter vectors in the order of ``model.robot.layout.names`` (default the
        model's); each is validated as a robot (:meth:`Robot.with_parameter_vector`).
    actuator : Actuator, optional
        Drive the members by this actuator's ``inputs`` instead of ``tau``: the force
        ``H(q) u`` is evaluated along each trajectory inside the integrator, as in
        :func:`~softcurve.simulation.simulate` (with the actuator's
        ``time_constant``, ``inputs`` are commands and the inputs start at zero).
    inputs : array_like, shape (B, m) or (m,), optional
        Constant actuator inputs per member [``actuator.input_unit``: Pa, N], within the
        actuator's bounds; required with ``actuator``.
    actuator_parameters : array_like, shape (B, k) or (k,), optional
        Actuator parameter vectors in the order of ``actuator.parameter_names()`` (e.g. a
        tendon's azimuth [rad], distance [m] and friction), default
        ``actuator.parameter_vector()``; each is validated as an actuator. Members with
        equal vectors share one integrator; each distinct vector builds its own (a few
        milliseconds).
    actuator_state : array_like, shape (B, m) or (m,), optional
        Initial inputs of an actuator with a ``time_constant`` per member (e.g. the
        chambers' pressures at the start [Pa]), within its bounds (default: zero clipped
        into them), as in :func:`~softcurve.simulation.simulate`.
    settings : SimulationSettings, optional
        As in :func:`~softcurve.simulation.simulate`; ``method`` is "cvodes"
        (chosen per member), "adams", "bdf", "radau" or "auto" (a member's input does
        not change: "cvodes"). Memory is ``B * T * (2 n + n_creep + 3)``
        doubles: use a coarser ``dt`` for large batches; the integration steps are chosen
        by error control, so a coarser grid keeps the accuracy. One integrator serves
        the batch, so a given ``atol`` is applied as the tightest ``atol / nominal`` over
        the members.
    threads : int, optional
        Threads over the members (default: the cores usable by this process).
    processes : int, optional
        Worker processes (default 1: the batch runs in this process on ``threads``
        threads). With more, the members are split into chunks of consecutive members
        (``CHUNKS_PER_PROCESS`` per worker), each integrated by a worker process on one
        thread; the workers are spawned at the first such call (about a second) and kept
        for later ones. With softcurve's C driver threads are as fast (it reads no
        clock); on CasADi's integrator, the fallback, processes are faster: it reads the
        process's CPU clock around every evaluation of the model, and the threads of one
        process contend for that clock (``benchmarks/bench_batch.py``). Results are
        identical either way, but with an ``atol`` given, which each worker applies as
        the tightest over its own members. Workers are spawned, so a script must call
        this under ``if __name__ == "__main__":``.
    lanes : bool
        Integrate consecutive members four at a time (of one actuator and one family,
        Adams or BDF) as one CVODES system on the state derivative in vector lanes
        (``docs/performance.md``), where the C compiler builds it (once per model,
        cached): the members share the group's steps, each within its tolerance.
        False integrates every member alone, as
        :func:`~softcurve.simulation.simulate` does (equal to it bit for bit), as
        ``method="radau"`` always does.
    **options : dict
        Fields of :class:`SimulationSettings` overriding ``settings``: ``t_final`` [s],
        ``dt`` [s], ``method``, ``rtol``, ``atol``, ``max_steps``.

    Returns
    -------
    BatchTrajectory
        Members that fail carry their status, message and the outputs reached.

    Examples
    --------
    >>> import softcurve as sc
    >>> model = sc.Model(sc.presets.ifac2020())
    >>> q0 = [[0.064, 5.0, 0.0], [0.064, -5.0, 0.0]]
    >>> batch = sc.simulate_batch(model, q0, [0.0, 0.0, 0.0], t_final=0.2, dt=0.01)
    >>> batch.success, batch.q.shape
    (True, (2, 21, 3))
    """
    if not isinstance(model, Model):
        raise ParameterError(f"model must be a softcurve.Model, got {type(model).__name__}")
    settings = settings_with(settings, options, "simulate_batch")
    if settings.method == "rk45":
        raise ParameterError(
            "method must be cvodes, auto, adams, bdf or radau in a batch, got 'rk45'"
        )
    threads = _count("threads", threads, default_threads())
    processes = _count("processes", processes, 1)
    n, n_creep = model.n, model.n_creep
    arrays = {
        "q0": member_rows("q0", q0, n),
        "qd0": member_rows("qd0", qd0, n),
        "lam0": member_rows("lam0", lam0, n_creep, np.zeros(n_creep)),
        "parameters": member_rows(
            "parameters", parameters, model.parameters.size, model.parameters
        ),
        **drive_arrays(model, tau, actuator, inputs, actuator_parameters, actuator_state),
    }
    sizes = {name: a.shape[0] for name, a in arrays.items() if a.shape[0] != 1}
    size = max(sizes.values(), default=1)
    for name, rows in sizes.items():
        if rows != size:
            raise ParameterError(
                f"{name} has {rows} rows, other inputs have {size}: one row per member"
            )
    arrays = {name: np.array(np.broadcast_to(a, (size, a.shape[1]))) for name, a in arrays.items()}
    x0 = np.hstack([arrays["q0"], arrays["qd0"], arrays["lam0"]])
    nominal, rest_lengths = _nominal(model, arrays["parameters"], x0, actuator)
    outside = ~model.robot.inside(arrays["q0"], rest_lengths)
    if np.any(outside):
        b = int(np.argmax(outside))
        problem = model.robot.domain_problem(
            arrays["q0"][b], entry=f"q0[{b}]", rest_lengths=rest_lengths[b]
        )
        raise ParameterError(f"q0[{b}] (member {b}): {problem}")
    if model.environment is not None:  # no member starts inside an obstacle
        for b in np.unique(arrays["q0"], axis=0, return_index=True)[1]:
            check_start(model.environment, model.robot, arrays["q0"][b], f"q0[{b}] (member {b})")
    atol = None if settings.atol is None else settings.atol_vector(nominal[0])  # (n_state,)
    if processes > 1 and size > 1:
        split = (min(processes, size), threads, lanes)
        return _in_processes(model, split, arrays, settings, actuator)
    drives = None
    if actuator is not None:
        drives = Drives.of(actuator, n, arrays["inputs"], arrays["actuator_parameters"])
        x0, nominal = drives.extended(x0, nominal, arrays.get("actuator_state"))
    scales = (nominal, atol, rest_lengths)
    return _integrate(model, x0, arrays, scales, settings, (threads, lanes), drives)


def _integrate(model, x0, arrays, scales, settings, how, drives) -> BatchTrajectory:
    """The batch in this process (see :func:`simulate_batch`); ``scales`` are the state
    scales of every member (B, N), the absolute tolerance of the model's states
    (n_state,) or None, and the rest lengths of every member (B, n_segments), ``how`` the
    threads and lanes, ``drives`` the actuator's (or None)."""
    threads, lanes = how
    params = arrays["parameters"]
    nominal, atol, rest_lengths = scales
    size, method, n_state = x0.shape[0], settings.method, model.n_state
    auto = {}
    if method == "auto":  # one input per member: no change of the input (auto_method)
        method, auto["method_reason"] = auto_method(0.0, None)
    grid = settings.output_times()
    # one problem of every member; the lagging inputs (after n_state) are held relative
    problem = Problem(model, None, nominal, atol, settings.rtol, settings.max_steps, grid,
                      params)  # fmt: skip
    if drives is None:
        u = tau = arrays["tau"]
    else:  # the force at the start chooses the family, as in simulate()
        u, tau = arrays["inputs"], drives.initial_forces(x0[:, : model.n], x0, arrays["inputs"])
    if method == "cvodes":
        state, scale = x0[:, :n_state], nominal[:, :n_state]
        ratios, fastest = linearization_rates(model, state, tau, scale, params, threads)
        initial = multistep_family(ratios, model.environment is not None)
    else:
        initial, fastest = np.full(size, method), None
    methods, used_bdf = initial, np.zeros(size, bool)
    states = np.full((size, grid.size, x0.shape[1]), np.nan)
    states[:, 0] = x0
    start = time.perf_counter()
    run = MemberRun(problem, threads, u, states, rest_lengths, drives)
    groups = [np.arange(size)] if drives is None else [
        np.flatnonzero(drives.group == g) for g in range(len(drives.inputs))]  # fmt: skip
    switch = fastest if method == "cvodes" and drives is None else None  # BDF once settled
    sizes = [g.size for g in groups]
    routes = _routes(model, method, drives, sizes, lanes, settings.jacobian)
    on_driver = all(route.built is not None for route in routes)
    if on_driver:
        native_bdf = integrate_native(run, initial, switch, [r.built for r in routes])
        used_bdf = native_bdf & (initial == "adams")
    else:  # every member on CasADi's integrator where one group cannot take the driver
        why = next(route.reason for route in routes if route.built is None)
        routes = [Route("casadi-cvodes", why)] * len(groups)
        if method == "radau":  # CasADi has no Radau IIA: its stiff family instead
            methods = initial = np.full(size, "bdf")
    member_routes = [""] * size
    for group, route in zip(groups, routes, strict=True):
        for b in group.tolist():
            member_routes[b] = route.name
    for k0, k1 in () if on_driver else restart_segments(grid):
        if method == "cvodes" and k0 > 0 and drives is None:  # as simulate(): BDF if settled
            xdot = rhs_along(model, np.nan_to_num(states[:, k0 : k0 + 1]), tau[:, None, :],
                             params, threads)[:, 0]  # fmt: skip
            methods = np.where(settled(xdot, nominal, fastest), "bdf", initial)
            used_bdf |= methods == "bdf"
        for multistep, group in ((m, g) for m in ("adams", "bdf") for g in groups):
            chosen = (methods[group] == multistep) & (run.reached[group] == grid.size)
            members = group[chosen]
            for block in blocks(members.size, k1 - k0 + 1, x0.shape[1] + u.shape[1]):
                run.integrate(multistep, members[block], k0, k1)
    wall = time.perf_counter() - start
    families = [method_name(m) for m in initial]
    for b in np.flatnonzero(used_bdf & (initial == "adams")):
        families[b] = "cvodes-adams+bdf"
    messages = run.messages
    for b in np.flatnonzero(run.reached == grid.size):
        messages[b] = success_message(settings.t_final, families[b])
    inputs = None
    if drives is not None:
        inputs = states[..., n_state:] if drives.lag else np.repeat(u[:, None, :], grid.size, 1)
        inputs = np.where(np.isnan(states[..., :1]), np.nan, inputs)  # NaN after a failure
    stats = {
        **auto,
        "methods": families,
        **_route_stats(member_routes, [route.reason for route in routes]),
        "rtol": settings.rtol,
        "abstol_scaled": problem.scaled_atol,
        "dt": settings.dt,
        "size": size,
        "threads": threads,
        "wall_time": wall,
        "simulated_time": float(np.sum(grid[run.reached - 1])),
    }
    x = states[..., :n_state]
    return _result(grid, x, inputs, arrays, run.status, messages, run.reached, stats, model,
                   None if drives is None else drives.actuator)  # fmt: skip


def _routes(model, method, drives, sizes, lanes, jacobian) -> list:
    """The route of each actuator group of a batch (one group without an actuator), of
    ``sizes`` members each, the driver's Newton matrix from ``jacobian``
    (:func:`~softcurve.simulation.solvers.choose_route`)."""
    kinds = [None] if drives is None else list(drives.inputs)
    return [
        choose_route(
            "batch",
            method,
            model=model,
            inputs=inputs,
            members=size,
            lanes=lanes,
            actuators=len(kinds),
            jacobian=jacobian,
        )
        for inputs, size in zip(kinds, sizes, strict=True)
    ]


def _result(t, x, inputs, arrays, member_status, messages, reached, stats, model, actuator):
    """The :class:`BatchTrajectory` of states ``x`` (B, T, n_state) and, with an actuator,
    its inputs (B, T, m), each member stopped where it left the actuator's domain."""
    outcome = (member_status, messages, reached)
    parameters = arrays.get("actuator_parameters")
    stop_at_actuator_domain(t, x, inputs, outcome, stats["methods"], actuator, parameters)
    status, message = batch_status(np.asarray(member_status, dtype=object))
    n = model.n
    return BatchTrajectory(
        t=t,
        q=x[..., :n],
        qd=x[..., n : 2 * n],
        lam=x[..., 2 * n :],
        tau=arrays.get("tau"),
        parameters=arrays["parameters"],
        member_status=member_status,
        member_message=messages,
        reached=reached,
        status=status,
        message=message,
        stats=stats,
        model=model,
        actuator=actuator,
        inputs=inputs,
        actuator_parameters=arrays.get("actuator_parameters"),
    )


def _nominal(model: Model, params: np.ndarray, x0: np.ndarray, actuator=None) -> tuple:
    """``(nominal_scale, rest lengths (B, N))`` of each member's own robot; validates
    every parameter vector, and the actuator against each member's robot (its fibers are
    laid along the robot it was built with: a member that changes a number they depend
    on, a strain segment's rest length or a rigid body's tip, is refused, not driven with
    the nominal geometry)."""
    robots: dict[bytes, _RobotView] = {model.parameters.tobytes(): _RobotView(model.robot)}
    nominal = np.empty_like(x0)
    rest_lengths = np.empty((x0.shape[0], model.robot.n_segments))
    for b in range(x0.shape[0]):
        key = params[b].tobytes()
        if key not in robots:
            try:
                robots[key] = _RobotView(model.robot.with_parameter_vector(params[b]))
                if actuator is not None:
                    actuator.check_robot(robots[key].robot)
            except ParameterError as exc:
                raise ParameterError(f"parameters[{b}]: {exc}") from None
        nominal[b] = nominal_scale(robots[key], x0[b])
        rest_lengths[b] = robots[key].robot.rest_lengths
    return nominal, rest_lengths


def _chunk(described, arrays, settings, actuator=None, lanes=True) -> tuple:
    """One chunk of a batch, in a worker process; the parent keeps the model (a Model
    holds a loaded library): ``described`` are the arguments of :func:`worker_model`."""
    model = worker_model(*described)
    rest = {k: a for k, a in arrays.items() if k not in ("q0", "qd0", "lam0")}
    chunk = simulate_batch(model, arrays["q0"], arrays["qd0"], arrays["lam0"], lanes=lanes,
                           settings=settings, threads=1, actuator=actuator, **rest)  # fmt: skip
    x = chunk.x if actuator is None else np.concatenate([chunk.x, chunk.inputs], axis=2)
    return chunk.member_status, chunk.member_message, chunk.reached, chunk.stats, x


def _in_processes(model, split, arrays, settings, actuator) -> BatchTrajectory:
    """:func:`simulate_batch` in chunks over ``processes`` worker processes, chunks of whole
    groups of each actuator's members (:func:`~softcurve.simulation.solvers.chunks`);
    ``threads`` is kept for what is later evaluated along the result in this process
    (tip, energy). ``split`` is ``(processes, threads, lanes)``."""
    processes, threads, lanes = split
    start = time.perf_counter()
    size = arrays["q0"].shape[0]
    kinds = np.zeros(size, int) if actuator is None else np.unique(
        arrays["actuator_parameters"], axis=0, return_inverse=True)[1].ravel()  # fmt: skip
    parts = chunks(kinds, LANE_WIDTH if lanes else 1, CHUNKS_PER_PROCESS * processes)
    described = model_description(model)
    rows = [{k: a[part] for k, a in arrays.items()} for part in parts]
    tasks = {c: (described, rows[c], settings, actuator, lanes) for c in range(len(parts))}
    done = dict(run_in_processes(_chunk, tasks, processes))
    member_status, messages, reached, stats, x = (
        list(part) for part in zip(*(done[c] for c in range(len(parts))), strict=True))  # fmt: skip
    order = np.argsort(np.concatenate(parts))  # the members' places among the chunks' rows
    member_status, reached = (np.concatenate(a)[order] for a in (member_status, reached))
    x, messages = np.concatenate(x)[order], [m for c in messages for m in c]
    messages = [messages[i] for i in order]
    methods = [m for s in stats for m in s["methods"]]
    member_routes = [r for s in stats for r in s["routes"]]
    member_routes = [member_routes[i] for i in order]
    stats = {
        **stats[0],
        "methods": [methods[i] for i in order],
        **_route_stats(member_routes, [s["route_reason"] for s in stats]),
        "size": size,
        "threads": threads,
        "processes": processes,
        "wall_time": time.perf_counter() - start,
        "simulated_time": float(sum(s["simulated_time"] for s in stats)),
    }
    n_state = model.n_state
    return _result(settings.output_times(), x[..., :n_state],
                   None if actuator is None else x[..., n_state:], arrays, member_status,
                   messages, reached, stats, model, actuator)  # fmt: skip


def _route_stats(member_routes: list, reasons: list) -> dict:
    """A batch's route entries of its ``stats``: one name (``batch_route``), each member's,
    and the reasons, each once."""
    return {
        "route": batch_route(member_routes),
        "routes": member_routes,
        "route_reason": "; ".join(sorted(set(reasons))),
    }


def simulated_seconds_per_second(batch: BatchTrajectory) -> float:
    """Throughput of a batch: simulated time summed over members per wall-clock second.

    Parameters
    ----------
    batch : BatchTrajectory
        A finished batch.
    """
    wall = batch.stats["wall_time"]
    return batch.stats["simulated_time"] / wall if wall > 0 else math.inf
