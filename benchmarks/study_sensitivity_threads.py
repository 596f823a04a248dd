"""How much two threads save on a dynamic fit's evaluation, by the size of the model's
sensitivity equations (issue 16, item 6; docs/validation.md, "third stop").

Run:  python benchmarks/study_sensitivity_threads.py [--duration 30] [--repeat 5]
      [--side-by-side]

The trial of ``bench_identification.py`` (the paper robot, three bellows, 12 Hz, five
free parameters, linear hold), shortened to ``--duration`` seconds, on models with 4, 6,
8 and 11 (the default) quadrature nodes: the operations of the sensitivity equations'
right-hand side, and one evaluation on one thread and on two (the right-hand side in two
parts, ``softcurve.simulation.sensitivity._sensitivity``), best of ``--repeat``, the two
alternating twice.

``--side-by-side`` instead times the default model on a busy machine: two processes
evaluating at once (as many as this machine's 2 cores), each on one thread and then on
two, so that every helper thread competes with the other process.
"""

from __future__ import annotations

import argparse
import multiprocessing
import os

from _timing import best_of  # benchmarks/_timing.py: a helper, not a benchmark
from bench_identification import dynamic_evaluator

NODES = (4, 6, 8, 11)
SIDE_BY_SIDE = 2
"""Processes evaluating at once in ``--side-by-side``."""


def _best(duration: float, threads: int, repeat: int, start) -> float:
    """Best of ``repeat`` evaluations on ``threads`` threads, timed once every process
    has built its evaluator (``start``, a barrier)."""
    evaluate, theta = dynamic_evaluator(duration, "linear", None, threads)
    evaluate(theta)  # warm-up
    start.wait()
    return best_of(repeat, lambda: evaluate(theta))[0]


def side_by_side(duration: float, repeat: int) -> None:
    context = multiprocessing.get_context("spawn")
    print(f"| threads per evaluation | best of {repeat} in each of {SIDE_BY_SIDE} processes [s] |")
    print("| --- | --- |")
    for _ in range(2):
        for threads in (1, 2):
            with context.Manager() as manager:
                start = manager.Barrier(SIDE_BY_SIDE)
                with context.Pool(SIDE_BY_SIDE) as pool:
                    task = (duration, threads, repeat, start)
                    walls = pool.starmap(_best, [task] * SIDE_BY_SIDE)
            print(f"| {threads} | {', '.join(f'{w:.3f}' for w in walls)} |", flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--side-by-side", action="store_true", help="two processes at once")
    args = parser.parse_args()
    if args.duration <= 0 or args.repeat < 1:
        parser.error("--duration must be > 0 and --repeat at least 1")
    print(f"load average {os.getloadavg()}, {os.cpu_count()} cores; {args.duration:g} s trial")
    if args.side_by_side:
        side_by_side(args.duration, args.repeat)
        return
    print("| quadrature nodes | operations | one thread [s] | two threads [s] | ratio |")
    print("| --- | --- | --- | --- | --- |")
    for nodes in NODES:
        evaluators = {t: dynamic_evaluator(args.duration, "linear", None, t, nodes) for t in (1, 2)}
        best = {1: float("inf"), 2: float("inf")}
        for _ in range(2):
            for threads, (evaluate, theta) in evaluators.items():
                evaluate(theta)  # warm-up
                wall, _ = best_of(args.repeat, lambda e=evaluate, th=theta: e(th))
                best[threads] = min(best[threads], wall)
        operations = evaluators[1][0].variational.n_instructions()
        print(f"| {nodes} | {operations:,} | {best[1]:.3f} | {best[2]:.3f} | "
              f"{best[1] / best[2]:.2f} |")  # fmt: skip


if __name__ == "__main__":
    main()
