"""Study: where a quasi-static fit's first evaluation pays for starting from equilibria of
nearby inputs (``softcurve.identification.fits._equilibria.WARM_START_MIN``).

Run:  python benchmarks/study_warm_start.py [--sizes 128,256,400,2000] [--repeat 5]

The sweep of ``tests/test_equilibrium_predictor.py``: one segment (four quadrature
nodes) under three bellows whose pressures turn twice around the segment over 6 s, with
a growing amplitude, sampled ``T`` times. For each size it prints the best of
``--repeat`` first evaluations of a fresh predictor with the warm start (about
``sqrt(T)`` samples solved first, every sample then from the nearest one's solution and
stiffness) and without it (every sample by Newton's method from the straight guess).
"""

from __future__ import annotations

import argparse
import time

import numpy as np

import softcurve as sc
from softcurve.identification.experiments import Experiment
from softcurve.identification.fits import _equilibria as equilibria
from softcurve.identification.fits._parameters import Free, FreeParameters
from softcurve.identification.maps import bellows_input_map, curvature_map


def sweep(samples: int) -> Experiment:
    """The tests' pressure sweep, ``samples`` samples over 6 s."""
    t = np.linspace(0.0, 6.0, samples)
    phase, amplitude = 4 * np.pi * t / 6.0, 3e3 + 1.4e4 * t / 6.0
    pressures = {f"p{i}": 2e4 + amplitude * np.sin(phase - 2 * np.pi * i / 3) for i in range(3)}
    return Experiment(t, {"kx": 0 * t, "ky": 0 * t}, pressures)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--sizes", default="128,256,400,2000")
    parser.add_argument("--repeat", type=int, default=5)
    args = parser.parse_args()
    segment = sc.Segment(
        rest_length=0.064, mass=0.017, radius=0.013,
        elongation_stiffness=sc.LinearStiffness(1000.0),
        bending_stiffness=sc.TanhStiffness(0.014, 0.006, 4.0), damping=[0.5, 4e-7, 4e-7],
    )  # fmt: skip
    model = sc.Model(sc.Robot(segments=(segment,)), quadrature_nodes=4)
    inputs, output = bellows_input_map(area=2.3e-5, distance=0.01), curvature_map()
    free = [Free("bellows.angle", -np.pi, np.pi), Free("bellows.area", 1e-7, 1e-3)]
    parameters = FreeParameters(model, free, {**inputs.parameters, **output.parameters}, {})
    q0, theta = np.array([0.064, 0.0, 0.0]), np.array([-0.5, 2.3e-5])
    print(f"WARM_START_MIN = {equilibria.WARM_START_MIN}; first evaluation, best of {args.repeat}")
    for samples in map(int, args.sizes.split(",")):
        record, best = sweep(samples), {}
        for warm in (True, False):
            equilibria.WARM_START_MIN = 1 if warm else samples + 1
            times = []
            for _ in range(args.repeat):
                evaluate = equilibria.EquilibriumPredictor(model, parameters, output, inputs, q0)(
                    record
                )
                start = time.perf_counter()
                evaluate(theta)
                times.append(time.perf_counter() - start)
            best[warm] = min(times)
        print(
            f"  {samples:5d} samples: {1e3 * best[True]:6.1f} ms with the warm start, "
            f"{1e3 * best[False]:6.1f} ms without"
        )


if __name__ == "__main__":
    main()
