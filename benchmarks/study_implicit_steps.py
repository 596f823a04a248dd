"""How many steps an L-stable one-step method takes against multistep methods (issue 46,
the choice of item 2), at the same tolerances (``rtol``, and ``atol = rtol`` times each
state's natural scale, as ``simulate``'s default), on the model's exact Jacobian.

- ``--case release``: the hanging chain of ``benchmarks/bench_jacobian.py``, 1 s from
  rest, by ``simulate`` (CVODES in the C driver, Adams or BDF as it picks) and by SciPy's
  ``Radau`` (Radau IIA of order 5) on the compiled right-hand side; per N the counts of
  both and the largest difference of the final states relative to their scales.
- ``--case slow``: the paper's robot (creep included) from its equilibrium under
  gravity, a bending moment ``M (1 - cos(2 pi t / 10 s)) / 2`` on ``kx`` for 30 s (``M``
  the elastic force of a 20 1/m bend): slow inputs, as the identification's trials,
  by SciPy's ``LSODA`` (Adams and BDF switched, as CVODES's choice), ``BDF`` and
  ``Radau``, at ``rtol`` 1e-6 and 1e-8.

SciPy's methods are Python driving NumPy's LU: their wall times say nothing of a method
in C, their counts do (steps, right-hand sides, Jacobians, LU factorizations).

Run: ``python benchmarks/study_implicit_steps.py [--case release|slow] [--segments 1 2 4
8 16] [--rtol 1e-6]``
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


SLOW_PERIOD = 10.0
"""Period of the slow case's moment [s]."""

SLOW_BEND = 20.0
"""The bend [1/m] whose elastic force is the slow case's peak moment."""


def slow_rows(rtols) -> list[dict]:
    model = sc.Model(sc.presets.ifac2020())
    robot = model.robot
    q0 = sc.equilibrium(model, robot.rest_configuration()).q
    x0 = np.concatenate([q0, np.zeros(model.n_state - model.n)])
    bent = robot.rest_configuration() + np.array([0.0, SLOW_BEND, 0.0])
    peak = np.abs(model.elastic_force(bent)) * np.array([0.0, 1.0, 0.0])

    def tau(t):
        return peak * 0.5 * (1.0 - np.cos(2.0 * np.pi * t / SLOW_PERIOD))

    scale = nominal_scale(model, x0)
    rows = []
    for rtol in rtols:
        for method in ("LSODA", "BDF", "Radau"):
            result = solve_ivp(
                lambda t, x: model.rhs(tau(t))(t, x), (0.0, 3 * SLOW_PERIOD), x0,
                method=method, rtol=rtol, atol=rtol * scale,
                jac=lambda t, x: model.rhs_jacobian(x, tau(t)),
            )  # fmt: skip
            assert result.success, result.message
            rows.append({
                "rtol": f"{rtol:g}", "method": method, "steps": result.t.size - 1,
                "rhs": result.nfev, "Jacobians": result.njev, "LU": result.nlu,
            })  # fmt: skip
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--case", choices=("release", "slow"), default="release")
    parser.add_argument("--segments", type=int, nargs="+", default=[1, 2, 4, 8, 16])
    parser.add_argument("--rtol", type=float, default=1e-6)
    args = parser.parse_args(argv)
    if args.case == "slow":
        rows = slow_rows([args.rtol, 1e-8])
    else:
        rows = [study_row(n, args.rtol) for n in args.segments]
    print("| " + " | ".join(rows[0]) + " |")
    print("|" + " --- |" * len(rows[0]))
    for row in rows:
        cells = [f"{v:.2g}" if isinstance(v, float) else str(v) for v in row.values()]
        print("| " + " | ".join(cells) + " |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
