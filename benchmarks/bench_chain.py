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
  the first simulation's wait; ``cc CPU [s]``: the CPU seconds of the compiler processes
  in it (their user and system time), which other work on the machine does not change:
  the wait is about the largest file's share of them where there are free cores, and
  grows with the machine's load where there are not;
- ``in C [us]``: one forward-dynamics evaluation in a C loop (``bench_model.inside_c``),
  and per segment;
- ``instr``: the machine instructions of that evaluation, counted by callgrind
  (``bench_model.executed_instructions``, the portable build), and per segment: a count
  that does not depend on the CPU's caches nor on the machine's load, where the time per
  segment does (``--no-instructions`` skips it; NaN without valgrind).

The comparison beside the figures is with N = 1 of the same run: the targets are a
compile time within 3x of N = 1 at N = 10, and a cost per segment within 1.5x.

With ``--cse`` it prints instead, per N, what CasADi's common-subexpression elimination
costs and saves on expressions holding the segments' calls (the forward dynamics and the
Christoffel matrix), the measurement behind building them without it
(``softcurve.symbolic.functions.build_functions``).

With ``--stepper`` it prints instead, per N, the environments' stepper
(``Stepper(model, period=0.02)``, its default ROS34PW2 with 16 steps): the build of its
compiled period from an empty cache (the model's library built before, not counted), and
one period per member over ``--members`` members on one thread, best of five rounds of a
second, beside N = 1, and the route; ``--jacobian exact`` takes the model's exact
Jacobian (``Stepper(jacobian="exact")``) in place of differences, ``--jacobian both``
prints both beside each other, and ``--contact`` puts the robots under a ceiling
(:func:`ceiling`; a fresh Jacobian at every step).

With ``--sensitivity`` it prints instead, per N, the identification's sensitivities:
the instructions and the operations executed of the columns' right-hand side
``f_x S + f_d E`` for eight columns, as CasADi's forward derivative through the
segments' calls (``jtimes``) and as the Jacobian's product, the measurement behind
``softcurve.simulation.sensitivity._sensitivity.tangents``; and the first
``fit_trajectory`` of one evaluation (a free swing of 0.1 s, the tip segment's bending
stiffness free) from an empty cache, the model's library built before and not counted,
and the same fit again (the libraries loaded).

With ``--kind strain`` the robots are of constant-strain segments with all six strains
(:data:`STRAIN_SEGMENT`: the paper's segment's length and radius, silicone of 1 MPa) in
place of the paper's constant-curvature segments; ``--kind both`` prints both tables and
then, per N, the six-strain robot's figures over the constant-curvature robot's (the
targets: forward dynamics of one six-strain segment at most 2.5x one constant-curvature
segment; per segment at N = 10 and 20 within 1.6x of N = 1; a ten-segment six-strain
robot compiled within 3x of one segment).

Run: ``python benchmarks/bench_chain.py [--segments 1 2 4 10 20] [--no-compile] [--cse]
[--no-instructions] [--stepper [--members 64] [--jacobian exact|both] [--contact]]
[--sensitivity]
[--kind curvature|strain|both]``
"""

from __future__ import annotations

import argparse
import math
import os
import resource
import tempfile
import time

import casadi as ca
import numpy as np
from _timing import best_of  # benchmarks/_timing.py: a helper, not a benchmark
from bench_model import executed_instructions, inside_c

import softcurve as sc
from softcurve.simulation.stepper import Stepper
from softcurve.symbolic.dynamics import build_dynamics
from softcurve.symbolic.functions import common_subexpressions

STRAIN_SEGMENT = sc.StrainSegment.from_material(
    sc.Material(youngs_modulus=1e6, density=1070.0, poisson_ratio=0.5),
    sc.Section.circle(0.0235),
    rest_length=0.0644,
    damping=[1e-6, 1e-6, 1e-6, 1e-2, 1e-2, 1e-2],
)
"""A segment of all six strains, the paper's segment's size (silicone of 1 MPa)."""


def robot_of(kind: str, n_segments: int) -> sc.Robot:
    """The benchmark's robot of ``n_segments`` segments of ``kind`` (``"curvature"``: the
    paper's; ``"strain"``: :data:`STRAIN_SEGMENT`)."""
    if kind == "strain":
        return sc.Robot(segments=(STRAIN_SEGMENT,) * n_segments)
    return sc.presets.ifac2020().with_segments(n_segments)


BENT = (0.0644, 5.0, -2.0)
"""Each segment's state for the stepper and the fits: the rest length [m] and the
curvatures [1/m]."""


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


CEILING_GAP = 5e-4
"""With ``--contact``: the gap [m] between the robot's tip and a ceiling above it."""

NEAR_STRAIGHT = (0.064, 0.5, -0.2)
"""With ``--contact``: each segment's state, near straight under the ceiling."""

STRETCHING = (0.2, 0.0, 0.0)
"""With ``--contact``: each segment's rates [m/s, 1/(m s)], stretching into the ceiling
within the period (0.2 m/s closes the gap of one segment, 0.9 mm, in 5 ms)."""


def ceiling(n_segments: int) -> sc.Environment:
    """A plane :data:`CEILING_GAP` above the tip of N paper segments at rest, the stepper
    tests' contact law (stiff, damped, with friction), a body of radius 1 mm."""
    height = n_segments * sc.presets.ifac2020().segments[0].rest_length + CEILING_GAP
    plane = sc.Plane([0.0, 0.0, height], [0.0, 0.0, -1.0])
    law = sc.ContactLaw(stiffness=1e7, smoothing=1e-6, damping=1.0, friction=0.5)
    return sc.Environment([plane], law, contact_radius=[1e-3] * n_segments)


def contact_force(model, x0, period: float = 0.02, parts: int = 4) -> float:
    """The largest force [N] of the environment on the robot from ``x0`` at the ends of
    ``parts`` equal parts of ``period``: whether the robots of ``--contact`` touch within
    the period (the stepper in CasADi's virtual machine, no compile, the default step)."""
    forces = []
    for k in range(1, parts + 1):
        stepper = Stepper(model, period=period * k / parts, compiled=False)
        result = stepper.step(x0[None], np.zeros((1, model.n)))
        forces.append(np.linalg.norm(result.contact_force[0]))
    return float(max(forces))


def stepper_cost(
    n_segments: int, members: int, jacobian: str = "differences", contact: bool = False
) -> tuple[float, float, str, float]:
    """``(build [s], one period per member [s], route, contact force [N])`` of the default
    stepper of N segments with ``jacobian``, built from an empty cache; with ``contact``,
    stretching into :func:`ceiling` (a Jacobian at every step, the stepper's default
    there; the force is :func:`contact_force`'s, zero without contact)."""
    robot = sc.presets.ifac2020().with_segments(n_segments)
    with tempfile.TemporaryDirectory() as cache:
        os.environ["SOFTCURVE_CACHE_DIR"] = cache
        model = sc.Model(robot, environment=ceiling(n_segments) if contact else None)
        start = time.perf_counter()
        stepper = Stepper(model, period=0.02, threads=1, jacobian=jacobian)
        if contact:
            x0 = stepper.initial_state(
                np.tile(NEAR_STRAIGHT, n_segments), np.tile(STRETCHING, n_segments)
            )
        else:
            x0 = stepper.initial_state(np.tile(BENT, n_segments))
        x = np.repeat(x0[None], members, axis=0)
        u = np.zeros((members, model.n))
        result = stepper.step(x, u)
        build = time.perf_counter() - start
    assert result.success, result.message
    one, _ = best_of(1, lambda: stepper.step(x, u))
    calls = max(1, round(1.0 / one))  # a round of about a second
    best, _ = best_of(5, lambda: [stepper.step(x, u) for _ in range(calls)])
    force = contact_force(model, x0) if contact else 0.0
    return build, best / calls / members, stepper.route.name, force


def sensitivity_operations(n_segments: int, columns: int = 8) -> dict:
    """``{form: (instructions, operations)}`` of the columns' right-hand side of N
    segments for ``columns`` columns, ``form`` "through calls" or "product" (NaN on a
    revision before ``tangents``, for ``first_fit`` alone: ``PYTHONPATH=<rev>/src``)."""
    try:
        from softcurve.simulation.sensitivity._sensitivity import parameter_seeds, tangents
    except ImportError:
        return {"through calls": (math.nan, math.nan), "product": (math.nan, math.nan)}

    robot = sc.presets.ifac2020().with_segments(n_segments)
    rhs = sc.Model(robot, compile=False).casadi_rhs()
    n_x, n_d = rhs.size1_in(0), rhs.size1_in(2)
    xs, tau, ds = ca.SX.sym("x", n_x), ca.SX.sym("tau", robot.n), ca.SX.sym("d", n_d)
    v, scales = ca.SX.sym("v", n_x, columns), ca.SX.sym("scale", columns)
    f = rhs(xs, tau, ds)
    seeds = parameter_seeds(n_d, [j * n_d // columns for j in range(columns)], scales)
    counts = {}
    for form, through in (("through calls", True), ("product", False)):
        derivative = tangents(f, xs, v, ds, seeds, through)
        function = ca.Function("columns", [xs, ca.vec(v), tau, ds, scales], [derivative])
        counts[form] = (function.n_instructions(), executed_operations(function))
    return counts


def first_fit(n_segments: int) -> tuple[float, float]:
    """Seconds of the first ``fit_trajectory`` of one evaluation of N segments from an
    empty cache (the model's library built before), and of the same fit again."""
    from softcurve.identification.maps import tip_position_map

    robot = sc.presets.ifac2020().with_segments(n_segments).replace(gravity=[0.0, 0.0, 9.81])
    t = np.linspace(0.0, 0.1, 11)
    experiment = sc.Experiment(t, {axis: 0.0 * t for axis in "xyz"}, {})
    with tempfile.TemporaryDirectory() as cache:
        os.environ["SOFTCURVE_CACHE_DIR"] = cache
        model = sc.Model(robot)
        x0 = np.zeros(model.n_state)
        x0[: model.n] = np.tile(BENT, n_segments)
        seconds = []
        for _ in range(2):
            start = time.perf_counter()
            sc.fit_trajectory(
                model, experiment, output=tip_position_map(model), x0=x0,
                free=[f"segments[{n_segments - 1}].bending_stiffness.a1"], max_evaluations=1,
                processes=1,
            )  # fmt: skip
            seconds.append(time.perf_counter() - start)
        return seconds[0], seconds[1]


def _children_cpu() -> float:
    """User and system CPU seconds of this process's finished child processes [s]."""
    usage = resource.getrusage(resource.RUSAGE_CHILDREN)
    return usage.ru_utime + usage.ru_stime


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segments", type=int, nargs="+", default=[1, 2, 4, 6, 8, 10, 20])
    parser.add_argument("--no-compile", action="store_true", help="skip compiling (C columns)")
    parser.add_argument("--repeat", type=int, default=100_000, help="C loop evaluations at N = 1")
    parser.add_argument(
        "--no-instructions", action="store_true", help="skip counting instructions (valgrind)"
    )
    parser.add_argument("--cse", action="store_true", help="the cost of cse around calls")
    parser.add_argument("--stepper", action="store_true", help="the stepper's build and period")
    parser.add_argument("--members", type=int, default=64, help="members stepped (--stepper)")
    parser.add_argument(
        "--contact", action="store_true", help="the robots under a ceiling (--stepper)"
    )
    parser.add_argument(
        "--jacobian", choices=("differences", "exact", "both"), default="differences",
        help="the stepper's Jacobian (--stepper; both: beside each other)",
    )  # fmt: skip
    parser.add_argument("--sensitivity", action="store_true", help="the sensitivities' cost")
    parser.add_argument(
        "--kind", choices=("curvature", "strain", "both"), default="curvature",
        help="segments of constant curvature (the paper's), of six strains, or both",
    )  # fmt: skip
    args = parser.parse_args()
    if args.cse:
        for n_segments in args.segments:
            cse_cost(n_segments)
        return
    if args.sensitivity:
        print(f"{'N':>3} {'through calls: instr':>21} {'ops':>9} {'product: instr':>15} "
              f"{'ops':>9} {'first fit [s]':>13} {'x N=1':>6} {'again [s]':>9}")  # fmt: skip
        first = None
        for n_segments in args.segments:
            counts = sensitivity_operations(n_segments)
            seconds, again = first_fit(n_segments)
            first = first or seconds
            (a, b), (c, d) = counts["through calls"], counts["product"]
            print(
                f"{n_segments:>3} {a:>21.0f} {b:>9.0f} {c:>15.0f} {d:>9.0f} {seconds:>13.1f} "
                f"{seconds / first:>6.2f} {again:>9.2f}",
                flush=True,
            )
        return
    if args.stepper and args.jacobian == "both":
        print(f"{'N':>3} {'differences: build [s]':>22} {'period [us]':>11} {'route':>15} "
              f"{'exact: build [s]':>16} {'period [us]':>11} {'route':>15} "
              f"{'exact / differences':>19} {'largest contact force [N]':>25}")  # fmt: skip
        for n_segments in args.segments:
            default = stepper_cost(n_segments, args.members, contact=args.contact)
            exact = stepper_cost(n_segments, args.members, "exact", args.contact)
            print(
                f"{n_segments:>3} {default[0]:>22.1f} {default[1] * 1e6:>11.1f} {default[2]:>15} "
                f"{exact[0]:>16.1f} {exact[1] * 1e6:>11.1f} {exact[2]:>15} "
                f"{exact[1] / default[1]:>19.2f} {exact[3]:>25.3f}",
                flush=True,
            )
        return
    if args.stepper:
        print(
            f"{'N':>3} {'build [s]':>9} {'x N=1':>6} {'period/member [us]':>18} {'x N=1':>6} "
            f"{'route':>16}"
        )
        first = None
        for n_segments in args.segments:
            build, period, route, _ = stepper_cost(
                n_segments, args.members, args.jacobian, args.contact
            )
            first = first or (build, period)
            print(
                f"{n_segments:>3} {build:>9.1f} {build / first[0]:>6.2f} {period * 1e6:>18.1f} "
                f"{period / first[1]:>6.2f} {route:>16}",
                flush=True,
            )
        return
    kinds = ("curvature", "strain") if args.kind == "both" else (args.kind,)
    tables = {kind: chain_table(kind, args) for kind in kinds}
    if len(tables) == 2:
        print(
            f"\nsix strains over constant curvature, same N ({'N':>3} ops, compile, in C, instr):"
        )
        for n_segments in args.segments:
            a, b = tables["strain"][n_segments], tables["curvature"][n_segments]
            ratios = "  ".join(f"{x / y:>6.2f}" for x, y in zip(a, b, strict=True))
            print(f"{n_segments:>3}  {ratios}")
    print(
        "\nTargets: compile time at N = 10 within 3x of N = 1; ops, time and instructions per "
        "segment at N = 10 and 20 within 1.6x of N = 1; one six-strain segment's forward "
        "dynamics within 2.5x of one constant-curvature segment's."
    )


def chain_table(kind: str, args) -> dict:
    """Print the cost table of robots of ``kind``; return per N ``(ops, compile [s], in C
    [s], instructions)``."""
    header = (
        f"{'N':>3} {'ops':>8} {'/seg':>7} {'x N=1':>6} {'inlined':>8} {'build [s]':>9} "
        f"{'compile [s]':>11} {'x N=1':>6} {'cc CPU [s]':>10} {'in C [us]':>9} {'/seg':>6} "
        f"{'x N=1':>6} {'instr':>8} {'/seg':>6} {'x N=1':>6}"
    )
    print(f"\n{kind} segments")
    print(header)
    print("-" * len(header))
    first, rows = None, {}
    for n_segments in args.segments:
        robot = robot_of(kind, n_segments)
        structure = robot.structure()
        ops = executed_operations(forward_dynamics_function(structure, None))
        inlined = forward_dynamics_function(structure, True).n_instructions()
        start = time.perf_counter()
        _ = sc.Model(robot, compile=False).symbolic
        build = time.perf_counter() - start
        compile_time = c_time = compilers = instructions = float("nan")
        if not args.no_compile:
            with tempfile.TemporaryDirectory() as cache:
                os.environ["SOFTCURVE_CACHE_DIR"] = cache
                start, children = time.perf_counter(), _children_cpu()
                model = sc.Model(robot)
                compile_time = time.perf_counter() - start
                compilers = _children_cpu() - children
                c_time = inside_c(model, max(args.repeat // n_segments, 1000))
                if not args.no_instructions:
                    instructions = executed_instructions(model)
        row = (ops / n_segments, compile_time, c_time / n_segments, instructions / n_segments)
        rows[n_segments] = (ops, compile_time, c_time, instructions)
        first = first or row
        print(
            f"{n_segments:>3} {ops:>8} {row[0]:>7.0f} {row[0] / first[0]:>6.2f} {inlined:>8} "
            f"{build:>9.2f} {compile_time:>11.1f} {compile_time / first[1]:>6.2f} "
            f"{compilers:>10.1f} {c_time * 1e6:>9.2f} {row[2] * 1e6:>6.2f} "
            f"{row[2] / first[2]:>6.2f} {instructions:>8.0f} {row[3]:>6.0f} "
            f"{row[3] / first[3]:>6.2f}",
            flush=True,
        )
    return rows


if __name__ == "__main__":
    main()
