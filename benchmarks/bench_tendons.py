"""Cost of a tendon-driven simulation against the bellows one, on the paper's robot.

Run:  python benchmarks/bench_tendons.py [--repeat N] [--t-final S]

The robot is softcurve.presets.ifac2020() (one segment, creep and damping). Two
actuators of comparable effect act on it:

- bellows: three at 12 mm from the backbone, 2 cm^2 each, 0-60 kPa
  (PneumaticActuator.three_bellows), pressures (25, 0, 10) kPa;
- tendons: three at the same 12 mm, at the opposite azimuths (a tendon bends the robot
  toward itself, a bellow away from itself), 0-12 N, tensions p A = (5, 0, 2) N: the
  same bending moments; the axial force has the opposite sign (bellows lengthen,
  tendons shorten the robot).

For each actuator, without and with a 10 ms input lag, the robot starts straight at rest
and the inputs are held for --t-final seconds (default 10 s, output every 1 ms). Printed
side by side: the median and least wall time of --repeat runs (after a warm-up run that
builds the integrator; the two actuators' runs alternate, so a changing machine load
hits both alike), CVODES's steps and right-hand-side evaluations (the trajectory's
stats), the wall time per evaluation, and the tip at the end. Then the cost of one evaluation of the
forward dynamics with each actuator: the integrator's right-hand side (compiled model plus
``H(q) u``) evaluated 20 000 times in one CasADi map call, and the Python route
(``actuator.input_matrix(q) @ u`` then ``model.state_derivative``).

Pin to one core for stable numbers:
    OPENBLAS_NUM_THREADS=1 taskset -c 0 python benchmarks/bench_tendons.py
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import casadi as ca
import numpy as np

import softcurve as sc
from softcurve.simulation.solvers._cvodes import ActuatorInput, scaled_dae

DISTANCE, AREA, P_MAX = 0.012, 2e-4, 6e4  # [m], [m^2], [Pa]
PRESSURES = np.array([25e3, 0.0, 10e3])  # [Pa]
TENSIONS = PRESSURES * AREA  # [N]: the same moments about the backbone
EVALUATIONS = 20_000


def actuators(time_constant):
    bellows = sc.PneumaticActuator.three_bellows(
        distance=DISTANCE, area=AREA, p_max=P_MAX, time_constant=time_constant
    )
    opposite = [math.pi + 2.0 * math.pi * k / 3.0 for k in range(3)]
    tendons = sc.TendonActuator.three_per_segment(
        distance=DISTANCE, t_max=P_MAX * AREA, azimuths=opposite, time_constant=time_constant
    )
    return {"bellows": (bellows, PRESSURES), "tendons": (tendons, TENSIONS)}


def timed_runs(model, cases, t_final, repeat):
    """``{name: (median wall [s], min wall [s], last trajectory)}``: the cases' runs
    interleaved (one of each per round), so a change of machine load hits them alike."""
    q0, qd0 = np.array([model.robot.rest_length, 0.0, 0.0]), np.zeros(3)

    def run(actuator, inputs):
        return sc.simulate(model, q0, qd0, actuator=actuator, inputs=inputs, t_final=t_final)

    walls = {name: [] for name in cases}
    last = {name: run(*case) for name, case in cases.items()}  # warm-up: builds integrators
    for _ in range(repeat):
        for name, case in cases.items():
            start = time.perf_counter()
            last[name] = run(*case)
            walls[name].append(time.perf_counter() - start)
    for trajectory in last.values():
        if not trajectory.success:
            raise SystemExit(trajectory.message)
    return {n: (statistics.median(w), min(w), last[n]) for n, w in walls.items()}


def mapped_rhs(model, actuator, inputs):
    """The integrator's right-hand side mapped over EVALUATIONS states, and its arguments
    (``actuator`` None: forces ``inputs`` applied directly, no ``H(q) u``)."""
    wrapped = None if actuator is None else ActuatorInput.of(actuator, model.n)
    dae = scaled_dae(model, wrapped)
    n_state = model.n_state + (0 if wrapped is None else wrapped.n_states)
    rng = np.random.default_rng(7)
    x = np.zeros((n_state, EVALUATIONS))
    x[0] = model.robot.rest_length * rng.uniform(0.95, 1.05, EVALUATIONS)
    x[1:3] = rng.uniform(-20.0, 20.0, (2, EVALUATIONS))
    p = np.concatenate([np.asarray(model.parameters).ravel(), [1.0], np.ones(n_state)])
    args = dict(t=0.0, x=x, z=np.zeros((0, EVALUATIONS)), p=ca.repmat(p, 1, EVALUATIONS))
    args["u"] = ca.repmat(inputs, 1, EVALUATIONS)
    mapped = dae.map(EVALUATIONS)
    mapped.call(args)  # warm-up
    return mapped, args


def rhs_costs(model, cases, rounds: int = 9) -> dict:
    """Median seconds per right-hand-side evaluation of each case, rounds interleaved."""
    functions = {name: mapped_rhs(model, *case) for name, case in cases.items()}
    walls = {name: [] for name in cases}
    for _ in range(rounds):
        for name, (mapped, args) in functions.items():
            start = time.perf_counter()
            mapped.call(args)
            walls[name].append((time.perf_counter() - start) / EVALUATIONS)
    return {name: statistics.median(w) for name, w in walls.items()}


def python_cost(model, actuator, inputs) -> float:
    """Seconds per ``model.state_derivative(x, H(q) u)`` called from Python."""
    x = np.concatenate([[model.robot.rest_length, 10.0, -5.0], np.zeros(model.n_state - 3)])
    calls, start = 2000, time.perf_counter()
    for _ in range(calls):
        model.state_derivative(x, actuator.input_matrix(x[:3]) @ inputs)
    return (time.perf_counter() - start) / calls


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        epilog="Details in the module docstring (python -m pydoc benchmarks/bench_tendons.py).",
    )
    parser.add_argument("--repeat", type=int, default=9, help="timed runs per case (median)")
    parser.add_argument("--t-final", type=float, default=10.0, help="simulated time [s]")
    args = parser.parse_args()

    model = sc.Model(sc.presets.ifac2020())
    print(f"paper robot, {args.t_final:g} s from rest, inputs held, output every 1 ms, "
          f"{args.repeat} runs per case, interleaved")  # fmt: skip
    header = (
        f"{'actuator':<10}{'lag':>7}{'median [ms]':>13}{'min [ms]':>10}{'steps':>7}{'rhs':>7}"
        f"{'us/rhs':>8}   {'tip at the end [mm]'}"
    )
    print(header)
    print("-" * (len(header) + 6))
    for lag in (None, 0.01):
        for name, (median, least, run) in timed_runs(
            model, actuators(lag), args.t_final, args.repeat
        ).items():
            stats = run.stats
            tip = ", ".join(f"{1e3 * v:6.2f}" for v in run.tip[-1])
            print(
                f"{name:<10}{'none' if lag is None else f'{1e3 * lag:g} ms':>7}"
                f"{1e3 * median:>13.2f}{1e3 * least:>10.2f}{stats['steps']:>7}"
                f"{stats['rhs_evaluations']:>7}{1e6 * median / stats['rhs_evaluations']:>8.2f}"
                f"   ({tip})"
            )
    print()
    cases = actuators(None)
    straight = np.array([model.robot.rest_length, 0.0, 0.0])
    tau = cases["bellows"][0].generalized_force(straight, PRESSURES)
    mapped = rhs_costs(model, {"none (tau)": (None, tau), **cases})
    print(f"forward dynamics, one evaluation [us] (median of 9 calls mapping {EVALUATIONS} / "
          f"2000 calls from Python):")  # fmt: skip
    print(f"{'actuator':<12}{'integrator rhs':>16}{'Python route':>15}")
    for name, cost in mapped.items():
        python = "" if name not in cases else f"{1e6 * python_cost(model, *cases[name]):.2f}"
        print(f"{name:<12}{1e6 * cost:>16.3f}{python:>15}")
    print()
    print("us/rhs: the run's median wall time per right-hand-side evaluation (integrator")
    print("overhead included); the integrator rhs column is one evaluation alone (compiled")
    print("model plus H(q) u in CasADi's virtual machine).")


if __name__ == "__main__":
    main()
