"""Timing shared by the benchmark scripts."""

from __future__ import annotations

import time


def best_of(repeat, run):
    """``(best wall time [s] of `repeat` calls of run(), the last call's result)``."""
    times, result = [], None
    for _ in range(repeat):
        start = time.perf_counter()
        result = run()
        times.append(time.perf_counter() - start)
    return min(times), result
