"""The exact Jacobian of the state derivative against forward differences (issue 46, item 1).

The robot: ``--segments`` segments of the paper's (``presets.ifac2020().with_segments``)
hanging from the base under gravity, from rest. For each N the script prints

- the Jacobian alone, in C through the compiled functions' ctypes calls: the exact
  ``rhs_jacobian`` (``Model.rhs_jacobian``'s library) against the ``n_state + 1``
  right-hand sides that forward differences take (one call of ``rhs`` timed and
  multiplied, so the calls' overhead counts once per right-hand side, as in the
  driver it does not: the differences' figure is a lower bound of nothing, an estimate);
- its compile time from an empty cache (the library of the Jacobian alone, beside the
  model's);
- 1 s of ``simulate`` with ``SimulationSettings(jacobian=...)`` each way, warm (best of
  ``--repeat``), with CVODES's steps and Jacobians, and the largest difference of the
  final states.

Run: ``python benchmarks/bench_jacobian.py [--segments 1 2 4 8 16] [--markdown]``
"""

from __future__ import annotations

import argparse
import os
import sys
import tempfile
import time

import numpy as np
from _timing import best_of

import softcurve as sc
from softcurve.simulation import SimulationSettings


def jacobian_row(n_segments: int, repeat: int) -> dict:
    robot = sc.presets.ifac2020().with_segments(n_segments)
    model = sc.Model(robot)
    start = time.perf_counter()
    native = model.compiled_jacobian()
    compile_time = time.perf_counter() - start
    rhs = model.compiled_function("rhs")
    x = np.concatenate([robot.rest_configuration(), np.zeros(model.n_state - model.n)])
    tau = np.zeros(model.n)
    calls = 20
    exact, _ = best_of(repeat, lambda: [native(x, tau, model.parameters) for _ in range(calls)])
    one, _ = best_of(repeat, lambda: [rhs(x, tau, model.parameters) for _ in range(50 * calls)])
    exact, one = exact / calls, one / (50 * calls)
    row = {
        "N": n_segments,
        "n_state": model.n_state,
        "exact [us]": 1e6 * exact,
        "differences [us]": 1e6 * one * (model.n_state + 1),
        "compile [s]": compile_time,
    }
    finals = {}
    q0, qd0 = robot.rest_configuration(), np.zeros(model.n)
    for jacobian in ("differences", "exact"):
        settings = SimulationSettings(t_final=1.0, jacobian=jacobian)
        wall, result = best_of(repeat, lambda s=settings: sc.simulate(model, q0, qd0, settings=s))
        assert result.success, result.message
        row[f"simulate {jacobian} [ms]"] = 1e3 * wall
        row[f"steps / Jacobians {jacobian}"] = (
            f"{result.stats['steps']} / {result.stats['jacobian_evaluations']}"
        )
        finals[jacobian] = np.concatenate([result.q[-1], result.qd[-1]])
    row["final state apart"] = float(np.abs(finals["exact"] - finals["differences"]).max())
    return row


def show(rows, markdown: bool) -> None:
    columns = list(rows[0])
    if markdown:
        print("| " + " | ".join(columns) + " |")
        print("|" + " --- |" * len(columns))
    for row in rows:
        cells = [f"{v:.3g}" if isinstance(v, float) else str(v) for v in row.values()]
        print(("| " + " | ".join(cells) + " |") if markdown else "  ".join(cells))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segments", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    parser.add_argument("--repeat", type=int, default=3, help="best of this many")
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args(argv)
    with tempfile.TemporaryDirectory() as cache:
        os.environ["SOFTCURVE_CACHE_DIR"] = cache  # every compile time from an empty cache
        rows = [jacobian_row(n, args.repeat) for n in args.segments]
    show(rows, args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
