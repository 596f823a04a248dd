"""``softcurve fit``: fit a stiffness law to quasi-static data in a CSV file.

The regression of the paper's Fig. 3: generalized force against strain (elongation
[m] or bending angle [rad]) with the hyper-elastic tanh law or a linear law; prints the
estimates with confidence intervals and correlations, optionally writes the figure.
Trajectory fits need a robot and output maps and are a Python API
(:mod:`softcurve.identification.fits`); ``examples/validate_caasenbrood2021.py`` shows them.
"""

from __future__ import annotations

import sys

from . import Command, _options, write_figure

SAMPLE = "examples/bending_moment.csv"
"""Sample data of the repository: bending angle [rad] and tip moment [N m] of the paper's
robot at equilibrium (docs/identify.md says how it was computed)."""


def _add_arguments(parser) -> None:
    """The options of ``softcurve fit``."""
    parser.add_argument("csv", help="CSV file with a header row")
    parser.add_argument("--strain", required=True, help="column of the strain (m or rad)")
    parser.add_argument("--force", required=True, help="column of the force (N or N m)")
    parser.add_argument(
        "--mode",
        choices=("elongation", "bending"),
        help="the strain's kind, for the units of the report and the figure: elongation "
        "[m] under a force [N], or bending angle [rad] under a moment [N m] (default: "
        "either, written as 'm or rad')",
    )
    parser.add_argument("--law", choices=("tanh", "linear"), default="tanh")
    parser.add_argument("--weights", help="optional column of residual weights")
    parser.add_argument(
        "--confidence", type=float, default=0.95, help="interval level in (0, 1) (default 0.95)"
    )
    parser.add_argument("--figure", help="write the fit figure to this PNG file")


def _run(args) -> int:
    """Run ``softcurve fit``; returns the exit code."""
    from softcurve.identification.experiments import load_csv
    from softcurve.identification.fits import check_confidence, fit_stiffness

    # every option before any work, by the library's own checks
    _options.as_option("--confidence", check_confidence, args.confidence)
    if args.figure:
        _options.figure_file(args.figure, "--figure")

    signals = [args.strain, args.force] + ([args.weights] if args.weights else [])
    # rows are data points, in any order: number them instead of reading a time column
    data = load_csv(args.csv, signals=signals, time=None, sample_rate=1.0)
    report = fit_stiffness(
        data.signals[args.strain],
        data.signals[args.force],
        args.law,
        weights=data.signals[args.weights] if args.weights else None,
        confidence=args.confidence,
        label=args.strain,
        mode=args.mode,
    )
    print(report.table())
    law = report.extra["law"]
    if law is not None:
        arguments = ", ".join(
            f"{n}={v:.6g}" for n, v in zip(report.names, report.values, strict=True)
        )
        print(f"law: {type(law).__name__}({arguments})")
    if args.figure:
        write_figure(lambda: report.plot(title=f"{args.law} law fitted to {args.csv}"), args.figure)
        print(f"figure: {args.figure}")
    if not report.success:
        print(f"softcurve fit: {report.status.value}: {report.message}", file=sys.stderr)
        return 1
    return 0


COMMAND = Command(
    "fit",
    help="fit a stiffness law (tanh or linear) to force-strain data in a CSV file",
    description="Fit k(x) x = force to quasi-static data (the paper's Fig. 3) and print "
    "a report: estimates, confidence intervals, correlations, residuals. Exit code 1 if "
    "the fit fails or a parameter is not identifiable from the data; 2 for bad input "
    "(e.g. fewer points than the law's parameters plus one). Data to try it on, from a "
    f"checkout of the repository: softcurve fit {SAMPLE} --strain angle --force moment "
    "--mode bending "
    "(the paper's robot bent by tip moments; docs/identify.md).",
    add_arguments=_add_arguments,
    run=_run,
)
