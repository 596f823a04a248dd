"""Parameter sweeps: a design over named robot parameters, initial conditions, actuator
inputs and actuator parameters, run in chunks through
:func:`~softcurve.simulation.batch.simulate_batch`, summarized into one Parquet table.

A sweep is described by a TOML file: the robot and simulation of a scenario
(``docs/configuration.md``) plus a ``[sweep]`` table (``docs/sweeps.md``). The whole
configuration, and the design built from it, is checked before any simulation runs
(:mod:`softcurve.scenarios.sweep_config`).

Results are written per chunk into ``<out>/parts/`` as whole files (temporary file, then
rename), next to ``manifest.json`` which fingerprints the configuration. Started again on
the same folder, a sweep skips the chunks already written, so a killed sweep loses at most
the chunks in flight. When all chunks are in, ``<out>/results.parquet`` holds the table,
one row per design point, sorted by ``index``.

Chunks run in this process (``workers=0``), in the worker pool of
``softcurve.simulation.batch._workers`` or on a Dask distributed cluster
(``scheduler="tcp://host:8786"`` or a ``distributed.Client``); by default the first two
chunks run here, timed, and the pool takes the others only where it finishes them sooner.
"""

from __future__ import annotations

import json
import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from softcurve.base.files import atomic_path, folder_lock, writable_folder
from softcurve.base.progress import ProgressLine
from softcurve.base.status import Result, Status
from softcurve.figures import plot_sweep
from softcurve.scenarios.config import ConfigError
from softcurve.scenarios.sweep_config import SweepConfig, load_sweep
from softcurve.scenarios.sweep_parts import intact, part_path, read_part
from softcurve.scenarios.sweep_variables import variable_label
from softcurve.simulation.batch import (
    default_threads,
    pool_pays,
    run_in_processes,
    simulate_batch,
    worker_model,
)
from softcurve.simulation.results import column_names, coordinate_columns

FORMAT = "softcurve-sweep"
"""The ``format`` of a sweep folder's ``manifest.json``."""


# -- one chunk -------------------------------------------------------------------------------
def run_chunk(config: SweepConfig, start: int, design: np.ndarray, threads: int = 1) -> dict:
    """Simulate the design rows ``design`` and summarize them: a dict of column arrays.

    Parameters
    ----------
    config : SweepConfig
        The sweep.
    start : int
        Index of the first row in the whole design.
    design : ndarray, shape (rows, len(config.variables))
        The design points to simulate.
    threads : int
        Threads of the batch.
    """
    model = worker_model(
        config.scenario.robot, config.quadrature_nodes, config.scenario.environment
    )
    arguments = config.batch_arguments(design)
    q0, qd0, lam0 = (arguments.pop(k) for k in ("q0", "qd0", "lam0"))
    batch = simulate_batch(
        model, q0, qd0, lam0, settings=config.settings, threads=threads, **arguments
    )
    size = design.shape[0]
    columns = {"index": np.arange(start, start + size, dtype=np.int64)}
    columns.update({v.name: design[:, j] for j, v in enumerate(config.variables)})
    columns.update(summarize(batch, config.outputs, config.settling_fraction))
    columns["status"] = np.array([s.value for s in batch.member_status], dtype=str)
    columns["message"] = np.asarray(batch.member_message, dtype=str)
    return columns


def settling_time(t: np.ndarray, tip: np.ndarray, fraction: float) -> np.ndarray:
    """First output time after which the tip stays within ``fraction`` of its largest
    distance from its final position: with ``e_k = |tip_k - tip_K|`` (K the last output),
    the smallest ``t_j`` such that ``e_k <= fraction * max_k e_k`` for every ``k >= j``.

    Returns (B,) [s], exact to one output interval; 0 for a tip that never moves; a value
    near ``t[-1]`` means not settled within the simulation.

    Parameters
    ----------
    t : ndarray, shape (T,)
        Output times [s].
    tip : ndarray, shape (B, T, 3)
        Tip positions [m].
    fraction : float
        The band, a fraction of the largest distance, in (0, 1).
    """
    distance = np.linalg.norm(tip - tip[:, -1:, :], axis=2)
    band = fraction * distance.max(axis=1, keepdims=True)
    outside = distance > band
    last_outside = np.where(
        outside.any(axis=1), outside.shape[1] - 1 - np.argmax(outside[:, ::-1], axis=1), -1
    )
    return np.where(last_outside < 0, t[0], t[np.minimum(last_outside + 1, t.size - 1)])


def summarize(batch, outputs, fraction: float) -> dict:
    """The chosen outputs of every member; NaN for members that failed (see their status).

    Parameters
    ----------
    batch : BatchTrajectory
        The simulated chunk.
    outputs : tuple of str
        Names from ``OUTPUTS``.
    fraction : float
        Band of the settling time, a fraction of the largest excursion (see
        :func:`settling_time`).
    """
    n, n_creep = batch.q.shape[2], batch.lam.shape[2]
    failed = ~batch.member_success
    columns: dict[str, np.ndarray] = {}
    if "final_state" in outputs:
        coordinates = None if batch.model is None else coordinate_columns(batch.model.robot)
        names = column_names(n, n_creep, with_tau=False, coordinates=coordinates)
        state_names = names[1 : 1 + 2 * n + n_creep]
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
@dataclass(frozen=True)
class SweepResult(Result):
    """What :func:`run_sweep` did; immutable.

    Attributes
    ----------
    path : Path
        The file ``results.parquet``.
    table : pyarrow.Table
        The results, one row per design point.
    chunks_run : int
        Chunks simulated now.
    chunks_skipped : int
        Chunks already written by an earlier run.
    failed : int
        Simulations that failed.
    wall_time : float
        Time of this run [s].
    status : Status
        ``SUCCESS``, ``PARTIAL`` (some simulations failed) or ``INTEGRATION_FAILED`` (all).
    message : str
        How many failed.
    stats : dict
        ``size`` (design points), ``chunks``, ``variables`` (the swept names),
        ``labels`` (each name in words with its unit, the figure's axis labels) and
        ``workers`` (the worker processes that ran the chunks, 0 for this process; None
        on a Dask cluster or with nothing to run).
    """

    path: Path
    table: object
    chunks_run: int
    chunks_skipped: int
    failed: int
    wall_time: float
    status: Status = Status.SUCCESS
    message: str = ""
    stats: dict = field(default_factory=dict)

    def plot(self, ax=None):
        """Each output against each swept variable, one point per simulation.

        Parameters
        ----------
        ax : None or sequence of matplotlib.axes.Axes, shape (outputs, variables)
            The panels, row by row (see :func:`softcurve.figures.plot_sweep`); None draws
            a new figure.

        Returns
        -------
        matplotlib.figure.Figure
            Write it with :func:`softcurve.figures.save_figure`.
        """
        variables, labels = self.stats.get("variables"), self.stats.get("labels")
        return plot_sweep(self.table, ax, variables=variables, labels=labels)


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
    config : SweepConfig or str or Path
        The sweep, or its TOML file.
    output : str or Path
        Folder for ``manifest.json``, ``parts/`` and ``results.parquet``.
    workers : int, optional
        Local worker processes; 0 runs in this process. Default: the first two chunks in
        this process, timed, then the others on one worker per usable core when that is
        sooner (a pool takes seconds to start), else here.
    scheduler : str or distributed.Client, optional
        A Dask scheduler address (``tcp://host:8786``) or client: run the chunks there.
    restart : bool
        Discard earlier results in ``output`` instead of resuming.
    progress : bool
        A progress line on stderr.
    on_chunk : callable, optional
        ``on_chunk(chunk_index, done, total)`` after each chunk is written.

    Raises
    ------
    ParameterError
        Before any work: ``output`` cannot be written, or another sweep is running in
        it (:class:`~softcurve.base.files.FolderLocked`, naming that sweep's pid).
    """
    if not isinstance(config, SweepConfig):
        config = load_sweep(config)
    if workers is not None and (isinstance(workers, bool) or not isinstance(workers, int)
                                or workers < 0):  # fmt: skip
        raise ConfigError(f"workers must be an integer >= 0, got {workers!r}")
    output = writable_folder(output, "output")
    with folder_lock(output, "sweep"):  # one sweep at a time in a folder
        return _sweep(config, output, workers, scheduler, restart, progress, on_chunk)


def _sweep(config, output, workers, scheduler, restart, progress, on_chunk) -> SweepResult:
    """:func:`run_sweep` in the locked folder ``output``."""
    import pyarrow as pa
    import pyarrow.parquet as pq

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
    done = {c for c, a, b in chunks if intact(part_path(parts, c), b - a)}
    design = config.design_points() if len(done) < len(chunks) else None
    pending = [(c, a, design[a:b]) for c, a, b in chunks if c not in done]
    start = time.perf_counter()

    def write(c, columns):
        with atomic_path(part_path(parts, c)) as tmp:
            pq.write_table(pa.table(columns), tmp)
        done.add(c)
        bar.update(len(done))
        if on_chunk is not None:
            on_chunk(c, len(done), len(chunks))

    client = _connect(scheduler) if scheduler is not None and pending else None
    chosen: dict = {"workers": None}
    bar = ProgressLine(len(chunks), len(done), progress, unit="chunks", beat=True)
    try:
        for c, columns in _execute(config, pending, workers, client, chosen):
            write(c, columns)
    finally:
        bar.close()
        if client is not None and client is not scheduler:
            client.close()
    table = pa.concat_tables([read_part(part_path(parts, c)) for c, _, _ in chunks])
    table = table.sort_by("index")
    with atomic_path(output / "results.parquet") as tmp:
        pq.write_table(table, tmp)
    failed = int(np.sum(np.asarray(table.column("status").to_pylist()) != Status.SUCCESS))
    if failed == 0:
        status, message = Status.SUCCESS, f"all {config.size} simulations succeeded"
    else:
        status = Status.INTEGRATION_FAILED if failed == config.size else Status.PARTIAL
        message = (
            f"{failed} of {config.size} simulations failed: see the status and message columns"
        )
    return SweepResult(
        output / "results.parquet",
        table,
        len(pending),
        len(chunks) - len(pending),
        failed,
        time.perf_counter() - start,
        status,
        message,
        {
            "size": config.size,
            "chunks": len(chunks),
            "variables": tuple(v.name for v in config.variables),
            "labels": {v.name: variable_label(config.scenario, v.name) for v in config.variables},
            "workers": chosen["workers"],
        },
    )


def _read_manifest(path: Path) -> dict:
    """The manifest of a sweep's folder; :class:`ConfigError` saying it is damaged (not
    JSON, or without the fields every manifest has), naming it and what to do."""
    try:
        old = json.loads(path.read_bytes().decode("utf-8"))
        reason = None
    except (OSError, ValueError) as exc:
        old, reason = None, " ".join(str(exc).split())
    if reason is None and not (
        isinstance(old, dict)
        and old.get("format") == FORMAT
        and isinstance(old.get("fingerprint"), str)
        and all(isinstance(old.get(k), int) for k in ("version", "size", "chunk_size"))
    ):
        reason = "not the fields of a softcurve sweep manifest"
    if reason is not None:
        raise ConfigError(
            f"{path}: damaged sweep manifest ({reason}); the results beside it cannot be "
            "matched to a configuration: run again with --restart to discard them, or "
            "choose a new output folder"
        )
    return old


def _prepare(output: Path, parts: Path, manifest: dict, restart: bool) -> None:
    """Create the folder, or check that it holds this same sweep."""
    path = output / "manifest.json"
    if output.exists() and not output.is_dir():
        raise ConfigError(f"{output}: exists and is not a folder")
    if path.exists() and not restart:
        if _read_manifest(path)["fingerprint"] != manifest["fingerprint"]:
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


MEASURED_CHUNKS = 2
"""Chunks a sweep without ``workers`` runs in this process before it chooses where the
others run: the first builds the integrators, the second gives the pace."""


def _execute(config, pending, workers, client, chosen: dict):
    """Yield ``(chunk, columns)`` as chunks finish, in this process, a pool or on Dask;
    ``chosen["workers"]`` is set to the worker processes used (0: this process).

    Without ``workers`` given, the first two chunks run in this process on all its
    threads, timed, and the others go to a pool of one worker per core only if that
    finishes them sooner than the second chunk's pace here
    (:func:`~softcurve.simulation.batch.pool_pays`): a small sweep never waits for
    workers to start. The first chunk also builds the model's integrators, once (a
    worker builds its own): its time would overstate the pace here."""
    if not pending:
        return
    if client is not None:
        yield from _on_dask(config, pending, client)
        return
    measured = MEASURED_CHUNKS if workers is None else 0
    while measured and pending:
        (c, a, rows), pending = pending[0], pending[1:]
        wall, cpu = time.perf_counter(), time.process_time()
        columns = run_chunk(config, a, rows, threads=default_threads())
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        measured -= 1
        if measured == 0 or not pending:
            pays = pool_pays(wall, cpu, len(pending), default_threads())
            workers = default_threads() if pays else 0
        chosen["workers"] = 0
        yield c, columns
    if workers == 0 or len(pending) == 1:
        chosen["workers"] = 0
        for c, a, rows in pending:
            yield c, run_chunk(config, a, rows, threads=default_threads())
        return
    chosen["workers"] = workers
    tasks = {c: (config, a, rows, 1) for c, a, rows in pending}
    yield from run_in_processes(run_chunk, tasks, workers)


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
