"""Gradients of rollouts (``sc.gradient``) against one forward simulation (``sc.simulate``)
on the paper's case: preset ifac2020, q0 = (0.064, 25, 0), qd0 = (0, 0, 1500), 10 s.

Run:  python benchmarks/bench_gradient.py [--intervals 1 100 1000] [--repeat 3]
      python benchmarks/bench_gradient.py --methods | --radau | --adams | --adams-atol
      python benchmarks/bench_gradient.py --costs | --flags
      python benchmarks/bench_gradient.py --chain 1 2 4

The cost is the integral of the squared coordinate rates over the 10 s (``running``,
integrated with the state) plus the squared tip height at every output time; the
inputs are zero generalized forces, one sample per output interval. For each number of
output intervals it prints the first call (the right-hand side and its derivatives
compiled, or loaded from the cache, and the CasADi Functions built) and the best of
``--repeat`` calls after it, along the parameters and the initial state (one integration
through the output times) and along the inputs too (one integration per interval), each
beside the best of ``simulate``'s default run (1 ms outputs, its compiled driver) as
their ratio, the issue's target being 5x. The gradient is ``method="auto"``: the discrete
adjoint of the driver's Radau IIA where the driver runs.

``--methods`` compares the three methods (``method=``) along the initial state alone
(9 seeds) and along the parameters and the initial state (58) on 100 intervals: what
``GRADIENT_METHODS`` says. ``--radau`` runs the discrete adjoint at several tolerances
(``rtol=``) on 100 intervals: the largest error of its states at the output times
against ``simulate`` at rtol 1e-12, each state over its nominal size, beside that of
``simulate``'s default run; its time against ``simulate``'s; how far its gradient lies
from CVODES's adjoint at 1e-10 (the largest difference over the largest entry); and how
far its derivative along the initial curvature lies from central differences of its own
values (relative; the derivative holds the step sizes, the differences move them).
``--adams`` compares the driver's two adjoints: on one output interval along the
parameters and the initial state, the continuous adjoint (``adams-adjoint``) at several
tolerances, its time against ``simulate``'s and how far it lies from CVODES's adjoint at
1e-10 (the largest difference over the largest entry, along the parameters and the
initial state), beside the discrete one at its default; then both at their defaults on
1, 10, 30 and 100 output intervals (the cost reads the tip at every output time, where
the continuous adjoint starts afresh), and what ``method="auto"`` takes
(``ADAMS_WITHIN``). ``--adams-atol`` measures the continuous adjoint's absolute tolerance
(``softcurve.simulation.solvers._adjoint.ADAMS_ATOL``, set for the run): on
``tests/test_gradient.py``'s case (pressures changing every 25 ms, a cost reading every
output time, rtol 1e-7) its distance from CVODES's adjoint at 1e-12, and on one output
interval of the paper swing its time and backward steps; then the second pass where the
adjoint decays (``ADAMS_DECAYED``; 0 runs one pass): the tip's height after 1 and 2 s of
the paper swing, each gradient's distance from CVODES's at 1e-12 along the initial
state and the parameters, beside the discrete adjoint's.

``--chain N ...`` runs chains of N paper segments, 1 s from a bent start at rest, 10
output intervals, the squared tip position at the end, along the parameters and the
initial state: the discrete adjoint (with its steps and reverse-mode evaluations a
step), the continuous one (its steps forward and backward, its evaluations a backward
step) and CVODES's adjoint (first call and best of ``--repeat``) beside ``simulate``'s
default run of the same second. ``--costs`` times other costs on 100 intervals along the
parameters and the initial state: the integral alone, the tip's height at the end, the
squared state at every output time, with the method ``auto`` takes.
``--flags`` compiles the right-hand side with its first derivatives under
``DERIVATIVE_FLAGS`` and under the model's flags, each in an empty cache, and times a
CVODES adjoint on 100 intervals with each (``DERIVATIVE_FLAGS``).
"""

from __future__ import annotations

import argparse
import os
import tempfile
import time

import casadi as ca
import numpy as np
from _timing import best_of  # benchmarks/_timing.py: a helper, not a benchmark

import softcurve as sc
from softcurve.compiled import _build as build
from softcurve.control import _transcription as transcription

Q0, QD0, DURATION = (0.064, 25.0, 0.0), (0.0, 0.0, 1500.0), 10.0
TARGET_RATIO = 5.0
"""Issue 47: the gradient along all parameters within 5x one forward simulation."""


def cost(trajectory):
    """The running integral plus the squared tip height at every output time [m^2]."""
    return trajectory.integral[0, -1] + ca.sumsqr(trajectory.tip[2, :]) / trajectory.t.size


def running(x, u, p):
    """The squared coordinate rates, scaled to the order of one."""
    return ca.sumsqr(x[3:6] / ca.DM([1.0, 1e3, 1e3]))


def one_gradient(
    model, intervals: int, method: str = "auto", wrt=sc.control.WITH_RESPECT_TO, of=cost,
    rtol=None,
):  # fmt: skip
    t = np.linspace(0.0, DURATION, intervals + 1)
    return sc.gradient(model, of, Q0, QD0, t=t, running=running, method=method, wrt=wrt, rtol=rtol)


RADAU_TOLERANCES = (1e-4, 3e-5, 1e-5, 1e-6, 1e-8)


ADAMS_TOLERANCES = (1e-6, 1e-7, 1e-8)


def apart(g, reference, wrt) -> float:
    """The largest difference of ``g`` from ``reference`` over its largest entry, along
    each of ``wrt``."""
    return max(np.max(np.abs(getattr(g, w) - getattr(reference, w)))
               / np.max(np.abs(getattr(reference, w))) for w in wrt)  # fmt: skip


def adams(model, forward: float, repeat: int) -> None:
    """The continuous adjoint against the discrete one (``--adams``)."""
    wrt = ("parameters", "x0")
    reference = one_gradient(model, 1, "adjoint", wrt)
    print("\n| method | rtol | gradient [ms] | / simulate | from CVODES's adjoint | "
          "steps forward, backward |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- |")
    for method, rtol in (("radau-adjoint", None),
                         *(("adams-adjoint", r) for r in ADAMS_TOLERANCES)):  # fmt: skip
        one_gradient(model, 1, method, wrt, rtol=rtol)
        wall, g = best_of(repeat, lambda m=method, r=rtol: one_gradient(model, 1, m, wrt,
                                                                          rtol=r))  # fmt: skip
        steps = f"{g.stats['steps']}, {g.stats.get('backward_steps', 'taped')}"
        default = {None: " (default)", sc.control.ADAMS_TOLERANCE: " (default)"}
        label = f"{rtol or sc.control.RADAU_TOLERANCE:g}{default.get(rtol, '')}"
        print(f"| {method} | {label} | {1e3 * wall:.1f} | "
              f"{wall / forward:.1f}x | {apart(g, reference, wrt):.1e} | {steps} |")  # fmt: skip
    print("\n| output intervals | radau-adjoint [ms] | adams-adjoint [ms] | auto takes |")
    print("| --- | --- | --- | --- |")
    for intervals in (1, 10, 30, 100):
        walls = []
        for method in ("radau-adjoint", "adams-adjoint"):
            one_gradient(model, intervals, method, wrt)
            walls.append(best_of(repeat, lambda k=intervals, m=method: one_gradient(
                model, k, m, wrt))[0])  # fmt: skip
        auto = one_gradient(model, intervals, "auto", wrt).method
        print(f"| {intervals} | {1e3 * walls[0]:.1f} | {1e3 * walls[1]:.1f} | {auto} |")


def test_case():
    """tests/test_gradient.py's case: the robot of three quadrature nodes under three
    bellows whose pressures change every 25 ms, a cost reading every output time."""
    model = sc.Model(sc.presets.ifac2020(), quadrature_nodes=3)
    bellows = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)
    t = np.linspace(0.0, 0.15, 7)
    pressures = 1e4 + 2e4 * np.random.default_rng(47).random((t.size, 3))  # [Pa]

    def of(trajectory):
        bends = ca.sumsqr(trajectory.q[1:3, :]) / trajectory.t.size
        return trajectory.tip[2, -1] + 1e-4 * bends + 1e-6 * trajectory.integral[0, -1]

    def run(method, rtol=None):
        return sc.gradient(model, of, [0.064, 5.0, -2.0], [0.0, 40.0, 0.0], t=t,
                           inputs=pressures, actuator=bellows, method=method, rtol=rtol,
                           running=lambda x, u, p: ca.sumsqr(x[4:6]))  # fmt: skip

    return run


ATOL_SCALES = (1.0, 0.1, 0.01)


def adams_atol(model, repeat: int) -> None:
    """``--adams-atol``: the continuous adjoint's absolute tolerance and its second pass."""
    from softcurve.simulation.solvers import _adjoint

    run = test_case()
    tight = run("adjoint", 1e-12)
    wrt = ("parameters", "x0")
    default = _adjoint.ADAMS_ATOL
    print("\n| ADAMS_ATOL | test case: from CVODES's at 1e-12 | paper swing [ms] | "
          "backward steps |")  # fmt: skip
    print("| --- | --- | --- | --- |")
    for scale in ATOL_SCALES:
        _adjoint.ADAMS_ATOL = scale
        try:
            error = apart(run("adams-adjoint"), tight, ("x0", "inputs", "parameters"))
            one_gradient(model, 1, "adams-adjoint", wrt)
            wall, g = best_of(repeat, lambda: one_gradient(model, 1, "adams-adjoint", wrt))
        finally:
            _adjoint.ADAMS_ATOL = default
        print(f"| {scale:g} | {error:.1e} | {1e3 * wall:.1f} | {g.stats['backward_steps']} |")
    decayed = _adjoint.ADAMS_DECAYED
    print("\n| tip's height after [s] | gradient | passes | from CVODES's along x0 | "
          "along the parameters | [ms] |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- |")
    for horizon in (1.0, 2.0):
        t = np.linspace(0.0, horizon, 101)

        def tip(method, rtol=None, t=t):
            return sc.gradient(model, lambda tr: tr.tip[2, -1], Q0, QD0, t=t, method=method,
                               rtol=rtol)  # fmt: skip

        reference = tip("adjoint", 1e-12)
        for name, method, threshold in (("adams-adjoint, one pass", "adams-adjoint", 0.0),
                                        ("adams-adjoint", "adams-adjoint", decayed),
                                        ("radau-adjoint", "radau-adjoint", decayed)):  # fmt: skip
            _adjoint.ADAMS_DECAYED = threshold
            try:
                tip(method)
                wall, g = best_of(repeat, lambda m=method: tip(m))
            finally:
                _adjoint.ADAMS_DECAYED = decayed
            passes = g.stats.get("backward_passes", "")
            print(f"| {horizon:g} | {name} | {passes} | {apart(g, reference, ('x0',)):.1e} | "
                  f"{apart(g, reference, ('parameters',)):.1e} | {1e3 * wall:.1f} |")  # fmt: skip


def radau(model, forward: float, repeat: int) -> None:
    """The discrete adjoint's accuracy and time at several tolerances (``--radau``)."""
    t = np.linspace(0.0, DURATION, 101)
    start = np.concatenate([Q0, QD0, np.zeros(model.n_state - 2 * model.n)])
    nominal = sc.simulation.solvers.state_scale(model, start)

    def states(**settings):
        run = sc.simulate(model, Q0, QD0, t_final=DURATION, dt=t[1], **settings)
        return np.hstack([run.q, run.qd, run.lam])

    tight = states(rtol=1e-12)
    error = np.max(np.abs(states() - tight) / nominal)
    print(f"\nsimulate's default run: error {error:.1e} of the states' scales")
    wrt = ("parameters", "x0")
    reference = one_gradient(model, 100, "adjoint", wrt)
    largest = np.max(np.abs(reference.parameters))
    print("\n| rtol | error of the states | gradient [ms] | / simulate | "
          "from CVODES's adjoint | from its own differences |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- |")
    for rtol in RADAU_TOLERANCES:
        one_gradient(model, 100, "radau-adjoint", wrt, rtol=rtol)
        wall, g = best_of(repeat, lambda r=rtol: one_gradient(model, 100, "radau-adjoint", wrt,
                                                                rtol=r))  # fmt: skip
        own = np.max(np.abs(g.x - tight) / nominal)
        apart = np.max(np.abs(g.parameters - reference.parameters)) / largest
        step = 1e-4 * abs(Q0[1])  # the curvature [1/m]

        def value(shift, r=rtol):
            q = np.array(Q0) + np.array([0.0, shift, 0.0])
            return sc.gradient(model, cost, q, QD0, t=t, running=running, wrt="x0",
                               method="radau-adjoint", rtol=r).value  # fmt: skip

        difference = (value(step) - value(-step)) / (2 * step)
        own_difference = abs(difference - g.x0[1]) / abs(g.x0[1])
        print(f"| {rtol:g} | {own:.1e} | {1e3 * wall:.1f} | {wall / forward:.1f}x | "
              f"{apart:.1e} | {own_difference:.1e} |")  # fmt: skip


COSTS = {
    "the integral alone": lambda trajectory: trajectory.integral[0, -1],
    "the tip's height at the end": lambda trajectory: trajectory.tip[2, -1],
    "the squared state at every output time": lambda trajectory: ca.sumsqr(trajectory.x),
}


def costs(model, repeat: int) -> None:
    print("\n| cost (100 intervals, along parameters and x0) | gradient [s] | auto takes |")
    print("| --- | --- | --- |")
    for name, of in COSTS.items():

        def run(of=of):
            return one_gradient(model, 100, wrt=("parameters", "x0"), of=of)

        run()
        wall, g = best_of(repeat, run)
        print(f"| {name} | {wall:.3f} | {g.method} |")


def flags(model, repeat: int) -> None:
    print("\n| flags | compile [s] | gradient [s] (100 intervals) |")
    print("| --- | --- | --- |")
    for chosen in (transcription.DERIVATIVE_FLAGS, build.FUNCTION_FLAGS):
        with tempfile.TemporaryDirectory() as folder:
            os.environ["SOFTCURVE_CACHE_DIR"] = folder
            transcription.DERIVATIVE_FLAGS = chosen
            began = time.perf_counter()
            sc.Transcription(model).compiled_rhs(1)
            compiled = time.perf_counter() - began
            one_gradient(model, 100, wrt=("parameters", "x0"))
            wall, _ = best_of(repeat, lambda: one_gradient(model, 100, wrt=("parameters", "x0")))
            print(f"| {' '.join(chosen)} | {compiled:.1f} | {wall:.3f} |")


def chains(segments, repeat: int) -> None:
    """``--chain``: the gradient of chains of paper segments against ``simulate``."""
    print("\n| N | method | first call [s] | gradient [ms] | simulate [ms] | / simulate | steps "
          "(backward) | reverse-mode evaluations a step |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    t = np.linspace(0.0, 1.0, 11)
    for n in segments:
        model = sc.Model(sc.presets.ifac2020().with_segments(n))
        q0, qd0 = np.tile([0.064, 5.0, 0.0], n), np.zeros(3 * n)
        sc.simulate(model, q0, qd0, t_final=1.0)
        forward, _ = best_of(repeat, lambda m=model, q=q0, v=qd0: sc.simulate(m, q, v, t_final=1.0))
        for method in ("radau-adjoint", "adams-adjoint", "adjoint"):

            def run(m=model, q=q0, method=method):
                return sc.gradient(m, lambda tr: ca.sumsqr(tr.tip[:, -1]), q, t=t,
                                   wrt=("parameters", "x0"), method=method)  # fmt: skip

            began = time.perf_counter()
            assert run().success
            cold = time.perf_counter() - began
            wall, g = best_of(repeat, run)
            steps = g.stats.get("steps", "")
            if "backward_steps" in g.stats:  # the continuous adjoint: a step of the backward's
                steps = f"{steps} ({g.stats['backward_steps']})"
                each = g.stats["backward_vjp_evaluations"] / g.stats["backward_steps"]
            else:
                each = g.stats["vjp_evaluations"] / steps if steps else None
            each = "" if each is None else f"{each:.1f}"
            print(f"| {n} | {method} | {cold:.1f} | {1e3 * wall:.1f} | {1e3 * forward:.1f} | "
                  f"{wall / forward:.0f}x | {steps} | {each} |")  # fmt: skip


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--intervals", type=int, nargs="+", default=[1, 100, 1000])
    parser.add_argument("--repeat", type=int, default=3)
    parser.add_argument("--methods", action="store_true")
    parser.add_argument("--radau", action="store_true")
    parser.add_argument("--adams", action="store_true")
    parser.add_argument("--adams-atol", action="store_true")
    parser.add_argument("--chain", type=int, nargs="+")
    parser.add_argument("--costs", action="store_true")
    parser.add_argument("--flags", action="store_true")
    args = parser.parse_args()
    model = sc.Model(sc.presets.ifac2020())
    sc.simulate(model, Q0, QD0)  # the driver compiled or loaded
    forward, run = best_of(5, lambda: sc.simulate(model, Q0, QD0))
    steps = run.stats["steps"]
    print(f"simulate, 10 s, 1 ms outputs: {1e3 * forward:.1f} ms (best of 5; {steps} steps)")
    if args.costs:
        costs(model, args.repeat)
        return
    if args.flags:
        flags(model, args.repeat)
        return
    if args.radau:
        radau(model, forward, args.repeat)
        return
    if args.adams:
        adams(model, forward, args.repeat)
        return
    if args.adams_atol:
        adams_atol(model, args.repeat)
        return
    if args.chain:
        chains(args.chain, args.repeat)
        return
    if args.methods:
        methods = sc.control.GRADIENT_METHODS
        print(f"\n| seeds | {' [s] | '.join(methods)} [s] |")
        print("| --- |" + " --- |" * len(methods))
        for wrt, seeds in ((("x0",), 9), (("parameters", "x0"), 58)):
            times = []
            for method in methods:
                one_gradient(model, 100, method, wrt)  # compiled and built
                wall, _ = best_of(
                    args.repeat, lambda m=method, w=wrt: one_gradient(model, 100, m, w)
                )
                times.append(wall)
            print(f"| {seeds} ({', '.join(wrt)}) | " + " | ".join(f"{w:.3f}" for w in times) + " |")
        return
    print("\n| output intervals | along | first call [s] | gradient [ms] | / simulate | target |")
    print("| --- | --- | --- | --- | --- | --- |")
    for intervals in args.intervals:
        for wrt in (("parameters", "x0"), sc.control.WITH_RESPECT_TO):
            began = time.perf_counter()
            first = one_gradient(model, intervals, wrt=wrt)
            cold = time.perf_counter() - began
            assert first.success, first.message
            wall, _ = best_of(args.repeat, lambda k=intervals, w=wrt: one_gradient(model, k, wrt=w))
            print(f"| {intervals} | {', '.join(wrt)} | {cold:.2f} | {1e3 * wall:.1f} | "
                  f"{wall / forward:.1f}x | {TARGET_RATIO:g}x |")  # fmt: skip


if __name__ == "__main__":
    main()
