"""Steps of one error-controlled integration of several batch members stacked into one
system, against the same members integrated alone.

Run:  python benchmarks/study_stacked_batch.py [--members 16] [--groups 1,2,4,8]

Issue 15 asks to measure "one stacked system for the whole batch": members that share
an integrator share its steps, so each group takes about the steps of its most violent
member, and the question is how many more than alone. The members are those of
``bench_batch.py`` (the paper's case, 10 s, initial curvature spread over [20, 30] 1/m
and initial rate over [1000, 2000] 1/(m s)); each group of ``g`` consecutive members is
one system of ``9 g`` states (each member scaled by its nominal scale, as softcurve's
driver scales them) integrated by CasADi's CVODES at rtol 1e-6 (absolute tolerance 1e-6
on the scaled states) divided by the square root of ``g``, as softcurve's driver sets a
group's tolerances (``groups.c`` of ``softcurve/simulation/solvers/c``: the group's norm then bounds
every member's own), with Adams and with BDF. Printed per group size: the mean over
the groups of CVODES's steps, the mean over the same members of their steps alone, and
the ratio (steps per member and group against alone: a group's step costs one
evaluation of every member's right-hand side, so this ratio is the extra work of
sharing the steps). Counts, not timings: the machine's load does not change them.
"""

from __future__ import annotations

import argparse

import casadi as ca
import numpy as np

import softcurve as sc
from softcurve.simulation.solvers._policy import nominal_scale
from softcurve.simulation.stepper._scheme import state_derivative

T_FINAL = 10.0


def initial_states(size: int) -> np.ndarray:
    """The members of ``bench_batch.py`` (same seed and spread), as states (size, 9)."""
    rng = np.random.default_rng(2020)
    q = np.column_stack([np.full(size, 0.064), rng.uniform(20, 30, size), np.zeros(size)])
    qd = np.column_stack([np.zeros(size), np.zeros(size), rng.uniform(1000, 2000, size)])
    return np.column_stack([q, qd, np.zeros((size, 3))])


def steps(model, f, states: np.ndarray, method: str) -> int:
    """CVODES's steps over ``T_FINAL`` for the members ``states`` stacked in one system."""
    scales = [nominal_scale(model, x0) for x0 in states]
    n = model.n_state
    x = ca.SX.sym("x", n * len(states))
    derivatives = [
        f(x[n * k : n * (k + 1)] * scale, np.zeros(model.n), model.parameters) / scale
        for k, scale in enumerate(scales)
    ]
    tolerance = 1e-6 / np.sqrt(len(states))  # the group's, as softcurve's driver sets it
    options = {"reltol": tolerance, "abstol": tolerance, "linear_multistep_method": method}
    options["max_num_steps"] = 1_000_000
    dae = {"x": x, "ode": ca.vertcat(*derivatives)}
    integrator = ca.integrator("stacked", "cvodes", dae, 0.0, T_FINAL, options)
    integrator(x0=np.concatenate([x0 / s for x0, s in zip(states, scales, strict=True)]))
    return int(integrator.stats()["nsteps"])


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--members", type=int, default=16, help="members in all")
    parser.add_argument("--groups", default="1,2,4,8", help="group sizes")
    args = parser.parse_args()
    model = sc.Model(sc.presets.ifac2020())
    f = state_derivative(model, None, True).expand()
    states = initial_states(args.members)
    sizes = [int(g) for g in args.groups.split(",")]
    print(
        f"paper case, {args.members} members, {T_FINAL:.0f} s, "
        "rtol 1e-6 / sqrt(group) (CasADi's CVODES)"
    )
    print(f"{'method':7s} {'group':>5s} {'steps per group':>16s} {'alone':>8s} {'ratio':>6s}")
    for method in ("adams", "bdf"):
        alone = np.array([steps(model, f, states[i : i + 1], method) for i in range(len(states))])
        for size in sizes:
            count = len(states) // size
            grouped = [
                steps(model, f, states[k * size : (k + 1) * size], method) for k in range(count)
            ]
            reference = alone[: count * size].mean()
            mean = float(np.mean(grouped))
            print(f"{method:7s} {size:5d} {mean:16.0f} {reference:8.0f} {mean / reference:6.2f}")


if __name__ == "__main__":
    main()
