"""Contact examples (docs/contact.md): a pneumatic finger pressing on a wall, a robot
bending around a cylinder, a robot released onto a floor.

``finger``: the paper's robot driven by three bellows (the illustrative geometry of
examples/pneumatic.toml: 12 mm from the backbone, 2 cm^2) inflates bellow 1 from 0 to
60 kPa. A wall stands beside it, halfway along the free tip's path. The script solves
the equilibrium at each pressure, free and against the wall, and prints the force the
finger exerts on the wall. Figure: that force and the tip's deflection against pressure.

``cylinder``: two segments of the paper's robot (without creep, lying on a table:
no gravity in the bending plane) bend under a growing bending moment against a
cylinder (a capsule 10 mm in radius, its axis normal to the bending plane) beside the
upper segment; the contact radius of the body is 10 mm.
Figure: the backbones at each load, with the cylinder (dotted: the cylinder grown by
the body's radius, which the backbone touches), and the contact force.

``floor``: the paper's robot lies sideways (gravity along -x of its base frame), bent
up by 20 1/m. It is released from rest, falls onto the floor 5 mm below its body, and
settles. Figures: the contact force against time, and the tip's path with the floor.

    python examples/contact_finger.py {finger,cylinder,floor,all} [--output contact] [--quick]

Equilibria run in CasADi's virtual machine. The floor's simulation compiles its model
once (about 30 s on two cores, then cached); ``--no-compile`` runs it uncompiled instead.
"""

from __future__ import annotations

import argparse
from pathlib import Path

import numpy as np

import softcurve as sc

LAW = sc.ContactLaw(stiffness=1e7, damping=1.0)
"""Penalty 1e7 N/m^2.5 (about 0.1 mm for 1 N over 2 cm of body), Hunt-Crossley 1 s/m."""

PRESSURE_STEP, MOMENT_STEP = 5e3, 0.01
"""Steps of the finger's pressure [Pa] and of the cylinder's moment [N m]: each
equilibrium starts from the one before, and a step twice as large carries the cylinder's
backbone through the cylinder."""
POINTS = {"pressures": 13, "moments": 7, "fall": 1.0}
"""Pressures of the finger (to 60 kPa), moments of the cylinder (to 0.06 N m), seconds of
the floor's fall [s]."""
QUICK = {"pressures": 4, "moments": 3, "fall": 0.3}
"""``--quick`` (the tests): the first few of each; the floor is touched at 0.03 s."""


def finger(output: Path, points: int = POINTS["pressures"]) -> list[Path]:
    """Force on the wall against bellow pressure at ``points`` pressures; returns the
    figures written."""
    robot = sc.presets.ifac2020()
    actuator = sc.PneumaticActuator.three_bellows(distance=0.012, area=2.0e-4, p_max=6.0e4)
    pressures = PRESSURE_STEP * np.arange(points)
    free = sc.Model(robot, compile=False)
    q, loose = np.array([0.0644, 0.0, 0.0]), []
    for p in pressures:
        q = sc.equilibrium(free, q, actuator=actuator, inputs=[p, 0.0, 0.0]).q
        loose.append(free.tip_pose(q).position)
    loose = np.array(loose)
    reach = loose[-1, :2]
    side = reach / np.linalg.norm(reach)  # where bellow 1 bends the finger
    radius = robot.segments[0].radius
    gap = 0.5 * np.linalg.norm(reach)  # the wall stops the tip halfway
    wall = sc.Plane(point=(radius + gap) * np.append(side, 0.0), normal=-np.append(side, 0.0))
    model = sc.Model(robot, environment=sc.Environment([wall], LAW), compile=False)
    q, forces, pressed = np.array([0.0644, 0.0, 0.0]), [], []
    print(f"finger: wall {1e3 * (radius + gap):.1f} mm from the backbone (body radius "
          f"{1e3 * radius:.1f} mm)")  # fmt: skip
    print(f"{'p [kPa]':>8} {'free tip [mm]':>14} {'tip [mm]':>9} {'force on wall [N]':>18}")
    for p, tip in zip(pressures, loose, strict=True):
        e = sc.equilibrium(model, q, actuator=actuator, inputs=[p, 0.0, 0.0])
        if not e.success:
            raise RuntimeError(f"no equilibrium at {p} Pa: {e.message}")
        q = e.q
        force = model.contact(q)["forces"][0] @ wall.normal  # = the finger's push into it
        forces.append(force)
        pressed.append(e.tip_position)
        print(f"{p / 1e3:8.1f} {1e3 * tip[:2] @ side:14.2f} {1e3 * e.tip_position[:2] @ side:9.2f} "
              f"{force:18.4f}")  # fmt: skip
    plt = _pyplot()
    figure, (top, bottom) = plt.subplots(
        2, 1, sharex=True, figsize=(6.0, 5.5), layout="constrained"
    )
    top.plot(pressures / 1e3, forces, "o-")
    top.set_ylabel("force on the wall [N]")
    top.set_title("A pneumatic finger pressing on a wall")
    bottom.plot(pressures / 1e3, 1e3 * loose[:, :2] @ side, "--", label="free")
    bottom.plot(pressures / 1e3, 1e3 * np.array(pressed)[:, :2] @ side, "o-", label="wall")
    bottom.axhline(1e3 * gap, color="0.5", lw=0.8, label="wall - body radius")
    bottom.set_ylabel("tip deflection [mm]")
    bottom.set_xlabel("pressure in bellow 1 [kPa]")
    bottom.legend()
    for a in (top, bottom):
        a.grid(True, alpha=0.3)
    return [sc.save_figure(figure, output / "finger_force.png")]


def cylinder(output: Path, points: int = POINTS["moments"]) -> list[Path]:
    """Two segments bending around a cylinder under a moment growing in ``points`` steps."""
    segment = sc.presets.ifac2020(creep=False).segments[0]
    robot = sc.Robot(segments=(segment, segment), gravity=np.zeros(3))  # on a flat table
    capsule = sc.Capsule(a=[0.045, -0.05, 0.1], b=[0.045, 0.05, 0.1], radius=0.01)
    environment = sc.Environment([capsule], LAW, contact_radius=[0.01, 0.01])
    model = sc.Model(robot, environment=environment, compile=False)
    moments = MOMENT_STEP * np.arange(points)  # bending moment on each segment [N m^2 per 1/m]
    q, shapes, forces = np.tile([0.0644, 0.0, 0.0], 2), [], []
    print(f"{'moment [N m]':>12} {'tip x [mm]':>10} {'tip z [mm]':>10} {'force [N]':>10}")
    for m in moments:
        tau = np.array([0.0, m * 0.0644, 0.0, 0.0, m * 0.0644, 0.0])
        e = sc.equilibrium(model, q, tau=tau)
        if not e.success:
            raise RuntimeError(f"no equilibrium at {m} N m: {e.message}")
        q = e.q
        shapes.append(model.backbone(q, 40))
        forces.append(np.linalg.norm(model.contact(q)["forces"][0]))
        print(f"{m:12.3f} {1e3 * e.tip_position[0]:10.2f} {1e3 * e.tip_position[2]:10.2f} "
              f"{forces[-1]:10.4f}")  # fmt: skip
    plt = _pyplot()
    figure, (left, right) = plt.subplots(1, 2, figsize=(9.0, 4.5), layout="constrained")
    for m, shape in zip(moments, shapes, strict=True):
        left.plot(1e3 * shape[:, 0], 1e3 * shape[:, 2], label=f"{m:.2f}")
    angle = np.linspace(0.0, 2.0 * np.pi, 100)
    left.fill(1e3 * (capsule.a[0] + capsule.radius * np.cos(angle)),
              1e3 * (capsule.a[2] + capsule.radius * np.sin(angle)), color="0.7")  # fmt: skip
    reach = capsule.radius + environment.contact_radius[0]  # where the backbone touches
    left.plot(1e3 * (capsule.a[0] + reach * np.cos(angle)),
              1e3 * (capsule.a[2] + reach * np.sin(angle)), "k:", lw=0.8)  # fmt: skip
    left.set(xlabel="x [mm]", ylabel="z [mm]", aspect="equal", title="Bending around a cylinder")
    left.legend(title="moment [N m]", fontsize="small")
    right.plot(moments, forces, "o-")
    right.set(xlabel="bending moment [N m]", ylabel="contact force [N]")
    right.grid(True, alpha=0.3)
    return [sc.save_figure(figure, output / "cylinder.png")]


def floor(output: Path, compile: bool, t_final: float = POINTS["fall"]) -> list[Path]:
    """The paper's robot released onto a floor, ``t_final`` seconds of it [s]."""
    robot = sc.presets.ifac2020().replace(gravity=np.array([-9.81, 0.0, 0.0]))
    radius = robot.segments[0].radius
    ground = sc.Plane(point=[-(radius + 0.005), 0.0, 0.0], normal=[1.0, 0.0, 0.0])
    model = sc.Model(robot, environment=sc.Environment([ground], LAW), compile=compile)
    trajectory = sc.simulate(model, [0.0644, 20.0, 0.0], np.zeros(3), t_final=t_final, dt=1e-3)
    if not trajectory.success:
        raise RuntimeError(trajectory.message)
    contact = trajectory.contact()
    first = trajectory.t[np.argmax(contact.in_contact[:, 0])]
    lowest = 1e3 * trajectory.tip[:, 0].min()
    print(f"floor: first touch at t = {first:.3f} s, largest force "
          f"{contact.magnitude.max():.3f} N, final force {contact.magnitude[-1, 0]:.3f} N, "
          f"lowest tip x {lowest:.2f} mm (floor + body radius: "
          f"{1e3 * (ground.point[0] + radius):.2f} mm); {trajectory.stats['method']}, "
          f"{trajectory.stats['wall_time']:.2f} s integrating")  # fmt: skip
    return [
        sc.save_figure(contact.plot(), output / "floor_force.png"),
        sc.save_figure(trajectory.plot_tip(), output / "floor_tip.png"),
    ]


def _pyplot():
    import matplotlib.pyplot as plt

    return plt


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("example", choices=("finger", "cylinder", "floor", "all"))
    parser.add_argument("--output", type=Path, default=Path("contact"), help="figure folder")
    parser.add_argument(
        "--no-compile", action="store_true", help="simulate the floor case uncompiled"
    )
    parser.add_argument(
        "--quick",
        action="store_true",
        help=f"a small run (for the tests): the first {QUICK['pressures']} pressures, "
        f"{QUICK['moments']} moments, {QUICK['fall']:g} s of fall",
    )
    args = parser.parse_args()
    size = QUICK if args.quick else POINTS
    args.output.mkdir(parents=True, exist_ok=True)
    chosen = ("finger", "cylinder", "floor") if args.example == "all" else (args.example,)
    written = []
    for name in chosen:
        if name == "floor":
            written += floor(args.output, compile=not args.no_compile, t_final=size["fall"])
        elif name == "finger":
            written += finger(args.output, size["pressures"])
        else:
            written += cylinder(args.output, size["moments"])
    print("wrote", ", ".join(str(p) for p in written))


if __name__ == "__main__":
    main()
