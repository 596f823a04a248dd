"""The driver's Newton matrices on SciPy's LAPACK against its own loops (``LAPACK_FROM``
of ``softcurve.simulation.solvers._driver``): 1 s of the hanging chain of
``benchmarks/bench_jacobian.py`` by ``simulate`` each way (warm, best of ``--repeat``,
both in one process), and a batch of two members on two threads of the driver
(``simulate_batch(threads=2, lanes=False)``, 0.3 s), where OpenBLAS's own threads would
compete with the driver's.

Run: ``python benchmarks/bench_lapack.py [--segments 2 3 4 8 16] [--repeat 7]``
"""

from __future__ import annotations

import argparse
import sys

import numpy as np
from _timing import best_of

import softcurve as sc
from softcurve.simulation.solvers import _driver

NEVER = 10**6
"""A ``from`` no Newton matrix reaches: the loops at every size."""


def row(n_segments: int, repeat: int, library, addresses) -> dict:
    robot = sc.presets.ifac2020().with_segments(n_segments)
    model = sc.Model(robot)
    q0, qd0 = robot.rest_configuration(), np.zeros(model.n)
    q0s = np.stack([q0, q0 + np.eye(model.n)[1]])  # two members, one bent by 1 1/m
    out = {"N": n_segments, "n_state": model.n_state}
    for label, start in (("loops", NEVER), ("LAPACK", 1)):
        library.softcurve_use_lapack(*addresses, start)
        sc.simulate(model, q0, qd0, t_final=1.0)  # warm
        wall, _ = best_of(repeat, lambda: sc.simulate(model, q0, qd0, t_final=1.0))
        batch, _ = best_of(3, lambda: sc.simulate_batch(
            model, q0s, np.zeros_like(q0s), t_final=0.3, threads=2, lanes=False))  # fmt: skip
        out[f"simulate, {label} [ms]"] = 1e3 * wall
        out[f"batch of 2 on 2 threads, {label} [ms]"] = 1e3 * batch
    library.softcurve_use_lapack(*addresses, _driver.LAPACK_FROM)
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segments", type=int, nargs="+", default=[2, 3, 4, 8, 16])
    parser.add_argument("--repeat", type=int, default=7, help="best of this many")
    args = parser.parse_args(argv)
    library, addresses = _driver.library(), _driver.lapack_addresses()
    rows = [row(n, args.repeat, library, addresses) for n in args.segments]
    print("| " + " | ".join(rows[0]) + " |")
    print("|" + " --- |" * len(rows[0]))
    for r in rows:
        print("| " + " | ".join(f"{v:.1f}" if isinstance(v, float) else str(v)
                                for v in r.values()) + " |")  # fmt: skip
    return 0


if __name__ == "__main__":
    sys.exit(main())
