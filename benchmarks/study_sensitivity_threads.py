"""How much two threads save on a dynamic fit's evaluation, by the size of the model's
sensitivity equations (issue 16, item 6; docs/validation.md, "third stop").

Run:  python benchmarks/study_sensitivity_threads.py [--duration 30] [--repeat 5]

The trial of ``bench_identification.py`` (the paper robot, three bellows, 12 Hz, five
free parameters, linear hold), shortened to ``--duration`` seconds, on models with 4, 6,
8 and 11 (the default) quadrature nodes: the operations of the sensitivity equations'
right-hand side, and one evaluation on one thread and on two (the right-hand side in two
parts, ``softcurve.simulation.sensitivity_split``), best of ``--repeat``, the two
alternating twice.
"""

from __future__ import annotations

import argparse
import os

from _timing import best_of  # benchmarks/_timing.py: a helper, not a benchmark
from bench_identification import dynamic_evaluator

NODES = (4, 6, 8, 11)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    if args.duration <= 0 or args.repeat < 1:
        parser.error("--duration must be > 0 and --repeat at least 1")
    print(f"load average {os.getloadavg()}, {os.cpu_count()} cores; {args.duration:g} s trial")
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
