"""Throughput of simulate_batch against a Python loop of simulate() calls.

Run:  python benchmarks/bench_batch.py [--size 200] [--loop 20] [--dt 0.01] [--repeat 5]
      [--nodes 11,6] [--lanes both|on|off]

The batch is the paper's case (preset ifac2020, one segment, 10 s, rtol 1e-6) with the
initial curvature kx spread over [20, 30] 1/m and the initial rate dky/dt over
[1000, 2000] 1/(m s), so that no two members are alike. Rows: a loop of simulate() over
``--loop`` members (scaled to the batch size); simulate_batch on 1 thread and on all
usable cores; ``simulate_batch(..., processes=cores)``, one worker process per core,
each on one thread (what ``softcurve sweep`` does); each with the members in groups of
four stacked into one CVODES system in vector lanes ("lanes", the default) and each
member alone ("alone", ``lanes=False``); for the default model (11 quadrature
nodes per segment) and for ``Model(robot, quadrature_nodes=6)``; then the previous route
(CasADi's CVODES integrator instead of softcurve's C driver) on threads and processes.

Columns: the median wall time of ``--repeat`` runs and that run's CPU time in this
process; simulated seconds per wall-clock second of the median run (the target of issue
6) and of the best run (this machine's two virtual cores share hardware with other
work: runs differ by 10-30 %); simulated seconds per CPU second of this
process (independent of other load on the machine; "-" when the work ran in other
processes); speed-up over the loop; ``diff single``: max difference from the loop's
simulate() results; ``error``: against a tight-tolerance run (default model, rtol 1e-10). Both
are the max over the loop's members, times and states of |x - x_ref| / (max_t |x_ref| +
the state's natural scale). Other processes on the machine slow every row; the load
average is printed.
"""

from __future__ import annotations

import argparse
import os
import platform
import time

import numpy as np

import softcurve as sc
from softcurve.simulation.batch._batch import default_threads, simulate_batch
from softcurve.simulation.batch._workers import stop_workers
from softcurve.simulation.solvers import _driver as native
from softcurve.simulation.solvers._policy import nominal_scale
from softcurve.symbolic.dynamics import DEFAULT_QUADRATURE_NODES

T_FINAL = 10.0
TARGET = 6000


def members(size: int) -> tuple[np.ndarray, np.ndarray]:
    rng = np.random.default_rng(2020)
    q0s = np.column_stack([np.full(size, 0.064), rng.uniform(20, 30, size), np.zeros(size)])
    qd0s = np.column_stack([np.zeros(size), np.zeros(size), rng.uniform(1000, 2000, size)])
    return q0s, qd0s


def best_of(repeat, run):
    """``((wall, cpu) of the run with the median wall time, best wall time), result``."""
    times, result = [], None
    for _ in range(repeat):
        wall, cpu = time.perf_counter(), time.process_time()
        result = run()
        times.append((time.perf_counter() - wall, time.process_time() - cpu))
    times.sort()
    return (times[len(times) // 2], times[0][0]), result


def previous(model, q0s, qd0s, args, threads, row) -> None:
    """The batch on CasADi's CVODES integrator, as before the C driver: on threads in this
    process, and in worker processes started with the driver switched off."""
    settings = {"t_final": T_FINAL, "dt": args.dt}
    with native.casadi_only():
        ((wall, cpu), best), x = best_of(
            args.repeat, lambda: simulate_batch(model, q0s, qd0s, threads=threads, **settings).x
        )
    row(f"previous: CasADi, {threads} thread(s)", wall, cpu, x, best)
    if threads > 1:
        stop_workers()
        os.environ["SOFTCURVE_NATIVE_CVODES"] = "0"  # read by the workers spawned next
        try:
            simulate_batch(model, q0s[:4], qd0s[:4], processes=threads, **settings)  # warm-up
            ((wall, cpu), best), x = best_of(
                args.repeat,
                lambda: simulate_batch(model, q0s, qd0s, processes=threads, **settings).x,
            )
        finally:
            stop_workers()
            del os.environ["SOFTCURVE_NATIVE_CVODES"]
        row(f"previous: CasADi, {threads} processes", wall, cpu, x, best)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=200, help="members in the batch")
    parser.add_argument("--loop", type=int, default=20, help="members simulated one by one")
    parser.add_argument("--dt", type=float, default=0.01, help="output interval [s]")
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument(
        "--nodes",
        default=f"{DEFAULT_QUADRATURE_NODES},6",
        help=f"quadrature nodes of the models to time (default {DEFAULT_QUADRATURE_NODES} and 6)",
    )
    parser.add_argument(
        "--lanes",
        choices=("both", "on", "off"),
        default="both",
        help="members in groups of four in vector lanes (on), each alone (off), or both",
    )
    args = parser.parse_args()

    model = sc.Model(sc.presets.ifac2020())
    q0s, qd0s = members(args.size)
    simulate_batch(
        model, q0s[:2], qd0s[:2], t_final=T_FINAL, dt=args.dt
    )  # warm-up: build integrators
    reference = simulate_batch(model, q0s, qd0s, t_final=T_FINAL, dt=args.dt, rtol=1e-10).x
    scale = np.abs(reference).max(axis=1, keepdims=True) + nominal_scale(
        model, np.zeros(model.n_state)
    )
    threads = default_threads()
    print(
        f"softcurve batch benchmark: paper case, {args.size} members x {T_FINAL:g} s, "
        f"rtol 1e-6, output every {args.dt:g} s"
    )
    print(
        f"  {platform.processor() or platform.machine()}, {os.cpu_count()} cores ({threads} "
        f"usable), load average {os.getloadavg()[0]:.1f}, Python {platform.python_version()}"
    )
    header = (
        f"{'how':<36}{'wall [s]':>9}{'cpu [s]':>9}{'sim s / s':>11}{'best':>7}{'per cpu s':>10}"
        f"{'speed-up':>10}{'diff single':>13}{'error':>10}"
    )
    print(header)
    print("-" * len(header))

    count = min(args.loop, args.size)
    ((wall, cpu), _), singles = best_of(
        1,
        lambda: [
            sc.simulate(model, q0s[i], qd0s[i], t_final=T_FINAL, dt=args.dt).x for i in range(count)
        ],
    )
    singles = np.array(singles)

    def row(label, wall, cpu, x, best=None):
        rate = args.size * T_FINAL / wall
        best = f"{args.size * T_FINAL / best:>7.0f}" if best else f"{'-':>7}"
        in_here = "processes" not in label  # the workers' CPU time is not counted
        per_cpu = f"{args.size * T_FINAL / cpu:>10.0f}" if in_here else f"{'-':>10}"
        diff = np.max(np.abs(x[:count] - singles) / scale[:count])
        error = np.max(np.abs(x[:count] - reference[:count]) / scale[:count])
        print(
            f"{label:<36}{wall:>9.2f}{cpu:>9.2f}{rate:>11.0f}{best}{per_cpu}"
            f"{rate / loop_rate:>10.1f}{diff:>13.1e}{error:>10.1e}"
        )

    x_loop = np.concatenate([singles, reference[count:]])  # only the first `count` are run
    loop_rate = count * T_FINAL / wall
    row(
        f"loop of simulate(), {model.quadrature_nodes} nodes ({count})",
        wall * args.size / count,
        cpu * args.size / count,
        x_loop,
    )
    for nodes in [int(n) for n in args.nodes.split(",")]:
        timed = (
            model
            if nodes == model.quadrature_nodes
            else sc.Model(sc.presets.ifac2020(), quadrature_nodes=nodes)
        )
        simulate_batch(timed, q0s[:4], qd0s[:4], t_final=T_FINAL, dt=args.dt)  # warm-up, lanes
        runs = [(f"{t} thread(s)", {"threads": t}) for t in sorted({1, threads})]
        if threads > 1:
            # warm-up: spawn the workers, load the model, build the integrators
            simulate_batch(timed, q0s[:8], qd0s[:8], t_final=T_FINAL, dt=args.dt, processes=threads)
            runs.append((f"{threads} processes", {"processes": threads}))
        ways = {"on": [True], "off": [False], "both": [True, False]}[args.lanes]
        runs = [
            (f"{'lanes' if lanes else 'alone'}, {label}", {**how, "lanes": lanes})
            for label, how in runs
            for lanes in ways
        ]
        for label, how in runs:
            ((wall, cpu), best), x = best_of(
                args.repeat,
                lambda h=how, m=timed: (
                    simulate_batch(m, q0s, qd0s, t_final=T_FINAL, dt=args.dt, **h).x
                ),
            )
            row(f"batch, {nodes} nodes, {label}", wall, cpu, x, best)
        if nodes == model.quadrature_nodes:
            previous(timed, q0s, qd0s, args, threads, row)
    print(f"Target (issue 15): >= {TARGET:,} simulated s per s on 2 cores (best column).")
    print("'previous' rows: CasADi's CVODES integrator, the route before softcurve's C driver.")
    print("cpu: this process only (the worker processes of the last rows are not counted);")
    nodes = model.quadrature_nodes
    print(f"error: against the {nodes}-node model at rtol 1e-10, so it includes the model error")
    print(f"of fewer quadrature nodes; diff single: against simulate(), {nodes} nodes.")


if __name__ == "__main__":
    main()
