"""Tip tracking of a circle with computed torque through bounded, lagged bellow pressures.

The paper's robot (preset ifac2020) with three bellows of illustrative geometry (the
paper does not publish it) follows a horizontal circle of radius 10 mm at 65 mm height,
one turn every 2 s. The reference in coordinates comes from the closed-form inverse
kinematics of one constant-curvature segment; the controller is computed torque
(feedback linearization, 20 Hz error dynamics) sampled at 500 Hz; its generalized
forces become pressures in [0, 60 kPa] by bounded least squares, and the pressures
follow their commands with a 10 ms first-order lag, inverted over one sample by the
pressure commands. The robot starts on the circle at rest with zero pressure, hence
the initial transient. A second run uses a controller model with 10 % softer
stiffness laws. A third run uses the re-linearized model-predictive controller
(softcurve.control.mpc: 10 samples of 10 ms, pressures bounded, no lag modeled or simulated).

    python examples/tip_circle.py [--output tip_circle.png]
"""

from __future__ import annotations

import argparse

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

import softcurve as sc
from softcurve.control.controllers import ActuatorDriven, ComputedTorque
from softcurve.control.mpc import ActuatorMPC
from softcurve.control.references import tip_circle
from softcurve.simulation import simulate

CIRCLE = dict(center=(0.02, 0.0, 0.065), radius=0.01, period=2.0)
OMEGA = 2 * np.pi * 20.0  # error dynamics: 20 Hz, damping ratio 0.9
TRANSIENT = 1.0  # [s] left out of the error statistics


def softer(robot, factor=0.9):
    s = robot.segments[0]
    e, b = s.elongation_stiffness, s.bending_stiffness
    return robot.replace(
        segments=(
            s.replace(
                elongation_stiffness=sc.TanhStiffness(factor * e.a1, factor * e.a2, e.a3),
                bending_stiffness=sc.TanhStiffness(factor * b.a1, factor * b.a2, b.a3),
            ),
        )
    )


def run(plant, controller_model, actuator, reference, t_final):
    controller = ComputedTorque(
        controller_model, reference, kp=OMEGA**2, kd=2 * 0.9 * OMEGA, sample_time=2e-3
    )
    driven = ActuatorDriven(controller, actuator, plant.robot)
    start = reference(0.0)
    trajectory = simulate(
        plant, start.q, start.qd, actuator=actuator, controller=driven, t_final=t_final, dt=5e-3
    )
    if not trajectory.success:
        raise SystemExit(trajectory.message)
    target = np.array([np.array(plant.tip_pose(reference(t).q).position) for t in trajectory.t])
    return trajectory, driven, np.linalg.norm(trajectory.tip - target, axis=1), target


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--output", default="tip_circle.png")
    parser.add_argument(
        "--t-final",
        type=float,
        default=4.0,
        help=f"simulated time [s], more than the {TRANSIENT:g} s transient (default 4)",
    )
    args = parser.parse_args()
    if not args.t_final > TRANSIENT:
        parser.error(f"--t-final must exceed the {TRANSIENT:g} s transient, not {args.t_final:g}")

    plant = sc.Model(sc.presets.ifac2020())
    actuator = sc.PneumaticActuator.three_bellows(
        distance=0.012, area=2e-4, p_max=6e4, time_constant=0.01
    )
    reference = tip_circle(**CIRCLE)
    exact, driven, error, target = run(plant, plant, actuator, reference, args.t_final)
    perturbed, _, error_10, _ = run(
        plant, sc.Model(softer(plant.robot)), actuator, reference, args.t_final
    )
    lag_free = sc.PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4)
    mpc = ActuatorMPC(plant, lag_free, reference, horizon=10, sample_time=0.01)
    start = reference(0.0)
    predictive = simulate(
        plant, start.q, start.qd, actuator=lag_free, controller=mpc, t_final=args.t_final, dt=5e-3
    )
    error_mpc = np.linalg.norm(predictive.tip - target, axis=1)
    settled = exact.t >= TRANSIENT
    print(f"tip error after {TRANSIENT:g} s: max {1e3 * error[settled].max():.3f} mm "
          f"(exact model), {1e3 * error_10[settled].max():.3f} mm (10 % stiffness error), "
          f"{1e3 * error_mpc[settled].max():.4f} mm (MPC)")  # fmt: skip
    print(f"pressures: max {driven.history('inputs').max() / 1e3:.1f} kPa; "
          f"{driven.history('saturated').any(axis=1).mean():.0%} of samples saturated")  # fmt: skip

    fig, (ax_xy, ax_p, ax_e) = plt.subplots(1, 3, figsize=(13, 4), constrained_layout=True)
    ax_xy.plot(1e3 * target[:, 0], 1e3 * target[:, 1], "k--", label="reference")
    ax_xy.plot(1e3 * exact.tip[:, 0], 1e3 * exact.tip[:, 1], label="computed torque")
    ax_xy.plot(
        1e3 * perturbed.tip[:, 0], 1e3 * perturbed.tip[:, 1], label="CT, 10 % stiffness error"
    )
    ax_xy.set(xlabel="tip x [mm]", ylabel="tip y [mm]", aspect="equal", title="tip path")
    ax_xy.legend(fontsize="small")
    t = driven.history("t")
    for i, line in enumerate(ax_p.plot(t, driven.history("inputs") / 1e3)):
        line.set_label(f"bellow {i + 1}")
    ax_p.axhline(actuator.upper[0] / 1e3, color="gray", lw=0.8)
    ax_p.set(xlabel="t [s]", ylabel="pressure [kPa]", title="bellow pressures (computed torque)")
    ax_p.legend(fontsize="small")
    ax_e.semilogy(exact.t, 1e3 * error, label="computed torque (CT)")
    ax_e.semilogy(perturbed.t, 1e3 * error_10, label="CT, 10 % stiffness error")
    ax_e.semilogy(predictive.t, 1e3 * error_mpc, label="MPC (no lag)")
    ax_e.set(xlabel="t [s]", ylabel="tip error [mm]", title="tracking error")
    ax_e.legend(fontsize="small")
    fig.savefig(args.output, dpi=120)
    print(f"figure: {args.output}")


if __name__ == "__main__":
    main()
