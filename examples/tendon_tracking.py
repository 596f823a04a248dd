"""Tip tracking by a tendon-driven two-segment soft robot: computed torque, bounded tensions.

The robot (defined below, illustrative numbers of a small tapered silicone continuum
robot) stands upright under gravity. Each segment has three tendons at 120 degrees,
8 mm from the backbone, tied to the segment's tip: the proximal set runs through
segment 1, the distal set through segments 1 and 2 (six tensions, proximal first).
Tensions are bounded to [T_MIN, T_MAX] (a small pretension: a tendon never pushes) and
follow their commands with a first-order lag (motor and cable, TIME_CONSTANT).

The tip follows a horizontal circle (CIRCLE); the reference in coordinates keeps the
backbone one circular arc through the tip, shared equally by the two segments
(softcurve.control.references.tip_circle with segments=2). Computed torque (feedback
linearization, error dynamics of natural frequency FREQUENCY and damping ratio 0.9,
sampled every SAMPLE_TIME) gives generalized forces; the allocator turns them into
tensions by bounded least squares (never negative), and the lag is inverted over one
sample (softcurve.control.controllers.ActuatorDriven). The proximal segment is twice
as stiff as the distal one, so both tendon sets pull along the path; with equal
segments the distal tendons alone would bend both segments and the proximal ones would
rest at their pretension.

The run starts on the reference with every tension at its pretension, hence a
transient. Printed: the tip error after it, and the share of controller samples with a
tension at a bound. Figures: the tensions with their bounds, and the backbone at six
times with the reference path.

    python examples/tendon_tracking.py [--output tendon_tracking] [--t-final 4]
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import softcurve as sc
from softcurve.control.controllers import ActuatorDriven, ComputedTorque
from softcurve.control.references import tip_circle
from softcurve.figures import plot_backbones, plot_inputs, save_figure

# -- the robot: two segments of 10 cm, the proximal one twice as stiff and heavy ---------
PROXIMAL = sc.Segment(
    rest_length=0.10,  # [m]
    mass=0.030,  # [kg]
    radius=0.012,  # [m], rotary inertia of the slices
    elongation_stiffness=sc.LinearStiffness(2000.0),  # [N/m]
    bending_stiffness=sc.LinearStiffness(0.04),  # [N m/rad]
    damping=[2.0, 4e-4, 4e-4],  # [N s/m, N m s, N m s]
)
DISTAL = sc.Segment(
    rest_length=0.10,
    mass=0.015,
    radius=0.010,
    elongation_stiffness=sc.LinearStiffness(1000.0),
    bending_stiffness=sc.LinearStiffness(0.02),
    damping=[1.0, 2e-4, 2e-4],
)
GRAVITY = (0.0, 0.0, -9.81)  # [m/s^2], upright

# -- the tendons ---------------------------------------------------------------------------
DISTANCE = 0.008  # [m] from the backbone
T_MIN, T_MAX = 0.2, 5.0  # [N]: pretension and motor limit
TIME_CONSTANT = 0.01  # [s] lag of the tensions behind their commands

# -- the task and the controller -----------------------------------------------------------
CIRCLE = dict(center=(0.05, 0.0, 0.175), radius=0.015, period=2.0)  # [m], [m], [s]
FREQUENCY = 20.0  # [Hz] of the error dynamics
SAMPLE_TIME = 2e-3  # [s]
TRANSIENT = 0.5  # [s] left out of the error statistics


def build(environment=None, time_constant=TIME_CONSTANT):
    """The model (in ``environment``, an ``sc.Environment`` or None), the tendons (their
    lag ``time_constant`` [s], None: none) and the reference."""
    robot = sc.Robot(segments=(PROXIMAL, DISTAL), gravity=np.array(GRAVITY))
    actuator = sc.TendonActuator.three_per_segment(
        distance=DISTANCE, t_max=T_MAX, t_min=T_MIN, n_segments=2, time_constant=time_constant
    )
    model = sc.Model(robot, environment=environment)
    return model, actuator, tip_circle(**CIRCLE, segments=2)


def track(model, actuator, reference, t_final: float, *, dt: float = 5e-3):
    """Simulate the closed loop: ``(trajectory, controller, tip error (T,) [m], reference
    tip path (T, 3) [m])``."""
    w = 2.0 * np.pi * FREQUENCY
    torque = ComputedTorque(model, reference, kp=w**2, kd=2 * 0.9 * w, sample_time=SAMPLE_TIME)
    driven = ActuatorDriven(torque, actuator, model.robot)
    start = reference(0.0)
    run = sc.simulate(
        model, start.q, start.qd, controller=driven, actuator=actuator, t_final=t_final, dt=dt
    )
    if not run.success:
        raise SystemExit(run.message)
    path = np.array([model.tip_pose(reference(t).q).position for t in run.t])
    return run, driven, np.linalg.norm(run.tip - path, axis=1), path


def main() -> None:
    parser = argparse.ArgumentParser(
        description=__doc__.splitlines()[0],
        epilog="Parameters of the robot, tendons and task are constants at the top of the file.",
    )
    parser.add_argument(
        "--output",
        type=Path,
        default=Path("tendon_tracking"),
        help="folder for the figures (default: ./tendon_tracking)",
    )
    parser.add_argument(
        "--t-final",
        type=float,
        default=4.0,
        help=f"simulated time [s], more than the {TRANSIENT:g} s transient (default 4)",
    )
    args = parser.parse_args()
    if not args.t_final > TRANSIENT:
        parser.error(f"--t-final must exceed the {TRANSIENT:g} s transient, not {args.t_final:g}")

    model, actuator, reference = build()
    run, driven, error, path = track(model, actuator, reference, args.t_final)
    settled = run.t >= TRANSIENT
    allocated = driven.history("saturated").any(axis=1)
    commanded = driven.history("command_saturated").any(axis=1)
    tensions = run.inputs
    print(f"tendon-driven two-segment robot, tip circle r = {1e3 * CIRCLE['radius']:g} mm, "
          f"{args.t_final:g} s, computed torque at {1 / SAMPLE_TIME:g} Hz")  # fmt: skip
    print(f"tip error after {TRANSIENT:g} s: RMS {1e3 * np.sqrt(np.mean(error[settled] ** 2)):.3f} "
          f"mm, max {1e3 * error[settled].max():.3f} mm (first {TRANSIENT:g} s: max "
          f"{1e3 * error[~settled].max():.2f} mm)")  # fmt: skip
    print(f"tensions {tensions.min():.3f} .. {tensions.max():.3f} N within [{T_MIN:g}, {T_MAX:g}] "
          f"N; samples with a tension at a bound: {allocated.mean():.1%} allocated, "
          f"{commanded.mean():.1%} commanded (after the lag inversion)")  # fmt: skip

    args.output.mkdir(parents=True, exist_ok=True)
    labels = [f"{'proximal' if i < 3 else 'distal'} {120 * (i % 3)}°" for i in range(6)]
    figure = plot_inputs(run, actuator, labels=labels)
    figure.axes[0].set_title(
        f"tendon tensions: computed torque, {1e3 * TIME_CONSTANT:g} ms lag inverted"
    )
    written = [save_figure(figure, args.output / "tendon_tracking_tensions.png", dpi=100)]
    last = max(0.0, args.t_final - CIRCLE["period"])  # the last turn
    times = np.linspace(last, args.t_final, 6, endpoint=False)
    figure = plot_backbones(run, times, path=path)
    figure.suptitle("backbone at six times of the last turn; reference tip path dashed")
    written.append(save_figure(figure, args.output / "tendon_tracking_shapes.png", dpi=100))
    for file in written:
        print(f"figure: {file}")


if __name__ == "__main__":
    main()
