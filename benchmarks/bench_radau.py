"""Radau IIA (``method="radau"``) against CVODES (``method="cvodes"``, Adams or BDF as it
picks) through the public entry points, warm, at several tolerances, each run's error
against a tight reference (issue 46, items 2 and 5).

Cases (``--case``):

- ``paper``: the paper's 10 s case (``simulate``, the README's first command).
- ``chain``: 1 s of the hanging chain of ``bench_jacobian.py`` (``--segments``), on the
  exact Jacobian.
- ``settle``: the paper's robot from its equilibrium under gravity, a bending moment (the
  elastic force of a 20 1/m bend) switched on at ``t = 0`` and held for 30 s: a transient
  that dies out, then creep; outputs every 10 ms.
- ``slow``: the same robot and start under the moment ``M (1 - cos(2 pi t / 10 s)) / 2``
  (the slow case of ``study_implicit_steps.py``) sampled at every output (``--dt``,
  default 10 ms) and held between them, as ``simulate`` takes inputs: ``30 s / dt`` small
  jumps of the input, where CVODES restarts and Radau IIA goes on with its step size and
  Jacobian.
- ``batch``: 100 windows of 1 s of the paper's robot (``simulate_batch``, one thread),
  each from a state of the paper's 10 s run (every 0.1 s) under a constant random moment;
  CVODES on its best route (``lanes=True``, groups of four) against Radau IIA.

Each row: the method and ``rtol``, the wall time [ms] (best of ``--repeat``), the work
(steps, right-hand sides, Jacobians, factorizations: CVODES's linear-solver setups,
Radau IIA's pairs of Newton matrices) and the error: the largest difference of the
coordinates from the reference (CVODES at rtol 1e-12), each relative to that coordinate's
largest magnitude. "vs CVODES" is the wall time of the fastest CVODES row at least as
accurate, divided by this row's (above 1: Radau IIA is faster at that error; "-": no
CVODES row that accurate).

Run: ``python benchmarks/bench_radau.py --case paper|chain|settle|slow|batch [--segments 1 2 4
8] [--dt 0.01] [--repeat 5] [--markdown]``
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from _timing import best_of

import softcurve as sc

REFERENCE_RTOL = 1e-12
CVODES_RTOLS = (1e-7, 1e-6, 1e-5, 1e-4)
RADAU_RTOLS = (1e-6, 1e-5, 1e-4, 1e-3)
WORK = {"steps": "steps", "rhs": "rhs_evaluations", "Jacobians": "jacobian_evaluations",
        "LU": "linear_solver_setups"}  # fmt: skip


def paper_case():
    model = sc.Model(sc.presets.ifac2020())
    start = ([0.064, 25.0, 0.0], [0.0, 0.0, 1500.0])
    return lambda **kw: sc.simulate(model, *start, t_final=10.0, **kw)


def chain_case(n_segments: int):
    robot = sc.presets.ifac2020().with_segments(n_segments)
    model = sc.Model(robot)
    q0, qd0 = robot.rest_configuration(), np.zeros(model.n)
    return lambda **kw: sc.simulate(model, q0, qd0, t_final=1.0, jacobian="exact", **kw)


def _moment(model, bend: float = 20.0) -> np.ndarray:
    """The generalized force of a bending moment: the elastic force of a ``bend`` [1/m]
    about x, on the bending coordinate only."""
    rest = model.robot.rest_configuration()
    force = np.abs(model.elastic_force(rest + np.array([0.0, bend, 0.0])))
    return force * np.array([0.0, 1.0, 0.0])


def settle_case():
    model = sc.Model(sc.presets.ifac2020())
    q0 = sc.equilibrium(model, model.robot.rest_configuration()).q
    tau = _moment(model)
    return lambda **kw: sc.simulate(model, q0, np.zeros(3), tau=tau, t_final=30.0, dt=0.01, **kw)


def slow_case(dt: float = 0.01):
    model = sc.Model(sc.presets.ifac2020())
    q0 = sc.equilibrium(model, model.robot.rest_configuration()).q
    t = np.arange(round(30.0 / dt) + 1) * dt
    tau = _moment(model) * 0.5 * (1.0 - np.cos(2.0 * np.pi * t / 10.0))[:, None]
    return lambda **kw: sc.simulate(model, q0, np.zeros(3), tau=tau, t_final=30.0, dt=dt, **kw)


BATCH_SIZE = 100


def batch_case(lanes_for_cvodes: bool = True):
    model = sc.Model(sc.presets.ifac2020())
    paper = sc.simulate(model, [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0], t_final=10.0, dt=0.1)
    rng = np.random.default_rng(46)
    tau = _moment(model) * rng.uniform(-1.0, 1.0, (BATCH_SIZE, 1))
    starts = dict(q0=paper.q[:BATCH_SIZE], qd0=paper.qd[:BATCH_SIZE], lam0=paper.lam[:BATCH_SIZE])

    def run(method="cvodes", **kw):
        lanes = lanes_for_cvodes and method == "cvodes"
        return sc.simulate_batch(model, tau=tau, t_final=1.0, threads=1, lanes=lanes,
                                 method=method, **starts, **kw)  # fmt: skip

    return run


def _error(run, reference) -> float:
    scale = np.abs(reference.q).max(axis=-2, keepdims=True) + 1e-12
    return float(np.max(np.abs(run.q - reference.q) / scale))


def _work(run) -> dict:
    """The run's counters ("-" for a batch, whose results carry none)."""
    return {name: run.stats.get(key, "-") for name, key in WORK.items()}


def rows_of(case, repeat: int) -> list[dict]:
    reference = case(method="cvodes", rtol=REFERENCE_RTOL)
    rows = []
    for method, rtols in (("cvodes", CVODES_RTOLS), ("radau", RADAU_RTOLS)):
        for rtol in rtols:
            wall, run = best_of(repeat, lambda m=method, r=rtol: case(method=m, rtol=r))
            assert run.success, run.message
            rows.append({
                "method": method, "rtol": f"{rtol:g}", "route": run.stats["route"],
                "wall [ms]": 1e3 * wall, **_work(run), "error": _error(run, reference),
            })  # fmt: skip
    cvodes = [r for r in rows if r["method"] == "cvodes"]
    for row in rows:
        accurate = [r["wall [ms]"] for r in cvodes if r["error"] <= row["error"]]
        row["vs CVODES"] = min(accurate) / row["wall [ms]"] if accurate else "-"
    return rows


def show(title: str, rows, markdown: bool) -> None:
    print(f"\n{title}")
    columns = list(rows[0])
    if markdown:
        print("| " + " | ".join(columns) + " |")
        print("|" + " --- |" * len(columns))
    else:
        print("  ".join(columns))
    for row in rows:
        cells = [f"{v:.3g}" if isinstance(v, float) else str(v) for v in row.values()]
        print(("| " + " | ".join(cells) + " |") if markdown else "  ".join(cells))


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=("paper", "chain", "settle", "slow", "batch"),
                        default="paper")  # fmt: skip
    parser.add_argument("--segments", type=int, nargs="+", default=[1, 2, 4, 8])
    parser.add_argument("--dt", type=float, default=0.01, help="--case slow: output interval")
    parser.add_argument("--repeat", type=int, default=5, help="best of this many")
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args(argv)
    if args.case == "chain":
        for n in args.segments:
            show(f"hanging chain, N = {n}, 1 s", rows_of(chain_case(n), args.repeat),
                 args.markdown)  # fmt: skip
        return 0
    cases = {"paper": paper_case, "settle": settle_case, "batch": batch_case,
             "slow": lambda: slow_case(args.dt)}  # fmt: skip
    case = cases[args.case]()
    show(args.case, rows_of(case, args.repeat), args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
