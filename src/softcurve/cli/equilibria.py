"""``softcurve equilibria``: every equilibrium in a region, classified, as a table."""

from __future__ import annotations

import numpy as np

from . import Command, _options, _robots, in_cli_terms, write_figure
from ._models import build_model

ADVICE = {
    r"none inside the bounds: widen them, add starts or change the loads": (
        "none inside the box searched (sc.equilibria's default_bounds, docs/statics.md): try "
        "more --starts, another --seed, or other loads (--tip-force, --inputs, --gravity)"
    ),
}
"""The library's advice, in the options of ``softcurve equilibria`` (it has none for the
box searched, ``bounds`` of :func:`~softcurve.equilibria`)."""


def _add_arguments(parser) -> None:
    """The options of ``softcurve equilibria``."""
    _robots.add_arguments(parser)
    gravity = parser.add_mutually_exclusive_group()
    gravity.add_argument("--hanging", action="store_true", help="gravity (0, 0, +9.81) m/s^2")
    gravity.add_argument(
        "--gravity", nargs=3, type=float, metavar=("GX", "GY", "GZ"), help="gravity [m/s^2]"
    )
    parser.add_argument(
        "--inputs",
        "--pressures",
        dest="inputs",
        nargs="+",
        type=float,
        metavar="U",
        help="constant actuator inputs, one per input of the actuator: bellow pressures "
        "[Pa] or tendon tensions [N] (--pressures is the older name)",
    )
    parser.add_argument(
        "--tip-force", nargs=3, type=float, metavar=("FX", "FY", "FZ"), help="world tip force [N]"
    )
    parser.add_argument("--starts", type=int, default=48, help="starting points (default 48)")
    parser.add_argument("--seed", type=int, default=0, help="seed of the starting points")
    parser.add_argument(
        "--modes", action="store_true", help="also print natural frequencies and mode shapes"
    )
    parser.add_argument("--plot", metavar="PATH", help="save the backbones of the equilibria")
    parser.add_argument(
        "--html",
        metavar="PATH",
        help="also write the interactive 3-D viewer of the equilibria, one per slider "
        "position (one offline .html file; needs the extra 'viewer')",
    )


def _run(args) -> int:
    """Run ``softcurve equilibria``; returns the exit code."""
    from softcurve.analysis.equilibrium_results import EIGENVALUE_HEADING
    from softcurve.analysis.statics import equilibria, linearize, starts_count
    from softcurve.base.files import writable_file

    # every option before any work
    seed, starts = _options.seed(args.seed), _options.count(args.starts, "--starts")
    robot, actuator, environment = _robots.robot_and_actuator(args)  # before any folder
    starts = _options.as_option("--starts", starts_count, "starts", starts, robot.n)
    if args.plot:
        _options.figure_file(args.plot, "--plot")
    if args.html:
        _options.viewer("--html")
        writable_file(args.html, "--html")
    # in CasADi's virtual machine: one search evaluates the static balance fewer times
    # than its compile costs (StaticBalance, COMPILE_AFTER) up to about twenty segments,
    # and the model's compiled functions are not used
    model = build_model(robot, environment=environment, compile=False)
    loads = {}
    if args.hanging:
        loads["gravity"] = -robot.gravity
    elif args.gravity is not None:
        loads["gravity"] = args.gravity
    if args.inputs is not None:
        # named as the actuator names them: "tensions[0] = 12.0 N is outside ..."
        inputs = _options.as_option("--inputs", actuator.check_inputs, args.inputs)
        loads.update(actuator=actuator, inputs=inputs)
    if args.tip_force is not None:
        loads["tip_force"] = args.tip_force
    table = equilibria(model, starts=starts, seed=seed, **loads)
    gravity = np.asarray(loads.get("gravity", robot.gravity), dtype=float) + 0.0  # no -0.0
    print(
        f"softcurve equilibria: {robot.n_segments} {robot.element_word}(s), "
        f"gravity {np.array2string(gravity)} m/s^2"
    )
    if args.inputs is not None:
        unit = f" {actuator.input_unit}" if actuator.input_unit else ""
        print(f"  {actuator.input_name} {args.inputs}{unit}")
    print(f"  {in_cli_terms(table.message, ADVICE)}; {table.evaluations} residual evaluations")
    print(table.table())
    if len(table):  # the Hessian in q has mixed units (J per product of two coordinates')
        print(
            f"  {EIGENVALUE_HEADING}: the smallest eigenvalue of S K S, the potential's "
            "Hessian in the\n  dimensionless coordinates (l/l0, kx l0, ky l0) per segment "
            "(docs/statics.md)"
        )
    if args.modes:
        for k, e in enumerate(table):
            lin = linearize(model, e.q, **loads)
            print(f"#{k}: natural frequencies [Hz] {np.array2string(lin.frequencies, precision=4)}")
            print(f"    omega^2 [rad^2/s^2] {np.array2string(lin.omega_squared, precision=5)}")
            print("    mode shapes (columns):")
            print("    " + np.array2string(lin.modes, precision=4).replace("\n", "\n    "))
    if args.plot:
        write_figure(table.plot, args.plot, dpi=120)
        print(f"  figure: {args.plot}")
    if args.html and len(table):
        print(f"  viewer: {table.to_html(args.html)}")
    return 0 if table.success else 1


COMMAND = Command(
    "equilibria",
    help="find and classify the equilibria of a robot (stable, unstable, saddle, rings)",
    description="Solve N(q) = tau + H(q) u + J^T w from many starting points (u: the "
    "actuator's inputs, pressures or tensions, given by --inputs), deduplicate, "
    "classify each equilibrium by the Hessian of the potential (rings of equilibria under "
    "rotational symmetry are reported once) and print the table. Exit code 1 when none "
    "is found.",
    add_arguments=_add_arguments,
    run=_run,
)
