"""Throughput and accuracy of the batched fixed-step stepper (softcurve.simulation.stepper).

Run:  python benchmarks/bench_stepper.py [--repeat 5] [--sizes 1,16,256,1024]
      [--accuracy-periods 100] [--skip-tendons] [--skip-flags]

The case is the paper's robot (preset ifac2020) with the bellows of
examples/pneumatic.toml (three per segment, 12 mm from the backbone, 2e-4 m^2, 0..60 kPa,
20 ms pressure lag), stepped at a 20 ms control period with the default method and
substeps.

1. Throughput: member-periods per wall-clock second for N members in one call (best of
   ``--repeat``), the real-time factor of one member (simulated / wall time), wall and
   CPU time per member-period, and the same as a multiple of one evaluation of the
   model's compiled right-hand side (``model.function("rhs")`` through CasADi's buffer
   interface, best of 20,000): the work of one member-period in right-hand sides.
2. Threads: N = 256 with 1 thread and with all cores (the speed-up shows whether the
   threads run in parallel).
3. Compiler flags: the stepper compiled with softcurve's flags (``STEPPER_FLAGS``) against
   ``compile_function``'s ``FUNCTION_FLAGS`` (``--skip-flags`` skips the extra compile;
   ``bench_compile_flags.py`` compares more).
4. Accuracy: random pressure commands, uniform in the bounds, held 20 ms each over
   ``--accuracy-periods`` periods (2 s), two seeds, against ``simulate(..., rtol=1e-10)``
   with the same piecewise-constant commands: the max tip-position error [mm] and
   relative to the tip's travel (its largest coordinate range), per method and
   substeps, with the right-hand sides per period; the explicit RK4 too (rows its
   stability check refuses at construction are printed so), and the fastest mode of the
   robot along each reference run against its value at rest (the check's margin). Run
   in CasADi's virtual machine on the model's compiled right-hand side (the same scheme
   as the compiled code to round-off; no compile per row).
5. The same accuracy for the two-segment tendon robot (presets rao2021 with
   rao2021_tendons, tensions 0..8 N) at 20 ms over ``--tendon-periods`` periods (0.4 s;
   the reference, at rtol 1e-8, needs ~8,000 right-hand sides per period), with a
   Jacobian per period or per step (``--skip-tendons`` skips it).
6. Contact: the paper's robot (body radius 1 mm) stretching into a ceiling 2 mm below its
   free tip, ``ContactLaw(1e7, smoothing=1e-6, damping=1, friction=0.5)``, from
   ``q0 = (60.5 mm, 2 1/m, 0)`` at rest, 0.1 s in 20 ms periods with ROS34PW2 x 16 and a
   fresh Jacobian every 1, 4 or 16 steps, against simulate(rtol=1e-10): the final state
   and the friction force (``--skip-contact`` skips it; compiles the contact model once).

The load average is printed: the machine's other work slows every row.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import softcurve as sc
from softcurve.compiled._build import FUNCTION_FLAGS
from softcurve.simulation.solvers._cvodes import ActuatorInput
from softcurve.simulation.stepper._methods import METHODS, Tableau
from softcurve.simulation.stepper._scheme import STEPPER_FLAGS, period_function
from softcurve.simulation.stepper._stability import fastest_rate, fastest_rate_at_rest
from softcurve.simulation.stepper._stepper import DEFAULT_METHOD, DEFAULT_SUBSTEPS, Stepper

PERIOD = 0.02


def paper_actuator():
    return sc.PneumaticActuator.three_bellows(
        distance=0.012, area=2e-4, p_max=6e4, time_constant=0.02
    )


def best_wall(repeat: int, run) -> tuple[float, float]:
    """``(best wall time, CPU time of that run)`` [s] of ``run()``."""
    best = (np.inf, np.inf)
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        run()
        best = min(best, (time.perf_counter() - wall, time.process_time() - cpu))
    return best


def rhs_cost(model) -> float:
    """Wall time [us] of one evaluation of the compiled right-hand side, best of 20,000."""
    f = model.function("rhs")
    buffer, evaluate = f.buffer()
    x = np.r_[0.064, 25.0, 0.0, 0.0, 0.0, 1500.0, 0.0, 0.0, 0.0][: model.n_state]
    x = np.ascontiguousarray(np.resize(x, model.n_state))
    tau, out, p = np.zeros(model.n), np.zeros(model.n_state), model.parameters.copy()
    for i, a in enumerate((x, tau, p)):
        buffer.set_arg(i, memoryview(a))
    buffer.set_res(0, memoryview(out))
    best = np.inf
    for _ in range(20):
        start = time.perf_counter()
        for _ in range(1000):
            evaluate()
        best = min(best, (time.perf_counter() - start) / 1000)
    return best * 1e6


def states(stepper, count: int) -> np.ndarray:
    """``count`` copies of the straight robot at rest."""
    robot = stepper.model.robot
    q0 = np.concatenate([[s.rest_length, 0.0, 0.0] for s in robot.segments])
    return np.tile(stepper.initial_state(q0), (count, 1))


def throughput(stepper, sizes, repeat, rhs_us) -> None:
    rng = np.random.default_rng(0)
    print(
        f"{'N':>6} {'member-periods/s':>17} {'real-time x':>12} {'wall us/member':>15} "
        f"{'CPU us/member':>14} {'rhs evals':>10}"
    )
    for count in sizes:
        x = states(stepper, count)
        u = rng.uniform(stepper.lower, stepper.upper, (count, stepper.n_inputs))
        stepper.step(x, u)  # builds the map for this N
        calls = max(1, 2000 // count)

        def run(x=x, u=u, calls=calls):
            for _ in range(calls):
                stepper.step(x, u)

        wall, cpu = best_wall(repeat, run)
        per_member = wall / (calls * count)
        realtime = f"{PERIOD / per_member:12.0f}" if count == 1 else f"{'':>12}"
        print(
            f"{count:6d} {1 / per_member:17.0f} {realtime} {per_member * 1e6:15.1f} "
            f"{cpu / (calls * count) * 1e6:14.1f} {per_member * 1e6 / rhs_us:10.1f}"
        )


def threads(model, actuator, repeat) -> None:
    rng = np.random.default_rng(1)
    rates = {}
    for count in (1, os.cpu_count() or 1):
        stepper = Stepper(model, actuator, period=PERIOD, threads=count)
        x = states(stepper, 256)
        u = rng.uniform(stepper.lower, stepper.upper, (256, stepper.n_inputs))
        stepper.step(x, u)
        wall, _ = best_wall(repeat, lambda s=stepper, x=x, u=u: s.step(x, u))
        rates[count] = 256 / wall
        print(f"threads={count}: {rates[count]:.0f} member-periods/s at N = 256")
    if len(rates) > 1:
        values = list(rates.values())
        print(f"speed-up of {max(rates)} threads over 1: {values[-1] / values[0]:.2f}x")


def compiler_flags(model, actuator, repeat) -> None:
    inputs = ActuatorInput.of(actuator, model.n)
    x = np.zeros(model.n_state + actuator.n_inputs)
    x[0] = 0.064
    u = np.full(actuator.n_inputs, 3e4)
    period = np.array([PERIOD])
    for flags in (STEPPER_FLAGS, FUNCTION_FLAGS):
        start = time.perf_counter()
        f = period_function(model, inputs, DEFAULT_SUBSTEPS, DEFAULT_METHOD, True, flags)
        built = time.perf_counter() - start
        buffer, evaluate = f.buffer()
        out = np.zeros(f.nnz_out(0))
        p = model.parameters.copy()
        for i, a in enumerate((x, u, p, period)):
            buffer.set_arg(i, memoryview(a))
        buffer.set_res(0, memoryview(out))

        def run(evaluate=evaluate):
            for _ in range(200):
                evaluate()

        wall, _ = best_wall(repeat, run)
        print(
            f"{' '.join(flags)} (with -march=native unless SOFTCURVE_PORTABLE): "
            f"{wall / 200 * 1e6:8.1f} us per member-period (load/compile {built:.1f} s)"
        )


def commands(rng, actuator, periods) -> np.ndarray:
    return rng.uniform(actuator.lower, actuator.upper, (periods, actuator.n_inputs))


def accuracy(model, actuator, q0, periods, rows, seeds=(1, 2), rtol=1e-10) -> None:
    cases = []
    for seed in seeds:
        held = commands(np.random.default_rng(seed), actuator, periods)
        reference = sc.simulate(
            model,
            q0,
            np.zeros(model.n),
            actuator=actuator,
            inputs=np.vstack([held, held[-1:]]),
            t_final=periods * PERIOD,
            dt=PERIOD,
            rtol=rtol,
        )
        if not reference.success:
            print(f"seed {seed}: reference failed: {reference.message}")
            continue
        tips = np.array([model.tip_pose(q).position for q in reference.q])
        cases.append((seed, held, tips))
        # the fastest mode along the run, against the one at rest that the explicit
        # method's check reads (docs/stepping.md: EXPLICIT_MARGIN)
        lag = reference.inputs if actuator.time_constant is not None else reference.x[:, :0]
        states = np.hstack([reference.x, lag])
        inputs = ActuatorInput.of(actuator, model.n)
        rates = [fastest_rate(model, inputs, x, held[min(k, periods - 1)]) for k, x in
                 enumerate(states)]  # fmt: skip
        at_rest = fastest_rate_at_rest(model, inputs)
        print(f"seed {seed}: fastest mode along the reference {max(rates):.0f} 1/s, at rest "
              f"{at_rest:.0f} 1/s ({max(rates) / at_rest:.2f} times)")  # fmt: skip
    print(
        f"{'method':>9} {'substeps':>8} {'Jacobian every':>14} {'rhs/period':>10}  "
        + "  ".join(f"seed {seed}: error [mm] (% of travel)" for seed, _, _ in cases)
    )
    extra = actuator.n_inputs if actuator.time_constant is not None else 0
    for row in rows:
        method, substeps, every = (*row, row[1])[:3]
        stages = len(METHODS[method].b)
        jacobians = -(-substeps // every) if isinstance(METHODS[method], Tableau) else 0
        rhs = jacobians * (model.n_state + extra + 1) + stages * substeps - jacobians
        line = f"{method:>9} {substeps:8d} {every if jacobians else '-':>14} {rhs:10d}  "
        try:
            stepper = Stepper(
                model,
                actuator,
                period=PERIOD,
                substeps=substeps,
                method=method,
                compiled=False,
                jacobian_every=every,
            )
        except sc.ParameterError as error:  # an explicit step beyond the robot's stability
            print(line + f"refused at construction: {str(error)[:90]}...", flush=True)
            continue
        texts = []
        for _, held, expected in cases:
            x = stepper.initial_state(q0)[None, :]
            tips = [stepper.tip(x)[0]]
            failed = None
            for k in range(periods):
                result = stepper.step(x, held[k : k + 1])
                if not result.ok[0]:
                    failed = result.reasons[0]
                    break
                x = result.x
                tips.append(result.tip[0])
            if failed:
                texts.append(f"failed at period {k}: {failed[:60]}")
                continue
            error = np.abs(np.array(tips) - expected).max()
            travel = np.ptp(expected, axis=0).max()
            texts.append(f"{error * 1e3:14.3f} mm ({100 * error / travel:5.2f} %)    ")
        print(line + "  ".join(texts), flush=True)


def contact() -> None:
    ceiling = sc.Plane([0.0, 0.0, 0.062], [0.0, 0.0, -1.0])
    law = sc.ContactLaw(stiffness=1e7, smoothing=1e-6, damping=1.0, friction=0.5)
    environment = sc.Environment([ceiling], law, contact_radius=[1e-3])
    model = sc.Model(sc.presets.ifac2020(), environment=environment)
    q0, periods = [0.0605, 2.0, 0.0], 5
    reference = sc.simulate(model, q0, np.zeros(3), t_final=periods * PERIOD, dt=PERIOD, rtol=1e-10)
    n = model.n
    q, qd = reference.q[-1], reference.qd[-1]
    force = model.contact(q, qd)["forces"].sum(axis=0)
    print(f"reference: q = {np.array2string(q, precision=5)}, force = {force.round(4)} N")
    for every in (1, 4, 16):
        stepper = Stepper(model, period=PERIOD, jacobian_every=every, compiled=False)
        x = stepper.initial_state(q0)[None, :]
        for _ in range(periods):
            result = stepper.step(x, np.zeros((1, n)))
            x = result.x
        print(
            f"Jacobian every {every:2d} steps: q = {np.array2string(x[0, :n], precision=5)}, "
            f"force = {result.contact_force[0].round(4)} N, "
            f"curvature error {abs(x[0, 1] - q[1]):.3g} 1/m"
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--sizes", default="1,16,256,1024")
    parser.add_argument("--accuracy-periods", type=int, default=100)
    parser.add_argument("--skip-tendons", action="store_true")
    parser.add_argument("--tendon-periods", type=int, default=20)
    parser.add_argument("--skip-flags", action="store_true")
    parser.add_argument("--skip-contact", action="store_true")
    args = parser.parse_args()
    sizes = [int(s) for s in args.sizes.split(",")]

    print(f"load average at start: {os.getloadavg()}, cores: {os.cpu_count()}")
    model, actuator = sc.Model(sc.presets.ifac2020()), paper_actuator()
    stepper = Stepper(model, actuator, period=PERIOD)
    rhs_us = rhs_cost(model)
    print(
        f"\n1. Throughput: paper robot, bellows, period {PERIOD * 1e3:g} ms, "
        f"{stepper.method} x {stepper.substeps} substeps, compiled, "
        f"{os.cpu_count()} threads; one compiled rhs: {rhs_us:.2f} us"
    )
    throughput(stepper, sizes, args.repeat, rhs_us)
    print("\n2. Threads")
    threads(model, actuator, args.repeat)
    if not args.skip_flags:
        print("\n3. Compiler flags of the stepper (one member)")
        compiler_flags(model, actuator, args.repeat)
    rows = [("ROS2", s) for s in (8, 16, 32, 64)] + [("ROS34PW2", s) for s in (4, 8, 12, 16, 24)]
    rows += [("RK4", s) for s in (4, 5, 6, 8, 12)]
    print(
        f"\n4. Accuracy: paper robot, random pressures held {PERIOD * 1e3:g} ms, "
        f"{args.accuracy_periods * PERIOD:g} s, against simulate(rtol=1e-10)"
    )
    accuracy(model, actuator, np.array([0.064, 0.0, 0.0]), args.accuracy_periods, rows)
    if not args.skip_tendons:
        print(
            "\n5. Accuracy: two-segment tendon robot (rao2021), tensions 0..8 N held "
            f"{PERIOD * 1e3:g} ms, {args.tendon_periods * PERIOD:g} s, against rtol=1e-8"
        )
        robot = sc.presets.rao2021()
        tendons = sc.presets.rao2021_tendons(t_max=8.0)
        tendon_model = sc.Model(robot)
        q0 = np.concatenate([[s.rest_length, 0.0, 0.0] for s in robot.segments])
        rows = [("ROS34PW2", 16), ("ROS34PW2", 64), ("ROS34PW2", 16, 1), ("ROS2", 16, 1)]
        rows += [("ROS2", 64, 1)]
        accuracy(tendon_model, tendons, q0, args.tendon_periods, rows, rtol=1e-8)
    if not args.skip_contact:
        print("\n6. Contact: a ceiling with friction, 0.1 s, ROS34PW2 x 16 per 20 ms")
        contact()
    print(f"\nload average at end: {os.getloadavg()}")


if __name__ == "__main__":
    main()
