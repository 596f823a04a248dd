"""What a new pool of sweep workers costs before its first result, against this process.

Run:  python benchmarks/bench_pool_start.py [--repeat 3] [--workers 2]

One-member chunks of ``examples/sweep_grid.toml`` (the model cached first): one chunk in
this process (wall and CPU time), then a new pool of ``--workers`` spawned workers that
each import softcurve, load the cached model and run one such chunk. The difference is
``softcurve.simulation.batch.POOL_START``, the start a default sweep weighs against the
work left (``pool_pays``). Other processes on the machine lengthen both; the load average
is printed.
"""

from __future__ import annotations

import argparse
import os
import time
from pathlib import Path

from softcurve.scenarios.sweep import run_chunk
from softcurve.scenarios.sweep_config import load_sweep
from softcurve.simulation.batch import run_in_processes, stop_workers

CONFIG = Path(__file__).parent.parent / "examples" / "sweep_grid.toml"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--workers", type=int, default=2)
    args = parser.parse_args()
    config = load_sweep(CONFIG)
    design = config.design_points()
    run_chunk(config, 0, design[:1], threads=1)  # the model compiled or loaded, once
    print(f"load average {os.getloadavg()[0]:.1f}, {os.cpu_count()} cores")
    for _ in range(args.repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        run_chunk(config, 0, design[:1], threads=1)
        wall, cpu = time.perf_counter() - wall, time.process_time() - cpu
        tasks = {w: (config, w, design[w : w + 1], 1) for w in range(args.workers)}
        start = time.perf_counter()
        list(run_in_processes(run_chunk, tasks, args.workers))
        pool = time.perf_counter() - start
        stop_workers()
        print(
            f"one-member chunk here {wall:.2f} s (CPU {cpu:.2f} s); a new pool of "
            f"{args.workers} running one each {pool:.2f} s: start {pool - wall:.2f} s"
        )


if __name__ == "__main__":
    main()
