"""``softcurve sweep``: run a parameter sweep from a TOML file into one Parquet table.

Exit code 0 when every simulation succeeded, 1 when some failed (their rows carry their
status, e.g. "integration_failed", and a message), 2 for a bad configuration (reported
before any work).
"""

from __future__ import annotations

import signal
import sys
import threading
from pathlib import Path

from softcurve.base.files import writable_folder
from softcurve.base.validation import ParameterError

from . import (
    Command,
    Interrupted,
    _options,
    add_progress_options,
    rate_text,
    show_progress,
    write_figure,
)
from ._models import build_model

FIGURE = "sweep.png"
"""The figure's file in the output folder when ``--figure`` names none."""


def _add_arguments(parser) -> None:
    """The options of ``softcurve sweep``."""
    parser.add_argument("config", help="sweep TOML file")
    parser.add_argument(
        "-o",
        "--output",
        default="softcurve-sweep",
        metavar="DIR",
        help="output folder (default: softcurve-sweep)",
    )
    where = parser.add_mutually_exclusive_group()
    where.add_argument(
        "--workers",
        type=int,
        metavar="N",
        help="local worker processes (default: the usable cores; 0: this process)",
    )
    where.add_argument(
        "--scheduler", metavar="ADDRESS", help="Dask scheduler to run on, e.g. tcp://10.0.0.5:8786"
    )
    parser.add_argument(
        "--restart",
        action="store_true",
        help="discard results already in the output folder instead of resuming",
    )
    parser.add_argument(
        "--figure",
        nargs="?",
        const=FIGURE,
        metavar="FILE",
        help="also draw each output against each swept variable into FILE (default: "
        f"{FIGURE} in the output folder; the suffix gives the format: .png, .pdf, .svg)",
    )
    add_progress_options(parser, everywhere=True)


def _run(args) -> int:
    """Run ``softcurve sweep``; returns the exit code."""
    from softcurve.scenarios.sweep import run_sweep
    from softcurve.scenarios.sweep_config import load_sweep

    try:
        import pyarrow  # noqa: F401
    except ImportError:
        raise ParameterError(
            "softcurve sweep writes Parquet with pyarrow: pip install 'softcurve[sweep]'"
        ) from None
    if args.workers is not None:
        _options.count(args.workers, "--workers", 0)
    config = load_sweep(args.config)
    figure = _figure_path(args.figure, args.output)
    show = show_progress(args)
    if args.scheduler is None:  # the local workers share this cache: compile once, here
        writable_folder(args.output, "--output")  # before any work
        build_model(
            config.scenario.robot,
            environment=config.scenario.environment,
            quadrature_nodes=config.quadrature_nodes,
        )
    result = _run_until_signal(
        run_sweep,
        config,
        args.output,
        workers=args.workers,
        scheduler=args.scheduler,
        restart=args.restart,
        progress=show,
    )
    simulated = config.size * config.settings.t_final
    summary = (
        f"softcurve sweep: {config.source}: {config.design} design of {config.size} "
        f"simulations over {', '.join(v.name for v in config.variables)}\n"
        f"  chunks      {result.chunks_run} run, {result.chunks_skipped} already done\n"
        f"  failed      {result.failed} of {config.size}\n"
        f"  wall time   {result.wall_time:.2f} s"
        + (
            f" ({rate_text(simulated / result.wall_time)} simulated s per s)"
            if result.chunks_skipped == 0 and result.wall_time > 0
            else ""
        )
        + f"\n  wrote       {result.path}"
    )
    if figure is not None:
        summary += f"\n  figure      {write_figure(result.plot, figure)}"
    if result.failed:
        print(summary, file=sys.stderr)
        print(
            f"softcurve sweep: {result.failed} simulation(s) failed: see the status and "
            "message columns",
            file=sys.stderr,
        )
        return 1
    if not args.quiet:
        print(summary)
    return 0


def _figure_path(figure, output):
    """The figure's file: a bare name goes into the output folder; checked before any work
    (its format, and that its folder exists)."""
    from softcurve.figures.drawing import figure_format

    if figure is None:
        return None
    path = Path(figure)
    if path.parent == Path():
        path = Path(output) / path
    figure_format(path, f"--figure {figure}")
    if path.parent != Path(output) and not path.parent.is_dir():
        raise ParameterError(f"--figure {figure}: the folder {path.parent} does not exist")
    return path


def _terminated(signum, frame):
    """SIGTERM: end like an interrupt, so that the workers are stopped on the way out."""
    raise SystemExit(128 + signum)


RESUME = "the chunks written are kept: run the same command to resume"
"""What an interrupted or terminated sweep kept."""


def _run_until_signal(function, *args, **kwargs):
    """``function(*args, **kwargs)``; on SIGTERM or an interrupt the worker processes are
    killed before the exception goes on (the chunks written so far are kept)."""
    from softcurve.simulation.batch import close_workers, stop_workers

    main_thread = threading.current_thread() is threading.main_thread()
    previous = signal.signal(signal.SIGTERM, _terminated) if main_thread else None
    try:
        result = function(*args, **kwargs)
        close_workers()  # here, where an interrupt is one line, not at the interpreter's exit
        return result
    except KeyboardInterrupt:
        stop_workers()
        raise Interrupted(RESUME) from None
    except BaseException as exc:
        stop_workers()
        if isinstance(exc, SystemExit):
            print(f"softcurve sweep: stopped by SIGTERM; {RESUME}", file=sys.stderr)
        raise
    finally:
        if main_thread:
            signal.signal(signal.SIGTERM, previous)


COMMAND = Command(
    "sweep",
    help="run a grid, random or Sobol design of simulations into one Parquet table",
    description="Run the design of a sweep file (schema: docs/sweeps.md, examples: "
    "examples/sweep_*.toml) and write OUTPUT/results.parquet: one row per simulation "
    "with the swept values and the chosen outputs. Chunks are written as they finish; "
    "run the same command again to resume a killed sweep. Needs pyarrow "
    "(pip install 'softcurve[sweep]'; with --scheduler, 'softcurve[cluster]').",
    add_arguments=_add_arguments,
    run=_run,
)
