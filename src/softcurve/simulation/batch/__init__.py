"""Batches: :func:`simulate_batch` over many members, and the worker processes that
spread members (and the identification's experiments) over cores."""

from softcurve.simulation.batch._batch import simulate_batch as simulate_batch
from softcurve.simulation.batch._workers import POOL_START as POOL_START
from softcurve.simulation.batch._workers import WorkerDied as WorkerDied
from softcurve.simulation.batch._workers import close_workers as close_workers
from softcurve.simulation.batch._workers import default_threads as default_threads
from softcurve.simulation.batch._workers import pool_pays as pool_pays
from softcurve.simulation.batch._workers import run_in_processes as run_in_processes
from softcurve.simulation.batch._workers import stop_workers as stop_workers
from softcurve.simulation.batch._workers import worker_model as worker_model

__all__ = [
    "simulate_batch",
    "WorkerDied",
    "POOL_START",
    "default_threads",
    "pool_pays",
    "run_in_processes",
    "stop_workers",
    "close_workers",
    "worker_model",
]
