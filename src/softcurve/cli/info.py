"""``softcurve info``: the paper's robot, its model, and what the compiled model costs."""

from __future__ import annotations

import time

import numpy as np

from . import Command


def _add_arguments(parser) -> None:
    """The options of ``softcurve info``."""


def _run(args) -> int:
    """Run ``softcurve info``; returns the exit code."""
    from softcurve.analysis.loads import rest_configuration
    from softcurve.compiled import Model
    from softcurve.description import presets

    robot = presets.ifac2020()
    start = time.perf_counter()
    model = Model(robot)
    build = time.perf_counter() - start
    segment = robot.segments[0]
    q0 = np.array([0.064, 25.0, 0.0])
    qd0 = np.array([0.0, 0.0, 1500.0])
    straight = rest_configuration(robot)
    print("softcurve: preset ifac2020 (Caasenbrood et al., IFAC 2020)")
    print(f"  segments {robot.n_segments}, coordinates n = {model.n}, creep states {model.n_creep}")
    print(f"  m = {segment.mass} kg, l0 = {segment.rest_length} m, r = {segment.radius} m")
    print(f"  gravity {robot.gravity.tolist()} m/s^2")
    print(f"  compiled library: {model.compiled_library or 'none (CasADi virtual machine)'}")
    print(f"  model ready in {build:.3f} s")
    print(f"  D(straight) diagonal: {np.diag(model.mass_matrix(straight)).tolist()}")
    print(f"  paper initial state q0 = {q0.tolist()}, qd0 = {qd0.tolist()}")
    print(f"    energy T + V = {model.energy(q0, qd0):.6g} J")
    print(f"    qdd = {model.forward_dynamics(q0, qd0).tolist()}")
    print(f"    tip position = {model.tip_pose(q0).position.tolist()} m")
    return 0


COMMAND = Command(
    "info",
    help="summarize the paper's study case (preset ifac2020) and its compiled model",
    description="Build the compiled model of the paper's study case and print its "
    "parameters, the straight configuration's inertia and energy, and timings.",
    add_arguments=_add_arguments,
    run=_run,
)
