"""The real-data goals of issue 16 on the Caasenbrood measurements, measured.

Builds on ``validate_caasenbrood2021.py`` (same robot, data, maps) and adds what that
script assumes away: the initial state of each free-oscillation recording (creep state
``lambda(0)``, released angle, IMU zero) as parameters *per recording*, a joint fit of
both recordings with one set of material parameters, cross-predictions where only the
test recording's initial state is estimated, and a dynamic fit of the open loop with a
slow creep state (does the hysteresis ask for a slower creep than the oscillations?)::

    python examples/validate_joint.py [--only oscillation|openloop|creep|rate]
        [--quick | --smoke] [--laws tanh,linear] [--figure PATH]

Every figure of the tables "real-data goals" in ``docs/validation.md`` is printed by it;
``--figure`` draws the free oscillations of both recordings, measured, fitted jointly and
predicted from the other recording, for the first law with the initial state, angle and
zero of each recording free.
The joint fits are the library's: :func:`~softcurve.identification.fits.fit_trajectory`
of a list of recordings, with the per-recording initial state and IMU zero as
``Free(..., per_experiment=True)`` entries ``x0.lam[1]``, ``x0.q[1]`` and ``offset``.
"""

from __future__ import annotations

import argparse
import importlib.util
import sys
import time
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple

import casadi as ca
import numpy as np
import scipy.optimize

import softcurve as sc
from softcurve.description.bellows import PneumaticActuator
from softcurve.identification.fits import (
    Free,
    fit_equilibria,
    fit_trajectory,
    predict_equilibria,
    predict_trajectory,
)
from softcurve.identification.maps import InputMap, bending_angle_map, curvature_map

HERE = Path(__file__).resolve().parent
_spec = importlib.util.spec_from_file_location("vc", HERE / "validate_caasenbrood2021.py")
vc = importlib.util.module_from_spec(_spec)
_spec.loader.exec_module(vc)

SEG = vc.SEG
RECORDINGS = ("b17", "b42")
# lambda enters the force as K[1,1] lambda with K[1,1] = 1e-2 (fixed, see
# docs/validation.md); the elastic generalized force at 40 deg is ~1e-4 N m, so
# lambda ~ 1e-2 is the scale of a pre-stress of the order of the elastic force.
LAMBDA_SCALE = 1e-2
GOALS = {"b42 in-sample": 0.20, "cross": 1.0, "joint": 0.4, "openloop": 0.30}
# |initial bending rate| allowed [1/(m s)]: 12.8 rad/s of tip angle, a third of the
# fastest swing of b42 (about 36 rad/s, 43 deg at 0.13 s)
RATE_BOUND = 200.0


class Size(NamedTuple):
    """How much of the data a run uses and how long its fits may search (a named tuple, as
    validate_caasenbrood2021.Size)."""

    oscillation_dt: float
    """The free oscillations resampled to this step [s]."""
    openloop_dt: float
    """The open loop resampled to this step for its dynamic fit [s]."""
    most_evaluations: int | None
    """Evaluations after which every fit stops (None: each at its own budget)."""
    reference: vc.Size
    """The studies of validate_caasenbrood2021.py that the open loop starts from."""

    def budget(self, evaluations: int) -> int:
        """A fit's budget of ``evaluations``, within :attr:`most_evaluations`."""
        return (
            evaluations
            if self.most_evaluations is None
            else min(evaluations, self.most_evaluations)
        )


# the open loop starts from validate_caasenbrood2021's oscillations at 2 ms, 120 evaluations
_REFERENCE = vc.SIZES["quick"]._replace(evaluations=120)
SIZES = {
    "full": Size(1e-3, 0.02, None, _REFERENCE),
    "quick": Size(2e-3, 0.04, None, _REFERENCE),
    # every step once, each fit stopped at its second evaluation: the numbers mean
    # nothing (the tests run it so that no step breaks)
    "smoke": Size(0.02, 0.04, 2, vc.SIZES["smoke"]),
}
"""The sizes of a run: full (the tables of docs/validation.md), ``--quick``, ``--smoke``."""


# -- the material ---------------------------------------------------------------------


def material_freedom(robot, law: str):
    """(extra values, bind, Free list) of the shared material: stiffness, damping, creep."""
    values, bind, free = vc.stiffness_freedom(robot, law)
    free += [
        Free(SEG + "damping[1,1]", 1e-9, 1e-4),
        Free(SEG + "creep.rate[1]", 1.0, 1000.0),
        Free(SEG + "creep.gain[1]", 0.0, 1.0, scale=1e-3),  # gain < 0 is active
    ]
    return values, bind, free


# -- joint fit of several recordings (the library's fit_trajectory of a list) --------


def recording_freedom(experiments: dict, what: tuple[str, ...]) -> list:
    """Per-recording ``Free`` entries of the initial state and the IMU zero (``what`` of
    ``lam``, ``beta``, ``offset``): one value per recording, named ``name[recording]``."""
    betas = [float(np.radians(e.signals["beta"][0])) for e in experiments.values()]
    free = []
    if "lam" in what:  # the bending creep state at release
        free.append(Free("x0.lam[1]", -1.0, 1.0, initial=0.0, scale=LAMBDA_SCALE,
                         per_experiment=True))  # fmt: skip
    if "beta" in what:  # the released bend: one box for all, 0.05 rad beyond the first samples
        lower, upper = (min(betas) - 0.05) / vc.REST_LENGTH, (max(betas) + 0.05) / vc.REST_LENGTH
        free.append(Free("x0.q[1]", lower, upper, scale=0.1 / vc.REST_LENGTH,
                         per_experiment=True))  # fmt: skip
    if "offset" in what:
        free.append(Free("offset", -3.0, 3.0, initial=0.0, scale=0.1, per_experiment=True))
    if "rate" in what:  # the bending rate at the first sample [1/(m s)]
        free.append(Free("x0.qd[1]", -RATE_BOUND, RATE_BOUND, initial=0.0, scale=10.0,
                         per_experiment=True))  # fmt: skip
    return free


def first_rate(experiment) -> float:
    """The bending angle's rate over the first two samples [deg/s]."""
    beta, t = experiment.signals["beta"][:2], experiment.t[:2]
    return (beta[1] - beta[0]) / (t[1] - t[0])


def start_state(experiment, what=()) -> np.ndarray:
    """The release state of ``validate_caasenbrood2021`` (at rest, creep relaxed) or, with
    ``"measured-rate"`` in ``what``, moving at the rate of the first two samples."""
    state = vc.release_state(experiment)
    if "measured-rate" in what:
        # qd[1] of (l, kx, ky, l', kx', ky', lam): the curvature rate of the bend's rate
        state[4] = np.radians(first_rate(experiment)) / vc.REST_LENGTH
    return state


def joint_fit(model, experiments: dict, shared, extra, bind, what, max_evaluations=120):
    """``fit_trajectory`` of the recordings together: the shared material and, per
    recording, the initial state and IMU zero of ``what`` (started from rest at the first
    measured angle, creep relaxed). Returns a dict with the estimate, per-recording
    predictions and RMS [deg], standard errors and the status."""
    data = [replace(e, name=tag) for tag, e in experiments.items()]
    values = dict(extra)
    if "offset" in what:
        values["offset"] = 0.0
    report = fit_trajectory(
        model, data, output=bending_angle_map(offset="offset" if "offset" in what else None),
        x0={e.name: start_state(e, what) for e in data},
        free=list(shared) + recording_freedom(experiments, what), extra=values, bind=bind,
        max_evaluations=max_evaluations, processes=1,
    )  # fmt: skip
    residual = report.predicted - report.measured
    return {
        "names": report.names,
        "values": report.values,
        "errors": report.standard_errors,
        "status": report.status,
        "message": report.message,
        "evaluations": report.n_evaluations,
        "rms": {tag: float(report.part(tag).rms[0]) for tag in experiments},
        "rms_all": float(np.sqrt(np.mean(residual**2))),
        "predicted": {tag: report.part(tag).predicted for tag in experiments},
        "parameters": report.extra["parameters"],
        "extra_values": report.extra["values"],
    }


def print_joint(label: str, result: dict):
    print(f"### {label}: status {result['status'].value}, {result['evaluations']} evaluations")
    print("```")
    for name, v, se in zip(result["names"], result["values"], result["errors"], strict=True):
        print(f"{name:40s} {v:12.5g} +- {1.96 * se:.3g}")
    rms = ", ".join(f"{k} {v:.3f}" for k, v in result["rms"].items())
    print(f"RMS [deg]: {rms}; all {result['rms_all']:.3f}")
    print("```\n")


# -- single-recording fits with free initial state, and cross-predictions -------------


def single_fit(model, experiments, train, law, what, max_evaluations=120, start=None):
    """Fit one recording: shared material plus its own initial state (``what``);
    ``start`` overrides initial values of the material (name -> value)."""
    robot = model.robot
    values, bind, free = material_freedom(robot, law)
    start = start or {}
    free = [f if f.label not in start else replace(f, initial=start[f.label]) for f in free]
    result = joint_fit(
        model, {train: experiments[train]}, free, values, bind, what, max_evaluations
    )
    result["bind"], result["extra"] = bind, values
    return result


def cross_predict(model, experiments, fit: dict, train: str, test: str, what, evaluations=60):
    """The test recording simulated with the material of ``fit``: (a) relaxed creep and
    the measured first angle (no parameter of the test recording estimated), (b) only the
    test recording's initial state and zero (``what``) estimated, the material fixed."""
    experiment = replace(experiments[test], name=test)
    own = ("x0.", "offset")  # the training recording's initial state and zero stay with it
    values = {**fit["extra"], **fit["extra_values"]}
    values = {k: v for k, v in values.items() if not k.startswith(own)}
    common = {"bind": fit["bind"], "parameters": fit["parameters"]}
    x0 = start_state(experiment, what)
    relaxed = fit_trajectory(
        model, experiment, output=bending_angle_map(), x0=x0, free=[], extra=values, **common
    )
    offset = "offset" if "offset" in what else None
    state = fit_trajectory(
        model, experiment, output=bending_angle_map(offset=offset), x0=x0,
        free=recording_freedom({test: experiment}, what),
        extra={**values, **({offset: 0.0} if offset else {})}, max_evaluations=evaluations,
        **common,
    )  # fmt: skip
    return relaxed, state


def swing_table(t, signals: dict):
    """Extrema of each signal (``label -> beta [deg]`` on the grid ``t`` [s]): period
    between maxima and the ratio of successive swings, which tell whether the decay
    depends on the amplitude (a linear model's ratio does not)."""
    head = "| signal | first extrema [deg] | period [s] | ratio min1/beta0, max1/min1, min2/max1 |"
    lines = [head,
             "| --- | --- | --- | --- |"]  # fmt: skip
    for label, y in signals.items():
        z = np.asarray(y) - np.mean(np.asarray(y)[t > 0.5])
        turns = np.where(np.diff(np.sign(np.diff(z))) != 0)[0] + 1
        turns = [k for k in turns if abs(z[k]) > 0.05]  # skip noise wiggles [deg]
        ext = z[turns][:4]
        peaks = t[turns][1::2][:3]
        period = float(np.mean(np.diff(peaks))) if len(peaks) > 1 else np.nan
        # min1/beta0, max1/min1, min2/max1: as many as there are extrema (a fit stopped
        # early may swing fewer times)
        ratios = [b / a for a, b in zip([z[0], *ext], ext[:3], strict=False)]
        lines.append(f"| {label} | {', '.join(f'{e:.2f}' for e in ext)} | {period:.3f} | "
                     f"{', '.join(f'{r:.3f}' for r in ratios)} |")  # fmt: skip
    return "\n".join(lines)


def oscillation_goals(experiments, laws=("tanh", "linear"), size: Size = SIZES["full"]):
    rows, swings = [], {}
    variants = {"creep": ("lam",), "creep+angle+zero": ("lam", "beta", "offset")}
    for law in laws:
        model = sc.Model(vc.data_robot(law), quadrature_nodes=vc.QUADRATURE_NODES)
        for label, what in variants.items():
            fits = {}
            for train in RECORDINGS:
                t0 = time.perf_counter()
                fits[train] = fit = single_fit(
                    model, experiments, train, law, what, size.budget(120)
                )
                print_joint(f"{law}, {label} free, fitted on {train}", fit)
                test = "b42" if train == "b17" else "b17"
                relaxed, state = cross_predict(
                    model, experiments, fit, train, test, what, size.budget(60)
                )
                rows.append((law, label, train, fit["rms"][train], test, relaxed.rms[0],
                             state.rms[0], state.table()))  # fmt: skip
                swings[(law, label, test)] = {
                    f"{test} measured": experiments[test].signals["beta"],
                    f"{test} from {train}, relaxed": relaxed.predicted[:, 0],
                    f"{test} from {train}, own initial state": state.predicted[:, 0],
                    f"{train} fitted": fit["predicted"][train][:, 0],
                }
                print(f"[{law} {label} {train}: {time.perf_counter() - t0:.0f} s]", flush=True)
            values, bind, free = material_freedom(model.robot, law)
            joint = joint_fit(model, experiments, free, values, bind, what, size.budget(150))
            print_joint(f"{law}, {label} free, JOINT fit of b17 + b42", joint)
            rows.append((law, label, "joint", joint["rms"], None, None, None, ""))
            for tag in RECORDINGS:
                swings[(law, label, tag)][f"{tag} joint fit"] = joint["predicted"][tag][:, 0]
            sys.stdout.flush()
    print("## Free oscillations with the initial state per recording [deg RMS]\n")
    print("| law | per recording | fitted on | fit | predicts | relaxed start | own start |")
    print("| --- | --- | --- | --- | --- | --- | --- |")
    for law, label, train, fit, test, relaxed, state, _ in rows:
        if train == "joint":
            joint = ", ".join(f"{k} {v:.2f}" for k, v in fit.items())
            print(f"| {law} | {label} | joint b17 + b42 | {joint} | - | - | - |")
        else:
            print(f"| {law} | {label} | {train} | {fit:.2f} | {test} | {relaxed:.2f} "
                  f"| {state:.2f} |")  # fmt: skip
    print()
    print("## Swings: is the decay amplitude dependent? (extrema after release)\n")
    for (law, label, tag), signals in swings.items():
        print(f"### {law}, {label} free, recording {tag}\n")
        print(swing_table(experiments[tag].t, signals) + "\n")
    for law, label, train, _, test, _, _, table in rows:
        if table:
            print(
                f"### {law}, {label}: {test} from {train}, own initial state\n```\n{table}\n```\n"
            )
    return rows, swings


def swing_figure(experiments, swings: dict, path) -> Path:
    """The free oscillations of each recording: measured, the joint fit, and predicted
    from the other recording's fit (relaxed start and own initial state), for the first
    law of ``swings`` with the most free variant; written to ``path``."""
    import matplotlib.pyplot as plt

    law, label = next(iter(swings))[:2]
    label = max({k[1] for k in swings if k[0] == law}, key=len)
    figure, axes = plt.subplots(len(RECORDINGS), 1, figsize=(8, 2.8 * len(RECORDINGS)))
    for ax, tag in zip(np.atleast_1d(axes), RECORDINGS, strict=True):
        t = experiments[tag].t
        for name, y in swings[(law, label, tag)].items():
            if not name.startswith(f"{tag} "):  # the other recording's own fit
                continue
            style = {"lw": 2.2, "color": "k", "alpha": 0.35} if "measured" in name else {"lw": 1}
            ax.plot(t, y, label=name, **style)
        ax.set(ylabel="bending angle beta [deg]", title=f"recording {tag}")
        ax.grid(True, alpha=0.3)
        ax.legend(fontsize="small", loc="upper right")
    np.atleast_1d(axes)[-1].set_xlabel("time t [s]")
    figure.suptitle(f"free oscillations, {law} law, {label} free per recording")
    figure.tight_layout()
    return sc.save_figure(figure, path, dpi=100)


def rate_probe(experiments, law="tanh", size: Size = SIZES["full"]):
    """Do the recordings start at rest, as the fits assume? The first samples' rates, and
    b17 -> b42 with each recording's initial bending rate measured or estimated."""
    for tag, e in experiments.items():
        print(f"{tag}: first angle {e.signals['beta'][0]:.2f} deg, then {first_rate(e):.0f} deg/s")
    model = sc.Model(vc.data_robot(law), quadrature_nodes=vc.QUADRATURE_NODES)
    head = ("b17 fitted with", "b17 fit", "b17's creep gain", "b42's own start estimated",
            "b42 predicted", "b42's estimated start")  # fmt: skip
    print("\n| " + " | ".join(head) + " |\n|" + " --- |" * len(head))
    trained = (("lam",), ("lam", "measured-rate"), ("lam", "rate"))
    for what in trained:
        fit = single_fit(model, experiments, "b17", law, what, size.budget(120))
        gain = fit["values"][fit["names"].index(SEG + "creep.gain[1]")]
        for own in [what] + ([] if "rate" in what else [(*what, "rate")]):
            _, state = cross_predict(model, experiments, fit, "b17", "b42", own, size.budget(60))
            start = ", ".join(
                f"{n} {v:.4g}" for n, v in zip(state.names, state.values, strict=True)
            )
            print(f"| {' + '.join(what)} | {fit['rms']['b17']:.2f} | {gain:.2g} | "
                  f"{' + '.join(own)} | {state.rms[0]:.2f} | {start} |", flush=True)  # fmt: skip


# -- open loop with a slow creep state ------------------------------------------------


def openloop_reference(directory, size: Size = SIZES["full"]):
    """Today's quasi-static study (validate_caasenbrood2021.py, k(0) from the b17
    oscillation at 2 ms): ``(openloop, results, b17 fit)``."""
    reference = size.reference
    experiments = vc.load_oscillations(directory, reference.oscillation_dt)
    b17 = vc.oscillation_study(experiments, "tanh", reference.evaluations)["b17"]["fit"]
    k_linear = vc.oscillation_study(experiments, "linear", reference.evaluations)["b17"]["fit"]
    openloop = vc.load_openloop(directory)
    k_zero = {"tanh": vc._static_stiffness(b17), "linear": vc._static_stiffness(k_linear)}
    results = vc.openloop_study(openloop, k_zero, reference)
    p = results[("tanh", "geometric")]["prediction"]
    print("quasi-static tanh/geometric (reference):")
    print("  fit 0-20", np.round(vc.window_rms(p, 0, 20), 3),
          "predict 20-40", np.round(vc.window_rms(p, 20, 40.1), 3))  # fmt: skip
    print("\n## Hysteresis probe: quasi-static residual against a creep response\n")
    print("| creep rate [1/s] | factor c | fit 0-20 s kx, ky | predict 20-40 s kx, ky |")
    print("| --- | --- | --- | --- |")
    for r, c, *e in hysteresis_probe(p):
        norm = "c: norm of the factors"
        label = f"{r:g}" if np.isfinite(r) else f"all seven together (Prony series); {norm}"
        label = label if r != -np.inf else f"all seven, passive (every c >= 0); {norm}"
        print(f"| {label} | {c:.3g} | {e[0]:.2f}, {e[1]:.2f} | {e[2]:.2f}, {e[3]:.2f} |")
    print()
    return openloop, results, b17


def openloop_creep(openloop, results, b17, size: Size = SIZES["full"]):
    """Dynamic fit of 0-20 s with a free (slow) bending creep state, prediction 20-40 s.

    Starts from the quasi-static tanh/geometric fit of validate_caasenbrood2021.py
    (k(0) from the b17 oscillation), frees the creep rate and gain of both bending
    coordinates (tied), and refits map gain, mounting angle, offsets and the law.
    """
    entry = results[("tanh", "geometric")]
    static, p = entry["fit"], entry["prediction"]
    rows = []
    data = openloop.resample(size.openloop_dt)
    for rate0 in (0.3, 3.0):
        robot = static.extra["robot"]
        segment = robot.segments[0]
        oscillating = b17.extra["robot"].segments[0]
        creep = sc.Creep(
            rate=[300.0, rate0, rate0], gain=[0.0, 2e-3, 2e-3], compliance=vc.CREEP_COMPLIANCE
        )
        segment = segment.replace(damping=oscillating.damping, creep=creep)
        robot = robot.replace(segments=(segment,))
        model = sc.Model(robot, quadrature_nodes=vc.QUADRATURE_NODES)
        values = {**entry["values"], **static.extra["values"]}
        problem = dict(entry["problem"])
        x0 = _openloop_start(entry, values, data)
        law = SEG + "bending_stiffness"
        free = [
            Free("bellows.area", 1e-8, 1e-2, initial=values["bellows.area"]),
            Free("bellows.angle", -4.0, 4.0, initial=values["bellows.angle"], scale=1.0),
            Free(f"{law}.k_inf", 1e-4, 1.0, initial=values[f"{law}.k_inf"]),
            Free(f"{law}.rate", 0.05, 50.0, initial=values[f"{law}.rate"]),
            *(Free(o, -3.0, 3.0, initial=values[o], scale=0.1) for o in vc.OFFSETS),
            Free((SEG + "creep.rate[1]", SEG + "creep.rate[2]"), 0.01, 100.0),
            Free((SEG + "creep.gain[1]", SEG + "creep.gain[2]"), 0.0, 1.0, scale=1e-3),
        ]
        t0 = time.perf_counter()
        fit = fit_trajectory(model, data.trim(0.0, 20.0), x0=x0, free=free, extra=values,
                             max_evaluations=size.budget(40), **problem)  # fmt: skip
        prediction = predict_trajectory(model, data, fit, x0=x0, extra=values, **problem)
        a, b = vc.window_rms(prediction, 0, 20), vc.window_rms(prediction, 20, 40.1)
        print(f"### open loop, dynamic with creep (start rate {rate0}) "
              f"[{time.perf_counter() - t0:.0f} s]\n```\n{fit.table()}\n```")  # fmt: skip
        print("  fit 0-20", np.round(a, 3), "predict 20-40", np.round(b, 3), flush=True)
        rows.append((rate0, fit, a, b))
    print("\n## Open loop with a slow bending creep state [1/m RMS: kx, ky, vector]\n")
    print("| model | fit 0-20 s | predict 20-40 s |")
    print("| --- | --- | --- |")
    a, b = vc.window_rms(p, 0, 20), vc.window_rms(p, 20, 40.1)
    print(f"| quasi-static tanh (today) | {a[0]:.2f}, {a[1]:.2f}, {a[2]:.2f} "
          f"| {b[0]:.2f}, {b[1]:.2f}, {b[2]:.2f} |")  # fmt: skip
    for rate0, fit, a, b in rows:
        rate = fit.value(f"{SEG}creep.rate[1]={SEG}creep.rate[2]")
        row = f"| {a[0]:.2f}, {a[1]:.2f}, {a[2]:.2f} | {b[0]:.2f}, {b[1]:.2f}, {b[2]:.2f} |"
        print(f"| dynamic tanh + creep rate {rate:.3g} 1/s (start {rate0}) {row}")
    return rows


def chamber_map(angles, areas) -> InputMap:
    """Three bellows, each with its own effective area (gain) and azimuth: extra
    parameters ``bellow{i}.area`` [m^2] and ``bellow{i}.angle`` [rad] (sensor frame),
    nominal values ``areas`` and ``angles``; distance fixed (only area x distance acts)."""
    actuator = PneumaticActuator.three_bellows(
        distance=vc.BELLOWS_DISTANCE, area=float(np.mean(areas)), p_max=1e9
    )

    def function(q, u, values):
        geometry = []
        for i in range(3):
            geometry += [values[f"bellow{i}.angle"], vc.BELLOWS_DISTANCE, values[f"bellow{i}.area"]]
        return actuator.input_matrix_symbolic(q, ca.vertcat(*geometry)) @ u

    nominal = {f"bellow{i}.area": float(areas[i]) for i in range(3)}
    nominal.update({f"bellow{i}.angle": float(angles[i]) for i in range(3)})
    return InputMap(function, nominal)


def openloop_maps(openloop, results, numbering, size: Size = SIZES["full"]):
    """Quasi-static tanh fits beyond today's: per-chamber gains and azimuths, and the
    in-sample reach (identified on all 40 s, or on 20-40 s only)."""
    data = openloop.resample(size.reference.openloop_dt)
    entry = results[("tanh", "geometric")]
    static = entry["fit"]
    values = {**entry["values"], **static.extra["values"]}
    model, law = entry["model"], SEG + "bending_stiffness"
    shape = [
        Free(f"{law}.k_inf", 1e-4, 1.0, initial=values[f"{law}.k_inf"]),
        Free(f"{law}.rate", 0.05, 50.0, initial=values[f"{law}.rate"]),
        *(Free(o, -3.0, 3.0, initial=values[o], scale=0.1) for o in vc.OFFSETS),
    ]
    same = [
        Free("bellows.area", 1e-8, 1e-2, initial=values["bellows.area"]),
        Free("bellows.angle", -4.0, 4.0, initial=values["bellows.angle"], scale=1.0),
    ]
    angles = [values["bellows.angle"] + numbering * 2 * np.pi * i / 3 for i in range(3)]
    chambers = chamber_map(angles, [values["bellows.area"]] * 3)
    per_chamber = [Free(f"bellow{i}.area", 1e-8, 1e-2) for i in range(3)]
    per_chamber += [
        Free(f"bellow{i}.angle", a - 1.0, a + 1.0, scale=1.0) for i, a in enumerate(angles)
    ]
    cases = {
        "one map, identified on 0-20 s": (entry["problem"]["input_map"], same, (0, 20)),
        "per-chamber map, identified on 0-20 s": (chambers, per_chamber, (0, 20)),
        "one map, identified on 0-40 s (in-sample reach)": (
            entry["problem"]["input_map"], same, (0, 40.1)),
        "one map, identified on 20-40 s": (entry["problem"]["input_map"], same, (20, 40.1)),
        "per-chamber map, identified on 0-40 s": (chambers, per_chamber, (0, 40.1)),
    }  # fmt: skip
    rows = []
    output = curvature_map(offsets=vc.OFFSETS)
    for label, (input_map, free, (a, b)) in cases.items():
        problem = {"output": output, "input_map": input_map, "bind": entry["problem"]["bind"]}
        fit = fit_equilibria(
            model, data.trim(a, b), free=free + shape, extra=values,
            max_evaluations=size.budget(150),
            parameters=static.extra["parameters"], **problem,
        )  # fmt: skip
        prediction = predict_equilibria(model, data, fit, extra=values, **problem)
        w1, w2 = vc.window_rms(prediction, 0, 20), vc.window_rms(prediction, 20, 40.1)
        print(f"### open loop, {label}\n```\n{fit.table()}\n```\n", flush=True)
        rows.append((label, w1, w2))
    print("## Open loop, quasi-static tanh law: curvature error [1/m] (kx, ky, vector)\n")
    print("| pressure map, identified on | 0-20 s | 20-40 s |")
    print("| --- | --- | --- |")
    for label, w1, w2 in rows:
        print(f"| {label} | {w1[0]:.2f}, {w1[1]:.2f}, {w1[2]:.2f} "
              f"| {w2[0]:.2f}, {w2[1]:.2f}, {w2[2]:.2f} |")  # fmt: skip
    print()
    return rows


def hysteresis_probe(prediction, rates=(0.03, 0.1, 0.3, 1.0, 3.0, 10.0, 30.0)):
    """Is the quasi-static residual a creep response? For each rate ``r`` filter the
    predicted curvature rate, ``s' = -r s + kappa_dot`` (what one linear creep state per
    coordinate adds, to first order), fit one factor ``c`` with ``kappa = kappa_qs - c s``
    on 0-20 s and apply it to 20-40 s; last row (rate inf): all rates at once, one factor
    each (a Prony series), and the same with every factor >= 0 (rate -inf; the sign a
    passive creep term has). Returns rows ``(r, c, rms 0-20, rms 20-40)``, the RMS per
    component (kx, ky) [1/m]."""
    t, y, m = prediction.abscissa, prediction.predicted, prediction.measured
    dt = float(t[1] - t[0])
    rate_of_change = np.gradient(y, dt, axis=0)
    train = t < 20.0
    residual = y - m
    rows, responses = [], []
    for r in rates:
        s = np.zeros_like(y)
        decay = np.exp(-r * dt)
        for k in range(1, t.size):  # exact for a piecewise constant rate
            s[k] = decay * s[k - 1] + (1 - decay) / r * rate_of_change[k - 1]
        responses.append(s)
        c = float(np.sum(residual[train] * s[train]) / np.sum(s[train] ** 2))
        e = residual - c * s
        rows.append((r, c, *np.sqrt(np.mean(e[train] ** 2, axis=0)),
                     *np.sqrt(np.mean(e[~train] ** 2, axis=0))))  # fmt: skip
    # all rates at once: a Prony series with one free factor per rate
    basis = np.stack([s.ravel() for s in responses], axis=1)
    keep = np.repeat(train, y.shape[1])
    c, *_ = np.linalg.lstsq(basis[keep], residual.ravel()[keep], rcond=None)
    e = residual - (basis @ c).reshape(y.shape)
    rows.append((np.inf, float(np.linalg.norm(c)), *np.sqrt(np.mean(e[train] ** 2, axis=0)),
                 *np.sqrt(np.mean(e[~train] ** 2, axis=0))))  # fmt: skip
    print("Prony factors, free sign:", np.array2string(c, precision=3))
    # passive: kappa = kappa_qs - (K gain / k) s with K / gain >= 0, so every c >= 0
    c, _ = scipy.optimize.nnls(basis[keep], residual.ravel()[keep])
    e = residual - (basis @ c).reshape(y.shape)
    print("Prony factors, passive (>= 0):", np.array2string(c, precision=3))
    rows.append((-np.inf, float(np.linalg.norm(c)), *np.sqrt(np.mean(e[train] ** 2, axis=0)),
                 *np.sqrt(np.mean(e[~train] ** 2, axis=0))))  # fmt: skip
    return rows


def _openloop_start(entry, values, data):
    """Quasi-static equilibrium at t = 0 of the static fit, creep relaxed."""
    first = predict_equilibria(entry["model"], data.trim(0.0, 0.05), entry["fit"],
                                  **entry["problem"])  # fmt: skip
    k0 = first.predicted[0] - np.array([values[o] for o in vc.OFFSETS])
    x0 = np.array([vc.REST_LENGTH, k0[0], k0[1], 0, 0, 0, 0, 0, 0])
    x0[0] = vc._equilibrium_length(entry, values, data, k0)
    return x0


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--data")
    parser.add_argument(
        "--only",
        choices=("oscillation", "openloop", "creep", "rate"),
        help="one part: free oscillations, open-loop maps (quasi-static), open loop with a slow "
        "creep state (dynamic, slow), initial rates of the oscillations",
    )
    parser.add_argument("--laws", default="tanh,linear")
    sizes = parser.add_mutually_exclusive_group()
    sizes.add_argument("--quick", action="store_true", help="2 ms oscillations, 25 Hz open loop")
    sizes.add_argument(
        "--smoke",
        action="store_true",
        help="for the tests: every step once, on oscillations sampled at 20 ms, each fit "
        "stopped at its second evaluation (the numbers mean nothing)",
    )
    parser.add_argument(
        "--figure", type=Path, help="draw the free oscillations' fits to this file (PNG, PDF)"
    )
    args = parser.parse_args(argv)
    size = SIZES["smoke" if args.smoke else "quick" if args.quick else "full"]
    directory = vc.data_directory(args.data)
    if directory is None:
        raise SystemExit("caasenbrood2021 data not found: give --data or set SOFTCURVE_DATA")
    start = time.perf_counter()
    out = {}
    if args.only in (None, "oscillation"):
        experiments = vc.load_oscillations(directory, size.oscillation_dt)
        laws = tuple(args.laws.split(","))
        out["oscillation"], swings = oscillation_goals(experiments, laws, size)
        if args.figure:
            print(f"figure: {swing_figure(experiments, swings, args.figure)}")
    if args.only == "rate":
        rate_probe(vc.load_oscillations(directory, size.oscillation_dt), size=size)
    if args.only in (None, "openloop", "creep"):
        openloop, results, b17 = openloop_reference(directory, size)
        if args.only != "creep":
            out["openloop"] = openloop_maps(openloop, results, results["numbering"], size)
        if args.only != "openloop":
            out["creep"] = openloop_creep(openloop, results, b17, size)
    print(f"total time {time.perf_counter() - start:.1f} s")
    return out


if __name__ == "__main__":
    main(sys.argv[1:])
