"""Parameter sweeps: a design over named parameters and initial conditions, run in chunks
through :func:`softcurve.batch.simulate_batch`, summarised into one Parquet table.

A sweep is described by a TOML file: the robot and simulation of a scenario
(``docs/configuration.md``) plus a ``[sweep]`` table (``docs/sweeps.md``). The whole
configuration, and the design built from it, is checked before any simulation runs.

Results are written per chunk into ``<out>/parts/`` as whole files (temporary file, then
rename), next to ``manifest.json`` which fingerprints the configuration. Started again on
the same folder, a sweep skips the chunks already written, so a killed sweep loses at most
the chunks in flight. When all chunks are in, ``<out>/results.parquet`` holds the table,
one row per design point, sorted by ``index``.

Chunks run in a local process pool (default), in this process (``workers=0``) or on a
Dask distributed cluster (``scheduler="tcp://host:8786"`` or a ``distributed.Client``).
"""

from __future__ import annotations

import hashlib
import itertools
import json
import math
import re
import sys
import time
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import dataclass, field
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from softcurve._version import __version__
from softcurve.base.files import atomic_path
from softcurve.scenarios.config import (
    ConfigError,
    _Reader,
    scenario_from_dict,
    tomllib,
)
from softcurve.simulation.batch import default_threads, simulate_batch
from softcurve.simulation.trajectory_files import column_names
from softcurve.simulation.workers import worker_model
from softcurve.symbolic.dynamics import DEFAULT_QUADRATURE_NODES

DESIGNS = ("grid", "random", "sobol")
OUTPUTS = ("final_state", "tip_range", "settling_time", "peak_energy")
MAX_DESIGN_SIZE = 10_000_000
FORMAT = "softcurve-sweep"
_STATE = re.compile(r"^(q0|qd0|lam0|tau)\[(\d+)\]$")


@dataclass(frozen=True)
class Variable:
    """One swept quantity: a robot parameter name or ``q0[i]``, ``qd0[i]``, ``lam0[i]``,
    ``tau[i]``; sampled in ``[low, high]`` on a ``linear`` or ``log`` scale."""

    name: str
    low: float
    high: float
    scale: str = "linear"
    points: int | None = None  # grid designs

    def values(self, unit: np.ndarray) -> np.ndarray:
        """Map ``unit`` in [0, 1] onto ``[low, high]`` (the ends exactly)."""
        if self.scale == "log":
            values = np.exp(np.log(self.low) + unit * (np.log(self.high) - np.log(self.low)))
        else:
            values = self.low * (1.0 - unit) + self.high * unit
        return np.where(unit == 0.0, self.low, np.where(unit == 1.0, self.high, values))


@dataclass(frozen=True)
class SweepConfig:
    """A validated sweep: the scenario, the variables and how to run and summarise."""

    scenario: object  # softcurve.io.Scenario
    variables: tuple[Variable, ...]
    design: str
    samples: int | None
    seed: int
    chunk_size: int
    output_dt: float
    outputs: tuple[str, ...]
    settling_fraction: float
    fingerprint: str
    quadrature_nodes: int = DEFAULT_QUADRATURE_NODES
    source: str = "<config>"

    def design_points(self) -> np.ndarray:
        """The design, shape (size, len(variables)), one row per simulation."""
        d = len(self.variables)
        if self.design == "grid":
            axes = [np.linspace(0.0, 1.0, v.points) for v in self.variables]
            unit = np.array(list(itertools.product(*axes)), dtype=np.float64).reshape(-1, d)
        elif self.design == "random":
            unit = np.random.default_rng(self.seed).random((self.samples, d))
        else:
            from scipy.stats import qmc

            sobol = qmc.Sobol(d, scramble=True, seed=self.seed)
            unit = sobol.random_base2(int(math.log2(self.samples)))
        return np.column_stack([v.values(unit[:, j]) for j, v in enumerate(self.variables)])

    @property
    def size(self) -> int:
        if self.design == "grid":
            return math.prod(v.points for v in self.variables)
        return self.samples


# -- reading and checking ------------------------------------------------------------------
def load_sweep(path) -> SweepConfig:
    """Read and check a sweep file; raises :class:`~softcurve.io.ConfigError` naming the key."""
    path = Path(path)
    try:
        data = tomllib.loads(path.read_bytes().decode("utf-8"))
    except FileNotFoundError:
        raise ConfigError(f"{path}: no such file") from None
    except (IsADirectoryError, PermissionError, UnicodeDecodeError) as exc:
        raise ConfigError(f"{path}: cannot read: {exc}") from None
    except tomllib.TOMLDecodeError as exc:
        raise ConfigError(f"{path}: not valid TOML: {exc}") from None
    return sweep_from_dict(data, str(path))


def sweep_from_dict(data: dict, file: str = "<config>") -> SweepConfig:
    """Build a :class:`SweepConfig` from parsed TOML; every check happens here."""
    if not isinstance(data, dict) or "sweep" not in data:
        raise ConfigError(f"{file}: sweep: is required (a [sweep] table, see docs/sweeps.md)")
    rest = {k: v for k, v in data.items() if k != "sweep"}
    scenario = scenario_from_dict(rest, file)
    if scenario.method == "rk45":
        raise ConfigError(f"{file}: simulation.method: sweeps run cvodes, adams or bdf, got 'rk45'")
    r = _Reader(file, "sweep", data["sweep"])
    design = r.get("design", "string", required=True)
    if design not in DESIGNS:
        r.fail("design", f"must be one of {', '.join(DESIGNS)}, got {design!r}")
    samples = r.get("samples", "integer")
    if design == "grid" and samples is not None:
        r.fail("samples", "is for random and sobol designs; a grid takes points per variable")
    if design != "grid":
        if samples is None or samples < 1:
            r.fail("samples", f"is required for a {design} design: an integer >= 1")
        if design == "sobol" and samples & (samples - 1):
            r.fail("samples", f"must be a power of 2 for a sobol design (balance), got {samples}")
    seed = r.get("seed", "integer", 0)
    if seed < 0:
        r.fail("seed", f"must be >= 0, got {seed}")
    chunk_size = r.get("chunk_size", "integer", 64)
    if chunk_size < 1:
        r.fail("chunk_size", f"must be >= 1, got {chunk_size}")
    output_dt = r.positive("output_dt", min(0.01, scenario.t_final))
    if output_dt > scenario.t_final:
        r.fail("output_dt", f"must be <= simulation.t_final = {scenario.t_final}, got {output_dt}")
    outputs = _strings(r, "outputs")
    nodes = r.get("quadrature_nodes", "integer", DEFAULT_QUADRATURE_NODES)
    if not 1 <= nodes <= 64:
        r.fail("quadrature_nodes", f"must be in [1, 64], got {nodes}")
    fraction = r.positive("settling_fraction", 0.02)
    if not fraction < 1:
        r.fail("settling_fraction", f"must be in (0, 1), got {fraction}")
    tables = r.get("variables", "tables", required=True)
    variables = tuple(
        _variable(_Reader(file, f"sweep.variables[{i}]", t), design, scenario)
        for i, t in enumerate(tables)
    )
    r.done()
    names = [v.name for v in variables]
    for name in names:
        if names.count(name) > 1:
            r.fail("variables", f"{name!r} appears more than once")
    config = SweepConfig(
        scenario=scenario,
        variables=variables,
        design=design,
        samples=samples,
        seed=seed,
        chunk_size=chunk_size,
        output_dt=output_dt,
        outputs=outputs,
        settling_fraction=fraction,
        fingerprint=_fingerprint(data),
        source=file,
        quadrature_nodes=nodes,
    )
    if config.size > MAX_DESIGN_SIZE:
        r.fail("variables", f"the design has {config.size} points, more than {MAX_DESIGN_SIZE}")
    _check_design_box(config, r)
    return config


def _strings(r: _Reader, name: str) -> tuple[str, ...]:
    r.used.add(name)
    value = r.table.get(name, list(OUTPUTS))
    if not (isinstance(value, list) and value and all(isinstance(v, str) for v in value)):
        r.fail(name, f"must be a non-empty array of names from {', '.join(OUTPUTS)}")
    for v in value:
        if v not in OUTPUTS:
            r.fail(name, f"unknown output {v!r} (allowed: {', '.join(OUTPUTS)})")
    return tuple(dict.fromkeys(value))


def _variable(r: _Reader, design: str, scenario) -> Variable:
    robot = scenario.robot
    name = r.get("name", "string", required=True)
    match = _STATE.match(name)
    if match:
        kind, index = match.group(1), int(match.group(2))
        size = robot.n_creep if kind == "lam0" else robot.n
        if index >= size:
            r.fail("name", f"{name!r}: index out of range, {kind} has {size} entries")
    elif name not in robot.parameter_names():
        r.fail(
            "name",
            f"{name!r} is neither q0[i], qd0[i], lam0[i], tau[i] nor a parameter "
            f"of the robot (e.g. {robot.parameter_names()[6]!r}; "
            "softcurve.Robot.parameter_names() lists them)",
        )
    elif name.startswith("base_rotation"):
        r.fail("name", "base_rotation entries cannot be swept one by one (it must stay a rotation)")
    low, high = r.get("low", "number", required=True), r.get("high", "number", required=True)
    if not low < high:
        r.fail("high", f"must be > low = {low}, got {high}")
    scale = r.get("scale", "string", "linear")
    if scale not in ("linear", "log"):
        r.fail("scale", f"must be 'linear' or 'log', got {scale!r}")
    if scale == "log" and not low > 0:
        r.fail("low", f"must be > 0 on a log scale, got {low}")
    points = r.get("points", "integer")
    if design == "grid" and (points is None or points < 2):
        r.fail("points", f"is required for a grid design: an integer >= 2, got {points!r}")
    if design != "grid" and points is not None:
        r.fail("points", f"is for grid designs; a {design} design takes sweep.samples")
    r.done()
    return Variable(name, low, high, scale, points)


def _check_design_box(config: SweepConfig, r: _Reader) -> None:
    """Every robot of the design is valid if every corner of the box of swept parameters is:
    the valid set (positive values, ``a1 > a2``, positive definite matrices, ...) is
    convex, and the box is the convex hull of its corners. Initial lengths likewise."""
    robot = config.scenario.robot
    names = robot.parameter_names()
    swept = [v for v in config.variables if not _STATE.match(v.name)]
    corners = itertools.product(*[(v.low, v.high) for v in swept]) if len(swept) <= 12 else ()
    base = robot.parameter_vector()
    for corner in corners:
        vector = base.copy()
        for v, value in zip(swept, corner, strict=True):
            vector[names.index(v.name)] = value
        try:
            robot.with_parameter_vector(vector)
        except ValueError as exc:
            where = ", ".join(f"{v.name} = {c:g}" for v, c in zip(swept, corner, strict=True))
            r.fail("variables", f"the robot at the corner {where} of the design is invalid: {exc}")
    for v in config.variables:
        match = _STATE.match(v.name)
        if match and match.group(1) == "q0" and int(match.group(2)) % 3 == 0 and v.low <= 0:
            r.fail("variables", f"{v.name} is a length: low must be > 0, got {v.low}")


def _fingerprint(data: dict) -> str:
    text = json.dumps({"config": data, "softcurve": __version__}, sort_keys=True, default=str)
    return hashlib.sha256(text.encode()).hexdigest()[:16]


# -- one chunk -------------------------------------------------------------------------------
def run_chunk(config: SweepConfig, start: int, design: np.ndarray, threads: int = 1) -> dict:
    """Simulate the design rows ``design`` (numbered from ``start``) and summarise them:
    a dict of column arrays."""
    scenario = config.scenario
    robot = scenario.robot
    model = worker_model(robot, config.quadrature_nodes)
    size = design.shape[0]
    q0, qd0, lam0 = scenario.initial_state()
    tau = np.zeros(robot.n) if scenario.tau is None else np.array(scenario.tau, dtype=float)
    inputs = {"q0": q0, "qd0": qd0, "lam0": lam0, "tau": tau}
    inputs = {k: np.repeat(v[None, :], size, axis=0) for k, v in inputs.items()}
    parameters = np.repeat(robot.parameter_vector()[None, :], size, axis=0)
    names = robot.parameter_names()
    for j, v in enumerate(config.variables):
        match = _STATE.match(v.name)
        if match:
            inputs[match.group(1)][:, int(match.group(2))] = design[:, j]
        else:
            parameters[:, names.index(v.name)] = design[:, j]
    batch = simulate_batch(
        model,
        scenario.t_final,
        inputs["q0"],
        inputs["qd0"],
        inputs["lam0"],
        inputs["tau"],
        parameters,
        config.output_dt,
        method=scenario.method,
        rtol=scenario.rtol,
        atol=scenario.atol,
        max_steps=scenario.max_steps,
        threads=threads,
    )
    columns = {"index": np.arange(start, start + size, dtype=np.int64)}
    columns.update({v.name: design[:, j] for j, v in enumerate(config.variables)})
    columns.update(summarise(batch, config.outputs, config.settling_fraction))
    columns["status"] = np.asarray(batch.status, dtype=str)
    columns["message"] = np.asarray(batch.message, dtype=str)
    return columns


def settling_time(t: np.ndarray, tip: np.ndarray, fraction: float) -> np.ndarray:
    """First output time after which the tip stays within ``fraction`` of its largest
    distance from its final position: with ``e_k = |tip_k - tip_K|`` (K the last output),
    the smallest ``t_j`` such that ``e_k <= fraction * max_k e_k`` for every ``k >= j``.

    ``tip`` is (B, T, 3); returns (B,) [s], exact to one output interval; 0 for a tip
    that never moves; a value near ``t[-1]`` means not settled within the simulation.
    """
    distance = np.linalg.norm(tip - tip[:, -1:, :], axis=2)
    band = fraction * distance.max(axis=1, keepdims=True)
    outside = distance > band
    last_outside = np.where(
        outside.any(axis=1), outside.shape[1] - 1 - np.argmax(outside[:, ::-1], axis=1), -1
    )
    return np.where(last_outside < 0, t[0], t[np.minimum(last_outside + 1, t.size - 1)])


def summarise(batch, outputs, fraction: float) -> dict:
    """The chosen outputs of every member; NaN for members that failed (see ``status``)."""
    n, n_creep = batch.q.shape[2], batch.lam.shape[2]
    failed = ~batch.success
    columns: dict[str, np.ndarray] = {}
    if "final_state" in outputs:
        state_names = column_names(n, n_creep, with_tau=False)[1 : 1 + 2 * n + n_creep]
        final = batch.x[:, -1, :]
        columns.update({f"final_{name}": final[:, i] for i, name in enumerate(state_names)})
        columns.update({f"final_tip_{a}": batch.tip[:, -1, i].copy() for i, a in enumerate("xyz")})
    if "tip_range" in outputs:
        span = batch.tip.max(axis=1) - batch.tip.min(axis=1)
        columns.update({f"tip_range_{a}": span[:, i] for i, a in enumerate("xyz")})
    if "settling_time" in outputs:
        columns["settling_time"] = settling_time(batch.t, batch.tip, fraction)
    if "peak_energy" in outputs:
        columns["peak_energy"] = batch.energy().max(axis=1)
    for value in columns.values():
        value[failed] = np.nan
    return columns


# -- the sweep -------------------------------------------------------------------------------
@dataclass
class SweepResult:
    """What :func:`run_sweep` did: ``path`` of results.parquet, the ``table`` (pyarrow),
    chunks run now and skipped (already done), failed members, ``wall_time`` [s]."""

    path: Path
    table: object
    chunks_run: int
    chunks_skipped: int
    failed: int
    wall_time: float
    stats: dict = field(default_factory=dict)

    @property
    def status(self) -> str:
        return "success" if self.failed == 0 else "failed"


def run_sweep(
    config,
    output,
    *,
    workers: int | None = None,
    scheduler=None,
    restart=False,
    progress=False,
    on_chunk=None,
) -> SweepResult:
    """Run (or resume) a sweep into the folder ``output``.

    Parameters
    ----------
    config : SweepConfig or path of a TOML file
    output : path
        Folder for ``manifest.json``, ``parts/`` and ``results.parquet``.
    workers : int, optional
        Local worker processes (default: the usable cores); 0 runs in this process.
    scheduler : str or distributed.Client, optional
        A Dask scheduler address (``tcp://host:8786``) or client: run the chunks there.
    restart : bool
        Discard earlier results in ``output`` instead of resuming.
    progress : bool
        A progress line on stderr.
    on_chunk : callable, optional
        ``on_chunk(chunk_index, done, total)`` after each chunk is written.
    """
    import pyarrow as pa
    import pyarrow.parquet as pq

    if not isinstance(config, SweepConfig):
        config = load_sweep(config)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 0):  # fmt: skip
        raise ConfigError(f"workers must be an integer >= 0, got {workers!r}")
    output = Path(output)
    parts = output / "parts"
    manifest = {
        "format": FORMAT,
        "version": 1,
        "fingerprint": config.fingerprint,
        "size": config.size,
        "chunk_size": config.chunk_size,
        "source": config.source,
    }
    _prepare(output, parts, manifest, restart)
    chunks = [
        (c, c * config.chunk_size, min(config.size, (c + 1) * config.chunk_size))
        for c in range(math.ceil(config.size / config.chunk_size))
    ]
    done = {c for c, _, _ in chunks if _part(parts, c).exists()}
    design = config.design_points() if len(done) < len(chunks) else None
    pending = [(c, a, design[a:b]) for c, a, b in chunks if c not in done]
    bar = _Progress(len(chunks), len(done), progress)
    start = time.perf_counter()

    def write(c, columns):
        with atomic_path(_part(parts, c)) as tmp:
            pq.write_table(pa.table(columns), tmp)
        done.add(c)
        bar.update(len(done))
        if on_chunk is not None:
            on_chunk(c, len(done), len(chunks))

    client = _connect(scheduler) if scheduler is not None and pending else None
    try:
        for c, columns in _execute(config, pending, workers, client):
            write(c, columns)
    finally:
        bar.close()
        if client is not None and client is not scheduler:
            client.close()
    table = pa.concat_tables([pq.read_table(_part(parts, c)) for c, _, _ in chunks])
    table = table.sort_by("index")
    with atomic_path(output / "results.parquet") as tmp:
        pq.write_table(table, tmp)
    failed = int(np.sum(np.asarray(table.column("status").to_pylist()) != "success"))
    wall = time.perf_counter() - start
    return SweepResult(
        output / "results.parquet",
        table,
        len(pending),
        len(chunks) - len(pending),
        failed,
        wall,
        {"size": config.size, "chunks": len(chunks)},
    )


def _part(parts: Path, c: int) -> Path:
    return parts / f"chunk-{c:06d}.parquet"


def _prepare(output: Path, parts: Path, manifest: dict, restart: bool) -> None:
    """Create the folder, or check that it holds this same sweep."""
    path = output / "manifest.json"
    if output.exists() and not output.is_dir():
        raise ConfigError(f"{output}: exists and is not a folder")
    if path.exists() and not restart:
        try:
            old = json.loads(path.read_text())
        except (OSError, ValueError) as exc:
            raise ConfigError(f"{path}: unreadable manifest ({exc}); use --restart") from None
        if old.get("format") != FORMAT or old.get("fingerprint") != manifest["fingerprint"]:
            raise ConfigError(
                f"{output} holds another sweep (its configuration differs): "
                "choose a new output folder, or --restart to discard it"
            )
        return
    if restart:
        for stale in [*parts.glob("chunk-*.parquet"), output / "results.parquet"]:
            stale.unlink(missing_ok=True)
    parts.mkdir(parents=True, exist_ok=True)
    with atomic_path(path) as tmp:
        tmp.write_text(json.dumps(manifest, indent=2))


def _connect(scheduler):
    """A Dask client: ``scheduler`` itself, or connected to the address ``scheduler``."""
    try:
        from distributed import Client
    except ImportError:
        raise ConfigError(
            "running on a Dask cluster needs dask.distributed: pip install 'softcurve[cluster]'"
        ) from None
    if isinstance(scheduler, Client):
        return scheduler
    try:
        return Client(scheduler, timeout="20s")
    except (OSError, TimeoutError, ValueError) as exc:
        raise ConfigError(f"scheduler {scheduler}: cannot connect ({exc})") from None


def _execute(config, pending, workers, client):
    """Yield ``(chunk, columns)`` as chunks finish, in this process, a pool or on Dask."""
    if not pending:
        return
    if client is not None:
        yield from _on_dask(config, pending, client)
        return
    workers = default_threads() if workers is None else workers
    if workers == 0 or len(pending) == 1:
        for c, a, rows in pending:
            yield c, run_chunk(config, a, rows, threads=default_threads())
        return
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
        futures = {pool.submit(run_chunk, config, a, rows, 1): c for c, a, rows in pending}
        try:
            for future in as_completed(futures):
                yield futures[future], future.result()
        except BaseException:
            for future in futures:
                future.cancel()
            raise


def _on_dask(config, pending, client):
    from distributed import as_completed as dask_completed

    futures = {
        client.submit(run_chunk, config, a, rows, 1, pure=False): c for c, a, rows in pending
    }
    try:
        for future in dask_completed(list(futures)):
            yield futures[future], future.result()
    except BaseException:
        client.cancel(list(futures))
        raise


class _Progress:
    """``[#####.....] 12/40 chunks, 10.1 s, ~23 s left`` on stderr."""

    def __init__(self, total: int, done: int, show: bool):
        self.total, self.first, self.show = total, done, show
        self.start = time.perf_counter()
        self.update(done)

    def update(self, done: int) -> None:
        if not self.show:
            return
        elapsed = time.perf_counter() - self.start
        rate = (done - self.first) / elapsed if elapsed > 0 else 0.0
        left = f", ~{(self.total - done) / rate:.0f} s left" if rate > 0 else ""
        filled = int(30 * done / max(self.total, 1))
        sys.stderr.write(
            f"\r[{'#' * filled}{'.' * (30 - filled)}] {done}/{self.total} chunks, "
            f"{elapsed:.1f} s{left}   "
        )
        sys.stderr.flush()

    def close(self) -> None:
        if self.show:
            sys.stderr.write("\n")
            sys.stderr.flush()
