"""The constant-strain segment against closed forms: the errors docs/strains.md quotes.

For a soft segment of all six strains (10 cm, radius 1 cm, E = 1 MPa, nu = 0.5, k = 0.9;
no gravity) it prints

- the pose against SciPy's matrix exponential ``expm(L0 xi^)`` at random strains and at
  strains of 1e-9 (the series near zero);
- pure torsion: the twist ``T L / GJ`` of the equilibrium under a tip moment ``T``;
- axial load: the tip displacement ``F L / EA`` under a tip force ``F``;
- a Timoshenko cantilever in the small-load limit: the tip deflection against
  ``F L^3 / (3 EI) + F L / (k G A)`` for 1, 2, 4, 8 equal segments, and the observed
  order;
- the strains (bend x, bend y, stretch) against the paper's constant-curvature segment:
  the largest difference of tip positions over random states, and of equilibria.

Each is a relative error (the largest entry's difference over the largest entry).

Run: ``python benchmarks/strain_checks.py``
"""

from __future__ import annotations

import argparse

import numpy as np
from scipy.linalg import expm

import softcurve as sc

SEGMENT = sc.StrainSegment.from_material(
    sc.Material(youngs_modulus=1e6, density=1070.0, poisson_ratio=0.5),
    sc.Section.circle(0.01),
    rest_length=0.1,
)


def twist_matrix(xi) -> np.ndarray:
    """``xi^`` (4, 4) of ``xi = (u, v)``."""
    u, v = xi[:3], xi[3:]
    m = np.zeros((4, 4))
    m[:3, :3] = [[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]]
    m[:3, 3] = v
    return m


def relative(a, b) -> float:
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    return float(np.abs(a - b).max() / max(np.abs(b).max(), np.finfo(float).tiny))


def weightless(*segments) -> sc.Robot:
    return sc.Robot(segments=segments, gravity=np.zeros(3))


def main() -> None:
    argparse.ArgumentParser(description=__doc__.splitlines()[0]).parse_args()
    rng = np.random.default_rng(45)
    model = sc.Model(weightless(SEGMENT), compile=False)
    length = SEGMENT.rest_length
    for label, scale in (("random strains", 1.0), ("strains of 1e-9", 1e-9)):
        worst = 0.0
        for _ in range(20):
            xi = SEGMENT.rest_strain + scale * rng.uniform(-1, 1, 6) * [30, 30, 30, 0.3, 0.3, 0.3]
            g = expm(length * twist_matrix(xi))
            tip = model.tip_pose(xi)
            worst = max(worst, relative(tip.rotation, g[:3, :3]), relative(tip.position, g[:3, 3]))
        print(f"pose against expm(L0 xi^), {label}: {worst:.1e}")
    gj, ea = SEGMENT.torsion_stiffness.k0, SEGMENT.stretch_stiffness.k0
    rest = SEGMENT.rest_configuration()
    torque = 5e-3
    e = sc.equilibrium(model, rest, tip_moment=[0, 0, torque])
    print(f"pure torsion, twist against T / GJ: {relative(e.q[2], torque / gj):.1e}")
    force = 20.0
    e = sc.equilibrium(model, rest, tip_force=[0, 0, force])
    tip = model.tip_pose(e.q).position[2]
    print(
        f"axial load, tip against L + F L / EA: {relative(tip, length + force * length / ea):.1e}"
    )
    ei, kga = SEGMENT.bending_stiffness.k0, SEGMENT.shear_stiffness.k0
    load = 1e-6 * ei / length**2
    expected = load * length**3 / (3 * ei) + load * length / kga
    print("Timoshenko cantilever, small load: N, relative error, observed order")
    previous = None
    for count in (1, 2, 4, 8):
        piece = SEGMENT.replace(rest_length=length / count, mass=SEGMENT.mass / count)
        chain = sc.Model(weightless(*(piece,) * count), compile=False)
        e = sc.equilibrium(chain, chain.robot.rest_configuration(), tip_force=[load, 0, 0])
        error = abs(chain.tip_pose(e.q).position[0] - expected) / expected
        order = "" if previous is None else f"{np.log2(previous / error):.2f}"
        print(f"  {count:>2}  {error:.2e}  {order}")
        previous = error
    paper = sc.presets.ifac2020(damping=False).with_segments(2)
    paper = paper.replace(
        segments=tuple(s.replace(creep=None) for s in paper.segments), gravity=[0, 0, 9.81]
    )

    def twin(segment):
        l0 = segment.rest_length
        laws = {
            "bending_stiffness": segment.bending_stiffness,
            "stretch_stiffness": segment.elongation_stiffness,
        }
        return sc.StrainSegment(
            rest_length=l0,
            mass=segment.mass,
            radius=segment.radius,
            strains=("bend_x", "bend_y", "stretch"),
            **{k: type(v)(*(l0 * p for p in v.parameters())) for k, v in laws.items()},
        )

    strain = paper.replace(segments=tuple(twin(s) for s in paper.segments))
    a, b = sc.Model(paper, compile=False), sc.Model(strain, compile=False)

    def to_strains(q):
        out = []
        for i, l0 in enumerate(paper.rest_lengths):
            sigma = q[3 * i] / l0
            out += [-sigma * q[3 * i + 2], sigma * q[3 * i + 1], sigma]
        return np.array(out)

    worst = 0.0
    for _ in range(20):
        q = np.concatenate([[l0 * rng.uniform(0.8, 1.2), *rng.uniform(-30, 30, 2)]
                            for l0 in paper.rest_lengths])  # fmt: skip
        worst = max(worst, relative(b.tip_pose(to_strains(q)).position, a.tip_pose(q).position))
    print(f"(bend x, bend y, stretch) against constant curvature, tip positions: {worst:.1e}")
    ea_ = sc.equilibrium(a, paper.rest_configuration(), tip_force=[0.02, -0.03, -0.1])
    eb_ = sc.equilibrium(b, strain.rest_configuration(), tip_force=[0.02, -0.03, -0.1])
    print(f"  equilibrium strains under a tip force: {relative(eb_.q, to_strains(ea_.q)):.1e}")


if __name__ == "__main__":
    main()
