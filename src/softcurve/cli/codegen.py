"""``softcurve codegen``: standalone C of the dynamics and H(q) for embedded controllers."""

from __future__ import annotations

import shlex
import subprocess
import sys

from softcurve.base.progress import elapsed_line

from . import Command, _options, _robots
from ._models import build_model


def _add_arguments(parser) -> None:
    """The options of ``softcurve codegen``."""
    _robots.add_arguments(parser)
    parser.add_argument(
        "--output", "-o", default="softcurve_c", help="directory (default ./softcurve_c)"
    )
    parser.add_argument("--prefix", default="softcurve_model", help="C name prefix")
    parser.add_argument(
        "--parameters-as-input",
        action="store_true",
        help="take the parameter vector p as the last input instead of compiling it in",
    )
    parser.add_argument("--no-actuator", action="store_true", help="do not export H(q)")
    parser.add_argument("--check", action="store_true", help="compile and run the test program")


def _run(args) -> int:
    """Run ``softcurve codegen``; returns the exit code."""
    from softcurve.base.files import writable_folder
    from softcurve.compiled import build_and_run_test, c_identifier, export_c

    _options.as_option("--prefix", c_identifier, "prefix", args.prefix)
    robot, actuator, environment = _robots.robot_and_actuator(args)  # a bad file: no folder
    writable_folder(args.output, "--output")  # before any work
    exported = export_c(
        build_model(robot, environment=environment, compile=False),
        args.output,
        actuator=None if args.no_actuator else actuator,
        prefix=args.prefix,
        embed_parameters=not args.parameters_as_input,
    )
    print(f"softcurve codegen: wrote {exported.source}, {exported.header}, {exported.test}")
    print(f"  functions: {', '.join(exported.functions)}")
    # quoted for the shell: the line is meant to be pasted, and a folder is any name
    folder, command = shlex.quote(str(exported.source.parent)), shlex.join(exported.compile_command)
    print(f"  build the test: cd {folder} && {command}")
    if args.check:
        try:
            with elapsed_line("softcurve codegen: compiling and running the test program"):
                output = build_and_run_test(exported)
        except subprocess.CalledProcessError as exc:
            detail = (exc.stderr or exc.stdout or "").strip()[:400]
            print(f"softcurve codegen: test FAILED: {detail}", file=sys.stderr)
            return 1
        print(f"  test program: {output.strip().splitlines()[-1]}")
    return 0


COMMAND = Command(
    "codegen",
    help="export forward/inverse dynamics, N(q) and H(q) as standalone C with a test",
    description="Write <prefix>.c, <prefix>.h and test_<prefix>.c (plain C99 + libm) "
    "into the output directory. The test program checks every function against the "
    "values of the Python model; --check compiles and runs it.",
    add_arguments=_add_arguments,
    run=_run,
)
