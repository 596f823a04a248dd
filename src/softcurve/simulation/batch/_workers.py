"""The one pool of worker processes, for batches and sweeps.

:func:`run_in_processes` hands tasks to spawned processes, kept between calls (spawning
costs about a second), and yields each result as it finishes; an error in a task, or an
interrupt, cancels the tasks not yet started. :func:`worker_model` keeps the model a
worker has loaded for the next task on the same robot.

Workers die with the process that started them, whatever kills it: a thread in each
worker ends it once its parent is gone (checked every ``PARENT_POLL`` seconds).

Processes rather than threads where CasADi's integrator runs (the fallback of
softcurve's C driver of CVODES, and CasADi's other solvers): it reads the process CPU
clock around every evaluation of the model, and the threads of one process contend for
that clock. The C driver reads no clock, so a batch on threads is as fast.
"""

from __future__ import annotations

import ast
import contextlib
import inspect
import math
import os
import signal
import sys
import threading
import time
from collections.abc import Callable, Iterator
from concurrent.futures import ProcessPoolExecutor, as_completed
from concurrent.futures.process import BrokenProcessPool
from multiprocessing import get_context

from softcurve.base.validation import ParameterError
from softcurve.compiled import Model
from softcurve.description.robot import Robot

_POOL: list = []  # [(size, ProcessPoolExecutor)], at most one
_WORKER_MODELS: dict = {}

PARENT_POLL = 0.5
"""Seconds between two checks of a worker that its parent still runs: a worker outlives a
killed parent by about this long, or until the compiled call it is in returns (the watcher
needs the interpreter)."""


class WorkerDied(RuntimeError):
    """A worker process ended while it held a task (killed, out of memory, a crash in
    compiled code): a fault of the machine, not of the task's model."""


def _worker_start(parent: int) -> None:
    """Initializer of each worker: die when the process ``parent`` is gone."""
    # Not the kernel's parent-death signal (prctl PR_SET_PDEATHSIG): it follows the THREAD
    # that spawned the worker, and executors spawn workers in whichever thread submits, so
    # a pool started from a thread that ends would lose its workers. A watcher thread is
    # portable and follows the process.
    if os.getppid() != parent:  # the parent died while this worker started
        os._exit(1)
    signal.signal(signal.SIGINT, signal.SIG_IGN)  # see _interrupts_blocked
    threading.Thread(target=_watch_parent, args=(parent,), daemon=True).start()


@contextlib.contextmanager
def _interrupts_blocked():
    """SIGINT blocked in this thread for the block: a worker process started in it
    inherits the mask, so a Ctrl-C (sent to the whole process group) never interrupts a
    worker, even while it imports softcurve; the parent alone decides (it kills the
    workers and says what was kept). An interrupt of the parent meanwhile waits until the
    block ends (a few milliseconds)."""
    if not hasattr(signal, "pthread_sigmask"):  # pragma: no cover - Windows
        yield
        return
    previous = signal.pthread_sigmask(signal.SIG_BLOCK, {signal.SIGINT})
    try:
        yield
    finally:
        signal.pthread_sigmask(signal.SIG_SETMASK, previous)


def _watch_parent(parent: int) -> None:
    """End this worker once its parent has exited (its parent pid changes)."""
    while os.getppid() == parent:
        time.sleep(PARENT_POLL)
    os._exit(1)


def stop_workers() -> None:
    """Kill the worker processes now (an interrupt or SIGTERM: the chunks they are running
    are abandoned) and forget the pool; the next call starts a new one."""
    if not _POOL:
        return
    pool = _POOL.pop()[1]
    processes = list(getattr(pool, "_processes", {}).values())  # no public API before 3.14
    for process in processes:
        if process.is_alive():
            process.kill()
    pool.shutdown(wait=False, cancel_futures=True)
    for process in processes:
        process.join(timeout=PARENT_POLL)


def close_workers() -> None:
    """End the idle worker processes and wait until they and the pool's thread are gone,
    so that the interpreter exits with nothing to wait for (a Ctrl-C while it waits at
    its exit is a traceback that no command can catch). An interrupt meanwhile leaves
    the pool to :func:`stop_workers`; the next call starts a new one."""
    if _POOL:
        _POOL[0][1].shutdown(wait=True)
        _POOL.clear()


def default_threads() -> int:
    """Cores usable by this process."""
    if hasattr(os, "sched_getaffinity"):
        return max(1, len(os.sched_getaffinity(0)))
    return os.cpu_count() or 1


POOL_START = 6.4
"""Seconds before a new pool's workers give their first result beyond the work itself
[s]: each spawned worker imports softcurve, loads the cached model and builds its
integrator. Two new workers that each ran a one-member chunk of
``examples/sweep_grid.toml`` took 6.4-7.6 s where the same chunk takes 0.02-0.04 s in
this process (``python benchmarks/bench_pool_start.py``, two cores). A start taken too
long or too short costs at most about itself: a sweep that would gain less stays here."""


def pool_pays(wall: float, cpu: float, remaining: int, processes: int) -> bool:
    """Whether ``remaining`` tasks like one measured in this process finish sooner on a
    new pool of ``processes`` workers, its start (:data:`POOL_START`) counted.

    Here the tasks take ``remaining * wall``. A worker runs a task on one thread, in
    about the CPU seconds it took here (on all of this process's threads), ``processes``
    at a time: ``POOL_START + ceil(remaining / processes) * cpu``. Work that this process
    already spreads over its threads (softcurve's C driver) gains nothing from
    processes; work on one thread (CasADi's integrator) gains when there is enough of it.

    Parameters
    ----------
    wall : float
        Wall time of the measured task in this process [s].
    cpu : float
        CPU time of this process during it, all threads [s].
    remaining : int
        Tasks still to run.
    processes : int
        Workers the pool would have.
    """
    if processes < 2 or remaining < 2:  # one task: one worker's start, nothing in parallel
        return False
    return POOL_START + math.ceil(remaining / processes) * cpu < remaining * wall


def worker_model(
    robot: Robot, quadrature_nodes: int, environment=None, compile: bool = True
) -> Model:
    """The model of ``robot`` in a worker process, kept between the tasks it runs (loading
    the cached library takes milliseconds, building integrators on it more).

    Parameters
    ----------
    robot : Robot
        The robot to model.
    quadrature_nodes : int
        Quadrature nodes of the model.
    environment : Environment, optional
        The obstacles and contact law of the model (None: the free robot).
    compile : bool
        Whether the model is compiled (as the parent's: False runs in CasADi's virtual
        machine).
    """
    key = (
        robot.structure(),
        robot.parameter_vector().tobytes(),
        quadrature_nodes,
        None if environment is None else environment.key(),
        compile,
    )
    if key not in _WORKER_MODELS:
        _WORKER_MODELS.clear()
        _WORKER_MODELS[key] = Model(
            robot, environment=environment, quadrature_nodes=quadrature_nodes, compile=compile
        )
    return _WORKER_MODELS[key]


def model_description(model: Model) -> tuple:
    """The arguments of :func:`worker_model` that rebuild ``model`` in a worker: robot,
    quadrature nodes, environment and whether it is compiled.

    Parameters
    ----------
    model : Model
        The parent's model.
    """
    compiled = model.compiled_library is not None
    return (model.robot, model.quadrature_nodes, model.environment, compiled)


def _is_main_guard(node: ast.AST) -> bool:
    """Whether ``node`` is ``if __name__ == "__main__":`` (either side of the ``==``)."""
    if not isinstance(node, ast.If) or not isinstance(node.test, ast.Compare):
        return False
    test = node.test
    if len(test.ops) != 1 or not isinstance(test.ops[0], ast.Eq):
        return False
    sides = [test.left, test.comparators[0]]
    named = any(isinstance(s, ast.Name) and s.id == "__name__" for s in sides)
    return named and any(isinstance(s, ast.Constant) and s.value == "__main__" for s in sides)


def unguarded_line() -> tuple[str, int] | None:
    """Where the main script calls into softcurve outside ``if __name__ == "__main__":``.

    A spawned worker runs the main script again, as the module ``__mp_main__``: whatever
    its top level does outside that block (loading data, building a model, a fit) is done
    again in every worker, and a worker that reaches a call starting processes fails. This
    walks the calling frames to the main script's top level and reads, from the script's
    syntax tree, whether the statement running there lies inside the block.

    Returns
    -------
    tuple of (str, int) or None
        The script's path and the line of the unguarded top-level statement; None when
        the call is guarded, or the main module is no script a worker would run again
        (an interactive session, ``python -c``, a notebook).
    """
    main = sys.modules.get("__main__")
    path = getattr(main, "__file__", None)
    if main is None or path is None or not os.path.isfile(path):
        return None
    spec = getattr(main, "__spec__", None)
    if spec is not None and (spec.name == "__main__" or spec.name.endswith(".__main__")):
        return None  # a package's __main__ (python -m package): spawn does not rerun it
    frame = inspect.currentframe()
    while frame is not None and not (
        frame.f_globals is vars(main) and frame.f_code.co_name == "<module>"
    ):
        frame = frame.f_back
    if frame is None:  # not called from the script's top level (e.g. a worker's thread)
        return None
    line = frame.f_lineno
    try:
        with open(path, encoding="utf-8") as file:
            tree = ast.parse(file.read(), path)
    except (OSError, SyntaxError, UnicodeDecodeError, ValueError):
        return None
    for node in tree.body:
        if node.lineno <= line <= (node.end_lineno or node.lineno):
            return None if _is_main_guard(node) else (path, line)
    return None


def _check_main_guard() -> None:
    """:class:`~softcurve.ParameterError` before any worker starts, where the main script
    would run again in every worker (:func:`unguarded_line`)."""
    where = unguarded_line()
    if where is None:
        return
    path, line = where
    raise ParameterError(
        f"{os.path.basename(path)}, line {line}: this call starts worker processes, and "
        "each worker runs the script again from the top (workers are spawned), so the "
        "script's loading, model building and fitting would be repeated in every one. "
        'Put the script\'s work under `if __name__ == "__main__":` (or in a function called '
        "from there), or pass processes=1 to stay in this process."
    )


def _pool(size: int) -> ProcessPoolExecutor:
    if _POOL and _POOL[0][0] != size:
        _POOL.pop()[1].shutdown()
    if not _POOL:
        _check_main_guard()
        pool = ProcessPoolExecutor(
            size,
            mp_context=get_context("spawn"),
            initializer=_worker_start,
            initargs=(os.getpid(),),
        )
        _POOL.append((size, pool))
    return _POOL[0][1]


def run_in_processes(function: Callable, tasks: dict, processes: int) -> Iterator[tuple]:
    """Yield ``(key, function(*arguments))`` for every ``key: arguments`` of ``tasks`` as
    the worker processes finish them.

    Parameters
    ----------
    function : callable
        A module-level function (it is pickled by reference into the workers).
    tasks : dict
        ``key -> tuple of arguments``; the arguments are pickled.
    processes : int
        Worker processes of the pool (kept for the next call of the same size).
    """
    pool = _pool(processes)
    futures = {}
    try:
        with _interrupts_blocked():  # the workers start here, as they are needed
            futures = {pool.submit(function, *arguments): key for key, arguments in tasks.items()}
        for future in as_completed(futures):
            yield futures[future], future.result()
    except (KeyboardInterrupt, SystemExit):  # the running tasks would go on: kill them
        futures = {}
        stop_workers()
        raise
    except BrokenProcessPool as exc:
        _POOL.clear()
        raise WorkerDied(
            f"a worker process died ({exc}). Workers are spawned and import the main "
            "module: in a script, start batches and sweeps under "
            "`if __name__ == '__main__':`"
        ) from None
    finally:  # an error, an interrupt or a consumer that stopped: drop what has not begun
        for future in futures:
            future.cancel()
