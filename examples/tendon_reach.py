"""Reaching behind a sphere: a two-segment tendon robot plans its way around a ball to a
point behind it, without touching it.

The robot and its tendons are tendon_tracking.py's (two segments of 10 cm, the proximal
one twice as stiff; three tendons per segment 8 mm from the backbone, tensions bounded
to [0.2, 5] N, here applied without a lag). A ball (BALL) stands between the upright
robot and the goal (GOAL), just behind the ball as the robot sees it. The plan
(softcurve.optimize_trajectory, direct collocation over the full nonlinear model with the
exact Hessian) asks for the tip within 2 mm of the goal after HORIZON seconds and at rest
there, with a small weight on the tensions, and for every contact point of the backbone
to keep CLEARANCE from the ball's surface at every node: the segments' contact radius,
inside which the contact law would push. The plan's tensions are then applied by
softcurve.simulate, the ball's contact law included, from the same start, its clearance
checked every millisecond (between the nodes the motion may cut a corner).

Printed: the plan's status, iterations and solve time, the least clearance of the plan
and of the simulated motion, and where the simulated tip ends. Written: the backbone at
eight times with the ball, from the side and from above (tendon_reach.png), and the
simulated motion in the interactive viewer (tendon_reach.html).

The first run compiles the robot's dynamics with their second derivatives (about half a
minute); the plan itself takes about 12 s on two cores.

    python examples/tendon_reach.py [--output tendon_reach] [--intervals 20]
"""

from __future__ import annotations

import argparse
import time
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from tendon_tracking import DISTAL, PROXIMAL, build

import softcurve as sc
from softcurve.figures import plot_backbones, save_figure

BALL = sc.Sphere([0.07, 0.0, 0.15], 0.02)
"""The obstacle [m]: between the upright robot (tip at 200 mm) and the goal."""

GOAL = np.array([0.105, 0.0, 0.12])
"""Where the tip goes [m], behind the ball."""

TOLERANCE = 2e-3
"""How close the tip must end to the goal [m]."""

HORIZON = 1.0
"""The plan's duration [s]."""

CONTACT_RADIUS = max(PROXIMAL.radius, DISTAL.radius)
"""The larger contact radius of the two segments (their slice radii) [m]: inside it from
the ball's surface, the contact law pushes."""

CLEARANCE = CONTACT_RADIUS
"""The least distance [m] of the backbone from the ball's surface at the plan's nodes: the
contact radius (a millimetre more left the plan without a solution in 300 iterations)."""

CONTACT_STIFFNESS = 1e4
"""The penalty stiffness of the ball's contact law [N/m per metre of backbone]: what
would push, were the clearance not kept."""

CHECK_STEP = 1e-3
"""The output step [s] at which the simulated motion's clearance is checked."""


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default="tendon_reach", help="folder of the files")
    parser.add_argument("--intervals", type=int, default=20, help="steps of the plan")
    args = parser.parse_args()
    if args.intervals < 2:
        parser.error(f"--intervals must be at least 2, not {args.intervals}")
    output = Path(args.output)
    output.mkdir(parents=True, exist_ok=True)

    began = time.perf_counter()
    environment = sc.Environment([BALL], sc.ContactLaw(CONTACT_STIFFNESS))
    model, tendons, _ = build(environment, time_constant=None)
    upright = [PROXIMAL.rest_length, 0.0, 0.0, DISTAL.rest_length, 0.0, 0.0]
    goal = sc.TipTarget(GOAL, tolerance=TOLERANCE)
    plan = sc.optimize_trajectory(
        model, upright, actuator=tendons, horizon=HORIZON, intervals=args.intervals,
        targets=[goal], effort_weight=1e-3, rest_at_end=True, clearance=CLEARANCE,
    )  # fmt: skip
    first = time.perf_counter() - began
    print(f"plan: {plan.status.name}: {plan.message}")
    if not plan.success:
        raise SystemExit(1)
    print(f"{plan.iterations} iterations, solved in {plan.solve_time:.1f} s ({first:.0f} s with "
          f"the model built and compiled); optimality {plan.optimality:.1e}, violation "
          f"{plan.violation:.1e}")  # fmt: skip
    run = sc.simulate(model, upright, np.zeros(model.n), actuator=tendons,
                      inputs=plan.input_function,
                      t_final=HORIZON, dt=CHECK_STEP)  # fmt: skip
    if not run.success:
        raise SystemExit(f"simulate: {run.message}")
    tr = plan.transcription
    obstacles = len(environment.obstacles)

    def least_clearance(states) -> float:
        """The least distance [m] of a contact point but the base (its rows first) from
        the ball's surface."""
        return min(np.array(tr.gaps(x, tr.parameters)).ravel()[obstacles:].min()
                   for x in states)  # fmt: skip

    simulated = np.column_stack([run.q, run.qd])
    print(f"least clearance: planned {1e3 * least_clearance(plan.x):.2f} mm (asked "
          f"{1e3 * CLEARANCE:g} mm at the nodes), simulated every {1e3 * CHECK_STEP:g} ms "
          f"{1e3 * least_clearance(simulated):.2f} mm (the contact law pushes inside "
          f"{1e3 * CONTACT_RADIUS:g} mm)")  # fmt: skip
    to_goal, to_plan = (np.linalg.norm(run.tip[-1] - p) for p in (GOAL, plan.tip[-1]))
    print(f"simulated: the tip ends {1e3 * to_goal:.2f} mm from the goal, "
          f"{1e3 * to_plan:.2f} mm from the plan")  # fmt: skip

    figure = plot_backbones(run, np.linspace(0.0, HORIZON, 8), path=plan.tip)
    for ax, (a, b) in zip(figure.axes[:2], ((0, 2), (0, 1)), strict=True):
        center = 1e3 * BALL.center[[a, b]]
        ax.add_patch(plt.Circle(center, 1e3 * BALL.radius, color="0.6", alpha=0.5))
        ax.add_patch(plt.Circle(center, 1e3 * (BALL.radius + CLEARANCE), fill=False,
                                ls=":", color="0.4"))  # fmt: skip
        ax.plot(*(1e3 * GOAL[[a, b]]), "x", color="C3", ms=9)
    figure.suptitle("around the ball (grey; dotted: the clearance) to the goal (x)")
    print(f"wrote {save_figure(figure, output / 'tendon_reach.png')}")
    print(f"wrote {run.to_html(output / 'tendon_reach.html', model, actuator=tendons)}")


if __name__ == "__main__":
    main()
