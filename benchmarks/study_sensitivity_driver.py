"""Study: the identification's forward sensitivities by softcurve's CVODES driver, per
family and tolerance, against CasADi's CVODES on the augmented system.

Run:  python benchmarks/study_sensitivity_driver.py [--duration 30] [--repeat 2]
      python benchmarks/study_sensitivity_driver.py --rates 12 100 300 500 1000

The case is ``bench_identification.py``'s (the paper robot, three bellows, smooth random
pressures sampled at 12 Hz and held linearly, five free parameters), over ``--duration``
seconds. CasADi's route integrates the augmented system ``(x, S)`` with Adams and
functional iteration (rtol 1e-8, atol 1e-10); the driver (``softcurve_sensitivities``)
integrates the state by Newton's method on its own Newton matrix and the sensitivities
by CVODES's staggered corrector, with the same compiled ``[f; f_x S + f_d]``. It
prints wall time, steps, right-hand sides and sensitivity evaluations per family
(Adams, BDF), tolerance (rtol 1e-8 down to 1e-4) and error test (the state alone, the
library's default, or the sensitivity columns too, ``fsens_err_con``), and the largest
difference from CasADi's route relative to each row's range; then the same for the
driver's Radau IIA with the sensitivities of its discrete scheme
(``integrator_options={"method": "radau"}``). The library's choice
(Adams, rtol 1e-8) is the first of
``softcurve.simulation.sensitivity._sensitivity.SENSITIVITY_METHODS``.
Beside each Adams row with the state alone in the error test it prints the cost of the
state alone, without the columns: what a fit pays for a trial point it evaluates
without the Jacobian (``SensitivityEvaluator.outputs``).

With ``--rates`` it prints instead what ``integrator_options={"method": "auto"}`` (a
fit's default) weighs: the same trial over 3 s with the pressures sampled at each rate
and held, Adams against Radau IIA at the fit's default tolerances through the public
evaluator, their errors against CVODES at rtol 1e-11, and what ``"auto"`` chose and why
(``softcurve.simulation.sensitivity.AUTO_WITHIN``).

First it prints the eigenvalues of the robot linearized at the trial's first state with
its first pressures, and their angle from the negative real axis: beyond a BDF order's
stability angle (86.0, 73.4, 51.8 deg for orders 3, 4, 5; Hairer and Wanner, Solving
Ordinary Differential Equations II, table V.2.1) that order's step is bounded by the
mode, whatever the tolerance.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import casadi as ca
import numpy as np
from scipy.integrate import solve_ivp

import softcurve as sc
from softcurve.identification.maps import bellows_input_map
from softcurve.simulation.sensitivity import AUTO_WITHIN
from softcurve.simulation.sensitivity._sensitivity import DriverSettings, integrate_sensitivities

sys.path.insert(0, str(Path(__file__).parent))
import bench_identification
from _timing import best_of  # benchmarks/_timing.py: a helper, not a benchmark


def modes() -> None:
    """The linearized robot's eigenvalues at the trial's start, with their angles."""
    model = sc.Model(sc.presets.ifac2020())
    actuator = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)
    q0 = np.array([0.0644, 1.0, 0.0])
    pressures = np.full(3, 1.5e4)
    eigenvalues = sc.linearize(model, q0, actuator=actuator, inputs=pressures).eigenvalues
    print("eigenvalues at the start [1/s], and degrees from the negative real axis:")
    for value in eigenvalues[eigenvalues.imag >= 0]:
        angle = np.degrees(np.arctan2(abs(value.imag), -value.real))
        print(f"  {value.real:9.2f} {value.imag:+9.2f}j  {angle:5.1f} deg")


def implicit_runge_kutta(duration: float) -> None:
    """Steps of SciPy's Radau IIA (order 5, L-stable) and BDF on the state alone (no
    sensitivities) of the trial, with the exact Jacobian: what a method whose stability
    is not bounded near the imaginary axis takes."""
    model = sc.Model(sc.presets.ifac2020())
    inputs = bellows_input_map(area=2e-5, distance=0.01)
    x, u = ca.SX.sym("x", model.n_state), ca.SX.sym("u", 3)
    values = {name: ca.DM(value) for name, value in inputs.parameters.items()}
    xdot = model.casadi_rhs()(x, inputs.function(x[: model.n], u, values), model.parameters)
    f = ca.Function("f", [x, u], [xdot, ca.jacobian(xdot, x)])
    t, pressures = bench_identification.random_pressures(duration)
    table = np.column_stack(list(pressures.values()))

    def at(time):
        return [np.interp(time, t, column) for column in table.T]

    x0 = np.zeros(model.n_state)
    x0[:3] = [0.0644, 1.0, 0.0]
    for method in ("Radau", "BDF"):
        for rtol in (1e-4, 1e-6):
            solution = solve_ivp(
                lambda time, state: np.array(f(state, at(time))[0]).ravel(),
                (0.0, duration), x0, method=method, rtol=rtol, atol=rtol * 1e-2,
                jac=lambda time, state: np.array(f(state, at(time))[1]),
            )  # fmt: skip
            print(f"SciPy {method:5s} (state only), rtol {rtol:.0e}: {solution.t.size - 1} steps")


def held_rates(rates, repeat: int) -> None:
    """Adams against Radau IIA on held pressures sampled at each rate, and ``"auto"``."""
    duration = 3.0
    print(f"held pressures over {duration:g} s, rtol 1e-8, atol 1e-10 (a fit's default); "
          "errors: of the outputs or the Jacobian, the larger, of the largest entry")  # fmt: skip
    model = sc.Model(sc.presets.ifac2020())
    actuator = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)
    first = [p[0] for p in bench_identification.random_pressures(duration)[1].values()]
    q0 = np.array([0.0644, 1.0, 0.0])  # the trial's start
    linear = sc.linearize(model, q0, actuator=actuator, inputs=np.array(first))
    fastest = np.abs(linear.eigenvalues).max()  # [1/s]
    print(f"fastest rate at the start {fastest:.0f} 1/s; auto takes Radau IIA below "
          f"{AUTO_WITHIN:g} / fastest rate ({AUTO_WITHIN / fastest:.2g} s)")  # fmt: skip
    print("| rate [Hz] | change x fastest rate | Adams [s] | Radau IIA [s] | Radau / Adams "
          "speed | error Adams | error Radau | auto |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for rate in rates:
        reference, theta = bench_identification.dynamic_evaluator(
            duration, "constant", {"reltol": 1e-11, "abstol": 1e-13}, rate=rate
        )
        y_reference, j_reference = reference(theta)
        row, errors = {}, {}
        for method in ("adams", "radau"):
            evaluate, _ = bench_identification.dynamic_evaluator(
                duration, "constant", {"method": method}, rate=rate
            )
            evaluate(theta)  # compiles and loads
            row[method], (y, jacobian) = best_of(repeat, lambda e=evaluate, at=theta: e(at))
            errors[method] = max(
                np.abs(y - y_reference).max() / np.abs(y_reference).max(),
                np.abs(jacobian - j_reference).max() / np.abs(j_reference).max(),
            )
        chosen, _ = bench_identification.dynamic_evaluator(duration, "constant", rate=rate)
        print(
            f"| {rate:g} | {fastest / rate:.2f} | {row['adams']:.3f} | "
            f"{row['radau']:.3f} | {row['adams'] / row['radau']:.2f} | "
            f"{errors['adams']:.1e} | {errors['radau']:.1e} | {chosen.method} |"
        )
        print(f"  ({chosen.method_reason})")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--duration", type=float, default=30.0)
    parser.add_argument("--repeat", type=int, default=2)
    parser.add_argument("--rates", type=float, nargs="+", help="held pressures' rates [Hz]")
    args = parser.parse_args()
    if args.rates:
        held_rates(args.rates, args.repeat)
        return
    modes()
    implicit_runge_kutta(args.duration)
    evaluate, theta = bench_identification.dynamic_evaluator(args.duration, "linear")
    evaluate(theta)  # compiles and loads the driver's functions
    problem, columns = evaluate._route()
    route = evaluate.driven
    times, table, linear = route.times, route.table, route.linear
    max_steps = route.settings.max_steps
    d_value = np.array(evaluate.direct(theta)[0]).ravel()
    start = np.concatenate([d_value[evaluate.n_p + evaluate.n_v :], evaluate.seed.ravel("F")])
    d_scaled = np.concatenate([d_value, evaluate.scale])

    def best(run):
        run()  # warm-up
        return best_of(args.repeat, run)

    wall, reference = best(
        lambda: np.array(evaluate.integrator(x0=start, p=d_scaled, u=evaluate.u_data)["xf"])
    )
    stats = evaluate.integrator.stats()
    scale = 300.0 / args.duration
    m = len(evaluate.active)
    print(f"{args.duration:g} s trial at 12 Hz, {m} sensitivity columns; per 300 s in brackets")
    print(
        f"CasADi's CVODES, Adams functional, rtol 1e-8: {wall:.3f} s ({wall * scale:.1f} s), "
        f"{stats['nsteps']} steps, {stats['nfevals']} augmented right-hand sides"
    )
    span = np.abs(reference).max(axis=1) + 1e-300
    n_x = evaluate.n_x
    tolerances = ((1e-8, 1e-10), (1e-6, 1e-8), (1e-4, 1e-6))
    cases = [(family, rtol, atol, tested) for family in (1, 2) for tested in (False, True)
             for rtol, atol in tolerances]  # fmt: skip
    # Radau IIA's columns are never in its error test: the sensitivities of its steps
    cases += [
        (3, rtol, atol, False) for rtol, atol in ((1e-8, 1e-10), (1e-7, 1e-9), *tolerances[1:])
    ]
    for family, rtol, atol, tested in cases:
        name = {1: "Adams", 2: "BDF", 3: "Radau"}[family]
        tested_text = "state and columns" if tested else "state only"
        settings = DriverSettings(rtol, atol, max_steps, family, tested)
        wall, (out, _, flag, counts) = best(
            lambda t=settings: integrate_sensitivities(
                problem, columns, start, d_value, d_scaled, times, table, linear, t, route.helper
            )
        )
        difference = np.abs(out.T - reference).max(axis=1) / span
        print(
            f"driver, {name:5s} Newton, rtol {rtol:.0e}, error test on {tested_text}: "
            f"{wall:.3f} s ({wall * scale:.1f} s), "
            f"flag {flag}, {counts['steps']} steps, {counts['rhs_evaluations']} right-hand "
            f"sides, {counts['sensitivity_evaluations']} sensitivity evaluations, "
            f"{counts['jacobian_evaluations']} Jacobians; difference from CasADi's route: "
            f"states {difference[:n_x].max():.1e}, sensitivities "
            f"{difference[n_x:].max():.1e} (of each row's range)"
        )
        if family == 1 and not tested:  # what a fit's trial point without the Jacobian costs
            alone, (out, _, flag, counts) = best(
                lambda t=settings: integrate_sensitivities(
                    problem, columns, start[:n_x], d_value, d_scaled, times, table, linear, t
                )
            )
            print(
                f"driver, {name:5s} Newton, rtol {rtol:.0e}, the state alone: {alone:.3f} s "
                f"({alone * scale:.1f} s, {wall / alone:.1f} times less), flag {flag}, "
                f"{counts['steps']} steps"
            )


if __name__ == "__main__":
    main()
