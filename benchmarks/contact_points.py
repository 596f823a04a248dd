"""Contact force against the number of contact points per segment (issue 13, item 2).

Two cases on the paper's robot (contact radius 1 mm, Hertz exponent 1.5):

- ``sphere``: a fixed bent configuration (``kx = 20 1/m``) pressed 0.5 mm deep into a
  ball of radius 0.1 m at ``s = 0.45`` on its convex side; the penalty force is a line
  integral along the backbone, and the trapezoidal rule converges to it as the points
  per segment ``K`` grow.
- ``wall``: a tip force of 0.3 N pushes the robot against a wall; the equilibrium
  (:func:`softcurve.equilibrium`) gives the contact force, the penetration and the tip
  position. The force is set by the load balance; ``K`` changes how deep the penalty
  has to go to carry it (fewer points share it).

The models run in CasADi's virtual machine (no compile). Run:
``python benchmarks/contact_points.py [--points 1 2 4 8 16 32] [--stiffness 1e7]``
"""

from __future__ import annotations

import argparse

import numpy as np

import softcurve as sc

RADIUS = 1e-3
"""Contact radius [m]."""


def _model(robot, obstacle, stiffness, points):
    law = sc.ContactLaw(stiffness, smoothing=1e-8, points_per_segment=points)
    env = sc.Environment([obstacle], law, contact_radius=[RADIUS])
    return sc.Model(robot, environment=env, compile=False)


def sphere_case(robot, stiffness, points):
    """Rows ``(K, |F| [N], relative change)`` at a fixed configuration."""
    free = sc.Model(robot, compile=False)
    q = np.array([0.0644, 20.0, 0.0])
    rotation, point = free.pose(q, 0.45)
    center = point - (0.1 + RADIUS - 5e-4) * rotation[:, 0]  # 0.5 mm deep, convex side
    ball = sc.Sphere(center, 0.1)
    rows = []
    for k in points:
        force = _model(robot, ball, stiffness, k).contact(q)["forces"][0]
        rows.append((k, float(np.linalg.norm(force))))
    return rows


def wall_case(robot, stiffness, points):
    """Rows ``(K, contact force [N], penetration [m], tip x [m])`` at equilibrium."""
    free = sc.Model(robot, compile=False)
    tip_force = np.array([0.3, 0.0, 0.0])
    start = sc.equilibrium(free, [0.0644, 0.0, 0.0], tip_force=tip_force)
    wall = 0.6 * free.tip_pose(start.q).position[0] + RADIUS
    rows = []
    for k in points:
        model = _model(robot, sc.Plane([wall, 0, 0], [-1, 0, 0]), stiffness, k)
        e = sc.equilibrium(model, start.q, tip_force=tip_force)
        tip = free.tip_pose(e.q).position[0]
        force = -model.contact(e.q)["forces"][0, 0]
        rows.append((k, force, tip + RADIUS - wall, tip))
    return rows


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--points", type=int, nargs="+", default=[1, 2, 4, 8, 16, 32, 64])
    parser.add_argument("--stiffness", type=float, default=1e7, help="k [N m^-2.5]")
    parser.add_argument("--case", choices=["sphere", "wall", "both"], default="both")
    args = parser.parse_args(argv)
    robot = sc.presets.ifac2020()
    if args.case in ("sphere", "both"):
        print_sphere(robot, args)
    if args.case in ("wall", "both"):
        print_wall(robot, args)


def print_sphere(robot, args):
    """Print the sphere case's table."""
    rows = sphere_case(robot, args.stiffness, args.points)
    reference = rows[-1][1]
    print(f"sphere pressed 0.5 mm into a bent robot at s = 0.45 (k = {args.stiffness:g})")
    print("| points per segment | force [N] | relative to the finest |")
    print("|---:|---:|---:|")
    for k, force in rows:
        print(f"| {k} | {force:.6f} | {abs(force - reference) / reference:.1e} |")


def print_wall(robot, args):
    """Print the wall case's table."""
    print(f"\nwall, tip force 0.3 N, equilibrium (k = {args.stiffness:g})")
    print("| points per segment | contact force [N] | penetration [mm] | tip x [mm] |")
    print("|---:|---:|---:|---:|")
    for k, force, depth, tip in wall_case(robot, args.stiffness, args.points):
        print(f"| {k} | {force:.6f} | {1e3 * depth:.4f} | {1e3 * tip:.4f} |")


if __name__ == "__main__":
    main()
