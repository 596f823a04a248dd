"""Minimum-time flick: the paper's robot swings its tip from rest to a point as fast as
its bellows allow, and stops there.

The paper's robot (preset ifac2020) stands upright at rest with three bellows of
illustrative geometry (10 mm from the backbone, 0.2 cm^2, 0 to 100 kPa). The plan
(softcurve.optimize_trajectory) asks for the tip at GOAL within 1 mm at the end and the
robot at rest there, in the shortest time between SHORTEST and LONGEST (a free final
time, weighted by 1 per second), with a small weight on the pressures' effort; direct
collocation over the full nonlinear model, IPOPT with the exact Hessian. The pressures
it finds are then applied by softcurve.simulate at its default tolerances from the same
start, as a user would apply them.

Printed: the plan's status, final time, iterations and solve time, its first-order
optimality and constraint violation, and how far the simulated tip ends from the goal
and from the plan. Written: the planned tip and pressures (flick.png) and the simulated
motion in the interactive viewer (flick.html).

    python examples/flick.py [--output flick] [--intervals 20] [--quick]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import numpy as np

import softcurve as sc
from softcurve.figures import save_figure

GOAL = np.array([0.02, 0.0, 0.062])
"""Where the tip goes [m], in the base frame: 20 mm to the side, 2 mm down."""

SHORTEST, LONGEST = 0.005, 0.5
"""The final times the plan may take [s]."""

TOLERANCE = 1e-3
"""How close the tip must end to the goal [m]."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default="flick", help="folder for the figure and view")
    parser.add_argument("--intervals", type=int, default=None,
                        help="steps of the plan (default 20)")  # fmt: skip
    parser.add_argument("--quick", action="store_true",
                        help="three quadrature nodes and eight steps (a smoke run)")  # fmt: skip
    args = parser.parse_args()
    if args.quick and args.intervals is not None:
        parser.error("--quick takes its own eight steps: leave out --intervals")
    intervals = 8 if args.quick else 20 if args.intervals is None else args.intervals
    if intervals < 1:
        parser.error(f"--intervals must be at least 1, not {intervals}")
    nodes = {"quadrature_nodes": 3} if args.quick else {}
    output = Path(args.output)
    output.mkdir(parents=True, exist_ok=True)

    began = time.perf_counter()
    model = sc.Model(sc.presets.ifac2020(), **nodes)
    upright = [model.robot.rest_length, 0.0, 0.0]  # straight, at rest
    bellows = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)
    goal = sc.TipTarget(GOAL, tolerance=TOLERANCE)
    plan = sc.optimize_trajectory(
        model, upright, actuator=bellows, horizon=(SHORTEST, LONGEST),
        intervals=intervals, targets=[goal], time_weight=1.0, effort_weight=1e-3,
        rest_at_end=True,
    )  # fmt: skip
    first = time.perf_counter() - began
    print(f"plan: {plan.status.name}: {plan.message}")
    if not plan.success:
        raise SystemExit(1)
    print(f"the tip at the goal in {1e3 * plan.horizon:.1f} ms ({intervals} steps); "
          f"{plan.iterations} iterations, solved in {plan.solve_time:.2f} s "
          f"({first:.1f} s with the model built and compiled)")  # fmt: skip
    print(f"optimality {plan.optimality:.1e}, constraint violation {plan.violation:.1e}")
    run = plan.simulate()
    if not run.success:
        raise SystemExit(f"simulate: {run.message}")
    end = run.tip[-1]
    print(f"simulated: the tip ends {1e3 * np.linalg.norm(end - GOAL):.2f} mm from the goal, "
          f"{1e3 * np.linalg.norm(end - plan.tip[-1]):.2f} mm from the plan; largest "
          f"pressure {plan.u.max() / 1e3:.0f} kPa of {bellows.upper.max() / 1e3:.0f}")  # fmt: skip
    figure = plan.plot(targets=[goal], title=f"minimum-time flick: {1e3 * plan.horizon:.0f} ms")
    print(f"wrote {save_figure(figure, output / 'flick.png')}")
    print(f"wrote {run.to_html(output / 'flick.html', model, actuator=bellows)}")


if __name__ == "__main__":
    main()
