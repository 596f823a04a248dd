"""Cost of robots of many segments: the model as algorithms over the chain.

For robots of N paper segments (``presets.ifac2020().with_segments(N)``) it prints, per N:

- ``ops``: operations of one forward-dynamics evaluation, the segment's Functions
  counted at each call (``n_instructions()`` of the Function and of each Function it
  calls), and per segment;
- ``inlined``: the same Function with every call inlined, where CasADi drops the terms
  a robot does not use (the one-segment model is built so);
- ``build [s]``: building the symbolic model (``Model(robot, compile=False).symbolic``,
  the segment's Functions included, which the first robot of a process builds);
- ``compile [s]``: building and compiling the model from an empty cache (``Model(robot)``),
  the first simulation's wait;
- ``in C [us]``: one forward-dynamics evaluation in a C loop (``bench_model.inside_c``),
  and per segment.

The comparison beside the figures is with N = 1 of the same run: the targets are a
compile time within 3x of N = 1 at N = 10, and a cost per segment within 1.5x.

With ``--cse`` it prints instead, per N, what CasADi's common-subexpression elimination
costs and saves on expressions holding the segments' calls (the forward dynamics and the
Christoffel matrix), the measurement behind building them without it
(``softcurve.symbolic.functions.build_functions``).

Run: ``python benchmarks/bench_chain.py [--segments 1 2 4 10 20] [--no-compile] [--cse]``
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import casadi as ca
from bench_model import inside_c

import softcurve as sc
from softcurve.symbolic.dynamics import build_dynamics
from softcurve.symbolic.functions import common_subexpressions


def executed_operations(function: ca.Function) -> int:
    """Operations of one evaluation of an SX Function: its own instructions, each call
    replaced by the called Function's operations (counted the same way). A call is told
    from the others by the sizes of its inputs and outputs, which differ between the
    segment's Functions."""
    callees = {}
    for name in function.get_function():
        callee = function.get_function(name)
        callees.setdefault((callee.nnz_in(), callee.nnz_out()), []).append(callee)
    total = 0
    for k in range(function.n_instructions()):
        if function.instruction_id(k) == ca.OP_CALL:
            size = (len(function.instruction_input(k)), len(function.instruction_output(k)))
            (callee,) = callees[size]
            total += executed_operations(callee)
        else:
            total += 1
    return total


def forward_dynamics_function(structure, inline) -> ca.Function:
    """The forward dynamics as the model builds it (``inline=None``), or inlined."""
    e = build_dynamics(structure, inline=inline)
    output = (
        ca.cse(e.forward_dynamics)
        if inline
        else common_subexpressions(e.forward_dynamics, len(structure))
    )
    return ca.Function("forward_dynamics", [e.q, e.qd, e.tau, e.lam, e.p], [output])


def cse_cost(n_segments: int) -> None:
    """Print the time of ``ca.cse`` and the operations before and after, per expression."""
    e = build_dynamics(sc.presets.ifac2020().with_segments(n_segments).structure())
    inputs = [e.q, e.qd, e.tau, e.lam, e.p]
    for name in ("forward_dynamics", "coriolis_matrix"):
        expression = getattr(e, name)
        start = time.perf_counter()
        eliminated = ca.cse(expression)
        seconds = time.perf_counter() - start
        before = ca.Function("f", inputs, [expression]).n_instructions()
        after = ca.Function("f", inputs, [eliminated]).n_instructions()
        print(
            f"N = {n_segments:>2} {name:>17}: cse {seconds:6.2f} s, "
            f"{before} -> {after} instructions ({100 * (1 - after / before):.0f} % fewer)",
            flush=True,
        )


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segments", type=int, nargs="+", default=[1, 2, 4, 6, 8, 10, 20])
    parser.add_argument("--no-compile", action="store_true", help="skip compiling (C columns)")
    parser.add_argument("--repeat", type=int, default=100_000, help="C loop evaluations at N = 1")
    parser.add_argument("--cse", action="store_true", help="the cost of cse around calls")
    args = parser.parse_args()
    if args.cse:
        for n_segments in args.segments:
            cse_cost(n_segments)
        return
    header = (
        f"{'N':>3} {'ops':>8} {'/seg':>7} {'x N=1':>6} {'inlined':>8} {'build [s]':>9} "
        f"{'compile [s]':>11} {'x N=1':>6} {'in C [us]':>9} {'/seg':>6} {'x N=1':>6}"
    )
    print(header)
    print("-" * len(header))
    first = None
    for n_segments in args.segments:
        robot = sc.presets.ifac2020().with_segments(n_segments)
        structure = robot.structure()
        ops = executed_operations(forward_dynamics_function(structure, None))
        inlined = forward_dynamics_function(structure, True).n_instructions()
        start = time.perf_counter()
        _ = sc.Model(robot, compile=False).symbolic
        build = time.perf_counter() - start
        compile_time = c_time = float("nan")
        if not args.no_compile:
            with tempfile.TemporaryDirectory() as cache:
                os.environ["SOFTCURVE_CACHE_DIR"] = cache
                start = time.perf_counter()
                model = sc.Model(robot)
                compile_time = time.perf_counter() - start
                c_time = inside_c(model, max(args.repeat // n_segments, 1000))
        row = (ops / n_segments, compile_time, c_time / n_segments)
        first = first or row
        print(
            f"{n_segments:>3} {ops:>8} {row[0]:>7.0f} {row[0] / first[0]:>6.2f} {inlined:>8} "
            f"{build:>9.2f} {compile_time:>11.1f} {compile_time / first[1]:>6.2f} "
            f"{c_time * 1e6:>9.2f} {row[2] * 1e6:>6.2f} {row[2] / first[2]:>6.2f}",
            flush=True,
        )
    print(
        "\nTargets (issue 32): compile time at N = 10 within 3x of N = 1; ops and time per "
        "segment at N = 10 and 20 within 1.5x of N = 1."
    )


if __name__ == "__main__":
    main()
