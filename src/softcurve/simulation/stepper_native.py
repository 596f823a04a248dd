"""The stepper's compiled period function called on many members from Python threads.

Why not CasADi's ``map(N, "thread")``: mapped over 256 members of the paper's robot it
ran 1.08x faster on two threads than on one on this project's 2-core machine with
nothing else running (``benchmarks/bench_stepper.py``, section 2, 2026-11-30), the
threads apparently not running the compiled code at the same time. Here the generated
library is opened with ctypes (:class:`~softcurve.compiled.native.NativeFunction`, one
set of work arrays per thread), which releases the GIL during the foreign call, and each
thread loops over a contiguous chunk of members.
"""

from __future__ import annotations

import ctypes
import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from softcurve.compiled.native import NativeFunction


def load_native(path, name: str) -> NativeFunction:
    """The function ``name`` of the compiled library at ``path``, called through ctypes.

    Parameters
    ----------
    path : str or pathlib.Path
        The shared library.
    name : str
        The generated function's name.
    """
    return NativeFunction(ctypes.CDLL(str(path)), name)


class ThreadedMembers:
    """``function(x_i, u_i, p, period)`` for every member ``i``, on ``threads`` threads.

    Parameters
    ----------
    function : NativeFunction
        The compiled period function ``(x, u, p, period) -> out``.
    threads : int
        Threads over the members (contiguous chunks, one per thread).
    """

    def __init__(self, function: NativeFunction, threads: int):
        self._function = function
        self._threads = threads
        self._pool: ThreadPoolExecutor | None = None
        self._lock = threading.Lock()

    def _executor(self) -> ThreadPoolExecutor:
        with self._lock:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(self._threads, "softcurve-stepper")
            return self._pool

    def __call__(self, x, u, p, period, out) -> list:
        """Fill ``out`` (N, n_out) row by row; return the members that failed as
        ``[(i, message), ...]`` (their rows are undefined).

        Parameters
        ----------
        x : ndarray, shape (N, n_x)
            States.
        u : ndarray, shape (N, m)
            Inputs.
        p : ndarray, shape (n_p,)
            The robot's parameter vector.
        period : ndarray, shape (1,)
            The control period [s].
        out : ndarray, shape (N, n_out)
            Where the outputs go (C-contiguous float64).
        """
        count = x.shape[0]
        arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (x, u, p, period)]

        def run(a: int, b: int) -> list:
            return self._function.call_rows(arrays, out, a, b)

        chunks = min(self._threads, count)
        if chunks <= 1:
            return run(0, count)
        bounds = np.linspace(0, count, chunks + 1).astype(int)
        pool = self._executor()
        parts = pool.map(run, bounds[:-1], bounds[1:])
        return [failure for part in parts for failure in part]
