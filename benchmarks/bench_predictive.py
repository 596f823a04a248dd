"""Nonlinear model-predictive control (``sc.PredictiveController``) of the paper's robot
with bellows tracking a tip circle, through ``simulate(controller=...)``, against the
linear MPC (``ActuatorMPC``) on the same robot, bounds and circle.

Run:  python benchmarks/bench_predictive.py [--t-final 2] [--hessians gauss-newton exact]
      [--iterations 1] [--horizon 0.5] [--intervals 25]

The robot is the paper's (preset ifac2020, its quadrature) with three bellows of 2 cm^2
at 12 mm, 0 to 60 kPa; the circle is docs/control.md's (radius 10 mm at 65 mm, period
2 s), started on it at rest with no pressure. The controller plans ``--horizon`` seconds
in ``--intervals`` steps and samples every step (20 ms by default: the target of a 0.5 s
horizon at 20 ms). For each Hessian of the Lagrangian it prints the first
sample's time (the problem built, its derivatives compiled where they are not cached, the
first solve to convergence),
the median and largest solve time of the later samples beside the sample time (the
real-time target: the median within it) and what their evaluations took (the Hessian of
the Lagrangian, the constraints' Jacobian, ...), their iterations and statuses, and the tip's
distance from the circle after the first second (mean, largest); then the linear MPC's
(the same rate weight) at the same steps and horizon, and at docs/control.md's 10
samples of 10 ms: its time per sample and tip errors.
"""

from __future__ import annotations

import argparse
import time
from collections import Counter

import numpy as np

import softcurve as sc
from softcurve.control.mpc import ActuatorMPC
from softcurve.control.references import tip_circle

CIRCLE = {"center": (0.02, 0.0, 0.065), "radius": 0.01, "period": 2.0}
"""docs/control.md's circle [m, m, s]."""

RATE_WEIGHT = 1e-6
"""The weight of the input changes of both controllers (dimensionless)."""

SETTLE = 1.0
"""The start's transient [s], left out of the tip errors."""


def tip_errors(model, run, reference) -> np.ndarray:
    """The tip's distance [m] from the circle at the outputs after the transient."""
    late = run.t >= SETTLE - 1e-12
    goal = np.array([model.tip_pose(reference(t).q).position for t in run.t[late]])
    return np.linalg.norm(run.tip[late] - goal, axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--t-final", type=float, default=2.0, help="simulated time [s]")
    parser.add_argument("--hessians", nargs="+", default=list(sc.control.PREDICTIVE_HESSIANS),
                        choices=sc.control.PREDICTIVE_HESSIANS)  # fmt: skip
    parser.add_argument("--iterations", type=int, default=1, help="budget of a later solve")
    parser.add_argument("--horizon", type=float, default=0.5, help="[s]")
    parser.add_argument("--intervals", type=int, default=25)
    args = parser.parse_args()
    if not args.t_final > SETTLE:
        parser.error(f"--t-final must exceed the {SETTLE:g} s transient")
    model = sc.Model(sc.presets.ifac2020())
    bellows = sc.PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4)
    circle = tip_circle(**CIRCLE)
    start = circle(0.0)
    step = args.horizon / args.intervals
    print(f"paper robot, bellows 0-60 kPa, circle r 10 mm; horizon {args.horizon:g} s in "
          f"{args.intervals} steps of {1e3 * step:g} ms, {args.t_final:g} s simulated")  # fmt: skip
    for hessian in args.hessians:
        mpc = sc.PredictiveController(
            model, bellows, circle, horizon=args.horizon, intervals=args.intervals,
            rate_weight=RATE_WEIGHT, hessian=hessian, iterations=args.iterations,
        )  # fmt: skip
        label = f"{hessian} Hessian"
        began = time.perf_counter()
        first = mpc(0.0, start.q, start.qd)
        first_time = time.perf_counter() - began
        mpc.reset()  # the problem and its solvers are kept: the run's first sample is warm
        run = sc.simulate(model, start.q, start.qd, actuator=bellows, controller=mpc,
                          t_final=args.t_final, dt=step)  # fmt: skip
        assert run.success, run.message
        np.testing.assert_allclose(mpc.log[0]["inputs"], first)
        solves = mpc.history("solve_time")[1:]
        iterations = mpc.history("iterations")[1:]
        statuses = Counter(entry["status"].name for entry in mpc.log[1:])
        errors = tip_errors(model, run, circle)
        print(f"{label}: first sample {first_time:.1f} s; later solves median "
              f"{1e3 * np.median(solves):.0f} ms, largest {1e3 * solves.max():.0f} ms "
              f"against the {1e3 * step:g} ms sample ({np.median(solves) / step:.0f}x); "
              f"iterations median {np.median(iterations):g}, largest {iterations.max()}; "
              f"{dict(statuses)}; tip after {SETTLE:g} s: mean {1e3 * errors.mean():.3f} mm, "
              f"largest {1e3 * errors.max():.3f} mm")  # fmt: skip
        timings = [entry["timings"] for entry in mpc.log[1:]]
        split = ", ".join(f"{name} {1e3 * np.median([t[name] for t in timings]):.0f}"
                          for name in timings[0])  # fmt: skip
        print(f"{label}: a later solve's evaluations, median [ms]: {split}")
    # the linear MPC at the nonlinear one's steps, and at docs/control.md's 10 x 10 ms
    for samples, sample_time in ((args.intervals, step), (10, 0.01)):
        linear = ActuatorMPC(model, bellows, circle, horizon=samples, sample_time=sample_time,
                             rate_weight=RATE_WEIGHT)  # fmt: skip
        began = time.perf_counter()
        run = sc.simulate(model, start.q, start.qd, actuator=bellows, controller=linear,
                          t_final=args.t_final, dt=sample_time)  # fmt: skip
        elapsed = time.perf_counter() - began
        if not run.success:
            print(f"linear MPC ({samples} x {1e3 * sample_time:g} ms): {run.message}")
            continue
        errors = tip_errors(model, run, circle)
        print(f"linear MPC ({samples} x {1e3 * sample_time:g} ms): "
              f"{1e3 * elapsed / len(linear.log):.0f} ms a sample (the run over its samples); "
              f"tip after {SETTLE:g} s: mean {1e3 * errors.mean():.3f} mm, largest "
              f"{1e3 * errors.max():.3f} mm")  # fmt: skip


if __name__ == "__main__":
    main()
