"""The one way softcurve spreads work over cores in one process: the members split into
contiguous shares (:func:`share_bounds`), each share one call of the serial algorithm
(:func:`run_shares`), on threads. The calls are foreign calls into compiled code that
release the GIL (ctypes), so threads run them at the same time.

The other ways, each where a loop of shares around the serial algorithm does not fit:

- worker processes, for CasADi's integrator, which reads the process CPU clock around
  every evaluation (threads of one process contend for it):
  :func:`softcurve.simulation.batch.run_in_processes` keeps spawned workers between calls
  and pickles each share's arguments, which a thread needs neither of;
- the sensitivities' helper thread, inside the C driver: it evaluates the second part of
  one right-hand side while the driver evaluates the first, within one integration,
  so there are no members to share out
  (the sensitivities' split in two parts);
- CasADi's map over threads, for CasADi Functions evaluated inside CasADi
  (:func:`softcurve.simulation.solvers.mapped`).
"""

from __future__ import annotations

from collections.abc import Callable
from concurrent.futures import Executor, ThreadPoolExecutor

import numpy as np


def share_bounds(count: int, shares: int, granularity: int = 1) -> list[int]:
    """Bounds ``b`` (k + 1 ints) of at most ``shares`` contiguous shares of ``count``
    members, share ``i`` being ``b[i]:b[i + 1]``: whole units of ``granularity`` members
    (members that must stay together, e.g. a group over lanes), the last share shorter.
    One share costs no NumPy call: a stepper of one environment asks every period.

    Parameters
    ----------
    count : int
        Members.
    shares : int
        Shares wanted, >= 1.
    granularity : int
        Members per unit.
    """
    units = -(-count // granularity)
    if min(units, shares) <= 1:
        return [0, count]
    bounds = np.linspace(0, units, min(units, shares) + 1).astype(int)
    return np.minimum(bounds * granularity, count).tolist()


def run_shares(function: Callable, bounds, threads: int, pool: Executor | None = None) -> list:
    """``[function(a, b) for each share a:b of bounds]``, in order, on ``threads`` threads
    (on the caller's thread where there is one share or one thread).

    Parameters
    ----------
    function : callable
        ``function(start, stop)``: the serial algorithm on members ``start:stop``.
    bounds : array_like of int, shape (k + 1,)
        The shares' bounds (:func:`share_bounds`).
    threads : int
        Threads, >= 1.
    pool : Executor, optional
        A pool kept by the caller between calls (default: one for this call).
    """
    starts, stops = bounds[:-1], bounds[1:]
    if threads <= 1 or len(starts) <= 1:
        return [function(a, b) for a, b in zip(starts, stops, strict=True)]
    if pool is not None:
        return list(pool.map(function, starts, stops))
    with ThreadPoolExecutor(min(threads, len(starts))) as executor:
        return list(executor.map(function, starts, stops))
