"""Why the ten-segment tendon plan of ``bench_planning.py --tendons`` cannot end at rest:
the controllability of the modes that do not settle by themselves within the horizon.

A plan with ``rest_at_end=True`` asks for zero rates and accelerations at the last node:
the robot at an equilibrium under its last inputs. The modes that decay within the
horizon by themselves (``-Re(lambda) T >= SETTLED``) settle whatever the inputs do; the
others must be steered by the inputs onto an equilibrium. For each chain of
``bench_planning``'s tendon robot (two sections of 10 cm, each in ``N / 2`` segments, six
tendons), this linearizes the actuated dynamics about the equilibrium that holds the tip
at the ``--tendons`` goal (``sc.inverse_statics``, then ``sc.linearize(...,
wrt="actuator")``), in the units the planner's IPOPT sees (the states over
``nominal_scale``, the tensions over their range), and prints those modes' count, their
range of rates, how many directions the inputs must steer, and the singular values of
their controllability Gramian over the horizon, each over the largest:
``W = integral_0^T exp(A t) B B^T exp(A^T t) dt`` restricted to the unsettled modes (their
right eigenvectors times the modal Gramian, so that the eigenvectors' scaling drops out),
with the equilibria's directions (``A^-1 B``: the last inputs may end the robot at any
equilibrium near the target's) projected out. Bringing an offset along a direction of
singular value ``s`` to an equilibrium takes inputs of ``1 / sqrt(s)`` per unit offset;
the last column counts the directions below :data:`STEERABLE`, out of the tensions'
reach.

Run:  python benchmarks/study_rest_at_end.py [--segments 2 4 10] [--horizon 1.0]
"""

from __future__ import annotations

import argparse

import numpy as np
from bench_planning import TENDON_GOAL, tendon_chain  # the robot of --tendons

import softcurve as sc
from softcurve.simulation.solvers import nominal_scale

SETTLED = 10.0
"""A mode with ``-Re(lambda) T`` at least this decays by ``exp(-10) = 4.5e-5`` within the
horizon by itself: it needs no input to settle."""

STEERABLE = 1e-3
"""Singular values (over the largest) counted as steerable: below it a unit offset needs
inputs more than 32 times those that move the best-steered direction (``1 / sqrt(s)``),
beyond the factor of 25 the tensions' bounds span (0.2 to 5 N)."""

ROUNDING = 1e-16
"""Singular values below this fraction of the largest are rounding: printed as such."""


def gramian_singular_values(A, B, horizon):
    """The unsettled modes' rates, and the singular values over the largest of their
    Gramian over ``horizon``, the equilibria's directions projected out (as many as the
    modes less the directions the last inputs' equilibria span among them; none where
    those span all)."""
    rates, vectors = np.linalg.eig(A)
    to_modes = np.linalg.inv(vectors)  # rows: the left eigenvectors, dual to the right
    unsettled = -rates.real * horizon < SETTLED
    lam, b = rates[unsettled], (to_modes @ B)[unsettled]
    exponent = lam[:, None] + lam.conj()[None, :]
    safe = np.where(exponent == 0, 1.0, exponent)  # an undamped pair: the limit T
    share = np.where(exponent == 0, horizon, np.expm1(exponent * horizon) / safe)
    modal = (b @ b.conj().T) * share
    right = vectors[:, unsettled]
    gramian = right @ modal @ right.conj().T  # the states' units, whatever the scaling
    # the equilibria's directions within the unsettled modes (the oblique projection on
    # them), which the last inputs may end on
    along = right @ to_modes[unsettled] @ np.linalg.solve(A, B)
    equilibria = np.linalg.svd(along, full_matrices=False)[0]
    kept = lam.size - np.linalg.matrix_rank(along)
    away = np.eye(A.shape[0]) - equilibria @ equilibria.conj().T
    singular = np.linalg.svd(away @ gramian @ away.conj().T, compute_uv=False)[:kept]
    return lam, singular / singular[0] if kept else singular  # none: the inputs place all


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segments", type=int, nargs="+", default=[2, 4, 10],
                        help="segments of the chain, even")  # fmt: skip
    parser.add_argument("--horizon", type=float, default=1.0, help="the plan's horizon [s]")
    args = parser.parse_args()
    odd = [n for n in args.segments if n < 2 or n % 2]
    if odd:
        parser.error(f"--segments must be even numbers of at least 2, got {odd}")
    if not args.horizon > 0:
        parser.error(f"--horizon must be positive, got {args.horizon}")
    print(f"horizon {args.horizon:g} s; modes with -Re(lambda) T < {SETTLED:g} must be steered")
    print("| segments | inputs | states | unsettled modes | their rates [1/s] | directions to "
          f"steer | Gramian's singular values / largest | below {STEERABLE:g} |")  # fmt: skip
    print("| --- | --- | --- | --- | --- | --- | --- | --- |")
    for segments in args.segments:
        model, actuator, _ = tendon_chain(segments)
        held = sc.inverse_statics(model, actuator, TENDON_GOAL)
        if not held.success:
            print(f"| {segments} | inverse statics failed: {held.message} |")
            continue
        linear = sc.linearize(model, held.q, wrt="actuator", actuator=actuator,
                              inputs=held.inputs)  # fmt: skip
        x = np.concatenate([held.q, np.zeros(model.n)])
        scale = nominal_scale(model, x)
        lower, upper = sc.Transcription(model, actuator).input_bounds
        A = linear.A / scale[:, None] * scale[None, :]
        B = linear.B / scale[:, None] * (upper - lower)[None, :]
        lam, singular = gramian_singular_values(A, B, args.horizon)
        shown = " ".join(f"{s:.0e}" if s >= ROUNDING else f"<{ROUNDING:.0e}" for s in singular)
        shown = shown or "none: the last inputs hold every mode on an equilibrium"
        rates = f"{-lam.real.max():.3g} to {-lam.real.min():.3g}"
        beyond = np.count_nonzero(singular < STEERABLE)
        print(f"| {segments} | {B.shape[1]} | {A.shape[0]} | {lam.size} | {rates} | "
              f"{singular.size} | {shown} | {beyond} |")  # fmt: skip


if __name__ == "__main__":
    main()
