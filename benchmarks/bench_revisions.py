"""One 10 s run of the paper case at two git revisions, alternating, in the same minutes.

Run:  python benchmarks/bench_revisions.py BASE [HEAD] [--runs 150] [--rounds 3]
      python benchmarks/bench_revisions.py BASE [HEAD] --script "bench_batch.py --repeat 3"

On a shared machine the speed of the minute swings by up to two times, so a change of
10 % shows only when the code before and after it run in turns. Each revision is
checked out in a temporary git worktree; each round runs ``--runs`` simulations per
revision in a fresh process pinned to one core (``taskset -c 0`` where it exists, one
BLAS thread) and prints the best and the median wall time of ``sc.simulate`` and of its
integration (``stats["wall_time"]``). Both revisions share this machine's compiled-model
cache; a driver whose C source differs is compiled at its first run, before the timing.

With ``--script``, each round runs that benchmark of ``benchmarks/`` instead, each
revision its own copy of it on its own code, and prints what it prints under a heading
naming the revision and the round: any benchmark before and after a change, in turns.
"""

from __future__ import annotations

import argparse
import os
import shutil
import subprocess
import sys
import tempfile
from pathlib import Path

RUN = """
import time, numpy as np, softcurve as sc
model = sc.Model(sc.presets.ifac2020())
q0, qd0 = np.array([0.064, 25.0, 0.0]), np.array([0.0, 0.0, 1500.0])
sc.simulate(model, q0, qd0, t_final=10.0)
total, inner = [], []
for _ in range({runs}):
    start = time.perf_counter()
    run = sc.simulate(model, q0, qd0, t_final=10.0)
    total.append(time.perf_counter() - start)
    inner.append(run.stats["wall_time"])
print(1e3 * min(total), 1e3 * np.median(total), 1e3 * min(inner), 1e3 * np.median(inner))
"""


def measure(source: Path, runs: int) -> list[float]:
    """``[best, median]`` of the whole run and of the integration [ms] at ``source``."""
    env = {**os.environ, "PYTHONPATH": str(source / "src"), "OPENBLAS_NUM_THREADS": "1"}
    pin = ["taskset", "-c", "0"] if shutil.which("taskset") else []
    command = [*pin, sys.executable, "-c", RUN.format(runs=runs)]
    result = subprocess.run(command, env=env, capture_output=True, text=True, check=True)
    return [float(value) for value in result.stdout.split()]


def run_script(source: Path, script: str) -> str:
    """The output of ``benchmarks/<script>`` (with its arguments) of the tree ``source``."""
    env = {**os.environ, "PYTHONPATH": str(source / "src")}
    name, *arguments = script.split()
    command = [sys.executable, str(source / "benchmarks" / name), *arguments]
    result = subprocess.run(command, env=env, capture_output=True, text=True, cwd=source)
    return result.stdout + result.stderr


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("base", help="the revision before (e.g. a commit)")
    parser.add_argument("head", nargs="?", default="HEAD", help="the revision after")
    parser.add_argument("--runs", type=int, default=150)
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument(
        "--script", help='a benchmark of benchmarks/ with its arguments, e.g. "bench_batch.py"'
    )
    args = parser.parse_args()
    repository = Path(__file__).resolve().parent.parent
    if args.runs < 1 or args.rounds < 1:
        parser.error(f"--runs and --rounds must be at least 1, got {args.runs} and {args.rounds}")
    for name in (args.base, args.head):
        verify = ["rev-parse", "--verify", "--quiet", f"{name}^{{commit}}"]
        known = subprocess.run(["git", "-C", str(repository), *verify], capture_output=True)
        if known.returncode != 0:
            parser.error(f"revision {name!r} is not a commit of {repository}")
    with tempfile.TemporaryDirectory() as scratch:
        trees = {}
        for name in (args.base, args.head):
            tree = Path(scratch) / f"tree{len(trees)}"
            subprocess.run(
                ["git", "-C", str(repository), "worktree", "add", "-q", "--detach", str(tree),
                 name], check=True)  # fmt: skip
            trees[name] = tree
        try:
            if args.script:
                for k in range(args.rounds):
                    for name, tree in trees.items():
                        print(f"== {args.script}: {name}, round {k + 1}", flush=True)
                        print(run_script(tree, args.script), flush=True)
                return
            print(f"{'round':>5}  {'revision':<12}{'best':>8}{'median':>9}"
                  f"{'integration best':>18}{'median':>9}   [ms]")  # fmt: skip
            for tree in trees.values():
                measure(tree, 1)  # builds what this revision needs, outside the timing
            for k in range(args.rounds):
                for name, tree in trees.items():
                    best, median, inner_best, inner_median = measure(tree, args.runs)
                    print(f"{k + 1:>5}  {name:<12}{best:>8.2f}{median:>9.2f}"
                          f"{inner_best:>18.2f}{inner_median:>9.2f}")  # fmt: skip
        finally:
            for tree in trees.values():
                subprocess.run(
                    ["git", "-C", str(repository), "worktree", "remove", "--force", str(tree)],
                    check=False,
                )


if __name__ == "__main__":
    main()
