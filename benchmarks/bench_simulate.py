"""Wall time of the paper's 10 s case: softcurve.simulation._simulate against SciPy's RK45.

Run:  python benchmarks/bench_simulate.py [--repeat N] [--quick]

Prints, for each integrator and tolerance, the best wall time of ``--repeat`` runs
(after a warm-up run, so the model is compiled and CasADi's integrator is set up), the
real-time factor (10 s simulated / wall time), the work (steps, right-hand sides,
Jacobians) and the error against a tight-tolerance run (adams, rtol 1e-11): the max over
time and states of |x - x_ref| / (max_t |x_ref| + the state's natural scale).

Pin to one core for the single-core figure, with one BLAS thread (OpenBLAS's idle threads
otherwise spin on the same core after NumPy's eigenvalue call and cost ~20 %):
    OPENBLAS_NUM_THREADS=1 taskset -c 0 python benchmarks/bench_simulate.py
"""

from __future__ import annotations

import argparse
import contextlib
import os
import platform

import numpy as np
from _timing import best_of  # benchmarks/_timing.py: a helper, not a benchmark
from scipy.integrate import solve_ivp

import softcurve as sc
from softcurve.simulation.solvers import _driver as native
from softcurve.simulation.solvers._policy import nominal_scale

Q0, QD0, T_FINAL = np.array([0.064, 25.0, 0.0]), np.array([0.0, 0.0, 1500.0]), 10.0
TARGET_MS = 5.0


def error(x, reference, scale) -> float:
    return float(np.max(np.abs(x - reference) / scale))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=10)
    parser.add_argument("--quick", action="store_true", help="fewer cases, fewer repeats")
    args = parser.parse_args()
    repeat = 3 if args.quick else args.repeat

    model = sc.Model(sc.presets.ifac2020())
    sc.simulate(model, Q0, QD0, t_final=T_FINAL)  # warm-up: CasADi builds its derivative functions
    reference = sc.simulate(model, Q0, QD0, t_final=T_FINAL, method="adams", rtol=1e-11)
    scale = np.abs(reference.x).max(axis=0) + nominal_scale(model, np.zeros(model.n_state))
    affinity = len(os.sched_getaffinity(0)) if hasattr(os, "sched_getaffinity") else "?"
    print(f"softcurve simulate benchmark: paper case, {T_FINAL:g} s, output every 1 ms")
    print(
        f"  {platform.processor() or platform.machine()}, {os.cpu_count()} cores "
        f"({affinity} usable by this process), Python {platform.python_version()}"
    )
    print(f"  reference: cvodes-adams rtol 1e-11, {reference.stats['steps']} steps")
    print()
    header = (
        f"{'integrator':<28}{'rtol':>7}{'wall [ms]':>11}{'x real time':>13}{'steps':>8}"
        f"{'rhs':>8}{'jac':>6}{'error':>10}"
    )
    print(header)
    print("-" * len(header))

    def row(label, rtol, wall, trajectory=None, x=None, work=("", "", "")):
        if trajectory is not None:
            x = trajectory.x
            s = trajectory.stats
            work = (s["steps"], s["rhs_evaluations"], s["jacobian_evaluations"])
        print(
            f"{label:<28}{rtol:>7.0e}{1e3 * wall:>11.2f}{T_FINAL / wall:>13.0f}"
            f"{work[0]!s:>8}{work[1]!s:>8}{work[2]!s:>6}{error(x, reference.x, scale):>10.1e}"
        )

    tolerances = (1e-6,) if args.quick else (1e-4, 1e-6, 1e-8)
    for method in ("cvodes", "adams", "bdf"):
        for rtol in tolerances:
            wall, trajectory = best_of(
                repeat,
                lambda m=method, r=rtol: sc.simulate(
                    model, Q0, QD0, t_final=T_FINAL, method=m, rtol=r
                ),
            )
            label = "simulate " + (
                "(default) " + trajectory.stats["method"]
                if method == "cvodes"
                else trajectory.stats["method"]
            )
            row(label, rtol, wall, trajectory)
    inner = min(
        sc.simulate(model, Q0, QD0, t_final=T_FINAL).stats["wall_time"] for _ in range(repeat)
    )
    label = "  of which integration only"
    print(f"{label:<28}{1e-6:>7.0e}{1e3 * inner:>11.2f}{T_FINAL / inner:>13.0f}")
    with native.casadi_only():  # the previous route: CasADi's CVODES integrator
        wall, trajectory = best_of(repeat, lambda: sc.simulate(model, Q0, QD0, t_final=T_FINAL))
    row("previous: CasADi integrator", 1e-6, wall, trajectory)
    actuated(model, repeat, row)

    x0 = np.concatenate([Q0, QD0, np.zeros(model.n_creep)])
    grid = np.linspace(0.0, T_FINAL, 10001)
    compiled = model.rhs()

    def rhs(t, x):  # a fresh array per call: RK45 keeps earlier derivatives
        return np.array(compiled(t, x))

    for rtol in (1e-6,) if args.quick else (1e-4, 1e-6):
        atol = rtol * nominal_scale(model, x0)
        wall, solution = best_of(
            min(repeat, 3),
            lambda r=rtol, a=atol: solve_ivp(
                rhs, (0.0, T_FINAL), x0, "RK45", t_eval=grid, rtol=r, atol=a
            ),
        )
        row("scipy solve_ivp RK45", rtol, wall, x=solution.y.T, work=("", solution.nfev, 0))
        wall, trajectory = best_of(
            min(repeat, 3),
            lambda r=rtol: sc.simulate(model, Q0, QD0, t_final=T_FINAL, method="rk45", rtol=r),
        )
        row("simulate rk45", rtol, wall, trajectory)

    virtual = sc.Model(sc.presets.ifac2020(), compile=False)
    sc.simulate(virtual, Q0, QD0, t_final=0.1)
    wall, trajectory = best_of(
        1 if args.quick else 2, lambda: sc.simulate(virtual, Q0, QD0, t_final=T_FINAL)
    )
    row("cvodes on CasADi VM (no C)", 1e-6, wall, trajectory)
    print()
    print(f"Target (issue 15): one 10 s run <= {TARGET_MS:g} ms on one core (default row, wall).")
    print("The default integrator is softcurve's C driver of the CVODES inside CasADi, on the")
    print("model's compiled C (Newton matrix by forward differences, kept while CVODES allows);")
    print("'previous' is CasADi's own CVODES integrator on the same C (the route before); the")
    print("VM row runs the right-hand side in CasADi's virtual machine (CasADi's integrator).")
    print(f"Load average while measuring: {os.getloadavg()[0]:.1f} (best of {repeat} runs).")


def actuated(model, repeat, row) -> None:
    """The paper case driven by three bellows at constant pressures (examples/pneumatic.toml's
    actuator), with the C driver and with CasADi's integrator; its own error reference."""
    actuator = sc.PneumaticActuator.three_bellows(
        distance=0.012, area=2e-4, p_max=6e4, time_constant=0.02
    )
    drive = {"actuator": actuator, "inputs": [2e4, 0.0, 1e4], "t_final": T_FINAL}
    sc.simulate(model, Q0, QD0, **drive)  # warm-up: compiles H(q) u once (cached on disk)
    reference = sc.simulate(model, Q0, QD0, **drive, method="adams", rtol=1e-11)
    natural = np.r_[nominal_scale(model, np.zeros(model.n_state)), np.full(3, 6e4)]
    scale = np.abs(reference.x).max(axis=0) + natural[: reference.x.shape[1]]
    for label, context in (("bellows (3 inputs, lag)", contextlib.nullcontext),
                           ("  previous: CasADi integr.", native.casadi_only)):  # fmt: skip
        with context():
            wall, trajectory = best_of(min(repeat, 3), lambda: sc.simulate(model, Q0, QD0, **drive))
        s = trajectory.stats
        work = (s["steps"], s["rhs_evaluations"], s["jacobian_evaluations"])
        x = trajectory.x
        print(
            f"{label:<28}{1e-6:>7.0e}{1e3 * wall:>11.2f}{T_FINAL / wall:>13.0f}"
            f"{work[0]!s:>8}{work[1]!s:>8}{work[2]!s:>6}"
            f"{np.max(np.abs(x - reference.x) / scale):>10.1e}"
        )


if __name__ == "__main__":
    main()
