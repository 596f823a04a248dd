"""Quasi-static pressure maps and inverse statics of the paper's robot with three bellows.

Three panels of the equilibrium as one bellow is pressurized from 0 to 60 kPa, each
quantity on its own axis (tip position [mm], curvature [1/m], elongation [mm]; in the
spirit of the paper's Fig. 3), followed by continuation. Top right: for target points on
a horizontal circle (radius 15 mm, 66 mm high) and on a line at 50 mm height, the
bounded pressures that put the tip closest to each target (IPOPT on the exact
equilibrium constraints), seen along y: a reached target is a +, one beyond reach an x
whose closest tip (a red circle) is reached with saturated pressures.
The bellow geometry (12 mm from the backbone, 2 cm^2) is illustrative: the paper does
not publish it.

    python examples/inverse_statics.py [--output inverse_statics.png]
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.lines import Line2D

import softcurve as sc
from softcurve.analysis.inverse_statics import inverse_statics
from softcurve.analysis.quasistatic import input_sweep


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default="inverse_statics.png")
    args = parser.parse_args()

    model = sc.Model(sc.presets.ifac2020())
    actuator = sc.PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4)

    path = np.zeros((41, 3))
    path[:, 0] = np.linspace(0.0, 6e4, 41)
    sweep = input_sweep(model, actuator, path)
    print(f"sweep: {sweep.message}; at 60 kPa tip {np.round(1e3 * sweep.tip[-1], 2)} mm, "
          f"curvature {sweep.curvature[-1, 0]:.2f} 1/m, {set(sweep.stability)}")  # fmt: skip

    angles = np.linspace(0, 2 * np.pi, 12, endpoint=False)
    targets = [np.array([0.015 * np.cos(a), 0.015 * np.sin(a), 0.066]) for a in angles]
    targets += [np.array([x, 0.0, 0.05]) for x in (0.01, 0.03, 0.05, 0.07)]
    results = [inverse_statics(model, actuator, target) for target in targets]
    for r in results:
        print(f"target {np.round(1e3 * r.target, 1)} mm -> p = {np.round(r.inputs / 1e3, 2)} "
              f"kPa, miss {1e3 * r.distance:.2e} mm, {r.stability}, {r.status.value}")  # fmt: skip

    draw(model, sweep, results).savefig(args.output, dpi=120)
    print(f"figure: {args.output}")


def draw(model, sweep, results):
    """The figure: the pressure map of ``sweep`` (one quantity per panel) and the
    inverse statics ``results`` seen along y."""
    fig, axes = plt.subplots(2, 2, figsize=(11, 8), constrained_layout=True)
    (ax_tip, ax_xz), (ax_k, ax_l) = axes
    p1 = sweep.inputs[:, 0] / 1e3
    for i, name in enumerate("xyz"):
        ax_tip.plot(p1, 1e3 * sweep.tip[:, i], label=f"tip {name}")
    ax_tip.set(xlabel="p1 [kPa] (p2 = p3 = 0)", ylabel="tip position [mm]",
               title="pressure map: the tip")  # fmt: skip
    ax_tip.legend(fontsize="small")
    ax_k.plot(p1, sweep.curvature[:, 0], color="C0")
    ax_k.set(xlabel="p1 [kPa] (p2 = p3 = 0)", ylabel="curvature |kappa| [1/m]",
             title="pressure map: the curvature")  # fmt: skip
    ax_l.plot(p1, 1e3 * (sweep.q[:, 0] - model.robot.rest_length), color="C1")
    ax_l.set(xlabel="p1 [kPa] (p2 = p3 = 0)", ylabel="elongation l - l0 [mm]",
             title="pressure map: the elongation")  # fmt: skip
    for r in results:
        color = "C0" if r.success else "C3"
        ax_xz.plot(1e3 * r.target[0], 1e3 * r.target[2], "k+" if r.success else "kx")
        ax_xz.plot(1e3 * r.tip[0], 1e3 * r.tip[2], "o", mfc="none", color=color)
        backbone = np.array([np.array(model.pose(r.q, s).position) for s in np.linspace(0, 1, 30)])
        ax_xz.plot(1e3 * backbone[:, 0], 1e3 * backbone[:, 2], lw=0.6, color="gray")
    legend = [
        Line2D([], [], ls="", marker="+", color="k", label="target, reached"),
        Line2D([], [], ls="", marker="x", color="k", label="target beyond reach"),
        Line2D([], [], ls="", marker="o", mfc="none", color="C0", label="tip at a reached target"),
        Line2D([], [], ls="", marker="o", mfc="none", color="C3",
               label="closest tip (saturated pressures)"),
        Line2D([], [], color="gray", lw=0.6, label="backbone at the solution"),
    ]  # fmt: skip
    ax_xz.legend(handles=legend, fontsize="small", loc="lower right")
    ax_xz.set(xlabel="x [mm]", ylabel="z [mm]", aspect="equal",
              title="inverse statics: targets and tips seen along y")  # fmt: skip
    return fig


if __name__ == "__main__":
    main()
