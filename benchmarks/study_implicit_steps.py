"""How many steps an L-stable one-step method takes where CVODES's multistep methods are
held by stability (issue 46, the choice of item 2): the hanging chain of
``benchmarks/bench_jacobian.py``, 1 s from rest, by ``simulate`` (CVODES in the C driver,
Adams or BDF as it picks, on the exact Jacobian) and by SciPy's ``Radau`` (Radau IIA of
order 5) on the compiled right-hand side with the model's exact Jacobian, at the same
tolerances (``rtol``, and ``atol = rtol`` times each state's natural scale, as
``simulate``'s default).

SciPy's Radau is Python driving NumPy's LU: its wall time says nothing of a method in C,
its counts do. For each N the script prints the steps, right-hand sides, Jacobians and
LU factorizations of both, and the largest difference of the final states relative to
their scales.

Run: ``python benchmarks/study_implicit_steps.py [--segments 1 2 4 8 16] [--rtol 1e-6]``
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from scipy.integrate import solve_ivp

import softcurve as sc
from softcurve.simulation import SimulationSettings
from softcurve.simulation.solvers import nominal_scale


def study_row(n_segments: int, rtol: float) -> dict:
    robot = sc.presets.ifac2020().with_segments(n_segments)
    model = sc.Model(robot)
    x0 = np.concatenate([robot.rest_configuration(), np.zeros(model.n_state - model.n)])
    settings = SimulationSettings(t_final=1.0, rtol=rtol, jacobian="exact")
    cvodes = sc.simulate(model, x0[: model.n], x0[model.n : 2 * model.n], settings=settings)
    assert cvodes.success, cvodes.message
    scale = nominal_scale(model, x0)
    tau = np.zeros(model.n)
    rhs = model.rhs(tau)
    radau = solve_ivp(
        rhs, (0.0, 1.0), x0, method="Radau", rtol=rtol, atol=rtol * scale,
        jac=lambda t, x: model.rhs_jacobian(x, tau),
    )  # fmt: skip
    assert radau.success, radau.message
    final = np.concatenate([cvodes.q[-1], cvodes.qd[-1], cvodes.lam[-1]])
    stats = cvodes.stats
    return {
        "N": n_segments,
        "CVODES": stats["method"],
        "steps": stats["steps"],
        "rhs": stats["rhs_evaluations"],
        "Jacobians": stats["jacobian_evaluations"],
        "Radau steps": radau.t.size - 1,
        "Radau rhs": radau.nfev,
        "Radau Jacobians": radau.njev,
        "Radau LU": radau.nlu,
        "apart / scale": float(np.max(np.abs(radau.y[:, -1] - final) / scale)),
    }


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segments", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    parser.add_argument("--rtol", type=float, default=1e-6)
    args = parser.parse_args(argv)
    rows = [study_row(n, args.rtol) for n in args.segments]
    print("| " + " | ".join(rows[0]) + " |")
    print("|" + " --- |" * len(rows[0]))
    for row in rows:
        cells = [f"{v:.2g}" if isinstance(v, float) else str(v) for v in row.values()]
        print("| " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
