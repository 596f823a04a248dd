"""Identification of a robot from long multi-trial records (issue 33, item 2): the cost of
one evaluation of ``fit_trajectory`` on nine trials of about 290 s at 12 Hz.

Run:  python benchmarks/bench_identification_trials.py [--trials 9] [--duration 290]
      [--cases linear,linear-loose,constant,fit,equilibrium] [--fit-duration 60]

The data have the shape of the report that led to the issue: the paper's robot
(ifac2020, with creep) driven by three chambers through a 50 ms pressure lag, pressure
steps every 2 s (10-40 kPa), the tip's x and z recorded in mm at 12 Hz with 0.1 mm of
noise, the commanded pressures in kPa; eight free parameters (bending a1, both bending
dampings tied, both creep gains tied, the lag, the chambers' area and mounting angle,
and two sensor offsets). Every figure calls the public ``fit_trajectory`` as a user
does, with the default processes and threads: one evaluation is the time of a fit with
``max_evaluations=3`` less that of one with ``max_evaluations=1``, halved (the set-up,
building the evaluators and the first evaluation, cancels), after a first fit that
compiles the sensitivities (printed as the cold time). A fit evaluates a trial point by
the outputs alone and adds the Jacobian where it steps, so the two evaluations timed
cost one Jacobian each where both are steps (printed: how many were); a Jacobian with
its outputs costs about seven times the outputs alone. Cases:

- ``linear``: ``input_hold="linear"``, the default tolerances (rtol 1e-8, atol 1e-10);
- ``linear-loose``: the same with rtol 1e-6 and atol 1e-8, whose integration error
  (printed: the largest change of an output against the default tolerances, and the
  fit's own check of it, ``extra["integration_error"]``, relative to the residuals)
  stays a small fraction of the 0.1 mm noise;
- ``constant``: the inputs held between samples, the default (one trial only, scaled:
  it is several times slower);
- ``fit``: a whole fit, the default budget and tolerances, the linear hold, on nine
  trials shortened to ``--fit-duration`` (60 s: a whole fit of the full records takes
  tens of minutes), printing its evaluations and those with the Jacobian;
- ``equilibrium``: ``fit_equilibria`` on the same records as if quasi-static (issue 33,
  item 3), five free parameters (bending a1, the chambers' area and mounting angle, the
  sensor offsets) on a model not compiled: a fit of one evaluation (set-up and the
  first evaluation, whose equilibria start from those of nearby inputs) and one later
  evaluation, as above, after a first fit that compiles the fit's functions.

The target is issue 33's: one evaluation of the nine trials within 5 s on a quiet
machine; the load average is printed first.
"""

from __future__ import annotations

import argparse
import os
import time

import numpy as np

import softcurve as sc

SEG = "segments[0]."
TARGET = 5.0
"""Issue 33: one evaluation of nine trials, 2,600 s at 12 Hz [s]."""
LOOSE = {"reltol": 1e-6, "abstol": 1e-8}
"""The looser tolerances of the ``linear-loose`` case."""


def trials(model, count: int, duration: float, seed: int = 33) -> list:
    """Synthetic trials (the module's docstring); simulated at 120 Hz, kept at 12 Hz."""
    rng = np.random.default_rng(seed)
    arm = sc.PneumaticActuator.three_bellows(
        distance=0.01, area=2e-5, p_max=2e5, time_constant=0.05
    )
    dt = 1.0 / 120.0
    t = np.arange(int(round(duration / dt)) + 1) * dt
    made = []
    for k in range(count):
        steps = 1e4 + 3e4 * rng.random((int(duration // 2) + 1, 3))
        commands = steps[np.minimum((t // 2.0).astype(int), len(steps) - 1)]
        rest = sc.equilibrium(model, [0.0644, 0.0, 0.0], actuator=arm, inputs=commands[0])
        run = sc.simulate(
            model, rest.q, np.zeros(3), actuator=arm, inputs=commands,
            actuator_state=commands[0], t_final=t[-1], dt=dt,
        )  # fmt: skip
        assert run.success, run.message
        kept = slice(None, None, 10)
        tips = np.array([model.tip_pose(q).position for q in run.q[kept]])
        seen = 1e3 * tips + 0.1 * rng.standard_normal(tips.shape)
        signals = {"x": seen[:, 0], "z": seen[:, 2]}
        inputs = {f"p{i}": commands[kept, i] / 1e3 for i in range(3)}
        units = {"x": "mm", "z": "mm", **dict.fromkeys(inputs, "kPa")}
        made.append(sc.Experiment(run.t[kept], signals, inputs, units, name=f"trial{k}"))
    return made


def problem(model, experiments):
    """The fit's keyword arguments, eight free parameters."""
    output = sc.tip_position_map(model, axes="xz", frame=sc.SensorFrame("camera"))
    input_map = sc.bellows_input_map(area=2e-5, distance=0.01)
    free = [
        sc.Free(SEG + "bending_stiffness.a1", 0.2, 1.0, initial=0.45),
        sc.Free((SEG + "damping[1,1]", SEG + "damping[2,2]"), 1e-8, 1e-5, initial=8e-7),
        sc.Free((SEG + "creep.gain[1]", SEG + "creep.gain[2]"), 1e-4, 1e-2, initial=2e-3),
        sc.Free("input_lag", 0.005, 0.5, initial=0.06),
        sc.Free("bellows.area", 1e-6, 1e-4, initial=2.1e-5),
        sc.Free("bellows.angle", -1.0, 1.0, initial=0.02, scale=1.0),
        sc.Free("camera.x", -0.05, 0.05, initial=0.0, scale=0.01),
        sc.Free("camera.z", -0.05, 0.05, initial=0.0, scale=0.01),
    ]
    starts = [sc.initial_equilibrium(model, e, input_map).x0 for e in experiments]
    return dict(output=output, input_map=input_map, x0=starts, free=free, input_lag=0.06)


def equilibrium_time(experiments):
    """``(first fit [s], fit of one evaluation [s], one later evaluation [s])`` of
    ``fit_equilibria`` (the module's docstring): the first builds and compiles its
    functions (where the cache does not hold them), the others reuse them."""
    model = sc.Model(sc.presets.ifac2020(), compile=False)
    kwargs = problem(model, experiments[:1])
    free = [f for f in kwargs["free"] if f.label.split(".")[0] in ("bellows", "camera")]
    free.insert(0, kwargs["free"][0])

    def fit(evaluations):
        start = time.perf_counter()
        sc.fit_equilibria(
            model, experiments, output=kwargs["output"], input_map=kwargs["input_map"],
            free=free, max_evaluations=evaluations,
        )  # fmt: skip
        return time.perf_counter() - start

    cold = fit(1)
    one = fit(1)
    return cold, one, (fit(3) - one) / 2


def evaluation_time(model, experiments, hold, options):
    """``(cold first fit [s], one evaluation [s], the first fit's report, Jacobians of
    the two evaluations timed)``."""
    kwargs = dict(problem(model, experiments), input_hold=hold, integrator_options=options)

    def fit(evaluations):
        start = time.perf_counter()
        report = sc.fit_trajectory(model, experiments, max_evaluations=evaluations, **kwargs)
        return time.perf_counter() - start, report

    cold, first = fit(1)
    one, _ = fit(1)
    three, report = fit(3)
    return cold, (three - one) / 2, first, report.n_jacobians - first.n_jacobians


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--trials", type=int, default=9)
    parser.add_argument("--duration", type=float, default=290.0)
    parser.add_argument("--cases", default="linear,linear-loose,constant,fit,equilibrium")
    parser.add_argument("--fit-duration", type=float, default=60.0)
    args = parser.parse_args()
    print(f"load average {os.getloadavg()[0]:.2f} on {os.cpu_count()} cores")
    model = sc.Model(sc.presets.ifac2020())
    start = time.perf_counter()
    data = trials(model, args.trials, args.duration)
    total = sum(e.duration for e in data)
    print(
        f"{args.trials} synthetic trials of {args.duration:g} s ({total:.0f} s at 12 Hz, "
        f"{sum(e.t.size for e in data)} samples) made in {time.perf_counter() - start:.1f} s"
    )
    reference = None
    for case in args.cases.split(","):
        if case == "fit":
            short = trials(model, args.trials, args.fit_duration)
            kwargs = dict(problem(model, short), input_hold="linear")
            start = time.perf_counter()
            report = sc.fit_trajectory(model, short, **kwargs)
            print(
                f"  {case:13s}: a whole fit of {args.trials} trials of {args.fit_duration:g} s "
                f"in {time.perf_counter() - start:6.1f} s, {report.n_evaluations} evaluations, "
                f"{report.n_jacobians} with the Jacobian "
                f"({report.status.value})", flush=True,
            )  # fmt: skip
            continue
        if case == "equilibrium":
            cold, first, one = equilibrium_time(data)
            print(
                f"  {case:13s}: fit of one evaluation {first:6.2f} s, one later "
                f"evaluation {one:6.2f} s on {args.trials} trial(s); first fit, cold "
                f"{cold:.1f} s", flush=True,
            )  # fmt: skip
            continue
        hold = "constant" if case == "constant" else "linear"
        options = LOOSE if case == "linear-loose" else None
        subset = data[:1] if case == "constant" else data
        cold, one, first, jacobians = evaluation_time(model, subset, hold, options)
        predicted = first.predicted
        scaled = one * total / sum(e.duration for e in subset)
        line = (
            f"  {case:13s}: one evaluation {one:6.2f} s on {len(subset)} trial(s)"
            f" -> {scaled:6.2f} s for all {args.trials} (target {TARGET:g} s: "
            f"{'met' if scaled <= TARGET else 'not met'}; of the two timed, {jacobians} "
            f"with the Jacobian); first fit, cold {cold:.1f} s"
        )
        if case == "linear":
            reference = predicted
        elif case == "linear-loose" and reference is not None:
            change = 1e3 * np.max(np.abs(predicted - reference))
            line += (
                f"; outputs within {change:.3g} mm of the default tolerances' (noise 0.1 mm), "
                f"the fit's own check {first.extra['integration_error']:.2g} of the residuals"
            )
        print(line, flush=True)


if __name__ == "__main__":
    main()
