"""The ``softcurve`` command line.

Each subcommand lives in its own module of this package, which defines
``register(subparsers)``: it adds its parser and sets ``handler`` to a function
``handler(args) -> int`` (the exit code). Add a module's name to ``COMMANDS`` to
expose it. Errors the user can fix (bad files, bad values) are printed on stderr
without a traceback and give exit code 2; a solver that fails gives exit code 1.
"""

from __future__ import annotations

import argparse
import importlib
import os
import sys

import matplotlib

from softcurve._version import __version__
from softcurve.base.validation import ParameterError

COMMANDS = ("info", "simulate", "equilibria", "codegen", "sweep", "fit")


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="softcurve",
        description="Dynamics of hyper-elastic soft robots as spatial curves "
        "(piecewise constant curvature): simulation, equilibria, control, identification.",
    )
    parser.add_argument("--version", action="version", version=f"softcurve {__version__}")
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for name in COMMANDS:
        importlib.import_module(f"{__name__}.{name}").register(subparsers)
    return parser


def add_progress_options(parser: argparse.ArgumentParser) -> None:
    """``--progress`` / ``--no-progress`` (default: when stderr is a terminal) and ``-q``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    """
    progress = parser.add_mutually_exclusive_group()
    progress.add_argument(
        "--progress",
        dest="progress",
        action="store_true",
        default=None,
        help="progress bar on stderr (default: when stderr is a terminal)",
    )
    progress.add_argument("--no-progress", dest="progress", action="store_false")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")


def main(argv: list[str] | None = None) -> int:
    """Run the ``softcurve`` command; returns the exit code.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default: ``sys.argv[1:]``).
    """
    matplotlib.use("Agg")  # the command writes figures to files and never opens a window
    parser = build_parser()
    args = parser.parse_args(argv)
    if getattr(args, "handler", None) is None:
        parser.print_help()
        return 2
    try:
        return int(args.handler(args))
    except (ParameterError, FileNotFoundError, IsADirectoryError) as exc:
        print(f"softcurve {args.command}: error: {exc}", file=sys.stderr)
        return 2
    except BrokenPipeError:  # the reader went away (softcurve info | head): not an error
        sys.stdout = open(os.devnull, "w")
        return 0


if __name__ == "__main__":  # pragma: no cover
    sys.exit(main())
