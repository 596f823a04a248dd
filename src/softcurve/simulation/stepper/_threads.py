"""The stepper's compiled period function called on many members from Python threads.

Why not CasADi's ``map(N, "thread")``: mapped over 256 members of the paper's robot it
ran 1.08x faster on two threads than on one on this project's 2-core machine with
nothing else running (``benchmarks/bench_stepper.py``, section 2, 2026-11-30), the
threads apparently not running the compiled code at the same time. Here the generated
library is opened with ctypes (:class:`~softcurve.compiled.NativeFunction`, one
set of work arrays per thread), which releases the GIL during the foreign call, and each
thread loops over a contiguous chunk of members.
"""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import numpy as np

from softcurve.base.shares import run_shares, share_bounds
from softcurve.compiled import NativeFunction


class MemberShares:
    """A compiled period on every member: the members split into one contiguous share per
    thread (a multiple of :attr:`granularity` members, but the last), each share one
    foreign call through ctypes, which releases the GIL
    (:func:`softcurve.base.shares.run_shares`, on a pool kept between periods).
    Subclasses say how a share is called (:meth:`_share`) and check the arrays
    (:meth:`_arrays`).

    Parameters
    ----------
    threads : int
        Threads over the members.
    """

    granularity = 1
    """Members per unit of a share."""

    def __init__(self, threads: int):
        self._threads = threads
        self._pool: ThreadPoolExecutor | None = None
        self._lock = threading.Lock()

    def _arrays(self, x, u, p, period, out) -> list:
        """``(x, u, p, period)`` as C-contiguous float64 arrays."""
        return [np.ascontiguousarray(a, dtype=np.float64) for a in (x, u, p, period)]

    def _share(self, arrays, out, start: int, stop: int) -> list:
        """Fill rows ``start:stop`` of ``out``; the failures as ``[(i, message), ...]``."""
        raise NotImplementedError

    def __call__(self, x, u, p, period, out) -> list:
        """Fill ``out`` (N, n_out); return the members that failed as ``[(i, message),
        ...]`` (their rows are undefined).

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
        arrays = self._arrays(x, u, p, period, out)
        bounds = share_bounds(out.shape[0], self._threads, self.granularity)
        if bounds.size > 2:
            with self._lock:
                if self._pool is None:
                    self._pool = ThreadPoolExecutor(self._threads, "softcurve-stepper")
        parts = run_shares(lambda a, b: self._share(arrays, out, a, b), bounds, self._threads,
                           self._pool)  # fmt: skip
        return [failure for part in parts for failure in part]


class ThreadedMembers(MemberShares):
    """``function(x_i, u_i, p, period)`` for every member ``i``, one call per member
    (:meth:`~softcurve.compiled.NativeFunction.call_rows`).

    Parameters
    ----------
    function : NativeFunction
        The compiled period function ``(x, u, p, period) -> out``.
    threads : int
        Threads over the members.
    """

    def __init__(self, function: NativeFunction, threads: int):
        super().__init__(threads)
        self._function = function

    def _share(self, arrays, out, start: int, stop: int) -> list:
        return self._function.call_rows(arrays, out, start, stop)
