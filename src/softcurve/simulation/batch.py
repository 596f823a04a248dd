"""Many simulations in one call: :func:`simulate_batch` and its :class:`BatchTrajectory`.

A batch is ``B`` robots of one structure (one compiled model) that differ in their
initial states, constant inputs and parameter values. The robot's parameter vector is a
run-time input of the compiled functions, so the whole batch shares one CVODES integrator
built on the compiled right-hand side (as :func:`softcurve.simulate` does) and CasADi's
``map`` runs it over the batch in compiled code, split over threads: the integration
never returns to Python between members.

Each member is integrated exactly as :func:`softcurve.simulate` would integrate it: the
same scaled state (``nominal_scale`` of the member's own robot and initial state), the
same tolerances and, for ``method="cvodes"``, the same choice between Adams and BDF per
member. Results therefore agree with single simulations to round-off (see
``tests/test_batch.py``).
"""

from __future__ import annotations

import contextlib
import io
import math
import os
import time
from dataclasses import dataclass, field

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.compiled.model import Model
from softcurve.description.robot import Robot
from softcurve.simulation.engine import (
    BufferedCall,
    _cvodes_reason,
    cvodes_integrator,
    cvodes_options,
    linear_rates,
    restart_segments,
    settled,
)
from softcurve.simulation.simulate import (
    METHODS,
    STIFFNESS_RATIO,
    _grid,
    check_settings,
    nominal_scale,
)
from softcurve.simulation.trajectory import Trajectory
from softcurve.simulation.workers import in_processes


class _RobotView:
    """What :func:`softcurve.simulate.nominal_scale` reads of a model: its robot."""

    def __init__(self, robot: Robot):
        self.robot = robot


# -- the result ------------------------------------------------------------------------------
@dataclass(eq=False)
class BatchTrajectory:
    """``B`` trajectories on one output grid.

    Attributes
    ----------
    t : ndarray (T,)
        Output times [s], shared by all members.
    q, qd : ndarray (B, T, n)
        Coordinates and rates per member.
    lam : ndarray (B, T, n_creep)
        Creep states.
    tip : ndarray (B, T, 3)
        Tip positions in the world frame [m], computed on first access (as for
        :class:`~softcurve.Trajectory`).
    tau : ndarray (B, n)
        The constant input of each member.
    parameters : ndarray (B, n_p)
        The parameter vector of each member (``model.robot.parameter_names()``).
    status : ndarray (B,) of str
        "success" or "failed" per member.
    message : list of str
        What happened to each member.
    reached : ndarray (B,) of int
        Number of valid output times per member; after a failure the remaining entries
        of ``q``, ``qd``, ``lam`` and ``tip`` are NaN (never otherwise).
    stats : dict
        ``methods`` (per member), ``wall_time`` [s] of the integration, ``threads``,
        ``size``, ``simulated_time`` [s] (summed over members) and the tolerances.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    lam: np.ndarray
    tau: np.ndarray
    parameters: np.ndarray
    status: np.ndarray
    message: list
    reached: np.ndarray
    stats: dict = field(default_factory=dict)
    model: Model | None = field(default=None, repr=False)
    tip_positions: np.ndarray | None = field(default=None, repr=False)

    @property
    def tip(self) -> np.ndarray:
        """Tip positions (B, T, 3) [m]; NaN where the state is."""
        if self.tip_positions is None:
            q = self.q
            tip = _tip_along(self.model, np.nan_to_num(q), self.parameters, self.stats["threads"])
            tip[np.isnan(q[..., 0])] = np.nan
            self.tip_positions = tip
        return self.tip_positions

    @property
    def size(self) -> int:
        """Number of members ``B``."""
        return self.q.shape[0]

    def __len__(self) -> int:
        return self.size

    @property
    def success(self) -> np.ndarray:
        """(B,) bool: which members reached ``t_final``."""
        return self.status == "success"

    @property
    def x(self) -> np.ndarray:
        """States ``(q, qd, lam)``, shape (B, T, n_state)."""
        return np.concatenate([self.q, self.qd, self.lam], axis=2)

    def member_model(self, i: int) -> Model:
        """The compiled model with member ``i``'s parameters (shares the compiled library)."""
        if np.array_equal(self.parameters[i], self.model.parameters):
            return self.model
        return Model(
            self.model.robot.with_parameter_vector(self.parameters[i]),
            quadrature_nodes=self.model.quadrature_nodes,
        )

    def member(self, i: int) -> Trajectory:
        """Member ``i`` as the :class:`~softcurve.Trajectory` of a single simulation."""
        i = int(i)
        if not -self.size <= i < self.size:
            raise IndexError(f"member index {i} out of range for a batch of {self.size}")
        i %= self.size
        k = int(self.reached[i])
        stats = {key: value for key, value in self.stats.items() if key != "methods"}
        stats["method"] = self.stats["methods"][i]
        return Trajectory(
            t=self.t[:k].copy(),
            q=self.q[i, :k].copy(),
            qd=self.qd[i, :k].copy(),
            lam=self.lam[i, :k].copy(),
            tip_positions=self.tip[i, :k].copy(),
            tau=np.repeat(self.tau[i][None, :], k, axis=0),
            stats=stats,
            status=str(self.status[i]),
            message=self.message[i],
            model=self.member_model(i),
        )

    def plot(self, path=None, members: int = 50):
        """The tip position of the first ``members`` members against time, one panel per
        axis; written to ``path`` (format from the suffix) if given. Returns the figure."""
        from softcurve.figures import _pyplot, _save

        plt = _pyplot()
        figure, axes = plt.subplots(3, 1, sharex=True, figsize=(7.0, 6.0), layout="constrained")
        for row, axis in enumerate("xyz"):
            axes[row].plot(self.t, 1e3 * self.tip[:members, :, row].T, lw=0.6, alpha=0.7)
            axes[row].set_ylabel(f"tip {axis} [mm]")
        axes[-1].set_xlabel("time [s]")
        axes[0].set_title(f"{min(members, self.size)} of {self.size} members")
        return _save(figure, path, 110)

    def energy(self) -> np.ndarray:
        """Mechanical energy ``T + V`` [J] of every member at every output time, (B, T);
        NaN after a member's failure."""
        return _energy_along(self.model, self.q, self.qd, self.parameters, self.stats["threads"])


# -- compiled pieces -------------------------------------------------------------------------
def _mapped(function: ca.Function, size: int, threads: int) -> ca.Function:
    if size == 1:
        return function
    return function.map(size, "thread", threads) if threads > 1 else function.map(size)


BLOCK_DOUBLES = 1 << 22
"""Members per compiled call are limited so that one call's arrays hold about this many
doubles (32 MB): the transient copies CasADi and NumPy make stay small next to the result."""


def _blocks(size: int, count: int, width: int) -> list[slice]:
    """Consecutive member ranges of at most ``BLOCK_DOUBLES / (count * width)`` members."""
    step = max(1, min(size, BLOCK_DOUBLES // max(1, count * width)))
    return [slice(a, min(size, a + step)) for a in range(0, size, step)]


def _along(model, name, build, columns, parameters, threads) -> list[np.ndarray]:
    """Evaluate ``build() -> Function(*per_point_inputs, p)`` at every (member, time):
    ``columns`` are (B, T, k) arrays, ``parameters`` (B, n_p); returns (B, T, m) arrays."""
    size, count = columns[0].shape[:2]
    point = model.cached(name, build)
    shared = [point.n_in() - 1]  # p: one per member, shared by its time points
    over_time = model.cached(
        (name, count), lambda: point.map(f"{name}_along", "serial", count, shared, [])
    )
    width = sum(c.shape[2] for c in columns) + point.nnz_out()
    pieces = []
    for block in _blocks(size, count, width):
        members = block.stop - block.start
        mapped = _mapped(over_time, members, threads)
        inputs = [np.ascontiguousarray(c[block].reshape(members * count, -1).T) for c in columns]
        outputs = mapped(*inputs, parameters[block].T)
        outputs = outputs if isinstance(outputs, tuple | list) else (outputs,)
        pieces.append([np.asarray(o).T.reshape(members, count, -1) for o in outputs])
    return [np.concatenate(parts) for parts in zip(*pieces, strict=True)]


def _tip_along(model, q, parameters, threads) -> np.ndarray:
    def build():
        pose = model.function("pose")
        qs, p = ca.MX.sym("q", model.n), ca.MX.sym("p", model.parameters.size)
        return ca.Function("tip", [qs, p], [pose(qs, 1.0, p)[1]])

    return _along(model, "tip", build, [q], parameters, threads)[0]


def _energy_along(model, q, qd, parameters, threads) -> np.ndarray:
    def build():
        terms, potential = (
            model.function("dynamics_terms"),
            model.function("potential_energy"),
        )
        qs, qds = ca.MX.sym("q", model.n), ca.MX.sym("qd", model.n)
        p = ca.MX.sym("p", model.parameters.size)
        mass = terms(qs, qds, ca.MX.zeros(model.n_creep), p)[0]
        gravity, elastic = potential(qs, p)
        return ca.Function(
            "energy", [qs, qds, p], [0.5 * ca.dot(qds, mass @ qds) + gravity + elastic]
        )

    return _along(model, "energy", build, [q, qd], parameters, threads)[0][..., 0]


def _rhs_along(model, x, tau, parameters, threads) -> np.ndarray:
    """The state derivative at states ``x`` (B, K, n_state) with inputs ``tau`` (B, K, n)."""

    def build():
        rhs = model.function("rhs")
        xs, u = ca.MX.sym("x", model.n_state), ca.MX.sym("u", model.n)
        p = ca.MX.sym("p", model.parameters.size)
        return ca.Function("rhs_point", [xs, u, p], [rhs(xs, u, p)])

    return _along(model, "rhs_point", build, [x, np.array(tau)], parameters, threads)[0]


def _linear_rates(model, x0, tau, parameters, nominal, threads) -> tuple:
    """:func:`softcurve._engines.linear_rates` for every member at once: eigenvalues of the
    central-difference linearisation of the right-hand side at the initial state."""
    size, n_state = x0.shape
    steps = 1e-6 * nominal  # (B, n_state), as in the single simulation
    offsets = np.einsum("bi,ij->bij", steps, np.eye(n_state))
    points = np.concatenate([x0[:, None, :] + offsets, x0[:, None, :] - offsets], axis=1)
    taus = np.broadcast_to(tau[:, None, :], (size, 2 * n_state, model.n))
    values = _rhs_along(model, points, taus, parameters, threads)
    columns = (values[:, :n_state] - values[:, n_state:]) / (2 * steps[:, :, None])
    return linear_rates(np.linalg.eigvals(columns.transpose(0, 2, 1)))  # [b, i, j] = dxdot_i/dx_j


# -- input checks ----------------------------------------------------------------------------
def _rows(name: str, value, width: int, default=None) -> np.ndarray | None:
    """``value`` as (B, width) or (1, width) float64, finite; None stays None."""
    if value is None:
        return None if default is None else np.asarray(default, dtype=np.float64)[None, :]
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a real array of shape (B, {width})") from None
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != width or a.shape[0] < 1:
        raise ParameterError(
            f"{name} must have shape (B, {width}) or ({width},), got {np.shape(value)}"
        )
    bad = ~np.all(np.isfinite(a), axis=1)
    if np.any(bad):
        raise ParameterError(
            f"{name}[{int(np.argmax(bad))}] must be finite, got {a[np.argmax(bad)].tolist()}"
        )
    return a


def default_threads() -> int:
    """Cores usable by this process."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


# -- the batch simulation --------------------------------------------------------------------
def simulate_batch(
    model: Model,
    t_final: float,
    q0s,
    qd0s,
    lam0s=None,
    tau=None,
    parameters=None,
    dt: float = 1e-3,
    *,
    method: str = "cvodes",
    rtol: float = 1e-6,
    atol=None,
    max_steps: int = 50_000,
    threads: int | None = None,
    processes: int = 1,
) -> BatchTrajectory:
    """Integrate ``B`` robots of the structure of ``model`` from their initial states.

    Every array argument is per member, shape (B, k), or shared, shape (k,); ``B`` is
    the common first dimension of the per-member ones.

    Parameters
    ----------
    model : Model
        The compiled model; its robot gives the structure and the default parameters.
    t_final : float
        End time [s], > 0.
    q0s, qd0s : array_like (B, n) or (n,)
        Initial coordinates and rates.
    lam0s : array_like (B, n_creep) or (n_creep,), optional
        Initial creep states (default zero).
    tau : array_like (B, n) or (n,), optional
        Constant input forces (default zero).
    parameters : array_like (B, n_p) or (n_p,), optional
        Parameter vectors in the order of ``model.robot.parameter_names()`` (default the
        model's); each is validated as a robot (:meth:`Robot.with_parameter_vector`).
    dt : float
        Output interval [s] (default 1 ms). Memory is ``B * T * (2 n + n_creep + 3)``
        doubles: use a coarser ``dt`` for large batches; the integration steps are chosen
        by error control, so a coarser grid keeps the accuracy.
    method : {"cvodes", "adams", "bdf"}
        As in :func:`softcurve.simulate`; "cvodes" chooses per member.
    rtol : float
        Relative tolerance (default 1e-6).
    atol : float or array_like (n_state,), optional
        Absolute tolerance per state; default ``rtol * nominal_scale`` per member, as in
        :func:`softcurve.simulate`. One integrator serves the batch, so a given ``atol``
        is applied as the tightest ``atol / nominal`` over the members.
    max_steps : int
        Internal steps allowed between two output times.
    threads : int, optional
        Threads of the compiled map (default: the cores usable by this process).
    processes : int
        Worker processes (default 1: the batch runs in this process on ``threads``
        threads). With more, the members are split into chunks of consecutive members
        (``softcurve._workers.CHUNKS_PER_PROCESS`` per worker), each integrated by a worker
        process on one thread; the workers are spawned at the first such call (about a
        second) and kept for later ones. Faster than threads on large
        batches: CasADi's integrator reads the process's CPU clock around every evaluation
        of the model, and the threads of one process contend for that clock
        (``benchmarks/bench_batch.py``). Results are identical either way. Workers are
        spawned, so a script must call this under ``if __name__ == "__main__":``.

    Returns
    -------
    BatchTrajectory
        Members that fail carry status "failed", their message and the outputs reached.
    """
    if not isinstance(model, Model):
        raise ParameterError(f"model must be a softcurve.Model, got {type(model).__name__}")
    batch_methods = tuple(m for m in METHODS if m != "rk45")
    t_final, dt, rtol = check_settings(t_final, dt, rtol, method, max_steps, batch_methods)
    threads = default_threads() if threads is None else threads
    if isinstance(threads, bool) or not isinstance(threads, int | np.integer) or threads < 1:
        raise ParameterError(f"threads must be an integer >= 1, got {threads!r}")
    if isinstance(processes, bool) or not isinstance(processes, int | np.integer) or processes < 1:
        raise ParameterError(f"processes must be an integer >= 1, got {processes!r}")
    n, n_creep = model.n, model.n_creep
    arrays = {
        "q0s": _rows("q0s", q0s, n),
        "qd0s": _rows("qd0s", qd0s, n),
        "lam0s": _rows("lam0s", lam0s, n_creep, np.zeros(n_creep)),
        "tau": _rows("tau", tau, n, np.zeros(n)),
        "parameters": _rows("parameters", parameters, model.parameters.size, model.parameters),
    }
    sizes = {name: a.shape[0] for name, a in arrays.items() if a.shape[0] != 1}
    size = max(sizes.values(), default=1)
    for name, rows in sizes.items():
        if rows != size:
            raise ParameterError(
                f"{name} has {rows} rows, other inputs have {size}: one row per member"
            )
    arrays = {name: np.array(np.broadcast_to(a, (size, a.shape[1]))) for name, a in arrays.items()}
    x0 = np.hstack([arrays["q0s"], arrays["qd0s"], arrays["lam0s"]])
    tau, params = arrays["tau"], arrays["parameters"]
    nominal = _nominal(model, params, x0)
    if atol is None:
        abstol = rtol
    else:
        atol = np.asarray(atol, dtype=np.float64)
        if atol.shape not in ((), (model.n_state,)) or not np.all(np.isfinite(atol) & (atol > 0)):
            raise ParameterError(
                f"atol must be a number or shape ({model.n_state},), finite and > 0, got {atol!r}"
            )
        abstol = float(np.min(atol / nominal))
    if processes > 1 and size > 1:
        settings = {"dt": dt, "method": method, "rtol": rtol, "atol": atol,
                    "max_steps": max_steps}  # fmt: skip
        return in_processes(model, min(processes, size), threads, t_final, arrays, settings)

    grid = _grid(t_final, dt)
    if method == "cvodes":
        ratios, fastest = _linear_rates(model, x0, tau, params, nominal, threads)
        initial = np.where(ratios > STIFFNESS_RATIO, "bdf", "adams")
    else:
        initial = np.full(size, method)
    methods, used_bdf = initial, np.zeros(size, bool)
    states = np.full((size, grid.size, model.n_state), np.nan)
    states[:, 0] = x0
    reached = np.full(size, grid.size)
    messages = [""] * size
    start = time.perf_counter()
    run = _Run(model, grid, rtol, abstol, max_steps, threads, tau, params, nominal)
    for k0, k1 in restart_segments(grid):
        if method == "cvodes" and k0 > 0:  # as simulate(): BDF for settled members
            xdot = _rhs_along(model, np.nan_to_num(states[:, k0 : k0 + 1]), tau[:, None, :],
                              params, threads)[:, 0]  # fmt: skip
            methods = np.where(settled(xdot, nominal, fastest), "bdf", initial)
            used_bdf |= methods == "bdf"
        for multistep in ("adams", "bdf"):
            members = np.flatnonzero((methods == multistep) & (reached == grid.size))
            for block in _blocks(members.size, k1 - k0 + 1, model.n_state + model.n):
                run.integrate(multistep, members[block], k0, k1, states, reached, messages)
    wall = time.perf_counter() - start
    status = np.where(reached == grid.size, "success", "failed")
    families = [f"cvodes-{m}" for m in initial]
    for b in np.flatnonzero(used_bdf & (initial == "adams")):
        families[b] = "cvodes-adams+bdf"
    for b in np.flatnonzero(status == "success"):
        messages[b] = f"integrated to t = {t_final:.6g} s with {families[b]}"
    q, qd, lam = states[..., :n], states[..., n : 2 * n], states[..., 2 * n :]
    stats = {
        "methods": families,
        "rtol": rtol,
        "abstol_scaled": abstol,
        "dt": dt,
        "size": size,
        "threads": threads,
        "wall_time": wall,
        "simulated_time": float(np.sum(grid[reached - 1])),
    }
    return BatchTrajectory(
        t=grid,
        q=q,
        qd=qd,
        lam=lam,
        tau=tau,
        parameters=params,
        status=status,
        message=messages,
        reached=reached,
        stats=stats,
        model=model,
    )


def _nominal(model: Model, params: np.ndarray, x0: np.ndarray) -> np.ndarray:
    """``nominal_scale`` of each member's own robot; validates every parameter vector."""
    robots: dict[bytes, _RobotView] = {model.parameters.tobytes(): _RobotView(model.robot)}
    nominal = np.empty_like(x0)
    for b in range(x0.shape[0]):
        key = params[b].tobytes()
        if key not in robots:
            try:
                robots[key] = _RobotView(model.robot.with_parameter_vector(params[b]))
            except ParameterError as exc:
                raise ParameterError(f"parameters[{b}]: {exc}") from None
        nominal[b] = nominal_scale(robots[key], x0[b])
    return nominal


@dataclass
class _Run:
    """One batch integration: the compiled map over members, with failures isolated."""

    model: Model
    grid: np.ndarray
    rtol: float
    abstol: float
    max_steps: int
    threads: int
    tau: np.ndarray
    params: np.ndarray
    nominal: np.ndarray

    def _p(self, members, h) -> np.ndarray:
        count = len(members)
        return np.hstack([self.params[members], np.full((count, 1), h), self.nominal[members]]).T

    def _mapped_integrator(self, multistep, tout, count):
        """The integrator mapped over ``count`` members, cached with the model."""
        threads = min(self.threads, count)
        options = cvodes_options(multistep, self.rtol, self.abstol, self.max_steps)
        key = ("batch", tuple(sorted(options.items())), tout.tobytes(), count, threads)

        def build():
            integrator = cvodes_integrator(self.model, tout, options)
            return BufferedCall(_mapped(integrator, count, threads))

        return self.model.cached(key, build)

    def integrate(self, multistep, members, k0, k1, states, reached, messages) -> None:
        """Fill ``states[members, k0+1 : k1+1]`` from ``states[members, k0]``; a failing map
        is split in halves until the failing members are found, which are then integrated
        output by output."""
        grid = self.grid[k0 : k1 + 1]
        h = grid[-1] - grid[0]
        tout = (grid[1:] - grid[0]) / h
        count, outputs = len(members), tout.size
        # column-major CasADi matrices: one member's (or one output's) column after another
        x0 = np.ascontiguousarray(states[members, k0] / self.nominal[members])
        p = np.ascontiguousarray(self._p(members, h).T)
        u = np.repeat(self.tau[members], outputs, axis=0)
        xf = np.zeros((count, outputs, self.model.n_state))
        # on a failure, CasADi's map prints every input of the batch to sys.stderr; the
        # reason is kept from the member integrated alone (below)
        with contextlib.redirect_stderr(io.StringIO()):
            failure, _ = self._mapped_integrator(multistep, tout, count)({0: x0, 2: p, 3: u}, xf)
        if failure is not None:
            if count > 1:
                half = count // 2
                for part in (members[:half], members[half:]):
                    self.integrate(multistep, part, k0, k1, states, reached, messages)
            else:
                self._one_by_one(multistep, int(members[0]), k0, k1, states, reached, messages)
            return
        states[members, k0 + 1 : k1 + 1] = xf * self.nominal[members, None, :]
        for b in members:
            bad = ~np.all(np.isfinite(states[b, k0 + 1 : k1 + 1]), axis=1)
            if np.any(bad):
                k = k0 + 1 + int(np.argmax(bad))
                self._fail(b, k, "the state became non-finite", states, reached, messages)

    def _one_by_one(self, multistep, b, k0, k1, states, reached, messages) -> None:
        """Output interval by output interval, to keep every output reached before a failure."""
        integrator = self._mapped_integrator(multistep, np.ones(1), 1)
        nominal = self.nominal[b]
        for k in range(k0 + 1, k1 + 1):
            h = self.grid[k] - self.grid[k - 1]
            x0 = np.ascontiguousarray(states[b, k - 1] / nominal)
            p = np.ascontiguousarray(self._p([b], h).T)
            xf = np.zeros(self.model.n_state)
            u = np.ascontiguousarray(self.tau[b])
            failure, _ = integrator({0: x0, 2: p, 3: u}, xf)
            if failure is not None:
                self._fail(b, k, _cvodes_reason(failure), states, reached, messages)
                return
            states[b, k] = xf * nominal
            if not np.all(np.isfinite(states[b, k])):
                self._fail(b, k, "the state became non-finite", states, reached, messages)
                return

    def _fail(self, b, k, reason, states, reached, messages) -> None:
        """Member ``b`` failed reaching output ``k``: keep outputs ``0 .. k-1``."""
        states[b, k:] = np.nan
        reached[b] = k
        messages[b] = (
            f"{reason}; the trajectory stops at t = {self.grid[k - 1]:.6g} s "
            f"(output {k - 1} of {self.grid.size - 1}). What to try: loosen rtol, "
            "raise max_steps, method='bdf', check the initial state and inputs"
        )


def simulated_seconds_per_second(batch: BatchTrajectory) -> float:
    """Throughput of a batch: simulated time summed over members per wall-clock second."""
    wall = batch.stats["wall_time"]
    return batch.stats["simulated_time"] / wall if wall > 0 else math.inf
