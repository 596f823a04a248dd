"""The ``softcurve`` command line.

Each subcommand lives in its own module of this package, which defines ``COMMAND``,
a :class:`Command`: its name, help texts, options and the function that runs it and
returns the exit code. Add a module's name to ``COMMANDS`` to expose it. Errors the
user can fix (bad files, bad values, an output folder that cannot be written) are
printed on stderr as one line without a traceback and give exit code 2; a solver that
fails, or an unexpected error, gives exit code 1 (``--debug`` shows the traceback).
Ctrl-C stops a command with exit code 130 and one line saying what was kept
(:class:`Interrupted`).
"""

from __future__ import annotations

import argparse
import contextlib
import dataclasses
import functools
import importlib
import logging
import os
import re
import signal
import sys
import traceback
import warnings
from collections.abc import Callable

from softcurve._version import __version__
from softcurve.base.log import PACKAGE, ConsoleHandler
from softcurve.base.progress import on_terminal

COMMANDS = ("info", "simulate", "equilibria", "codegen", "sweep", "fit")


@dataclasses.dataclass(frozen=True)
class Command:
    """A subcommand of ``softcurve``.

    Parameters
    ----------
    name : str
        What the user types, e.g. ``"simulate"``.
    help : str
        Its line in ``softcurve --help``.
    description : str
        The text of ``softcurve NAME --help``.
    add_arguments : callable
        ``add_arguments(parser)`` adds the subcommand's options to its parser.
    run : callable
        ``run(args) -> int`` does the work on the parsed command line and returns the
        exit code.
    """

    name: str
    help: str
    description: str
    add_arguments: Callable[[argparse.ArgumentParser], None]
    run: Callable[[argparse.Namespace], int]


class Interrupted(KeyboardInterrupt):
    """Ctrl-C, carrying what the command kept (its files are written whole or not at all).

    Parameters
    ----------
    kept : str
        What was kept and how to go on, e.g. ``"the chunks written are kept: run the
        same command to resume"``.
    """

    def __init__(self, kept: str):
        super().__init__(kept)
        self.kept = kept


NOTHING_HALF_WRITTEN = (
    "nothing was half-written (files are written whole or not at all); run the same "
    "command again to start over"
)
"""What an interrupted command kept when it does not say more."""


class Parser(argparse.ArgumentParser):
    """An argument parser that reads ``-1e6``, ``-2E+4``, ``-.5`` and ``-inf`` as
    negative numbers, not as options (argparse's own pattern misses the exponent)."""

    def __init__(self, *args, **kwargs):
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = re.compile(
            r"^-(\d+\.?\d*|\.\d+)([eE][+-]?\d+)?$|^-(inf|infinity|nan)$", re.IGNORECASE
        )


def build_parser() -> argparse.ArgumentParser:
    parser = Parser(
        prog="softcurve",
        description="Dynamics of hyper-elastic soft robots as spatial curves "
        "(piecewise constant curvature): simulation, equilibria, control, identification.",
    )
    parser.add_argument("--version", action="version", version=f"softcurve {__version__}")
    debug_help = "show the traceback of an error"
    parser.add_argument("--debug", action="store_true", help=debug_help)
    subparsers = parser.add_subparsers(dest="command", metavar="COMMAND")
    for module in COMMANDS:
        command = importlib.import_module(f"{__name__}.{module}").COMMAND
        subparser = subparsers.add_parser(
            command.name, help=command.help, description=command.description
        )
        command.add_arguments(subparser)
        subparser.add_argument(
            "--debug", action="store_true", default=argparse.SUPPRESS, help=debug_help
        )
        subparser.set_defaults(handler=command.run)
    return parser


def add_progress_options(parser: argparse.ArgumentParser, everywhere: bool = False) -> None:
    """``--progress`` / ``--no-progress`` and ``-q``.

    Parameters
    ----------
    parser : argparse.ArgumentParser
        The subcommand's parser.
    everywhere : bool
        Show the progress by default also when stderr is not a terminal (as lines, per
        tenth of the work or per ``LINE_EVERY`` seconds: a long command whose output goes
        to a log); default: only on a terminal.
    """
    progress = parser.add_mutually_exclusive_group()
    default = (
        "redrawn on a terminal, else a line per tenth of the work or per 10 s"
        if everywhere
        else "when stderr is a terminal"
    )
    parser.set_defaults(progress_everywhere=everywhere)
    progress.add_argument(
        "--progress",
        dest="progress",
        action="store_true",
        default=None,
        help=f"progress on stderr (default: {default})",
    )
    progress.add_argument("--no-progress", dest="progress", action="store_false")
    parser.add_argument("-q", "--quiet", action="store_true", help="print nothing on success")


def in_cli_terms(text: str, options: dict[str, str]) -> str:
    """``text``, a message or advice of the library, in the words of a command: each
    pattern of ``options`` (a regular expression of the library's words, e.g. a Python
    argument ``\\bmax_steps\\b``, not preceded by a letter, ``-`` or ``.``) replaced by
    what the user of the command types or can do (``--max-steps``).

    Parameters
    ----------
    text : str
        The library's message.
    options : dict of str to str
        Pattern -> replacement (``re.sub`` syntax).
    """
    for pattern, option in options.items():
        text = re.sub(r"(?<![-\w.])" + pattern, option, text)
    return text


RATE_DIGITS = 3
"""Significant digits of a printed rate: enough to tell 0.38 from 0.4, few enough to read."""


def rate_text(value: float) -> str:
    """A rate for a command's summary (e.g. simulated seconds per wall-clock second), to
    :data:`RATE_DIGITS` significant digits and without an exponent from 1e-4 up to any
    size: 0.38 is ``"0.38"`` (not ``"0"``), 12.34 ``"12.3"``, 123456.7 ``"123457"``.

    Parameters
    ----------
    value : float
        The rate [the caller's unit, e.g. simulated s per s].
    """
    if abs(value) >= 10**RATE_DIGITS:
        return f"{value:.0f}"
    return f"{value:.{RATE_DIGITS}g}"


def write_figure(draw, path, *, figsize=None, **options):
    """Draw a figure, save it and close it; returns the path written.

    Parameters
    ----------
    draw : callable
        ``draw() -> matplotlib.figure.Figure``, e.g. a result's ``plot`` method.
    path : str or Path
        The image file.
    figsize : tuple of float, optional
        ``(width, height)`` of the figure [inches] (default: the figure's own).
    **options
        Passed on to :func:`softcurve.figures.save_figure` (e.g. ``dpi``).
    """
    import matplotlib.pyplot as plt  # here: 0.6 s that commands without figures skip

    from softcurve.figures import save_figure

    figure = draw()
    if figsize is not None:
        figure.set_size_inches(*figsize)
    written = save_figure(figure, path, **options)
    plt.close(figure)
    return written


def main(argv: list[str] | None = None) -> int:
    """Run the ``softcurve`` command; returns the exit code.

    Parameters
    ----------
    argv : list of str, optional
        The arguments (default: ``sys.argv[1:]``).
    """
    _figures_to_files()
    try:  # the commands' modules are imported here: seconds in which Ctrl-C may come
        parser = build_parser()
        args = parser.parse_args(argv)
    except KeyboardInterrupt:
        print("softcurve: interrupted before starting: nothing was done", file=sys.stderr)
        return 128 + signal.SIGINT
    if getattr(args, "handler", None) is None:
        parser.print_help()
        return 2
    try:
        with warnings.catch_warnings(), _library_lines(args):
            if not args.debug:  # one line per warning, without the source line
                warnings.showwarning = functools.partial(_show_warning, args.command)
            return int(args.handler(args))
    except KeyboardInterrupt as exc:  # Ctrl-C: one line, exit 130 (128 + SIGINT)
        if args.debug:
            traceback.print_exc()
        kept = exc.kept if isinstance(exc, Interrupted) else NOTHING_HALF_WRITTEN
        print(f"softcurve {args.command}: interrupted: {kept}", file=sys.stderr)
        return 128 + signal.SIGINT
    except BrokenPipeError:  # the reader went away (softcurve info | head): not an error
        sys.stdout = open(os.devnull, "w")
        return 0
    except Exception as exc:
        code, line = _error_line(exc)
        if args.debug:
            traceback.print_exc()
        else:
            line += "" if code == 2 else " (run with --debug for the traceback)"
        print(f"softcurve {args.command}: error: {line}", file=sys.stderr)
        return code


def _figures_to_files() -> None:
    """Matplotlib's backend to Agg: the command writes figures to files and never opens
    a window. Matplotlib is not imported for it (0.1-0.3 s that most commands skip)."""
    if "matplotlib" in sys.modules:  # imported already (main called from Python)
        import matplotlib

        matplotlib.use("Agg")
    else:
        os.environ["MPLBACKEND"] = "Agg"  # read when matplotlib is imported


def show_progress(args) -> bool:
    """Whether the command shows its progress: ``--progress``/``--no-progress``, else
    when stderr is a terminal, or everywhere for a command that shows it so
    (:func:`add_progress_options`) without ``--quiet``; a command without these options:
    no.

    Parameters
    ----------
    args : argparse.Namespace
        The parsed command line.
    """
    progress = getattr(args, "progress", False)
    if progress is not None:
        return bool(progress)
    return on_terminal() or (args.progress_everywhere and not args.quiet)


@contextlib.contextmanager
def _library_lines(args):
    """While the command runs, what the library logs (:mod:`softcurve.base.log`: what it
    compiles, where and how long) as lines ``softcurve COMMAND: ...`` on stderr: none
    with ``--quiet``, the seconds so far of a compile too with the progress shown."""
    package = logging.getLogger(PACKAGE)
    handler = ConsoleHandler(f"softcurve {args.command}: ")
    saved = package.level, package.propagate
    if getattr(args, "quiet", False):
        package.setLevel(logging.WARNING)
    else:
        package.setLevel(logging.DEBUG if show_progress(args) else logging.INFO)
    package.propagate = False  # the command's lines, once, whatever else is configured
    package.addHandler(handler)
    try:
        yield
    finally:
        package.removeHandler(handler)
        package.setLevel(saved[0])
        package.propagate = saved[1]


def _show_warning(command, message, category, filename, lineno, file=None, line=None):
    """Print a warning as ``softcurve COMMAND: warning: text`` on one line."""
    text = " ".join(str(message).split())
    print(f"softcurve {command}: warning: {text}", file=sys.stderr if file is None else file)


def _error_line(exc: Exception) -> tuple[int, str]:
    """``(exit code, one line)`` for an error: 2 for input the user can fix, 1 else."""
    from softcurve.base.validation import ParameterError

    text = " ".join(str(exc).split()) or type(exc).__name__
    if isinstance(exc, ParameterError | FileNotFoundError | IsADirectoryError):
        return 2, text
    if isinstance(exc, MemoryError):
        return 1, "out of memory: ask for fewer outputs (--dt, --t-final) or less work"
    if isinstance(exc, OSError):
        where = f"{exc.filename}: " if exc.filename else ""
        return 1, f"{where}{exc.strerror or text} (check the folder and the free space)"
    return 1, f"{type(exc).__name__}: {text}"
