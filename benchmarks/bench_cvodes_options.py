"""The measurements behind the integrator's settings and the batch's limits (issue 6).

Run:  python benchmarks/bench_cvodes_options.py [--size 60]

Prints, for a batch of paper-case robots (10 s, rtol 1e-6, one thread):
1. simulated seconds per CPU second against the restart interval of the multistep method
   (``softcurve.simulation.solvers._policy.RESTART_INTERVAL`` is 1 s);
2. the same for other CVODES options on CasADi's integrator (the route before
   softcurve's C driver, whose rate is printed first): ``max_order`` (softcurve's default
   is 5, CasADi's 12; ``softcurve.simulation.solvers.MAX_ORDER``) and the linear solver,
   and without the switch to BDF once a member has settled
   (``softcurve.simulation.solvers.SETTLED_RATIO``);
3. the size of the compiled right-hand side against its exact state Jacobian (the
   integrator uses finite differences: 10 right-hand sides per Jacobian);
4. the CPU time of one worker process integrating 100 members alone and while a second
   worker does the same on the other core (a pure-Python loop for comparison);
5. Adams against BDF once the transient is over: 5 members integrated with Adams up to
   ``split`` seconds, then for the rest of the 10 s with each method (steps, Jacobians,
   wall time summed over the members): what the switch to BDF once settled is for.
"""

from __future__ import annotations

import argparse
import time
from concurrent.futures import ProcessPoolExecutor
from multiprocessing import get_context

import casadi as ca
import numpy as np

import softcurve as sc
from softcurve.simulation.batch import _batch as batch
from softcurve.simulation.solvers import _driver as native
from softcurve.simulation.solvers import _policy as _engines
from softcurve.simulation.solvers import _problem

T_FINAL = 10.0


def members(size: int, seed: int = 0):
    rng = np.random.default_rng(seed)
    q0 = np.column_stack([np.full(size, 0.064), rng.uniform(20, 30, size), np.zeros(size)])
    qd0 = np.column_stack([np.zeros(size), np.zeros(size), rng.uniform(1000, 2000, size)])
    return q0, qd0


def rate(model, q0, qd0, repeat: int = 3) -> float:
    """Simulated seconds per CPU second of this process, best of ``repeat``."""
    best = np.inf
    for _ in range(repeat):
        start = time.process_time()
        batch.simulate_batch(model, q0, qd0, t_final=T_FINAL, dt=0.01, threads=1)
        best = min(best, time.process_time() - start)
    return q0.shape[0] * T_FINAL / best


def with_options(extra: dict):
    """Route the batch's integrators through extra CVODES options."""
    original = _engines.cvodes_options

    def patched(multistep, *args, **kwargs):
        options = {**original(multistep, *args, **kwargs), **extra}
        if multistep == "bdf":  # BDF has orders 1-5 only
            options["max_order"] = min(options["max_order"], 5)
        return options

    _problem.cvodes_options = patched if extra else original  # Problem.cvodes_options reads it


def _worker(args) -> tuple[float, float]:
    kind, seed, size = args
    start = time.process_time()
    if kind == "python":
        total = 0.0
        for i in range(10_000_000):
            total += i * 0.5
    else:
        model = sc.Model(sc.presets.ifac2020())
        q0, qd0 = members(size, seed)
        batch.simulate_batch(model, q0[:2], qd0[:2], t_final=T_FINAL, dt=0.01, threads=1)  # warm-up
        start = time.process_time()
        batch.simulate_batch(model, q0, qd0, t_final=T_FINAL, dt=0.01, threads=1)
    return time.process_time() - start


def casadi_options(model, q0, qd0) -> None:
    """Section 2 on CasADi's integrator: its options."""
    variants = (
        {},
        {"max_order": 12},
        {"max_order": 8},
        {"max_order": 4},
        {"linear_solver": "csparse"},
        {"linear_solver": "lapacklu"},
    )
    for extra in variants:
        with_options(extra)
        print(f"   {str(extra or 'defaults'):>30}: {rate(model, q0, qd0):7.0f}")
    with_options({})
    default = _engines.SETTLED_RATIO
    _engines.SETTLED_RATIO = np.inf
    print(f"   {'Adams throughout (no BDF once settled)':>30}: {rate(model, q0, qd0):7.0f}")
    _engines.SETTLED_RATIO = default


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--size", type=int, default=60, help="members per batch")
    args = parser.parse_args()
    model = sc.Model(sc.presets.ifac2020())
    q0, qd0 = members(args.size)
    rate(model, q0[:2], qd0[:2], repeat=1)  # warm-up

    print(f"1. restart interval ({args.size} members, simulated s per CPU s)")
    defaults = batch.restart_segments.__defaults__
    for interval in (0.5, 1.0, 2.0, 1e9):
        batch.restart_segments.__defaults__ = (interval,)
        label = "never" if interval > T_FINAL else f"{interval:g} s"
        print(f"   {label:>8}: {rate(model, q0, qd0):7.0f}")
    batch.restart_segments.__defaults__ = defaults

    print(f"2. CVODES options (restarts every 1 s; defaults: max_order {_engines.MAX_ORDER})")
    print("   on CasADi's integrator, whose options these are (softcurve's C driver: first row)")
    print(f"   {'C driver (default route)':>30}: {rate(model, q0, qd0):7.0f}")
    with native.casadi_only():
        casadi_options(model, q0, qd0)

    print("3. instructions of the compiled right-hand side and of its exact state Jacobian")
    rhs = model.symbolic["rhs"]
    x, u = ca.SX.sym("x", model.n_state), ca.SX.sym("u", model.n)
    p = ca.SX.sym("p", model.parameters.size)
    jacobian = ca.Function("J", [x, u, p], [ca.cse(ca.jacobian(rhs(x, u, p), x))])
    ratio = jacobian.n_instructions() / rhs.n_instructions()
    print(f"   rhs {rhs.n_instructions()}, Jacobian {jacobian.n_instructions()} ({ratio:.1f} rhs;")
    print(f"   finite differences cost {model.n_state + 1} rhs)")

    print("4. CPU seconds of a worker, alone and with a second worker on the other core")
    with ProcessPoolExecutor(2, mp_context=get_context("spawn")) as pool:
        for kind in ("python", "softcurve"):
            jobs = [(kind, seed, 100) for seed in (0, 1)]
            alone = min(pool.submit(_worker, jobs[0]).result() for _ in range(3))
            paired = min(max(pool.map(_worker, jobs)) for _ in range(3))
            print(f"   {kind:>10}: alone {alone:.2f} s, paired {paired:.2f} s")

    print("5. the rest of 10 s after an Adams transient, with each method (5 members)")
    after_the_transient(model)


def after_the_transient(model) -> None:
    rng = np.random.default_rng(1)
    starts = [([0.064, rng.uniform(20, 30), 0.0], [0.0, 0.0, rng.uniform(1000, 2000)])
              for _ in range(5)]  # fmt: skip
    for split in (1.0, 2.0, 3.0):
        totals = {}
        for q0, qd0 in starts:
            x = sc.simulate(model, q0, qd0, t_final=split, dt=0.01, method="adams").x[-1]
            for method in ("adams", "bdf"):
                rest = (model, x[:3], x[3:6], x[6:])
                settings = dict(t_final=T_FINAL - split, dt=0.01, method=method)
                sc.simulate(*rest, **settings)  # warm-up
                start = time.perf_counter()
                run = sc.simulate(*rest, **settings)
                wall = time.perf_counter() - start
                steps, jacobians, time_sum = totals.get(method, (0, 0, 0.0))
                totals[method] = (
                    steps + run.stats["steps"],
                    jacobians + run.stats["jacobian_evaluations"],
                    time_sum + wall,
                )
        line = ", ".join(
            f"{m} {s} steps, {j} Jacobians, {1e3 * w:.1f} ms" for m, (s, j, w) in totals.items()
        )
        print(f"   after {split:g} s: {line}")


if __name__ == "__main__":
    main()
