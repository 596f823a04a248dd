"""One right-hand side per member as lanes of members (softcurve.compiled._lanes) against
CasADi's scalar C, and the explicit stepper's period both ways.

Run:  python benchmarks/bench_lanes.py [--members 256] [--rounds 7]

The case is the paper's robot (preset ifac2020) with generalized forces as inputs. Every
variant is compiled once (``-O2 -march=native``, softcurve's model flags), then all are
timed in turn, ``--rounds`` times, on the same ``--members`` states; the best round of
each is printed, in microseconds per member, with its largest difference from CasADi's
C relative to the largest value of each output.

1. The state derivative: CasADi's generated C called per member in a C loop, and lanes
   of width 1, 2, 4 and 8 with the C library's elementary functions, and width 4 with
   glibc's vector math (libmvec).
2. The RK4 period (6 steps per 20 ms, 24 right-hand sides and the observation): the
   scalar compiled period per member (``period_function(..., native=True)``, the route
   before lanes) against the lanes period (``stepper_lanes.lanes_period``), one thread.
3. The same for ROS34PW2 (16 steps per 20 ms, a forward-difference Newton matrix and
   its QR once per period: 77 right-hand sides, 64 solves); its difference is the
   round-off of the forward differences (about 1e-8), not of the arithmetic.

The load average is printed: the machine's other work slows every row.
"""

from __future__ import annotations

import argparse
import ctypes
import os
import time
from functools import partial

import casadi as ca
import numpy as np

import softcurve as sc
from softcurve.compiled._lanes import VECTOR_MATH_LIBRARY, lanes_function, lanes_prelude, lanes_work
from softcurve.compiled._source import compile_source
from softcurve.simulation.stepper._lanes import LanesMembers, lanes_period
from softcurve.simulation.stepper._scheme import period_function, state_derivative

PERIOD = 0.02


def lanes_kernel(f, width: int, vector_math: bool):
    """``run(x, u, p, y, n)``: ``f`` on ``n`` members (rows), ``width`` at a time."""
    n_x, n_u = f.size1_in(0), f.size1_in(1)
    source = "\n".join(
        [
            "#include <stdlib.h>",
            lanes_prelude(width, vector_math),
            lanes_function(f, "xdot", (False, False, True)),
            '__attribute__((visibility("default"))) void run(const double* x, '
            "const double* u, const double* p, double* y, long n) {",
            f"  sc_v X[{n_x}], U[{n_u}], Y[{n_x}];",
            f"  sc_v* w = aligned_alloc(sizeof(sc_v), sizeof(sc_v) * {lanes_work(f)});",
            "  if (w == NULL) return;",
            "  for (long i = 0; i + SC_W <= n; i += SC_W) {",
            "    for (int l = 0; l < SC_W; l++) {",
            f"      for (int j = 0; j < {n_x}; j++) X[j][l] = x[(i + l) * {n_x} + j];",
            f"      for (int j = 0; j < {n_u}; j++) U[j][l] = u[(i + l) * {n_u} + j];",
            "    }",
            "    xdot(X, U, p, Y, w);",
            "    for (int l = 0; l < SC_W; l++)",
            f"      for (int j = 0; j < {n_x}; j++) y[(i + l) * {n_x} + j] = Y[j][l];",
            "  }",
            "  free(w);",
            "}",
        ]
    )
    library = compile_source(f"bench_lanes_{width}", source, VECTOR_MATH_LIBRARY * vector_math)
    if library is None:
        raise SystemExit("no C compiler with vector extensions: nothing to compare")
    run = library.run
    run.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_long]
    return lambda x, u, p, y: run(
        x.ctypes.data, u.ctypes.data, p.ctypes.data, y.ctypes.data, len(x)
    )


def casadi_kernel(f):
    """CasADi's generated C of ``f``, called per member in a C loop."""
    generator = ca.CodeGenerator("xdot.c", {"with_header": False})
    generator.add(f)
    n_x, n_u = f.size1_in(0), f.size1_in(1)
    source = generator.dump() + "\n".join(
        [
            '__attribute__((visibility("default"))) void run(const double* x, '
            "const double* u, const double* p, double* y, long n) {",
            f"  static casadi_real w[{f.sz_w()}]; static casadi_int iw[{max(f.sz_iw(), 1)}];",
            f"  const casadi_real* arg[{f.sz_arg()}]; casadi_real* res[{f.sz_res()}];",
            "  for (long i = 0; i < n; i++) {",
            f"    arg[0] = x + i * {n_x}; arg[1] = u + i * {n_u}; arg[2] = p;",
            f"    res[0] = y + i * {n_x}; {f.name()}(arg, res, iw, w, 0);",
            "  }",
            "}",
        ]
    )
    library = compile_source("bench_lanes_casadi", source)
    run = library.run
    run.argtypes = [ctypes.c_void_p] * 4 + [ctypes.c_long]
    return lambda *arrays: run(*(a.ctypes.data for a in arrays), len(arrays[0]))


def timed(rounds: int, calls: dict, members: int) -> dict:
    """Best seconds per member of each call (name -> callable without arguments) over
    ``rounds`` alternating rounds of 20 calls."""
    best = dict.fromkeys(calls, np.inf)
    for _ in range(rounds):
        for name, call in calls.items():
            start = time.perf_counter()
            for _ in range(20):
                call()
            best[name] = min(best[name], (time.perf_counter() - start) / 20 / members)
    return best


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--members", type=int, default=256, help="members per call, a multiple of 8"
    )
    parser.add_argument("--rounds", type=int, default=7, help="alternating rounds (best kept)")
    args = parser.parse_args()
    if args.members <= 0 or args.members % 8:
        parser.error(f"--members must be a positive multiple of 8, got {args.members}")
    print(f"softcurve {sc.__version__}, {os.cpu_count()} CPUs, load average {os.getloadavg()}")
    model = sc.Model(sc.presets.ifac2020())
    rng = np.random.default_rng(0)
    n = args.members
    x = np.zeros((n, model.n_state))
    x[:, 0] = 0.064 + rng.normal(0, 1e-3, n)
    x[:, 1:3] = rng.uniform(-20, 20, (n, 2))
    x[:, 3:6] = rng.normal(0, 1, (n, 3)) * [0.01, 10, 10]
    u = rng.normal(0, 1e-3, (n, model.n))
    p = np.ascontiguousarray(model.parameters)

    f = state_derivative(model, None, True)
    variants = {"CasADi's C": casadi_kernel(f)}
    expanded = f.expand()
    for width in (1, 2, 4, 8):
        variants[f"lanes of {width}"] = lanes_kernel(expanded, width, False)
    variants["lanes of 4, libmvec"] = lanes_kernel(expanded, 4, True)
    outputs = {name: np.zeros_like(x) for name in variants}
    calls = {name: partial(run, x, u, p, outputs[name]) for name, run in variants.items()}
    best = timed(args.rounds, calls, n)
    reference = outputs["CasADi's C"]
    scale = np.abs(reference).max(axis=0) + np.finfo(float).tiny
    print(f"\n1. state derivative of the paper robot, {n} members, best of {args.rounds} rounds")
    for name in variants:
        error = (np.abs(outputs[name] - reference) / scale).max()
        print(f"  {name:26s} {best[name] * 1e6:7.3f} us per member   difference {error:.1e}")

    shared = [p, np.array([PERIOD])]
    for section, (method, substeps) in enumerate((("RK4", 6), ("ROS34PW2", 16)), start=2):
        scalar = period_function(model, None, substeps, method, True, None, None, native=True)
        lanes = LanesMembers(lanes_period(model, None, substeps, method), threads=1)
        before, after = np.zeros((n, model.n_state + 6)), np.zeros((n, model.n_state + 6))
        outs = {"scalar period per member": before, "lanes period": after}
        periods = {
            "scalar period per member": lambda s=scalar, b=before: s.call_rows(
                [x, u, *shared], b, 0, n
            ),
            "lanes period": lambda s=lanes, a=after: s(x, u, *shared, a),
        }
        best = timed(args.rounds, periods, n)
        print(f"\n{section}. {method} x {substeps} period of {PERIOD * 1e3:.0f} ms, {n} members")
        scale = np.abs(before).max(axis=0) + 1e-3
        for name in periods:
            error = (np.abs(outs[name] - before) / scale).max()
            print(f"  {name:26s} {best[name] * 1e6:7.2f} us per member   difference {error:.1e}")
    print(f"\nload average after the runs: {os.getloadavg()}")


if __name__ == "__main__":
    main()
