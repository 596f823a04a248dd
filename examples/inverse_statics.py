"""Quasi-static pressure maps and inverse statics of the paper's robot with three bellows.

Left: the equilibrium as one bellow is pressurized from 0 to 60 kPa (tip position and
curvature against pressure, in the spirit of the paper's Fig. 3), followed by
continuation. Right: for target points on a horizontal circle (radius 15 mm, 66 mm
high) and on a line at 50 mm height, the bounded pressures that put the tip closest to
each target (IPOPT on the exact equilibrium constraints); unreachable targets end at
saturated pressures.
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

    fig, (ax_tip, ax_k, ax_xz) = plt.subplots(1, 3, figsize=(14, 4), constrained_layout=True)
    p1 = sweep.inputs[:, 0] / 1e3
    for i, name in enumerate("xyz"):
        ax_tip.plot(p1, 1e3 * sweep.tip[:, i], label=f"tip {name}")
    ax_tip.set(xlabel="p1 [kPa] (p2 = p3 = 0)", ylabel="tip position [mm]", title="pressure map")
    ax_tip.legend(fontsize="small")
    ax_k.plot(p1, sweep.curvature[:, 0], label="|kappa| [1/m]")
    ax_k.plot(p1, 1e3 * (sweep.q[:, 0] - model.robot.rest_length), label="l - l0 [mm]")
    ax_k.set(xlabel="p1 [kPa]", title="curvature and elongation")
    ax_k.legend(fontsize="small")
    for r in results:
        reached = r.success
        ax_xz.plot(1e3 * r.target[0], 1e3 * r.target[2], "k+" if reached else "rx")
        ax_xz.plot(1e3 * r.tip[0], 1e3 * r.tip[2], "o", mfc="none", color="C0" if reached else "C3")
        backbone = np.array([np.array(model.pose(r.q, s).position) for s in np.linspace(0, 1, 30)])
        ax_xz.plot(1e3 * backbone[:, 0], 1e3 * backbone[:, 2], lw=0.6, color="gray")
    ax_xz.set(xlabel="x [mm]", ylabel="z [mm]", aspect="equal",
              title="inverse statics (+ reached, x beyond reach)")  # fmt: skip
    fig.savefig(args.output, dpi=120)
    print(f"figure: {args.output}")


if __name__ == "__main__":
    main()
