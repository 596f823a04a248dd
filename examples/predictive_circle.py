"""Nonlinear model-predictive control against the linear one: the paper's robot tracks a
tip circle with bounded bellows.

The paper's robot (preset ifac2020) with three bellows of illustrative geometry (12 mm
from the backbone, 2 cm^2, 0 to 60 kPa) follows docs/control.md's horizontal circle
(radius 10 mm at 65 mm height, one turn in 2 s), started on it at rest with no pressure.
Three controllers, each run by softcurve.simulate:

- softcurve.PredictiveController: the full nonlinear model by direct collocation over a
  0.5 s horizon in 25 steps of 20 ms, re-planned at every 20 ms sample, warm-started
  from the previous plan, one IPOPT iteration a sample (a real-time iteration) on the
  Gauss-Newton Hessian (the defaults);
- the linear MPC (softcurve.control.mpc.ActuatorMPC, re-linearized at every sample) at
  the same 25 steps of 20 ms;
- the linear MPC at its own 10 samples of 10 ms (docs/control.md's).

Printed per controller: the tip's mean and largest distance from the circle after the
first second, and the time a sample took to compute (the nonlinear controller's solves:
median and largest, and its iterations). Written: the tip errors over time and the
nonlinear controller's solve times (predictive_circle.png), and its run in the
interactive viewer (predictive_circle.html).

    python examples/predictive_circle.py [--output predictive_circle] [--t-final 2]
    python examples/predictive_circle.py --quick   # a smoke run: 0.2 s, a 0.1 s horizon
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import softcurve as sc
from softcurve.control.mpc import ActuatorMPC
from softcurve.control.references import tip_circle
from softcurve.figures import save_figure

CIRCLE = {"center": (0.02, 0.0, 0.065), "radius": 0.01, "period": 2.0}
"""The circle [m, m, s]."""

RATE_WEIGHT = 1e-6
"""Weight of the pressures' changes, both controllers (dimensionless)."""

SETTLE = 1.0
"""The start's transient [s], left out of the printed errors."""


def tip_errors(model, run, reference) -> np.ndarray:
    """The tip's distance [m] from the circle at the outputs."""
    goal = np.array([model.tip_pose(reference(t).q).position for t in run.t])
    return np.linalg.norm(run.tip - goal, axis=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default="predictive_circle", help="folder of the files")
    parser.add_argument("--t-final", type=float, default=None,
                        help="simulated time [s] (default 2)")  # fmt: skip
    parser.add_argument("--quick", action="store_true",
                        help="0.2 s, a 0.1 s horizon of 5 steps, a three-node model in "
                             "CasADi's virtual machine (a smoke run)")  # fmt: skip
    args = parser.parse_args()
    if args.quick and args.t_final is not None:
        parser.error("--quick takes its own 0.2 s: leave out --t-final")
    t_final = 0.2 if args.quick else 2.0 if args.t_final is None else args.t_final
    settle = 0.1 if args.quick else SETTLE
    if not t_final > settle:
        parser.error(f"--t-final must exceed the {settle:g} s transient, not {t_final:g}")
    horizon, intervals = (0.1, 5) if args.quick else (0.5, 25)
    step = horizon / intervals
    output = Path(args.output)
    output.mkdir(parents=True, exist_ok=True)

    settings = {"quadrature_nodes": 3, "compile": False} if args.quick else {}
    model = sc.Model(sc.presets.ifac2020(), **settings)
    bellows = sc.PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4)
    circle = tip_circle(**CIRCLE)
    start = circle(0.0)
    controllers = {
        f"nonlinear MPC, {intervals} x {1e3 * step:g} ms": sc.PredictiveController(
            model, bellows, circle, horizon=horizon, intervals=intervals,
            rate_weight=RATE_WEIGHT,
        ),
        f"linear MPC, {intervals} x {1e3 * step:g} ms": ActuatorMPC(
            model, bellows, circle, horizon=intervals, sample_time=step, rate_weight=RATE_WEIGHT
        ),
        "linear MPC, 10 x 10 ms": ActuatorMPC(
            model, bellows, circle, horizon=10, sample_time=0.01, rate_weight=RATE_WEIGHT
        ),
    }  # fmt: skip
    figure, (errors_ax, solves_ax) = plt.subplots(2, 1, figsize=(7.5, 6), sharex=True)
    runs = {}
    for name, controller in controllers.items():
        began = time.perf_counter()
        run = sc.simulate(model, start.q, start.qd, actuator=bellows, controller=controller,
                          t_final=t_final, dt=controller.sample_time)  # fmt: skip
        elapsed = time.perf_counter() - began
        runs[name] = run
        if not run.success:  # a result where a linear MPC leaves the domain
            print(f"{name}: {run.message}")
            continue
        errors = tip_errors(model, run, circle)
        late = errors[run.t >= settle - controller.sample_time / 2]  # outputs from settle on
        line = (f"{name}: tip after {settle:g} s: mean {1e3 * late.mean():.3f} mm, largest "
                f"{1e3 * late.max():.3f} mm; ")  # fmt: skip
        if isinstance(controller, sc.PredictiveController):
            solves = controller.history("solve_time")
            line += (f"solves median {1e3 * np.median(solves[1:]):.0f} ms, largest "
                     f"{1e3 * solves[1:].max():.0f} ms (first {solves[0]:.2f} s), iterations "
                     f"median {np.median(controller.history('iterations')[1:]):g}")  # fmt: skip
            solves_ax.semilogy(controller.history("t"), 1e3 * solves, ".-", label=name)
            solves_ax.axhline(1e3 * step, color="0.4", ls="--", lw=0.8, label="the sample time")
        else:
            line += f"{1e3 * elapsed / len(controller.log):.0f} ms a sample (the whole run)"
        print(line)
        errors_ax.semilogy(run.t[1:], 1e3 * errors[1:], label=name)  # the start is on it
    errors_ax.set(ylabel="tip from the circle [mm]", title="tracking a 10 mm circle, 0-60 kPa")
    errors_ax.legend(fontsize=8)
    solves_ax.set(xlabel="time t [s]", ylabel="solve [ms]")
    solves_ax.legend(fontsize=8)
    for ax in (errors_ax, solves_ax):
        ax.grid(alpha=0.3)
    print(f"wrote {save_figure(figure, output / 'predictive_circle.png')}")
    plt.close(figure)
    nonlinear = runs[next(iter(controllers))]
    if not nonlinear.success:
        raise SystemExit(1)
    print(f"wrote {nonlinear.to_html(output / 'predictive_circle.html', model, actuator=bellows)}")


if __name__ == "__main__":
    main()
