"""Trajectory optimization (``sc.optimize_trajectory``) on a reach task of the paper's
robot with bellows: direct collocation against direct multiple shooting, cold (the
problem built and solved) and warm (solved again from the first plan), and each plan's
inputs simulated forward by ``simulate`` at its default tolerances.

Run:  python benchmarks/bench_planning.py [--intervals 15] [--methods collocation shooting]
      [--hessians exact limited-memory]
      python benchmarks/bench_planning.py --lbfgs-history 6 20 50
      python benchmarks/bench_planning.py --baselines
      python benchmarks/bench_planning.py --long [--hessians exact limited-memory]
      python benchmarks/bench_planning.py --tendons [--hessians exact limited-memory]
      [--iterations 300] [--without-rest] [--segments 10] [--effort-weight 1e-3]
      any of them with [--jacobian-route auto|stages|casadi]
      python benchmarks/bench_planning.py --stage-jacobians

The task: from rest straight up, the tip to (20, 0, 62) mm within 1 mm at 0.3 s and at
rest there, the pressures within the bellows' bounds (0 to 100 kPa), a small effort
weight (1e-3). It prints per method (and Hessian of the Lagrangian, ``--hessians``: the
exact one by default) the wall time to the first plan (in an empty cache holding the
model alone: the Functions built, the collocation's derivatives compiled, IPOPT's
solve), the solve alone, IPOPT's iterations, the cost, the constraint
violation, and the distance of the simulated tip from the planned one at the end; then
the share of each solve that IPOPT's Hessian of the Lagrangian took.

With ``--lbfgs-history`` it solves the task with the limited-memory Hessian at each number
of pairs (``LBFGS_HISTORY``). With ``--baselines`` it compares, on the same robot and
bounds over 0.6 s, the plan's inputs (held at rest after the horizon) with the linear
MPC (``ActuatorMPC``, 20 x 10 ms) and computed torque (``ComputedTorque`` through
``ActuatorDriven``, kp 400 1/s^2, kd 40 1/s, 10 ms), both tracking the plan's final
configuration from the start: the time after which the simulated tip stays within 1 mm
of the goal, the tip's distance from the goal at 0.3 s, and the plan's own cost terms
(the goal at 0.3 s, the effort over 0.3 s) evaluated on each run. With ``--long`` it plans
a 2 s horizon at 20 ms (100 steps: the circle of docs/control.md from rest) with each
Hessian, from a cold start with the model and its derivatives cached, and simulates the
plan against the circle. With ``--tendons`` it plans 1 s of a ten-segment tendon robot
(``tendon_chain``; ``--segments`` another even count), first in an empty cache, then
from a cold start with the model and its derivatives cached, at most ``--iterations`` of
IPOPT (``--without-rest``: the tip within 2 mm at the end, no rest asked;
``benchmarks/study_rest_at_end.py`` says why the rest is out of reach of the tensions;
``--effort-weight`` the weight of the tensions' effort, default ``TENDON_EFFORT``).
``--jacobian-route`` makes the exact Hessian's plans take their constraints' Jacobian
stage by stage or CasADi's through the compiled collocation, where the library chooses
by the robot (``jacobian_by_stages``). With ``--stage-jacobians`` it builds and compiles the stage
Jacobian (``Transcription.compiled_stage_jacobian``) by each route, in an empty cache
holding the model alone, for the paper's robot with the task's bellows and for the
ten-segment tendon robot, and times it over 60 stages (a plan of 20 steps), best of five,
at a bent and moving state, the inputs mid-range.
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import numpy as np
from _timing import best_of  # benchmarks/_timing.py: a helper, not a benchmark

import softcurve as sc
from softcurve.control import _problem as problem

TARGET = np.array([0.02, 0.0, 0.062])
"""The tip's goal [m]."""


def task(method: str, intervals: int, warm_start=None, hessian: str = "exact"):
    model = sc.Model(sc.presets.ifac2020())
    bellows = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)
    goal = sc.TipTarget(TARGET, tolerance=1e-3)
    return sc.optimize_trajectory(
        model, [0.064, 0.0, 0.0], actuator=bellows, horizon=0.3, intervals=intervals,
        targets=[goal], effort_weight=1e-3, rest_at_end=True, method=method,
        warm_start=warm_start, hessian=hessian,
    )  # fmt: skip


def print_shares(shares: dict) -> None:
    """What share of each cold solve IPOPT's Hessian of the Lagrangian took."""
    for method, share in shares.items():
        print(f"{method}: the Hessian of the Lagrangian took {100 * share:.0f} % of the solve")


def baselines(intervals: int) -> None:
    """The plan against the linear MPC and computed torque on the same task."""
    model = sc.Model(sc.presets.ifac2020())
    bellows = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)
    plan = task("collocation", intervals)
    final = sc.Reference.constant(plan.x[-1, : model.n])
    dt, duration, horizon = 0.01, 0.6, plan.horizon
    mpc = sc.ActuatorMPC(model, bellows, final, horizon=20, sample_time=dt)
    torque = sc.ComputedTorque(model, final, kp=400.0, kd=40.0, sample_time=dt)
    driven = sc.ActuatorDriven(torque, bellows, model.robot)
    step = float(plan.t[1] - plan.t[0])
    grid = np.arange(0.0, duration + step / 2, step)
    held = np.vstack([plan.u, np.tile(plan.u[-1], (grid.size - plan.u.shape[0], 1))])
    runs = {
        "optimize_trajectory": (
            sc.simulate(
                model,
                [0.064, 0.0, 0.0],
                np.zeros(3),
                actuator=bellows,
                inputs=held,
                t_final=duration,
                dt=step,
            ),
            plan.solve_time,
        ),  # fmt: skip
    }
    for name, controller in (("ActuatorMPC", mpc), ("ComputedTorque", driven)):
        began = time.perf_counter()
        run = sc.simulate(model, [0.064, 0.0, 0.0], np.zeros(3), actuator=bellows,
                          controller=controller, t_final=duration, dt=dt)  # fmt: skip
        runs[name] = (run, time.perf_counter() - began)
    span = bellows.upper - bellows.lower
    length = model.robot.rest_length
    print(f"reach task over {duration:g} s, goal {1e3 * TARGET} mm")
    print("| inputs by | computing [s] | within 1 mm from [s] | off at 0.3 s [mm] | goal term "
          "| effort term | cost |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for name, (run, seconds) in runs.items():
        tips = np.array([run.model.tip_pose(q).position for q in run.q])
        off = np.linalg.norm(tips - TARGET, axis=1)
        outside = np.flatnonzero(off > 1e-3)
        settled = "never" if outside.size and outside[-1] == off.size - 1 else (
            f"{run.t[outside[-1] + 1] if outside.size else 0.0:.3f}")  # fmt: skip
        at = int(np.argmin(np.abs(run.t - horizon)))
        goal_term = off[at] ** 2 / length**2
        during = run.t < horizon - 1e-12
        effort = 1e-3 * np.mean(np.sum(((run.inputs[during] - bellows.rest_inputs()) / span) ** 2,
                                       axis=1))  # fmt: skip
        print(f"| {name} | {seconds:.2f} | {settled} | {1e3 * off[at]:.2f} | {goal_term:.3g} | "
              f"{effort:.3g} | {goal_term + effort:.3g} |")  # fmt: skip


LONG = {"horizon": 2.0, "intervals": 100}
"""The long task's horizon [s] and steps: 20 ms each."""


def long_horizon(hessians) -> None:
    """The circle of docs/control.md tracked over one turn (2 s) in 100 steps of 20 ms,
    from rest on it with no pressure, bellows of 2 cm^2 at 12 mm (0 to 60 kPa): each
    Hessian's plan from a cold start (the problem built, no warm start) in a cache that
    holds the model and the plan's compiled derivatives (a first plan before it)."""
    from softcurve.control.references import tip_circle

    model = sc.Model(sc.presets.ifac2020())
    bellows = sc.PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4)
    circle = tip_circle(center=(0.02, 0.0, 0.065), radius=0.01, period=2.0)
    start = circle(0.0)
    print(f"the circle over {LONG['horizon']:g} s in {LONG['intervals']} steps of 20 ms")
    print("| Hessian | plan, cold [s] | of it the solve [s] | of that the Hessian's evaluations "
          "[s] | iterations | tip off the circle, simulated after 0.5 s: mean (largest) [mm] "
          "| status |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for hessian in hessians:
        request = {"actuator": bellows, "reference": circle, "rate_weight": 1e-6,
                   "hessian": hessian, **LONG}  # fmt: skip
        sc.optimize_trajectory(model, start.q, start.qd, **request)  # compiles, caches
        began = time.perf_counter()
        result = sc.optimize_trajectory(model, start.q, start.qd, **request)
        cold = time.perf_counter() - began
        run = result.simulate()
        late = run.t >= 0.5
        goal = np.array([model.tip_pose(circle(t).q).position for t in run.t[late]])
        off = 1e3 * np.linalg.norm(run.tip[late] - goal, axis=1)
        print(f"| {hessian} | {cold:.1f} | {result.solve_time:.1f} | "
              f"{result.timings['hessian']:.1f} | {result.iterations} | "
              f"{off.mean():.3f} ({off.max():.3f}) | {result.status.value} |")  # fmt: skip


TENDON_SEGMENTS = 10
"""Segments of the tendon robot of ``--tendons``."""


def tendon_chain(segments: int = TENDON_SEGMENTS):
    """``(model, tendons, start)``: examples/tendon_tracking.py's two sections of 10 cm
    (the proximal one twice as stiff and heavy), each in ``segments / 2`` segments (a
    segment's stiffnesses per unit of its length, its mass and damping shares), upright
    under gravity; three tendons 8 mm from the backbone tied to each section's tip (0.2 to
    5 N, no lag)."""
    half = segments // 2
    share = 1.0 / half

    def section(mass, radius, elongation, bending, damping):
        return sc.Segment(
            rest_length=0.10 * share, mass=mass * share, radius=radius,
            elongation_stiffness=sc.LinearStiffness(elongation / share),
            bending_stiffness=sc.LinearStiffness(bending / share),
            damping=[d * share for d in damping],
        )  # fmt: skip

    proximal = section(0.030, 0.012, 2000.0, 0.04, (2.0, 4e-4, 4e-4))
    distal = section(0.015, 0.010, 1000.0, 0.02, (1.0, 2e-4, 2e-4))
    robot = sc.Robot(segments=(proximal,) * half + (distal,) * half,
                     gravity=np.array([0.0, 0.0, -9.81]))  # fmt: skip
    actuator = sc.TendonActuator(
        [sc.Tendon(azimuth=a, distance=0.008, t_max=5.0, t_min=0.2, anchor=anchor)
         for anchor in (half - 1, segments - 1) for a in (0.0, 2 * np.pi / 3, 4 * np.pi / 3)],
        n_segments=segments,
    )  # fmt: skip
    start = np.ravel([[segment.rest_length, 0.0, 0.0] for segment in robot.segments])
    return sc.Model(robot), actuator, start


TENDON_GOAL = np.array([0.06, 0.0, 0.17])
"""Where the tip of ``--tendons`` goes [m] (it stands at 200 mm)."""

TENDON_EFFORT = 1e-3
"""The effort weight of ``--tendons`` (``optimize_trajectory``'s ``effort_weight``)."""


def tendons(hessians, iterations: int, rest: bool = True, segments: int = TENDON_SEGMENTS,
            effort: float = TENDON_EFFORT) -> None:  # fmt: skip
    """A tendon robot's 1 s plan (``tendon_chain(segments)``, 20 steps of 50 ms): the tip to
    ``TENDON_GOAL`` within 2 mm and, with ``rest``, at rest there, the effort weight ``effort``,
    at most ``iterations`` of IPOPT; the first plan in an empty cache (the model and the plan's
    derivatives compiled) and a second from a cold start with them cached, whose solve is
    split into the Hessian's and the constraints' Jacobian's evaluations."""
    print(f"{segments} segments, six tendons, 1 s in 20 steps of 50 ms, "
          f"{'at rest at the end' if rest else 'no rest asked'}, "
          f"effort weight {effort:g}")  # fmt: skip
    print("| Hessian | first plan, empty cache [s] | plan, cold, cached [s] | of it the solve [s] "
          "| the Hessian's evaluations [s] | the Jacobian's [s] | iterations | violation "
          "| simulated tip off the plan at the end [mm] | status |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    for hessian in hessians:
        with tempfile.TemporaryDirectory(prefix="bench_planning") as folder:
            os.environ["SOFTCURVE_CACHE_DIR"] = folder
            times, plans = [], []
            for _ in range(2):
                began = time.perf_counter()
                model, actuator, start = tendon_chain(segments)
                plans.append(sc.optimize_trajectory(
                    model, start, actuator=actuator, horizon=1.0, intervals=20,
                    targets=[sc.TipTarget(TENDON_GOAL, tolerance=2e-3)], effort_weight=effort,
                    rest_at_end=rest, hessian=hessian, progress=True, max_iterations=iterations,
                ))  # fmt: skip
                times.append(time.perf_counter() - began)
        plan = plans[-1]
        run = plan.simulate()
        off = 1e3 * np.linalg.norm(run.tip[-1] - plan.tip[-1]) if run.success else np.nan
        print(f"| {hessian} | {times[0]:.1f} | {times[1]:.1f} | {plan.solve_time:.1f} | "
              f"{plan.timings['hessian']:.1f} | {plan.timings['jacobian']:.1f} | "
              f"{plan.iterations} | {plan.violation:.2g} | {off:.2f} | "
              f"{plan.status.value} |")  # fmt: skip


def stage_jacobians() -> None:
    """Each route of the stage Jacobian: its build and compile, then 60 stages."""
    robots = {
        "paper robot, bellows": lambda: (
            sc.Model(sc.presets.ifac2020()),
            sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5),
        ),
        f"{TENDON_SEGMENTS}-segment tendon robot": lambda: tendon_chain()[:2],
    }
    stages = 60
    print("| robot | route | build and compile [s] | 60 stages [ms] |")
    print("| --- | --- | --- | --- |")
    for name, make in robots.items():
        for route in sc.control.STAGE_JACOBIAN_ROUTES:
            with tempfile.TemporaryDirectory(prefix="bench_planning") as folder:
                os.environ["SOFTCURVE_CACHE_DIR"] = folder
                model, actuator = make()
                tr = sc.Transcription(model, actuator)
                began = time.perf_counter()
                mapped = tr.compiled_stage_jacobian(route).map(stages)
                built = time.perf_counter() - began
                scale = model.robot.coordinate_scale()  # bent and moving, any kind
                x = tr.start(model.robot.rest_configuration() + 0.2 * scale, scale)
                low, high = tr.input_bounds
                X, U = np.tile(x[:, None], stages), np.tile(((low + high) / 2)[:, None], stages)
                mapped(X, U, tr.parameters)
                wall, _ = best_of(5, lambda f=mapped, a=(X, U, tr.parameters): f(*a))
            print(f"| {name} | {route} | {built:.1f} | {1e3 * wall:.1f} |")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--intervals", type=int, default=15)
    parser.add_argument("--methods", nargs="+", default=list(sc.control.PLAN_METHODS))
    parser.add_argument("--hessians", nargs="+", default=["exact"],
                        choices=sc.control.PLAN_HESSIANS)  # fmt: skip
    parser.add_argument("--lbfgs-history", type=int, nargs="+", default=None,
                        help="limited-memory pairs to compare (LBFGS_HISTORY)")  # fmt: skip
    parser.add_argument("--baselines", action="store_true", help="against MPC and torque")
    parser.add_argument("--long", action="store_true",
                        help="a 2 s horizon at 20 ms: the circle tracked from rest")  # fmt: skip
    parser.add_argument("--tendons", action="store_true",
                        help=f"a {TENDON_SEGMENTS}-segment tendon robot's 1 s plan")  # fmt: skip
    parser.add_argument("--stage-jacobians", action="store_true",
                        help="the stage Jacobian by each route")  # fmt: skip
    parser.add_argument("--iterations", type=int, default=sc.control.PLAN_ITERATIONS,
                        help="IPOPT's iterations at most (--tendons)")  # fmt: skip
    parser.add_argument("--without-rest", action="store_true",
                        help="--tendons without the rest at the end")  # fmt: skip
    parser.add_argument("--segments", type=int, default=TENDON_SEGMENTS,
                        help="--tendons: the robot's segments, even")  # fmt: skip
    parser.add_argument("--effort-weight", type=float, default=TENDON_EFFORT,
                        help="--tendons: the tensions' effort weight")  # fmt: skip
    parser.add_argument("--jacobian-route", choices=("auto", "stages", "casadi"),
                        default="auto",
                        help="the exact Hessian's constraint Jacobian: as the library "
                             "chooses (jacobian_by_stages), stage by stage, or CasADi's "
                             "through the compiled collocation")  # fmt: skip
    args = parser.parse_args()
    if args.segments < 2 or args.segments % 2:
        parser.error(f"--segments must be an even number of at least 2, got {args.segments}")
    if not args.effort_weight > 0:
        parser.error(f"--effort-weight must be positive, got {args.effort_weight}")
    if args.iterations < 1:
        parser.error(f"--iterations must be at least 1, got {args.iterations}")
    if args.jacobian_route != "auto":
        by_stages = args.jacobian_route == "stages"
        problem.jacobian_by_stages = lambda tr, hessian: (
            hessian == "gauss-newton" or (hessian == "exact" and by_stages)
        )
    if args.stage_jacobians:
        stage_jacobians()
        return
    if args.tendons:
        tendons(args.hessians, args.iterations, rest=not args.without_rest,
                segments=args.segments, effort=args.effort_weight)  # fmt: skip
        return
    if args.baselines:
        baselines(args.intervals)
        return
    if args.long:
        long_horizon(args.hessians)
        return
    if args.lbfgs_history:
        print("| limited-memory pairs | solve | iterations | cost |")
        print("| --- | --- | --- | --- |")
        for pairs in args.lbfgs_history:
            problem.LBFGS_HISTORY = pairs
            plan = task("collocation", args.intervals, hessian="limited-memory")
            print(f"| {pairs} | {plan.solve_time:.1f} | {plan.iterations} | {plan.cost:.4g} |")
        return
    print(f"reach task, {args.intervals} intervals of {300 / args.intervals:.3g} ms; times in s")
    print("| method | Hessian | first plan | solve | iterations | warm solve | warm iterations "
          "| cost | violation | simulated tip off [mm] | status |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- | --- | --- | --- |")
    shares = {}
    for method in args.methods:
        for hessian in args.hessians:
            if hessian == "limited-memory" and method == "shooting":
                continue  # refused: collocation alone
            # each row in an empty cache holding the model alone: its first plan compiles
            # what it plans with
            with tempfile.TemporaryDirectory(prefix="bench_planning") as folder:
                os.environ["SOFTCURVE_CACHE_DIR"] = folder
                sc.Model(sc.presets.ifac2020())
                began = time.perf_counter()
                plan = task(method, args.intervals, hessian=hessian)
                first = time.perf_counter() - began
                again = task(method, args.intervals, warm_start=plan, hessian=hessian)
            run = plan.simulate()
            tip = run.model.tip_pose(run.q[-1]).position
            off = 1e3 * np.linalg.norm(tip - plan.tip[-1])
            if hessian == "exact":
                shares[method] = plan.timings["hessian"] / plan.solve_time
            print(
                f"| {method} | {hessian} | {first:.1f} | {plan.solve_time:.1f} | "
                f"{plan.iterations} | {again.solve_time:.1f} | {again.iterations} | "
                f"{plan.cost:.4g} | {plan.violation:.1e} | {off:.2f} | {plan.status.value} |"
            )
    print_shares(shares)


if __name__ == "__main__":
    main()
