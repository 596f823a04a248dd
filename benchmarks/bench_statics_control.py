"""Cost of the statics and control tools on the paper's robot (preset ifac2020).

Prints:
- ``equilibria()`` with 48 starts, upright and hanging: wall time, residual evaluations;
- ``inverse_statics()`` for five reachable targets: wall time per target, with the NLP
  expanded to SX (the default) against CasADi's MX graph (the comparison);
- one sample of ``ActuatorMPC`` (horizon 10) against one of ``ComputedTorque``;
- ``export_c()`` and compiling its test program at -O0 and -O2.

Run: ``python benchmarks/bench_statics_control.py [--skip-compile]``
"""

from __future__ import annotations

import argparse
import tempfile
import time
from unittest import mock

import casadi as ca
import numpy as np

import softcurve as sc
from softcurve.analysis.inverse_statics import inverse_statics
from softcurve.analysis.statics import equilibria
from softcurve.compiled._export import build_and_run_test, export_c
from softcurve.control.controllers import ComputedTorque
from softcurve.control.mpc import ActuatorMPC
from softcurve.control.references import tip_circle


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--skip-compile", action="store_true", help="skip the C compile timings")
    args = parser.parse_args()
    model = sc.Model(sc.presets.ifac2020())
    equilibria(model, starts=1)  # build the cached symbolic functions once

    for name, gravity in (("upright", [0, 0, -9.81]), ("hanging", [0, 0, 9.81])):
        start = time.perf_counter()
        table = equilibria(model, gravity=gravity, starts=48)
        wall = time.perf_counter() - start
        print(f"equilibria {name:8s}: {wall:6.3f} s, {table.evaluations} residual evaluations, "
              f"{table.message}")  # fmt: skip

    actuator = sc.PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4)
    angles = np.linspace(0, 2 * np.pi, 5, endpoint=False)
    targets = [np.array([0.015 * np.cos(a), 0.015 * np.sin(a), 0.066]) for a in angles]
    original = ca.Opti.solver

    def without_expand(self, name, options, solver_options):
        return original(self, name, {**options, "expand": False}, solver_options)

    for label, patch in (("expanded (SX)", None), ("MX graph", without_expand)):
        context = mock.patch.object(ca.Opti, "solver", patch) if patch else _nothing()
        with context:
            start = time.perf_counter()
            misses = [inverse_statics(model, actuator, t).distance for t in targets]
            wall = (time.perf_counter() - start) / len(targets)
        print(
            f"inverse_statics {label:14s}: {wall:6.3f} s per target, max miss {max(misses):.1e} m"
        )

    reference = tip_circle(center=(0.02, 0.0, 0.065), radius=0.01, period=2.0)
    state = reference(0.0)
    lam = np.zeros(model.n_creep)
    controllers = {
        "ComputedTorque": ComputedTorque(model, reference, kp=1e4, kd=200, sample_time=1e-3),
        "ActuatorMPC(10)": ActuatorMPC(model, actuator, reference, horizon=10, sample_time=0.01),
    }
    for label, controller in controllers.items():
        controller(0.0, state.q, state.qd, lam)  # first call builds cached functions
        samples = 50
        start = time.perf_counter()
        for k in range(samples):
            controller(0.01 * k, state.q, state.qd, lam)
        wall = (time.perf_counter() - start) / samples
        print(f"{label:16s}: {1e3 * wall:7.3f} ms per sample")

    if args.skip_compile:
        return
    with tempfile.TemporaryDirectory() as directory:
        start = time.perf_counter()
        exported = export_c(model, directory, actuator=actuator)
        print(f"export_c: {time.perf_counter() - start:.2f} s")
        for level in ("-O0", "-O2"):
            start = time.perf_counter()
            result = build_and_run_test(exported, optimization=level).strip().splitlines()[-1]
            wall = time.perf_counter() - start
            print(f"compile + run test program {level}: {wall:.2f} s ({result})")


class _nothing:
    def __enter__(self):
        return self

    def __exit__(self, *exc):
        return False


if __name__ == "__main__":
    main()
