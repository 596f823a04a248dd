"""Identify softcurve on the real measurements of Caasenbrood et al. and validate it.

Data: ``../shared/data/caasenbrood2021`` relative to the repository (or the directory
in ``$SOFTCURVE_DATA``); see its README. Writes ``docs/figures/validation_*.png`` and
prints the tables of ``docs/validation.md``::

    python examples/validate_caasenbrood2021.py [--data DIR] [--figures DIR] [--quick | --smoke]

1. Free oscillations (IMU tip angle beta, 10 kHz, used at 1 kHz): identify bending
   stiffness, bending damping and creep on one recording, predict the other without
   refitting, and the reverse; hyper-elastic (tanh) and linear bending laws.
2. Open loop (three pressures, curvatures kx, ky at 250 Hz, used at 25 Hz): identify
   the pressure map (geometric bellows, or the authors' constant H), the mounting
   angle and numbering of the bellows, the sensor zero and the bending stiffness on
   the first 20 s as quasi-static equilibria, predict the last 20 s; then check the
   quasi-static assumption by a full dynamic simulation of all 40 s.
"""

from __future__ import annotations

import argparse
import os
import sys
import time
from pathlib import Path
from typing import NamedTuple

import casadi as ca
import matplotlib
import numpy as np

import softcurve as sc
from softcurve.base.status import Status
from softcurve.identification.experiments import load_mat
from softcurve.identification.fits import (
    Free,
    fit_equilibria,
    fit_stiffness,
    fit_trajectory,
    predict_equilibria,
    predict_trajectory,
    tanh_parameters,
)
from softcurve.identification.maps import (
    bellows_input_map,
    bending_angle_map,
    constant_input_map,
    curvature_map,
)

matplotlib.use("Agg")
import matplotlib.pyplot as plt

REPO = Path(__file__).resolve().parents[1]
SEG = "segments[0]."
# The data robot (data README): one segment, upright.
MASS, REST_LENGTH, RADIUS = 0.017, 0.064, 0.013
# Not measured (no elongation sensor): fixed, see docs/validation.md.
ELONGATION_STIFFNESS, ELONGATION_DAMPING = 1000.0, 0.5  # N/m, N s/m
CREEP_COMPLIANCE = (1.0, 1e-2, 1e-2)  # only gain * compliance is identifiable
BELLOWS_DISTANCE = 0.01  # m; only area * distance matters for bending
QUADRATURE_NODES = 6  # beta < 0.8 rad: 6 Gauss nodes are exact to ~1e-10


class Size(NamedTuple):
    """How much of the data a run uses and how long its fits may search (a named tuple:
    a dataclass needs its module in ``sys.modules``, which a script loaded by
    ``importlib`` from another is not)."""

    oscillation_dt: float
    """The free oscillations resampled to this step [s]."""
    openloop_dt: float
    """The open loop resampled to this step [s]."""
    evaluations: int
    """Evaluations of each fit of a free oscillation."""
    equilibrium_evaluations: int
    """Evaluations of each fit of the open loop's equilibria."""
    dynamic_check: bool
    """Whether the open loop's 40 s are simulated with the identified robot."""


SIZES = {
    "full": Size(1e-3, 0.04, 120, 150, True),
    # 40 evaluations: every quick fit within 0.01 deg of 120's
    "quick": Size(2e-3, 0.04, 40, 150, False),
    # every step once, on samples 20 ms (oscillations) and 0.4 s (open loop) apart, each
    # fit stopped at its second evaluation: its numbers mean nothing (the tests run it so
    # that no step breaks)
    "smoke": Size(0.02, 0.4, 2, 2, False),
}
"""The sizes of a run: ``full`` (the figures of docs/validation.md), ``--quick`` (CI) and
``--smoke``."""


def data_directory(explicit: str | None = None) -> Path | None:
    """The caasenbrood2021 data: ``explicit``, ``$SOFTCURVE_DATA`` or ../shared/data."""
    candidates = [explicit, os.environ.get("SOFTCURVE_DATA"), REPO.parent / "shared" / "data"]
    for base in candidates:
        if base:
            path = Path(base)
            path = path if path.name == "caasenbrood2021" else path / "caasenbrood2021"
            if (path / "openloop_data_p123.mat").is_file():
                return path
    return None


def data_robot(law: str) -> sc.Robot:
    bending = sc.TanhStiffness(0.02, 0.01, 3.0) if law == "tanh" else sc.LinearStiffness(0.008)
    creep = sc.Creep.from_gamma([300.0, 0.0, 30.0, 2e-3, 30.0, 2e-3], CREEP_COMPLIANCE)
    segment = sc.Segment(
        rest_length=REST_LENGTH,
        mass=MASS,
        radius=RADIUS,
        elongation_stiffness=sc.LinearStiffness(ELONGATION_STIFFNESS),
        bending_stiffness=bending,
        damping=[ELONGATION_DAMPING, 5e-7, 5e-7],
        creep=creep,
    )
    return sc.Robot(segments=(segment,))


def stiffness_freedom(robot: sc.Robot, law: str, fixed_zero: float | None = None):
    """(extra values, bind rules, free list) for the bending law."""
    name = SEG + "bending_stiffness"
    if law == "linear":
        free = [] if fixed_zero is not None else [Free(f"{name}.k0", 1e-4, 1.0)]
        return {}, {}, free
    values, bind = tanh_parameters(robot, name)
    free = [Free(f"{name}.k_inf", 1e-4, 1.0), Free(f"{name}.rate", 0.05, 50.0)]
    if fixed_zero is None:
        free.insert(0, Free(f"{name}.k_zero", 1e-4, 1.0))
    else:
        values[f"{name}.k_zero"] = fixed_zero
    return values, bind, free


# -- 1. free oscillations ------------------------------------------------------------


def load_oscillations(directory: Path, dt: float = 1e-3):
    return {
        key: load_mat(
            directory / f"oscill_data_{key}.mat",
            time="x",
            signals={"beta": "y"},
            units={"beta": "deg"},
        ).resample(dt)
        for key in ("b17", "b42")
    }


def release_state(experiment) -> np.ndarray:
    """Released from rest at the first measured angle, creep relaxed (lam = 0)."""
    beta0 = np.radians(experiment.signals["beta"][0])
    return np.array([REST_LENGTH, beta0 / REST_LENGTH, 0.0, 0, 0, 0, 0, 0, 0])


def oscillation_study(experiments, law: str, evaluations: int = 120):
    robot = data_robot(law)
    model = sc.Model(robot, quadrature_nodes=QUADRATURE_NODES)
    values, bind, free = stiffness_freedom(robot, law)
    free += [
        Free(SEG + "damping[1,1]", 1e-9, 1e-4),
        Free(SEG + "creep.rate[1]", 1.0, 1000.0),
        Free(SEG + "creep.gain[1]", -1.0, 1.0, scale=1e-3),
    ]
    rows = {}
    for train, test in (("b17", "b42"), ("b42", "b17")):
        common = {"output": bending_angle_map(), "bind": bind}
        fit = fit_trajectory(
            model, experiments[train], x0=release_state(experiments[train]), free=free,
            extra=values, max_evaluations=evaluations, **common,
        )  # fmt: skip
        prediction = predict_trajectory(
            model, experiments[test], fit, x0=release_state(experiments[test]), extra=values,
            **common,
        )  # fmt: skip
        rows[train] = {"fit": fit, "prediction": prediction, "test": test}
    return rows


# -- 2. open loop ----------------------------------------------------------------------


def load_openloop(directory: Path):
    return load_mat(
        directory / "openloop_data_p123.mat",
        sample_rate=250.0,
        signals={"kx": "kx_", "ky": "ky_"},
        inputs={"p1": "U_:0", "p2": "U_:1", "p3": "U_:2"},
        units={"kx": "1/m", "ky": "1/m", "p1": "Pa", "p2": "Pa", "p3": "Pa"},
    )


def pressure_map(kind: str, numbering: int):
    if kind == "geometric":
        return bellows_input_map(area=2e-5, distance=BELLOWS_DISTANCE, numbering=numbering)
    return constant_input_map(
        elongation_gain=2e-5, bending_gain=2e-5 * BELLOWS_DISTANCE * REST_LENGTH,
        numbering=numbering,
    )  # fmt: skip


def map_freedom(kind: str, angle: float):
    gain = Free("bellows.area", 1e-8, 1e-2) if kind == "geometric" else Free("map.a_k", 1e-13, 1e-3)
    prefix = "bellows" if kind == "geometric" else "map"
    return [gain, Free(f"{prefix}.angle", angle - 4.0, angle + 4.0, initial=angle, scale=1.0)]


OFFSETS = ("offset.kx", "offset.ky")


def openloop_fit(model, robot, data, law, kind, numbering, angle, k_zero, evaluations=150):
    values, bind, free = stiffness_freedom(robot, law, fixed_zero=k_zero)
    if law == "linear":
        values = {}
    free = map_freedom(kind, angle) + free
    free += [Free(o, -3.0, 3.0, initial=0.0, scale=0.1) for o in OFFSETS]
    problem = {
        "output": curvature_map(offsets=OFFSETS),
        "input_map": pressure_map(kind, numbering),
        "bind": bind,
    }
    fit = fit_equilibria(
        model, data, free=free, extra=values, max_evaluations=evaluations, **problem
    )
    return fit, problem, values


def static_robot(law: str, k_zero: float) -> sc.Robot:
    """The data robot for equilibria; the linear law gets ``k0 = k_zero`` (fixed)."""
    robot = data_robot(law)
    if law == "tanh":
        return robot
    segment = robot.segments[0].replace(bending_stiffness=sc.LinearStiffness(k_zero))
    return robot.replace(segments=(segment,))


def openloop_study(experiment, k_zero: dict, size: Size = SIZES["full"]):
    """Quasi-static identification on 0-20 s, prediction of 20-40 s."""
    data = experiment.resample(size.openloop_dt)
    train = data.trim(0.0, 20.0)
    results = {}
    # Mounting angle and numbering: a coarse search with the cheapest model. Creep and
    # damping play no role in equilibria; keeping them reuses the oscillation's compiled
    # model (same structure).
    robot = static_robot("linear", k_zero["linear"])
    model = sc.Model(robot, quadrature_nodes=QUADRATURE_NODES)
    search = []
    for numbering in (1, -1):
        for angle in (-2.0, 0.0, 2.0):
            fit, *_ = openloop_fit(model, robot, train, "linear", "constant", numbering, angle, 1,
                                   size.equilibrium_evaluations)  # fmt: skip
            if fit.status not in (Status.NOT_CONVERGED, Status.INFEASIBLE):
                search.append((float(np.sum(fit.rms**2)), numbering, fit.value("map.angle"), fit))
    search.sort(key=lambda item: item[0])
    _, numbering, angle, _ = search[0]
    results["search"] = [(n, a, np.sqrt(c / 2)) for c, n, a, _ in search]
    for law in ("tanh", "linear"):
        robot = static_robot(law, k_zero[law])
        model = sc.Model(robot, quadrature_nodes=QUADRATURE_NODES)
        for kind in ("geometric", "constant"):
            fit, problem, values = openloop_fit(
                model, robot, train, law, kind, numbering, angle, k_zero[law],
                size.equilibrium_evaluations,
            )  # fmt: skip
            prediction = predict_equilibria(model, data, fit, extra=values, **problem)
            results[(law, kind)] = {"fit": fit, "prediction": prediction, "model": model,
                                    "problem": problem, "values": values}  # fmt: skip
    results["numbering"], results["angle"] = numbering, angle
    return results


def window_rms(report, start: float, stop: float) -> np.ndarray:
    """RMS of each signal's residual and of the curvature vector error on [start, stop)."""
    keep = (report.abscissa >= start) & (report.abscissa < stop)
    r = report.residuals[keep]
    return np.append(np.sqrt(np.mean(r**2, axis=0)), np.sqrt(np.mean(np.sum(r**2, axis=1))))


def dynamic_check(experiment, oscillation_fit, entry):
    """Simulate all 40 s with the identified robot (damping and creep from the free
    oscillation, stiffness and pressure map from the open loop) to test the
    quasi-static assumption."""
    static_robot = entry["fit"].extra["robot"]
    oscillating = oscillation_fit.extra["robot"].segments[0]
    segment = oscillating.replace(bending_stiffness=static_robot.segments[0].bending_stiffness)
    robot = static_robot.replace(segments=(segment,))
    model = sc.Model(robot, quadrature_nodes=QUADRATURE_NODES)
    data = experiment.resample(0.01)
    values = {**entry["values"], **entry["fit"].extra["values"]}
    problem = dict(entry["problem"])
    # start from the quasi-static equilibrium at t = 0
    first = predict_equilibria(entry["model"], data.trim(0.0, 0.02), entry["fit"], **problem)
    k0 = first.predicted[0] - np.array([values[o] for o in OFFSETS])
    x0 = np.array([REST_LENGTH, k0[0], k0[1], 0, 0, 0, 0, 0, 0])
    x0[0] = _equilibrium_length(entry, values, data, k0)
    return fit_trajectory(model, data, x0=x0, free=[], extra=values, **problem)


def _equilibrium_length(entry, values, data, kappa) -> float:
    """Arc length of the quasi-static equilibrium at t = 0 (elongation by the pressures)."""
    model = entry["model"]
    q = ca.SX.sym("q", 3)
    u = data.input_matrix()[0]
    tau = entry["problem"]["input_map"].function(q, ca.DM(u), values)
    force = model.symbolic["gravity_force"](q, entry["fit"].extra["parameters"])
    force += model.symbolic["elastic_force"](q, entry["fit"].extra["parameters"]) - tau
    solve = ca.rootfinder("l", "newton", ca.Function("g", [q[0], q[1:]], [force[0]]))
    return float(solve(REST_LENGTH, ca.DM(kappa)))


# -- figures and tables ----------------------------------------------------------------


def oscillation_figure(experiments, studies, path: Path):
    fig, axes = plt.subplots(2, 2, figsize=(11, 6.5), sharex=True)
    for row, train in enumerate(("b17", "b42")):
        for col, key in enumerate(("b17", "b42")):
            ax = axes[row, col]
            e = experiments[key]
            ax.plot(e.t, e.signals["beta"], "k--", lw=1.2, label="IMU")
            for law, style in (("tanh", "C0-"), ("linear", "C1-")):
                entry = studies[law][train]
                report = entry["fit"] if key == train else entry["prediction"]
                what = "fit" if key == train else "prediction"
                ax.plot(report.abscissa, report.predicted[:, 0], style, lw=1,
                        label=f"{law}: {what}, RMS {report.rms[0]:.2f} deg")  # fmt: skip
            ax.set_title(f"{key}, model identified on {train}")
            ax.set_ylabel("beta [deg]")
            ax.legend(fontsize=7)
    for ax in axes[1]:
        ax.set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def openloop_figure(results, path: Path):
    fig, axes = plt.subplots(2, 1, figsize=(11, 6.5), sharex=True)
    measured = results[("tanh", "geometric")]["prediction"]
    for j, (ax, name) in enumerate(zip(axes, ("kx", "ky"), strict=True)):
        # raw sensor signals: the model's outputs include the identified sensor zero
        ax.plot(measured.abscissa, measured.measured[:, j], "k--", lw=1.2,
                label="measured")  # fmt: skip
        for (law, kind), style in (
            (("tanh", "geometric"), "C0-"),
            (("linear", "geometric"), "C1-"),
        ):
            report = results[(law, kind)]["prediction"]
            ax.plot(report.abscissa, report.predicted[:, j], style, lw=1,
                    label=f"{law} stiffness, {kind} map")  # fmt: skip
        if "dynamic" in results:
            report = results["dynamic"]
            ax.plot(report.abscissa, report.predicted[:, j], "C2:", lw=1,
                    label="tanh, dynamic simulation")  # fmt: skip
        ax.axvline(20.0, color="0.4", lw=0.8)
        ax.set_ylabel(f"{name} [1/m]")
        ax.legend(fontsize=7, loc="upper left")
    axes[0].set_title("open loop: identified on 0-20 s (left of the line), predicted after")
    axes[1].set_xlabel("t [s]")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def static_figure(results, data, path: Path, dt: float = 0.04):
    """The paper's Fig. 3 on measured data: bending moment against bending angle.

    The moment ``k_b(beta) beta`` on each sample of 0-20 s follows from the identified
    geometric pressure map and gravity at the measured curvature (offsets removed,
    rotated into the bellows' frame); both laws are then fitted to it by
    :func:`softcurve.identification.fits.fit_stiffness`.
    """
    entry = results[("tanh", "geometric")]
    fit, model = entry["fit"], entry["model"]
    values = {**entry["values"], **fit.extra["values"]}
    train = data.resample(dt).trim(0.0, 20.0)
    kappa = train.signal_matrix(["kx", "ky"]) - np.array([values[o] for o in OFFSETS])
    q = ca.SX.sym("q", 3)
    u = ca.SX.sym("u", 3)
    tau = ca.Function("tau", [q, u], [entry["problem"]["input_map"].function(q, u, values)])
    beta, moment = [], []
    for k_vec, pressures in zip(kappa, train.input_matrix(), strict=True):
        qk = np.array([REST_LENGTH, *k_vec])
        net = np.array(tau(qk, pressures)).ravel() - model.gravity_force(qk)
        norm = np.linalg.norm(k_vec)
        beta.append(norm * REST_LENGTH)
        moment.append(net[1:] @ (k_vec / norm) / REST_LENGTH)  # = k_b(beta) beta
    beta, moment = np.array(beta), np.array(moment)
    reports = {law: fit_stiffness(beta, moment, law, label="beta", mode="bending")
               for law in ("tanh", "linear")}  # fmt: skip
    fig, ax = plt.subplots(figsize=(6, 4))
    ax.plot(beta, moment, "k.", ms=2, label="measured (via identified pressure map)")
    grid = np.linspace(0.0, beta.max() * 1.05, 200)
    for law, style in (("tanh", "C0-"), ("linear", "C1--")):
        ax.plot(grid, reports[law].extra["law"].force(grid), style,
                label=f"{law}: RMS {reports[law].rms[0]:.2e} N m")  # fmt: skip
    ax.set_xlabel("bending angle beta [rad]")
    ax.set_ylabel("k_b(beta) beta [N m]")
    ax.legend(fontsize=8)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return reports


def main(argv=None) -> dict:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--data", help="data directory (default: $SOFTCURVE_DATA or ../shared/data)"
    )
    parser.add_argument("--figures", default=str(REPO / "docs" / "figures"))
    size = parser.add_mutually_exclusive_group()
    size.add_argument(
        "--quick",
        action="store_true",
        help="for CI: oscillations at 2 ms with 40 evaluations per fit, no dynamic check "
        "of the open loop",
    )
    size.add_argument(
        "--smoke",
        action="store_true",
        help="for the tests: every step once on samples 20 ms and 0.4 s apart, each fit stopped at "
        "its second evaluation (seconds; the numbers mean nothing)",
    )
    args = parser.parse_args(argv)
    size = SIZES["smoke" if args.smoke else "quick" if args.quick else "full"]
    directory = data_directory(args.data)
    if directory is None:
        raise SystemExit("caasenbrood2021 data not found: give --data or set SOFTCURVE_DATA")
    figures = Path(args.figures)
    figures.mkdir(parents=True, exist_ok=True)
    start = time.perf_counter()

    experiments = load_oscillations(directory, size.oscillation_dt)
    studies = {
        law: oscillation_study(experiments, law, size.evaluations) for law in ("tanh", "linear")
    }
    print("## Free oscillations: tip bending angle error [deg]\n")
    print("| model | identified on | fit RMS / max | predicts | prediction RMS / max |")
    print("| --- | --- | --- | --- | --- |")
    for law in ("tanh", "linear"):
        for train, entry in studies[law].items():
            f, p = entry["fit"], entry["prediction"]
            print(f"| {law} | {train} | {f.rms[0]:.2f} / {f.max_error[0]:.2f} | {entry['test']} "
                  f"| {p.rms[0]:.2f} / {p.max_error[0]:.2f} |")  # fmt: skip
    print("| authors (thesis) | each recording | b17: 0.19, b42: 0.78 | - | - |\n")
    for law in ("tanh", "linear"):
        for train, entry in studies[law].items():
            print(f"### {law}, identified on {train}\n```\n{entry['fit'].table()}\n```\n")
    oscillation_figure(experiments, studies, figures / "validation_oscillation.png")

    openloop = load_openloop(directory)
    k_zero = {law: _static_stiffness(studies[law]["b17"]["fit"]) for law in ("tanh", "linear")}
    results = openloop_study(openloop, k_zero, size)
    if size.dynamic_check:
        results["dynamic"] = dynamic_check(
            openloop, studies["tanh"]["b17"]["fit"], results[("tanh", "geometric")]
        )
    print("## Open loop: curvature error [1/m], identified on 0-20 s\n")
    search = ", ".join(f"{n:+d}/{a:.2f} rad: {c:.2f}" for n, a, c in results["search"])
    print(f"bellows numbering {results['numbering']:+d} (numbering/angle: RMS {search})\n")
    print("| stiffness | pressure map | fit 0-20 s | predict 20-40 s |  (kx, ky, vector)")
    print("| --- | --- | --- | --- |")
    for law in ("tanh", "linear"):
        for kind in ("geometric", "constant"):
            p = results[(law, kind)]["prediction"]
            a, b = window_rms(p, 0.0, 20.0), window_rms(p, 20.0, 40.1)
            print(f"| {law} | {kind} | {a[0]:.2f}, {a[1]:.2f}, {a[2]:.2f} "
                  f"| {b[0]:.2f}, {b[1]:.2f}, {b[2]:.2f} |")  # fmt: skip
    if "dynamic" in results:
        d = results["dynamic"]
        a, b = window_rms(d, 0.0, 20.0), window_rms(d, 20.0, 40.1)
        print(f"| tanh, dynamic simulation | geometric | {a[0]:.2f}, {a[1]:.2f}, {a[2]:.2f} "
              f"| {b[0]:.2f}, {b[1]:.2f}, {b[2]:.2f} |")  # fmt: skip
    print("| authors (thesis) | constant, fitted | 0.21 (tanh), 1.79 (linear) | - |\n")
    for key in (("tanh", "geometric"), ("tanh", "constant"), ("linear", "geometric")):
        print(f"### {key[0]} stiffness, {key[1]} map\n```\n{results[key]['fit'].table()}\n```\n")
    openloop_figure(results, figures / "validation_openloop.png")
    static = static_figure(results, openloop, figures / "validation_static.png", size.openloop_dt)
    print("## Static fit of the bending law to the open-loop data (Fig. 3 style)\n")
    for law, report in static.items():
        print(f"### {law}\n```\n{report.table()}\n```\n")
    print(f"total time {time.perf_counter() - start:.1f} s")
    return {"oscillation": studies, "openloop": results, "static": static}


def _static_stiffness(fit) -> float:
    """Bending stiffness at zero strain ``k(0)`` of an oscillation fit [N m/rad]."""
    return float(fit.extra["robot"].segments[0].bending_stiffness.stiffness(0.0))


if __name__ == "__main__":
    main(sys.argv[1:])
