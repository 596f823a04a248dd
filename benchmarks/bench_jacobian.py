"""The exact Jacobian of the state derivative against forward differences (issue 46, item 1).

The robot: ``--segments`` segments of the paper's (``presets.ifac2020().with_segments``)
hanging from the base under gravity, from rest. For each N the script prints

- the compile times from an empty cache of the model's library and then of the exact
  Jacobian's (its own library, built on first use);
- the Jacobian alone through the compiled functions' ctypes calls (about 10 us each):
  the exact ``rhs_jacobian`` against ``n_state + 1`` calls of ``rhs``, what forward
  differences take (an estimate: the driver makes those calls from C, without the
  ctypes overhead, so the ``simulate`` columns are the comparison to read);
- 1 s of ``simulate`` with ``SimulationSettings(jacobian=...)`` each way, warm (best of
  ``--repeat``), with CVODES's steps and Jacobians (the same both ways, else both are
  printed) and the largest difference of the final states.

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

CALLS = 20
"""Calls of the exact Jacobian per timing (a few milliseconds at sixteen segments)."""

RHS_CALLS = 1000
"""Calls of ``rhs`` per timing (a few microseconds each)."""


def jacobian_row(n_segments: int, repeat: int) -> dict:
    robot = sc.presets.ifac2020().with_segments(n_segments)
    start = time.perf_counter()
    model = sc.Model(robot)
    model_compile = time.perf_counter() - start
    native = model.compiled_jacobian()
    jacobian_compile = time.perf_counter() - start - model_compile
    rhs = model.compiled_function("rhs")
    x = np.concatenate([robot.rest_configuration(), np.zeros(model.n_state - model.n)])
    tau, p = np.zeros(model.n), model.parameters
    exact, _ = best_of(repeat, lambda: [native(x, tau, p) for _ in range(CALLS)])
    one, _ = best_of(repeat, lambda: [rhs(x, tau, p) for _ in range(RHS_CALLS)])
    row = {
        "N": n_segments,
        "n_state": model.n_state,
        "model's compile [s]": model_compile,
        "Jacobian's compile [s]": jacobian_compile,
        "one exact Jacobian [us]": 1e6 * exact / CALLS,
        "differences, estimated [us]": 1e6 * one / RHS_CALLS * (model.n_state + 1),
    }
    finals, counts = {}, {}
    q0, qd0 = robot.rest_configuration(), np.zeros(model.n)
    for jacobian in ("differences", "exact"):
        settings = SimulationSettings(t_final=1.0, jacobian=jacobian)
        wall, result = best_of(repeat, lambda s=settings: sc.simulate(model, q0, qd0, settings=s))
        assert result.success, result.message
        row[f"simulate, {jacobian} [ms]"] = 1e3 * wall
        counts[jacobian] = f"{result.stats['steps']} / {result.stats['jacobian_evaluations']}"
        finals[jacobian] = np.concatenate([result.q[-1], result.qd[-1]])
    same = counts["differences"] == counts["exact"]
    row["steps / Jacobians"] = counts["exact"] if same else " vs ".join(counts.values())
    row["final states apart"] = float(np.abs(finals["exact"] - finals["differences"]).max())
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
