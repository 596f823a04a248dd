"""Contact against a peer (issue 13, item 6): one soft rod pushed against one wall, in
softcurve and in PyElastica.

The robot is a straight, clamped, linear-elastic rod along +z (length ``--length``,
radius ``--radius``, Young's modulus ``--young``, density ``--density``, gravity off).
A constant tip force ``--force`` along +x bends it toward the wall ``x = --wall``
(a plane, normal -x). Both codes model the same rod:

- softcurve: ``--segments`` constant-curvature (PCC) segments, each with
  ``LinearStiffness(E I / l0)`` in bending and ``LinearStiffness(E A / l0)`` in
  elongation, mass ``rho A l0``, contact radius the rod radius, a linear contact law
  (``exponent=1``) whose stiffness per metre of backbone is PyElastica's per-element
  stiffness divided by the element length. The equilibrium is
  ``softcurve.equilibrium(model, q0, tip_force=...)``, started from the free
  equilibrium; the models run in CasADi's virtual machine (no compile).
- PyElastica: ``CosseratRod.straight_rod`` with ``--elements`` elements, the same E,
  radius, length and density (Poisson ratio 0.5), ``OneEndFixedBC``, ``EndpointForces``
  at the tip, ``AnalyticalLinearDamper``, ``RodPlaneContact`` (linear penalty ``k`` per
  element plus the plane's response force), Position Verlet to ``--time`` seconds.
  The contact force is what the contact adds to the rod's external forces, summed over
  the nodes, at the last step.

Each case is also solved free (no wall), to separate the discretisation from the
contact. The linear Euler-Bernoulli beam gives the reference lines: free tip deflection
``F L^3 / (3 E I)`` and, with the tip held at the wall, contact force
``F - 3 E I d / L^3``.

PyElastica is a benchmark-only dependency (``pip install pyelastica``); the script
exits with status 2 when it is missing.

Run: ``python benchmarks/contact_vs_pyelastica.py [--markdown]``
"""

from __future__ import annotations

import argparse
import importlib.metadata
import math
import sys
import time

import numpy as np


def elastica_tip(bending, length, load):
    """Tip ``(x, z)`` [m] of the inextensible, unshearable planar elastica (the exact
    large-deflection Euler-Bernoulli cantilever) clamped along +z under a tip force
    ``load`` [N] along +x: ``theta' = kappa``, ``EI kappa' = -P cos(theta)``,
    ``theta(0) = 0``, ``kappa(L) = 0``, shot on ``kappa(0)``."""
    from scipy.integrate import solve_ivp
    from scipy.optimize import brentq

    def shoot(kappa0):
        def rhs(_, y):
            return [y[1], -load / bending * math.cos(y[0]), math.sin(y[0]), math.cos(y[0])]

        return solve_ivp(rhs, (0, length), [0.0, kappa0, 0.0, 0.0], rtol=1e-11, atol=1e-13)

    if load == 0:
        return 0.0, length
    bound = 1.01 * abs(load) * length / bending
    kappa0 = brentq(lambda k: shoot(k).y[1, -1], -bound if load < 0 else 0.0, bound, xtol=1e-14)
    y = shoot(kappa0).y[:, -1]
    return y[2], y[3]


def elastica_contact(bending, length, force, gap):
    """Contact force [N] that holds the elastica's tip at ``x = gap`` under the tip
    force ``force`` (a hard wall touching the tip only), and the tip ``(x, z)``."""
    from scipy.optimize import brentq

    if elastica_tip(bending, length, force)[0] <= gap:
        return 0.0, elastica_tip(bending, length, force)
    reaction = brentq(
        lambda r: elastica_tip(bending, length, force - r)[0] - gap, 0.0, force, xtol=1e-14
    )
    return reaction, elastica_tip(bending, length, force - reaction)


def softcurve_case(args, wall):
    """softcurve's equilibrium: ``(tip (3,), contact force along -x [N], seconds)``;
    ``wall`` None for the free rod."""
    import softcurve as sc

    # nu = 0.5: PyElastica's rod has G = E / 3 (pyelastica_case)
    rubber = sc.Material(youngs_modulus=args.young, density=args.density, poisson_ratio=0.5)
    rod = sc.section_properties(rubber, sc.Section.circle(args.radius))
    l0 = args.length / args.segments
    segment = sc.Segment(
        rest_length=l0,
        mass=rod.mass_per_length * l0,
        radius=args.radius,
        elongation_stiffness=sc.LinearStiffness(rod.elongation_stiffness(l0)),
        bending_stiffness=sc.LinearStiffness(rod.bending_angle_stiffness(l0)),
    )
    robot = sc.Robot(segments=(segment,) * args.segments, gravity=np.zeros(3))
    tip_force = np.array([args.force, 0.0, 0.0])
    start = time.perf_counter()
    free = sc.Model(robot, compile=False)
    q0 = np.tile([l0, 1e-3, 0.0], args.segments)
    e = sc.equilibrium(free, q0, tip_force=tip_force)
    if wall is not None:
        law = sc.ContactLaw(
            args.stiffness / (args.length / args.elements),
            exponent=1.0,
            smoothing=1e-8,
            points_per_segment=args.points,
        )
        env = sc.Environment(
            [sc.Plane([wall, 0.0, 0.0], [-1.0, 0.0, 0.0])],
            law,
            contact_radius=[args.radius] * args.segments,
        )
        model = sc.Model(robot, environment=env, compile=False)
        e = sc.equilibrium(model, e.q, tip_force=tip_force)
        force = -float(model.contact(e.q)["forces"][0, 0])
    else:
        force = 0.0
    seconds = time.perf_counter() - start
    if e.status.name != "SUCCESS":
        print(f"warning: softcurve equilibrium status {e.status.name}", file=sys.stderr)
    return free.tip_pose(e.q).position, force, seconds


def pyelastica_case(ea, args, wall):
    """PyElastica's damped steady state: ``(tip (3,), contact force along -x [N], seconds,
    largest node speed at the end [m/s])``; ``wall`` None for the free rod."""
    from elastica.contact_forces import RodPlaneContact

    class Simulator(ea.BaseSystemCollection, ea.Constraints, ea.Forcing, ea.Damping, ea.Contact):
        pass

    record = {}

    class RecordedRodPlaneContact(RodPlaneContact):
        """RodPlaneContact that keeps the force it adds to the rod."""

        def apply_contact(self, system_one, system_two, time=0.0):
            before = system_one.external_forces.copy()
            super().apply_contact(system_one, system_two, time)
            record["force"] = (system_one.external_forces - before).sum(axis=1)

    start = time.perf_counter()
    sim = Simulator()
    rod = ea.CosseratRod.straight_rod(
        args.elements,
        np.zeros(3),
        np.array([0.0, 0.0, 1.0]),
        np.array([1.0, 0.0, 0.0]),
        args.length,
        args.radius,
        args.density,
        youngs_modulus=args.young,
        shear_modulus=args.young / 3.0,
    )
    sim.append(rod)
    sim.constrain(rod).using(
        ea.OneEndFixedBC, constrained_position_idx=(0,), constrained_director_idx=(0,)
    )
    sim.add_forcing_to(rod).using(
        ea.EndpointForces,
        start_force=np.zeros(3),
        end_force=np.array([args.force, 0.0, 0.0]),
        ramp_up_time=args.time / 10,
    )
    sim.dampen(rod).using(
        ea.AnalyticalLinearDamper, uniform_damping_constant=args.damping, time_step=args.dt
    )
    if wall is not None:
        plane = ea.Plane(np.array([wall, 0.0, 0.0]), np.array([-1.0, 0.0, 0.0]))
        sim.append(plane)
        sim.detect_contact_between(rod, plane).using(
            RecordedRodPlaneContact, k=args.stiffness, nu=args.contact_damping
        )
    sim.finalize()
    steps = int(round(args.time / args.dt))
    ea.integrate(ea.PositionVerlet(), sim, args.time, steps, progress_bar=False)
    seconds = time.perf_counter() - start
    tip = rod.position_collection[:, -1].copy()
    speed = float(np.linalg.norm(rod.velocity_collection, axis=0).max())
    force = -float(record["force"][0]) if wall is not None else 0.0
    return tip, force, seconds, speed


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--length", type=float, default=0.25, help="rod length L [m]")
    parser.add_argument("--radius", type=float, default=5e-3, help="rod radius [m]")
    parser.add_argument("--young", type=float, default=1e6, help="Young's modulus E [Pa]")
    parser.add_argument("--density", type=float, default=1000.0, help="density [kg/m^3]")
    parser.add_argument("--force", type=float, default=5e-3, help="tip force along +x [N]")
    parser.add_argument(
        "--wall", type=float, default=None, help="wall x [m] (default: 60 %% of the free tip's)"
    )
    parser.add_argument(
        "--stiffness", type=float, default=1e2, help="PyElastica k per element [N/m]"
    )
    parser.add_argument("--segments", type=int, nargs="+", default=[1, 3, 5])
    parser.add_argument("--points", type=int, default=2, help="softcurve points per segment")
    parser.add_argument("--elements", type=int, default=40, help="PyElastica elements")
    parser.add_argument("--dt", type=float, default=5e-5, help="PyElastica time step [s]")
    parser.add_argument("--time", type=float, default=3.0, help="PyElastica final time [s]")
    parser.add_argument(
        "--damping", type=float, default=10.0, help="PyElastica damping constant [1/s]"
    )
    parser.add_argument(
        "--contact-damping", type=float, default=1e-2, help="PyElastica contact nu [N s/m]"
    )
    parser.add_argument("--markdown", action="store_true", help="print markdown tables")
    args = parser.parse_args(argv)
    try:
        import elastica as ea
    except ImportError:
        print(
            "contact_vs_pyelastica.py needs PyElastica (a benchmark-only dependency): "
            "pip install pyelastica",
            file=sys.stderr,
        )
        sys.exit(2)
    import softcurve as sc

    run(ea, sc, args)


def run(ea, sc, args):
    """Solve every case and print the table."""
    bending = args.young * math.pi / 4 * args.radius**4
    beam = args.force * args.length**3 / (3 * bending)
    print(
        f"PyElastica {importlib.metadata.version('pyelastica')}, softcurve {sc.__version__}; "
        f"L = {args.length} m, r = {args.radius} m, E = {args.young:g} Pa, "
        f"rho = {args.density:g} kg/m^3, tip force {args.force:g} N"
    )
    free_pe = pyelastica_case(ea, args, None)
    wall = args.wall if args.wall is not None else 0.6 * free_pe[0][0] + args.radius
    gap = wall - args.radius  # backbone x at which the body touches
    print(
        f"wall x = {1e3 * wall:.3f} mm (the backbone touches at x = {1e3 * gap:.3f} mm); "
        f"linear beam: free tip x = {1e3 * beam:.3f} mm, contact force "
        f"{max(0.0, args.force - 3 * bending * gap / args.length**3):.6f} N"
    )
    start = time.perf_counter()
    free_ref = elastica_tip(bending, args.length, args.force)
    seconds = time.perf_counter() - start
    rows = [
        ("elastica (exact beam)", None, (np.array([free_ref[0], 0, free_ref[1]]), 0.0, seconds))
    ]
    start = time.perf_counter()
    force_ref, tip_ref = elastica_contact(bending, args.length, args.force, gap)
    seconds = time.perf_counter() - start
    rows.append(
        ("elastica (exact beam)", wall, (np.array([tip_ref[0], 0, tip_ref[1]]), force_ref, seconds))
    )
    rows.append((f"PyElastica, {args.elements} elements", None, free_pe))
    rows.append((f"PyElastica, {args.elements} elements", wall, pyelastica_case(ea, args, wall)))
    for n in args.segments:
        args_n = argparse.Namespace(**{**vars(args), "segments": n})
        for w in (None, wall):
            label = f"softcurve, {n} PCC segment{'s' if n > 1 else ''}"
            rows.append((label, w, softcurve_case(args_n, w)))
    print()
    print("| model | wall | tip x [mm] | tip z [mm] | contact force [N] | wall time [s] |")
    print("|---|---|---:|---:|---:|---:|")
    for name, w, result in rows:
        tip, force, seconds = result[:3]
        print(
            f"| {name} | {'yes' if w is not None else 'no'} | {1e3 * tip[0]:.3f} | "
            f"{1e3 * tip[2]:.3f} | {force:.6f} | {seconds:.2f} |"
        )
    print(
        f"\nPyElastica's largest node speed at t = {args.time} s: free "
        f"{rows[2][2][3]:.2e} m/s, wall {rows[3][2][3]:.2e} m/s"
    )


if __name__ == "__main__":
    main()
