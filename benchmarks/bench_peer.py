"""Side by side with a peer (issue 45, item 9): softcurve's piecewise-constant-strain
robot against SoRoMoX's on the same robot, statics, a free trajectory and wall times.

The robot (``case()``): a soft rod of ``--segments`` constant-strain segments, each
``--length`` long, solid circular section of radius ``--radius``, density ``--density``,
Young's modulus ``--young`` and shear modulus ``--shear``, all six strains free, clamped
horizontally (base rotation: the backbone leaves along world +x) under gravity
``(0, 0, -9.81)``. Every segment is precurved in the horizontal plane (rest bend about
its slice x axis, ``--precurve``), so the weight of the curved rod twists it as well as
bending, shearing and stretching it. The static shape is the equilibrium under gravity;
the free trajectory starts at rest from the rest strains plus a vertical bend
(``--lift``, about the slice y axis: the rod lifted) and falls under gravity for
``--time`` seconds with stiffness-proportional damping ``D = beta L0 K``
(``--beta``).

Both codes get the same parameters (the peer's side, ``benchmarks/peer/soromox_side.py``,
reads the same case as JSON and states the conventions' map in full):

- strains: softcurve ``(u_x, u_y, u_z, v_x, v_y, v_z)`` (slice z along the backbone) is
  SoRoMoX's ``(kappa_y, kappa_z, kappa_x, sigma_y, sigma_z, sigma_x)`` (material x
  along the backbone): a cyclic relabelling of the axes, no sign changes; the peer's
  base rotation is ours times ``[e_z, e_x, e_y]``;
- stiffness: ``E I`` bending, ``G J`` torsion (``J = 2 I``), ``G A`` shear (SoRoMoX has
  no shear coefficient, so ``k = 1`` here), ``E A`` stretch, per unit reference length;
- inertia: mass ``rho A`` per unit reference length and rotary inertia per unit mass
  ``r^2 (1/4, 1/4, 1/2)`` (softcurve's default ``slice_inertia``; SoRoMoX's
  ``rho diag(J, I, I)``);
- damping: the generalized matrix ``D`` on the strain rates, diagonal.

Statics: softcurve's ``equilibrium`` from the rest configuration; the peer has no static
solver, its side runs Newton's method on its ``potential_force``. Trajectory: softcurve's
``simulate`` (CVODES) and the peer's ``rollout_to`` (diffrax Tsit5, adaptive), both at
``--rtol``; the table gives the largest distance between the tips over the output times.
Wall times: each code's first call in a fresh process (compiling: softcurve's C build or
its cache, the peer's JIT) and a second call.

``--pcc`` runs the restricted case (bend x, bend y, stretch; straight at rest; undamped,
since a damping on the strain rates is not one on ``(l, kx, ky)``) with softcurve's side
today's constant-curvature ``Segment`` (``StrainSegment``'s map ``sigma = l / l0``,
``u = sigma (-ky, kx, 0)``, ``v = (0, 0, sigma)``).

The peer lives in its own virtual environment (``python -m venv peer-venv &&
peer-venv/bin/pip install soromox``, or the extra ``peer``); without ``--peer-python`` the
script says so and stops.

Run: ``python benchmarks/bench_peer.py --peer-python peer-venv/bin/python [--pcc]
[--markdown]``
"""

from __future__ import annotations

import argparse
import json
import math
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

STRAINS = ("bend_x", "bend_y", "twist", "shear_x", "shear_y", "stretch")
PEER_SCRIPT = Path(__file__).resolve().parent / "peer" / "soromox_side.py"
# the base frame's z (the backbone) along world +x, its y along world y: a horizontal
# cantilever under gravity along -z
HORIZONTAL = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])


def section(radius):
    """``(A, I, J)`` of a solid circle [m^2, m^4, m^4]."""
    area = math.pi * radius**2
    second = math.pi * radius**4 / 4
    return area, second, 2 * second


def stiffness(args):
    """Per-unit-length stiffness of each strain, softcurve's order (6,)."""
    area, second, polar = section(args.radius)
    e, g = args.young, args.shear
    return np.array([e * second, e * second, g * polar, g * area, g * area, e * area])


def case(args):
    """The robot, load and runs, in softcurve's conventions (JSON-ready)."""
    n = args.segments
    precurve, beta = (0.0, 0.0) if args.pcc else (args.precurve, args.beta)
    rest = np.tile([precurve, 0.0, 0.0, 0.0, 0.0, 1.0], (n, 1))
    initial = rest + np.tile([0.0, -args.lift, 0.0, 0.0, 0.0, 0.0], (n, 1))
    damping = np.tile(beta * args.length * stiffness(args), (n, 1))
    return {
        "n_segments": n,
        "rest_length": args.length,
        "radius": args.radius,
        "density": args.density,
        "youngs_modulus": args.young,
        "shear_modulus": args.shear,
        "strains": ["bend_x", "bend_y", "stretch"] if args.pcc else list(STRAINS),
        "rest_strain": rest.tolist(),
        "damping": damping.tolist(),
        "gravity": [0.0, 0.0, -9.81],
        "base_rotation": HORIZONTAL.tolist(),
        "initial_strain": initial.tolist(),
        "t_final": args.time,
        "n_out": args.outputs,
        "rtol": args.rtol,
        # the peer's absolute tolerance: rtol times the smallest strain scale (1/m or 1)
        "atol": args.rtol * 1e-2,
        "max_steps": 1_000_000,
        "num_gauss_points": args.gauss,
        "static_tol": 1e-12,
        "static_max_iter": 50,
        "n_backbone": 11,
    }


def run_peer(python, spec):
    """The peer's results (dict) from its own interpreter, or None with a message."""
    with tempfile.TemporaryDirectory() as folder:
        case_file, result_file = Path(folder) / "case.json", Path(folder) / "result.json"
        case_file.write_text(json.dumps(spec))
        done = subprocess.run(
            [str(python), str(PEER_SCRIPT), str(case_file), str(result_file)],
            capture_output=True,
            text=True,
        )
        if done.returncode != 0:
            print(f"peer side failed (exit {done.returncode}):\n{done.stderr[-2000:]}")
            return None
        return json.loads(result_file.read_text())


def strain_robot(sc, spec):
    """The case as ``StrainSegment``s: ``(robot, q of per-segment strains, strains of
    q)``."""
    n, length, radius = spec["n_segments"], spec["rest_length"], spec["radius"]
    area, second, polar = section(radius)
    e, g = spec["youngs_modulus"], spec["shear_modulus"]
    chosen = [STRAINS.index(name) for name in spec["strains"]]
    segments = tuple(
        sc.StrainSegment(
            rest_length=length,
            mass=spec["density"] * area * length,
            radius=radius,
            strains=tuple(spec["strains"]),
            bending_stiffness=sc.LinearStiffness(e * second),
            torsion_stiffness=sc.LinearStiffness(g * polar),
            # k = 1: the peer has no shear coefficient
            shear_stiffness=sc.LinearStiffness(g * area),
            stretch_stiffness=sc.LinearStiffness(e * area),
            rest_strain=tuple(spec["rest_strain"][i]),
            damping=np.asarray(spec["damping"][i])[chosen],
        )
        for i in range(n)
    )
    robot = sc.Robot(
        segments=segments, gravity=spec["gravity"], base_rotation=spec["base_rotation"]
    )

    def to_q(strains):
        return np.asarray(strains, dtype=float)[:, chosen].reshape(-1)

    def to_strains(q):
        strains = np.array(spec["rest_strain"], dtype=float)
        strains[:, chosen] = np.reshape(q, (n, len(chosen)))
        return strains

    return robot, to_q, to_strains


def curvature_robot(sc, spec):
    """The restricted case (bend x, bend y, stretch; straight at rest; undamped) as
    today's constant-curvature ``Segment``s: ``(robot, to_q, to_strains)``. The map of
    ``StrainSegment``'s docstring: ``sigma = l / l0``, ``u = sigma (-ky, kx, 0)``,
    ``v = (0, 0, sigma)``; its energy is the strains' with ``k_b = E I / l0``,
    ``k_e = E A / l0``."""
    n, length, radius = spec["n_segments"], spec["rest_length"], spec["radius"]
    area, second, _ = section(radius)
    e = spec["youngs_modulus"]
    segment = sc.Segment(
        rest_length=length,
        mass=spec["density"] * area * length,
        radius=radius,
        elongation_stiffness=sc.LinearStiffness(e * area / length),
        bending_stiffness=sc.LinearStiffness(e * second / length),
    )
    robot = sc.Robot(
        segments=(segment,) * n, gravity=spec["gravity"], base_rotation=spec["base_rotation"]
    )

    def to_q(strains):
        u_x, u_y, sigma = np.asarray(strains, dtype=float)[:, [0, 1, 5]].T
        return np.column_stack([sigma * length, u_y / sigma, -u_x / sigma]).reshape(-1)

    def to_strains(q):
        arc, kx, ky = np.reshape(q, (n, 3)).T
        sigma = arc / length
        zero = np.zeros(n)
        return np.column_stack([-sigma * ky, sigma * kx, zero, zero, zero, sigma])

    return robot, to_q, to_strains


def run_ours(sc, spec, robot, to_q, to_strains):
    """softcurve's results in the peer's layout."""
    start = time.perf_counter()
    model = sc.Model(robot)
    build_time = time.perf_counter() - start
    q_rest = to_q(spec["rest_strain"])

    static_times, equilibrium = [], None
    for _ in range(2):
        start = time.perf_counter()
        equilibrium = sc.equilibrium(model, q_rest)
        static_times.append(time.perf_counter() - start)
    if not equilibrium.success:
        raise RuntimeError(f"softcurve's equilibrium failed: {equilibrium.message}")
    tip = model.tip_pose(equilibrium.q)
    backbone = np.array(
        [model.pose(equilibrium.q, s).position for s in np.linspace(0, 1, spec["n_backbone"])]
    )

    q0 = to_q(spec["initial_strain"])
    dt = spec["t_final"] / (spec["n_out"] - 1)
    trajectory_times, trajectory = [], None
    for _ in range(2):
        start = time.perf_counter()
        trajectory = sc.simulate(
            model, q0, np.zeros_like(q0), t_final=spec["t_final"], dt=dt, rtol=spec["rtol"]
        )
        trajectory_times.append(time.perf_counter() - start)
    if not trajectory.success:
        raise RuntimeError(f"softcurve's simulation failed: {trajectory.message}")
    return {
        "build_time": build_time,
        "static": {
            "strains": to_strains(equilibrium.q).tolist(),
            "tip_position": np.asarray(tip.position).tolist(),
            "tip_rotation": np.asarray(tip.rotation).tolist(),
            "backbone": backbone.tolist(),
            "time_cold": static_times[0],
            "time_warm": static_times[1],
        },
        "trajectory": {
            "t": np.asarray(trajectory.t).tolist(),
            "tip_position": [model.tip_pose(q).position.tolist() for q in trajectory.q],
            "time_cold": trajectory_times[0],
            "time_warm": trajectory_times[1],
        },
    }


def _mm(x):
    return "(" + ", ".join(f"{v * 1e3:.4f}" for v in x) + ") mm"


def _distance(a, b):
    """Largest distance [m] between matching rows of two (..., 3) arrays of points [m]."""
    d = np.linalg.norm(np.atleast_2d(np.subtract(a, b)), axis=1)
    return f"{d.max():.2e} m"


def _timings(result):
    """(static first, static second, trajectory first, trajectory second) [s]."""
    static, trajectory = result["static"], result["trajectory"]
    return (
        result["build_time"] + static["time_cold"],
        static["time_warm"],
        trajectory["time_cold"],
        trajectory["time_warm"],
    )


def rows(peer, ours):
    """The table's rows: (quantity, softcurve, peer, difference or time ratio)."""
    p_static, p_traj = peer["static"], peer["trajectory"]
    o_static, o_traj = ours["static"], ours["trajectory"]
    if not np.allclose(o_traj["t"], p_traj["t"], atol=1e-12):
        raise RuntimeError("the two trajectories' output times differ")
    # the angle of R_o^T R_p from |R_o - R_p|_F = 2 sqrt(2) sin(angle / 2), exact near
    # zero, where the trace's arccos loses its digits
    gap = np.linalg.norm(np.subtract(o_static["tip_rotation"], p_static["tip_rotation"]))
    angle = math.degrees(2 * math.asin(min(1.0, gap / math.sqrt(8))))
    table = [
        ("peer", "softcurve", f"soromox {peer['peer_version']} (jax {peer['jax_version']})", ""),
        (
            "static tip position",
            _mm(o_static["tip_position"]),
            _mm(p_static["tip_position"]),
            _distance(o_static["tip_position"], p_static["tip_position"]),
        ),
        (
            "static backbone, largest distance",
            "",
            "",
            _distance(o_static["backbone"], p_static["backbone"]),
        ),
        ("static tip rotation, angle between", "", "", f"{angle:.2e} deg"),
        (
            "static twist, segment 1 [1/m]",
            f"{o_static['strains'][0][2]:.8g}",
            f"{p_static['strains'][0][2]:.8g}",
            "",
        ),
        (
            "trajectory, final tip position",
            _mm(o_traj["tip_position"][-1]),
            _mm(p_traj["tip_position"][-1]),
            "",
        ),
        (
            "trajectory, largest tip distance",
            "",
            "",
            _distance(o_traj["tip_position"], p_traj["tip_position"]),
        ),
    ]
    labels = (
        "static, first call (build + solve)",
        "static, second call",
        "trajectory, first call",
        "trajectory, second call",
    )
    for label, o, p in zip(labels, _timings(ours), _timings(peer), strict=True):
        table.append((label, f"{o:.3f} s", f"{p:.3f} s", f"{p / o:.2f}x"))
    return table


def show(table, markdown):
    """Print the rows as Markdown or as aligned text."""
    header = ("quantity", "softcurve", "peer", "difference / peer:softcurve")
    if markdown:
        print("| " + " | ".join(header) + " |")
        print("|" + "---|" * len(header))
        for row in table:
            print("| " + " | ".join(row) + " |")
        return
    widths = [max(len(r[i]) for r in (header, *table)) for i in range(len(header))]
    for row in (header, *table):
        print("  ".join(cell.ljust(w) for cell, w in zip(row, widths, strict=True)))


def main(argv=None):
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--peer-python", help="the python of an environment with soromox (a path or a command)"
    )
    parser.add_argument("--segments", type=int, default=2)
    parser.add_argument("--length", type=float, default=0.1, help="per segment [m]")
    parser.add_argument("--radius", type=float, default=0.02, help="[m]")
    parser.add_argument("--density", type=float, default=1000.0, help="[kg/m^3]")
    parser.add_argument("--young", type=float, default=2e6, help="[Pa]")
    parser.add_argument("--shear", type=float, default=2e6 / 3, help="[Pa]")
    parser.add_argument("--precurve", type=float, default=4.0, help="rest bend x [1/m]")
    parser.add_argument("--lift", type=float, default=3.0, help="initial bend [1/m]")
    parser.add_argument("--beta", type=float, default=0.01, help="damping D = beta L0 K [s]")
    parser.add_argument("--time", type=float, default=0.5, help="t_final [s]")
    parser.add_argument("--outputs", type=int, default=51, help="output times")
    parser.add_argument("--rtol", type=float, default=1e-8)
    parser.add_argument("--gauss", type=int, default=5, help="the peer's Gauss points")
    parser.add_argument(
        "--pcc",
        action="store_true",
        help="the restricted case: bend x, bend y and stretch, straight, undamped, "
        "softcurve's side today's constant-curvature Segment",
    )
    parser.add_argument("--markdown", action="store_true")
    args = parser.parse_args(argv)

    python = args.peer_python and shutil.which(str(args.peer_python))
    if python is None:
        print(
            "skipped: no peer environment (give --peer-python PATH to a python with "
            "soromox installed: python -m venv peer-venv && peer-venv/bin/pip install soromox)"
        )
        return 0
    spec = case(args)
    peer = run_peer(python, spec)
    if peer is None:
        return 1
    import softcurve as sc

    ours = run_ours(sc, spec, *(curvature_robot if args.pcc else strain_robot)(sc, spec))
    show(rows(peer, ours), args.markdown)
    return 0


if __name__ == "__main__":
    sys.exit(main())
