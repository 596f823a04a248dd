"""Cost of the contact: the right-hand side with 0, 1, 3 and 10 obstacles, and the
paper's case thrown against a wall, in real-time factor.

The robot is the paper's (``softcurve.presets.ifac2020()``, creep and damping on), its
body the slice radius (23.5 mm), the law ``ContactLaw(1e7, damping=1.0, friction=0.5)``
with the default 8 points per segment. The obstacles of the right-hand-side rows are a
mix of planes, spheres and capsules placed around the robot (the cost does not depend on
whether they touch: every gap is evaluated at every point). Each model is compiled once
(about a minute per model on two cores, then cached).

The paper's case (q0 = (0.064, 25, 0), qd0 = (0, 0, 1500), 10 s, output every 1 ms) is
simulated free and against the wall ``x = -45 mm`` (normal +x), which the body hits
on its first swing. Targets of issue 13: 3 obstacles at most 3x the free right-hand side,
the paper robot against a wall at least 100x real time.

The right-hand side is timed inside the compiled library (its ``rhs`` mapped over
``--number`` states in one call), round robin over the models, best of ``--rounds``;
the simulations keep the fastest of ``--rounds`` runs.

Run: ``python benchmarks/bench_contact.py [--number 20000] [--rounds 5] [--obstacles 0 1 3 10]``
"""

from __future__ import annotations

import argparse
import time
import timeit

import numpy as np

import softcurve as sc

LAW = sc.ContactLaw(1e7, damping=1.0, friction=0.5)
WALL = sc.Plane(point=[-0.045, 0.0, 0.0], normal=[1.0, 0.0, 0.0])
POOL = (
    WALL,
    sc.Sphere(center=[0.08, 0.0, 0.04], radius=0.02),
    sc.Capsule(a=[0.0, 0.07, 0.0], b=[0.0, 0.07, 0.08], radius=0.01),
    sc.Plane(point=[0.0, 0.0, -0.01], normal=[0.0, 0.0, 1.0]),
    sc.Sphere(center=[0.0, -0.08, 0.06], radius=0.02),
    sc.Capsule(a=[0.07, 0.07, 0.0], b=[0.07, 0.07, 0.08], radius=0.01),
    sc.Plane(point=[0.09, 0.0, 0.0], normal=[-1.0, 0.0, 0.0]),
    sc.Sphere(center=[-0.06, -0.06, 0.05], radius=0.015),
    sc.Capsule(a=[-0.07, 0.07, 0.0], b=[-0.07, 0.07, 0.08], radius=0.01),
    sc.Plane(point=[0.0, 0.0, 0.15], normal=[0.0, 0.0, -1.0]),
)
"""Ten obstacles around the paper robot; the first n are used for n obstacles."""
PAPER = {"q0": [0.064, 25.0, 0.0], "qd0": [0.0, 0.0, 1500.0], "t_final": 10.0}


def model_with(count: int) -> sc.Model:
    """The paper robot with the first ``count`` obstacles of :data:`POOL` (compiled)."""
    robot = sc.presets.ifac2020()
    if count == 0:
        return sc.Model(robot)
    return sc.Model(robot, environment=sc.Environment(POOL[:count], LAW))


def rhs_seconds(model: sc.Model, number: int) -> float:
    """Seconds per evaluation of the compiled right-hand side: ``number`` states in one
    call of the library's ``rhs`` mapped over them (no Python per evaluation)."""
    rng = np.random.default_rng(0)
    x = np.concatenate([[0.064, 20.0, -5.0], [0.01, 100.0, 300.0], np.zeros(model.n_creep)])
    states = x[:, None] * (1.0 + 1e-3 * rng.standard_normal((model.n_state, number)))
    mapped = model.cached(("bench_rhs", number), lambda: model.function("rhs").map(number))
    tau = np.zeros((model.n, number))
    mapped(states, tau, model.parameters)
    return timeit.timeit(lambda: mapped(states, tau, model.parameters), number=1)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--number", type=int, default=20000, help="calls per timing")
    parser.add_argument("--obstacles", type=int, nargs="+", default=[0, 1, 3, 10])
    parser.add_argument("--rounds", type=int, default=5, help="timings per model, best kept")
    args = parser.parse_args()
    print(f"{'obstacles':>9} {'compile/load [s]':>16} {'rhs [us]':>9} {'vs free':>8}")
    models, built = {}, {}
    for count in args.obstacles:
        start = time.perf_counter()
        models[count] = model_with(count)
        built[count] = time.perf_counter() - start
    best = dict.fromkeys(models, np.inf)
    for _ in range(args.rounds):  # round robin: a busy machine slows every model alike
        for count, model in models.items():
            best[count] = min(best[count], rhs_seconds(model, args.number) / args.number)
    free = best.get(0)
    for count in args.obstacles:
        ratio = f"{best[count] / free:8.2f}" if free else f"{'-':>8}"
        print(f"{count:>9} {built[count]:16.1f} {1e6 * best[count]:9.2f} {ratio}")
    print()
    print(f"{'paper case (10 s)':<22} {'method':>7} {'steps':>6} {'wall [ms]':>10} "
          f"{'x real time':>11} {'max force [N]':>13}")  # fmt: skip
    for label, count in (("free", 0), ("against a wall", 1)):
        model = model_with(count)
        runs = [
            sc.simulate(model, PAPER["q0"], PAPER["qd0"], t_final=PAPER["t_final"])
            for _ in range(args.rounds)
        ]
        trajectory = min(runs, key=lambda run: run.stats["wall_time"])
        wall = trajectory.stats["wall_time"]
        force = np.nan
        if count:
            force = np.nanmax(np.linalg.norm(trajectory.contact().forces[:, 0], axis=1))
        print(
            f"{label:<22} {trajectory.stats['method']:>7} {trajectory.stats['steps']:>6} "
            f"{1e3 * wall:10.1f} {PAPER['t_final'] / wall:11.0f} {force:13.3f}"
        )


if __name__ == "__main__":
    main()
