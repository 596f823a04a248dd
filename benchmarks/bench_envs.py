"""Throughput of the learning environments (softcurve.envs) as a user calls them,
``gymnasium.make_vec("softcurve/Reach-v0", num_envs=N, ...)``, in the form of the
published GPU figures, and the accuracy of the stepper behind them.

Run:  python benchmarks/bench_envs.py [--sizes 1,16,256,1024] [--repeat 3] [--seconds 2]
      [--no-tendons] [--methods default,ROS34PW2]

Robots: the paper's one-segment robot with three bellows driven by pressures (the
default of softcurve/Reach-v0: preset ifac2020, 0-6e4 Pa, 20 ms lag), and the
two-segment tendon robot of Rao et al. 2021 with its material damping
(``presets.rao2021(damping_time=presets.RAO2021_DAMPING_TIME)``, six tensions of
``presets.rao2021_tendons()``, 0-8 N), both at the default 20 ms control period. Each
vector environment comes from ``gymnasium.make_vec`` with the keywords a user gives:
``default`` in ``--methods`` is no ``method=`` (what ``make_vec`` gives: RK4 for the
paper's robot, ROS34PW2 for the tendon robot, whose axial modes are stiff), any other
entry passes ``method=`` (a method the robot refuses prints the reason; one the default
already measured is skipped). For each number of environments N, ``step`` runs with
``action_space.sample()`` actions (drawn inside the timed loop), 2 s episodes and the
autoreset included; printed: aggregate environment steps per second, simulated seconds
per second (steps/s times the period), the real-time factor of one environment (the
same number at N = 1), the steps that failed (each truncates its episode), the best of
``--repeat`` runs of about ``--seconds`` each, and the stepper alone (``Stepper.step``
on the same batch) for the overhead of the environment.

Accuracy: 16 members hold random constant inputs for 1 s from the start state; their
tips after every period against ``softcurve.simulate`` at rtol 1e-10 with the same
inputs (max distance over members and periods, in mm and relative to the workspace's
radius).

Floor: the same 256 robots integrated over one period by the adaptive CVODES of
``softcurve.simulate`` (softcurve's C driver, ``softcurve.simulation.solvers._driver``), from
states reached under random pressures, at rtol 1e-6 and 1e-4: the steps and right-hand
sides one period of this robot needs under a new random input at every period, the
member-periods per second on 2 threads, and the cost of one right-hand side (with the
bellows' force) in a batch call: how far below the cost of these evaluations any
integrator of the same accuracy must stay.

Published figures quoted by issue 15, for comparison: SoRoMoX, about 21 simulated
seconds per second at 256 environments (desktop GPU, explicit 0.1 ms steps, a 3-DoF soft
robot); DisMech-RL, a few thousand environment steps per second with 500 environments on
a CPU. At a 20 ms control period, 21 simulated s/s is about 1,000 environment steps/s;
the issue's target on a 2-core machine is >= 50,000 at 256 environments.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import gymnasium
import numpy as np

import softcurve as sc
import softcurve.envs  # registers the ids
from softcurve.simulation.solvers import _driver as native
from softcurve.simulation.solvers._cvodes import ActuatorInput
from softcurve.simulation.stepper._scheme import rest_scale as stepper_scale

ENV_ID = "softcurve/Reach-v0"
"""The registered id every row is made from (``gymnasium.make_vec``)."""
DEFAULT = "default"
"""The entry of ``--methods`` that passes no ``method=``: the environments' default."""


def _robots(tendons: bool):
    yield "paper robot, 3 bellows (pressures)", {}
    if tendons:
        damped = sc.presets.rao2021(damping_time=sc.presets.RAO2021_DAMPING_TIME)
        robot = {"robot": damped, "actuator": sc.presets.rao2021_tendons()}
        yield "rao2021 (damped), 2 segments, 6 tendons (tensions)", robot


def _make(size: int, method: str, robot: dict):
    """The vector environment of ``size`` members, as a user makes it."""
    options = robot if method == DEFAULT else {**robot, "method": method}
    return gymnasium.make_vec(ENV_ID, num_envs=size, **options)


def _throughput(vector, seconds: float) -> tuple[float, float, int, int]:
    """Environment steps per second through ``vector.step`` with
    ``action_space.sample()``, through the stepper alone, and the environment steps
    that failed out of those taken."""
    size = vector.num_envs
    vector.reset(seed=0)
    vector.action_space.seed(0)
    for _ in range(3):  # warm-up: first calls build buffers
        vector.step(vector.action_space.sample())
    steps, failed, start = 0, 0, time.perf_counter()
    while time.perf_counter() - start < seconds or steps < 3:
        info = vector.step(vector.action_space.sample())[-1]
        if "final_info" in info:
            failed += sum(f is not None for f in info["final_info"]["failure"])
        steps += 1
    env_rate = steps * size / (time.perf_counter() - start)
    taken = steps * size
    episodes = vector.episodes
    stepper, x = episodes.setup.stepper, episodes.x.copy()
    inputs = episodes.inputs(vector.action_space.sample())
    steps, start = 0, time.perf_counter()
    while time.perf_counter() - start < seconds / 2 or steps < 3:
        x = stepper.step(x, inputs).x
        steps += 1
    return env_rate, steps * size / (time.perf_counter() - start), failed, taken


def _accuracy(vector) -> tuple[float, float]:
    """Max tip distance [m] against sc.simulate at rtol 1e-10, and relative to the radius."""
    episodes = vector.episodes
    stepper, x0 = episodes.setup.stepper, episodes.setup.x0
    rng = np.random.default_rng(1)
    inputs = stepper.lower + rng.random((16, stepper.lower.size)) * (stepper.upper - stepper.lower)
    period = stepper.period
    count = round(1.0 / period)
    x, tips = np.tile(x0, (16, 1)), []
    for _ in range(count):
        result = stepper.step(x, inputs)
        x = result.x
        tips.append(result.tip)
    tips = np.stack(tips, axis=1)  # (16, count, 3)
    n = stepper.model.n
    worst, notes = 0.0, set()
    for i in range(16):
        reference = sc.simulate(
            stepper.model, x0[:n], x0[n : 2 * n], t_final=1.0, dt=period,
            actuator=stepper.actuator, inputs=inputs[i], rtol=1e-10, max_steps=1_000_000,
        )  # fmt: skip
        reached = min(reference.tip.shape[0] - 1, count)
        if not reference.success:
            notes.add(f"reference stopped after {reached} periods: {reference.message[:120]}")
        if reached:
            difference = reference.tip[1 : reached + 1] - tips[i, :reached]
            worst = max(worst, float(np.max(np.linalg.norm(difference, axis=1))))
    for note in sorted(notes):
        print(f"  note: {note}")
    return worst, worst / episodes.task.calibration.radius


def _adaptive_floor(vector, rng) -> None:
    """Print what the adaptive CVODES needs per period for the robots of ``vector``."""
    stepper = vector.episodes.setup.stepper
    model, actuator = stepper.model, stepper.actuator
    problem = native.problem(model, ActuatorInput.of(actuator, model.n))
    if problem is None:
        print("adaptive floor: softcurve's C driver of CVODES is not available here")
        return
    size, m = 256, actuator.n_inputs
    period = stepper.period
    x = np.tile(vector.episodes.setup.x0, (size, 1))
    for _ in range(25):  # 0.5 s of random pressures: states of a policy's episode
        x = stepper.step(x, rng.uniform(actuator.lower, actuator.upper, (size, m))).x
    nominal = np.tile(stepper_scale(model, ActuatorInput.of(actuator, model.n)), (size, 1))
    p = np.tile(model.parameters, (size, 1))
    times, segments = np.array([0.0, period]), (np.array([1]), np.array([1]))
    for rtol in (1e-6, 1e-4):
        best, counts = np.inf, None
        for _ in range(5):
            u = rng.uniform(actuator.lower, actuator.upper, (size, 1, m))
            start = time.perf_counter()
            _, _, _, counts, _ = native.integrate(
                problem, np.ones(size, dtype=int), x, u, p, nominal, times, segments,
                native.options(rtol, rtol, 100_000), threads=os.cpu_count() or 1,
            )  # fmt: skip
            best = min(best, time.perf_counter() - start)
        steps, rhs, jacobians = counts[:, :3].mean(axis=0)
        print(f"  adaptive CVODES, rtol {rtol:g}: {size / best:,.0f} member-periods/s "
              f"({steps:.0f} steps, {rhs:.0f} right-hand sides and {jacobians:.1f} "
              f"Jacobians per member and period)")  # fmt: skip
    xs, us = np.repeat(x, 20, axis=0), rng.uniform(actuator.lower, actuator.upper, (20 * size, m))
    start = time.perf_counter()
    native.evaluate(problem, xs, us, model.parameters)
    print(
        f"  one right-hand side with the bellows' force: "
        f"{(time.perf_counter() - start) / xs.shape[0] * 1e6:.2f} us (batch call)"
    )


def _rows(label, robot, method, sizes, args, measured) -> None:
    """The accuracy and the throughput rows of one robot and stepper method, unless
    ``measured`` (the ``(label, method)`` pairs done) holds them already."""
    start = time.perf_counter()
    try:
        first = _make(1, method, robot)
    except sc.ParameterError as error:  # RK4 on a robot with stiff modes
        print(f"\n{label}, {method}: refused at construction: {error}")
        return
    stepper = first.episodes.setup.stepper
    if (label, stepper.method) in measured:
        return
    measured.add((label, stepper.method))
    setup_time = time.perf_counter() - start
    period = stepper.period
    print(f"\n{label}, method={method}: control period {period * 1e3:g} ms, "
          f"{stepper.method} x {stepper.substeps} steps ({stepper.route.name}), set-up "
          f"(compile or load, calibration) {setup_time:.1f} s")  # fmt: skip
    error, relative = _accuracy(first)
    print(f"accuracy: tip within {error * 1e3:.3g} mm of softcurve.simulate at rtol "
          f"1e-10 over 1 s ({relative:.2g} of the workspace radius)")  # fmt: skip
    print(f"{'N':>6} {'env steps/s':>12} {'sim s/s':>10} {'stepper steps/s':>16} "
          f"{'real-time factor (N=1)':>23} {'failed steps':>14}")  # fmt: skip
    for size in sizes:
        vector = first if size == 1 else _make(size, method, robot)
        runs = [_throughput(vector, args.seconds) for _ in range(args.repeat)]
        env_rate, stepper_rate = max(r[0] for r in runs), max(r[1] for r in runs)
        failed, taken = sum(r[2] for r in runs), sum(r[3] for r in runs)
        factor = f"{env_rate * period:.0f}x" if size == 1 else ""
        print(f"{size:>6} {env_rate:>12,.0f} {env_rate * period:>10,.0f} "
              f"{stepper_rate:>16,.0f} {factor:>23} {f'{failed} of {taken}':>14}")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--sizes", default="1,16,256,1024", help="numbers of environments")
    parser.add_argument("--repeat", type=int, default=3, help="runs per row (best kept)")
    parser.add_argument("--seconds", type=float, default=2.0, help="duration of one run [s]")
    parser.add_argument("--no-tendons", action="store_true", help="skip the tendon robot")
    parser.add_argument(
        "--methods",
        default=f"{DEFAULT},ROS34PW2",
        help=f"the stepper's methods, one set of rows each ({DEFAULT!r}: no method=)",
    )
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]
    print(f"softcurve {sc.__version__}, Python {platform.python_version()}, "
          f"{os.cpu_count()} CPUs, load average {os.getloadavg()}")  # fmt: skip
    rng = np.random.default_rng(0)
    methods, measured = args.methods.split(","), set()
    for index, (label, robot) in enumerate(_robots(not args.no_tendons)):
        for method in methods:
            _rows(label, robot, method, sizes, args, measured)
        if index == 0:  # the paper's robot: what an adaptive integrator needs
            _adaptive_floor(_make(1, DEFAULT, robot), rng)
    print(f"\nload average after the runs: {os.getloadavg()}")


if __name__ == "__main__":
    main()
