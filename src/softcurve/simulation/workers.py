"""Worker processes for batches and sweeps: :func:`softcurve.simulate_batch` with
``processes > 1`` hands chunks of members to a pool of spawned processes, kept between
calls; ``softcurve sweep`` runs its chunks on the models :func:`worker_model` keeps.

Processes rather than threads: CasADi's integrator reads the process CPU clock around
every evaluation of the model, and the threads of one process contend for that clock.
"""

from __future__ import annotations

import time
from concurrent.futures import ProcessPoolExecutor
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context
from typing import TYPE_CHECKING

import numpy as np

from softcurve.compiled.model import Model
from softcurve.description.robot import Robot

if TYPE_CHECKING:
    from softcurve.simulation.batch import BatchTrajectory

_POOL: list = []  # [(size, ProcessPoolExecutor)], at most one
_WORKER_MODELS: dict = {}


def worker_model(robot: Robot, quadrature_nodes: int) -> Model:
    """The model of ``robot`` in a worker process, kept between the tasks it runs (loading
    the cached library takes milliseconds, building integrators on it more)."""
    key = (robot.structure(), robot.parameter_vector().tobytes(), quadrature_nodes)
    if key not in _WORKER_MODELS:
        _WORKER_MODELS.clear()
        _WORKER_MODELS[key] = Model(robot, quadrature_nodes=quadrature_nodes)
    return _WORKER_MODELS[key]


def _pool(size: int) -> ProcessPoolExecutor:
    if _POOL and _POOL[0][0] != size:
        _POOL.pop()[1].shutdown()
    if not _POOL:
        _POOL.append((size, ProcessPoolExecutor(size, mp_context=get_context("spawn"))))
    return _POOL[0][1]


def _chunk(robot, quadrature_nodes, t_final, arrays, settings) -> BatchTrajectory:
    """One chunk of a batch, in a worker process."""
    from softcurve.simulation.batch import simulate_batch

    model = worker_model(robot, quadrature_nodes)
    chunk = simulate_batch(
        model, t_final, arrays["q0s"], arrays["qd0s"], arrays["lam0s"], arrays["tau"],
        arrays["parameters"], **settings, threads=1,
    )  # fmt: skip
    chunk.model = None  # the parent has it; a Model holds a loaded library
    return chunk


CHUNKS_PER_PROCESS = 4
"""Chunks of members per worker process: members differ in their cost (a violent
transient takes more steps), so smaller chunks handed out as workers finish balance the
load; each chunk costs one call across processes."""


def in_processes(model, processes, threads, t_final, arrays, settings) -> BatchTrajectory:
    """:func:`simulate_batch` in chunks over ``processes`` worker processes; ``threads`` is
    kept for what is later evaluated along the result in this process (tip, energy)."""
    from softcurve.simulation.batch import BatchTrajectory

    start = time.perf_counter()
    size = arrays["q0s"].shape[0]
    count = min(size, CHUNKS_PER_PROCESS * processes)
    bounds = np.linspace(0, size, count + 1).astype(int)
    pool = _pool(processes)
    try:
        futures = [
            pool.submit(
                _chunk,
                model.robot,
                model.quadrature_nodes,
                t_final,
                {k: a[lo:hi] for k, a in arrays.items()},
                settings,
            )  # fmt: skip
            for lo, hi in zip(bounds[:-1], bounds[1:], strict=True)
        ]
        chunks = [f.result() for f in futures]
    except BrokenProcessPool as exc:
        _POOL.clear()
        raise RuntimeError(
            f"a worker process of simulate_batch died ({exc}). Workers are spawned and "
            "import the main module: in a script, call simulate_batch(processes=...) under "
            "`if __name__ == '__main__':`"
        ) from None
    first = chunks[0]
    stats = {
        **first.stats,
        "methods": [m for c in chunks for m in c.stats["methods"]],
        "size": size,
        "threads": threads,
        "processes": processes,
        "wall_time": time.perf_counter() - start,
        "simulated_time": float(sum(c.stats["simulated_time"] for c in chunks)),
    }
    return BatchTrajectory(
        t=first.t,
        **{
            name: np.concatenate([getattr(c, name) for c in chunks])
            for name in ("q", "qd", "lam", "tau", "parameters", "status", "reached")
        },
        message=[m for c in chunks for m in c.message],
        stats=stats,
        model=model,
    )
