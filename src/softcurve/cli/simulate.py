"""``softcurve simulate``: simulate a robot (by default the paper's case) and write the results.

Writes into the output folder: ``trajectory.csv`` (and ``trajectory.npz`` with
``--npz``), ``states.png`` (paper Fig. 4), ``tip.png`` (Fig. 5), ``contact.png`` (the
forces of the obstacles, with an ``[environment]``) and, with
``--animate``, ``animation.gif`` (``.mp4`` too where ffmpeg exists), with ``--html``
``viewer.html`` (the interactive 3-D viewer); prints a summary, naming the files of an
earlier run in the folder that it replaced (and those it left). The figures and the
animation show the motion (from the start to where the states settle, as the Python
API's ``window="auto"``; their titles say the window and the run's end), or
``--window T0 T1``.
Exit code 0 on success, 1 when the integrator fails (the partial trajectory and its
figures are still written), 2 for usage or configuration errors.
"""

from __future__ import annotations

import dataclasses
import shutil
import sys
import time

import numpy as np

from softcurve.base.files import writable_folder
from softcurve.base.validation import ParameterError

from . import (
    Command,
    Interrupted,
    _options,
    add_progress_options,
    in_cli_terms,
    rate_text,
    write_figure,
)
from . import (
    show_progress as progress_shown,
)
from ._models import build_model


def _add_arguments(parser) -> None:
    """The options of ``softcurve simulate``."""
    parser.add_argument("config", nargs="?", help="scenario TOML file (default: the paper's case)")
    parser.add_argument(
        "-o",
        "--output",
        default="softcurve-output",
        metavar="DIR",
        help="output folder (default: softcurve-output)",
    )
    parser.add_argument("--t-final", type=float, metavar="S", help="end time [s]")
    parser.add_argument("--dt", type=float, metavar="S", help="output interval [s]")
    parser.add_argument(
        "--method",
        choices=("cvodes", "auto", "adams", "bdf", "radau", "rk45"),
        help="integrator (default cvodes: Adams or BDF chosen per problem; radau: the "
        "L-stable Radau IIA of order 5; auto: radau where the input changes often, "
        "else cvodes)",
    )
    parser.add_argument("--rtol", type=float, help="relative tolerance (default 1e-6)")
    parser.add_argument(
        "--jacobian",
        choices=("differences", "exact"),
        help="the Newton matrix's Jacobian (default differences; exact: the model's own, "
        "compiled on first use, cheaper from two segments on)",
    )
    parser.add_argument("--atol", type=float, help="absolute tolerance for every state")
    parser.add_argument("--max-steps", type=int, help="internal steps allowed per output interval")
    parser.add_argument(
        "--max-outputs",
        type=int,
        metavar="N",
        help="output times allowed (default 10 000 000, about 1 GB of memory and 3 GB of CSV "
        "for one segment): larger records are refused before integrating",
    )
    parser.add_argument("--npz", action="store_true", help="also write trajectory.npz")
    parser.add_argument("--no-figures", action="store_true", help="skip states.png and tip.png")
    parser.add_argument(
        "--window",
        type=float,
        nargs=2,
        metavar=("T0", "T1"),
        help="the time window the figures and the animation show [s], 0 <= T0 < T1 <= the "
        "end time (default: the motion, from the start to where the states settle; "
        "--window 0 T_FINAL for the whole run)",
    )
    parser.add_argument(
        "--animate",
        action="store_true",
        help="also write animation.gif (and animation.mp4 if ffmpeg exists) of the figures' "
        f"time window, in real time up to {MOST_FRAMES} frames, faster beyond",
    )
    parser.add_argument(
        "--fps", type=int, default=25, help="frames per second of the animation and the viewer"
    )
    parser.add_argument(
        "--html",
        action="store_true",
        help="also write viewer.html, the interactive 3-D viewer (one offline file; needs "
        "the extra viewer: pip install softcurve[viewer])",
    )
    parser.add_argument(
        "--figsize",
        type=float,
        nargs=2,
        metavar=("W", "H"),
        help="size of the figures and the animation [inches]",
    )
    parser.add_argument(
        "--dpi", type=float, help="resolution of the figures and the animation [dots per inch]"
    )
    add_progress_options(parser)


def _scenario(args):
    from softcurve.scenarios.config import load_config, paper_scenario
    from softcurve.simulation import SettingsError

    scenario = load_config(args.config) if args.config else paper_scenario()
    overrides = {
        "t_final": args.t_final,
        "dt": args.dt,
        "method": args.method,
        "rtol": args.rtol,
        "jacobian": args.jacobian,
        "atol": args.atol,
        "max_steps": args.max_steps,
        "max_outputs": args.max_outputs,
    }
    overrides = {k: v for k, v in overrides.items() if v is not None}
    _options.count(args.fps, "--fps")
    if args.figsize is not None and not all(0 < v < 1000 for v in args.figsize):
        raise ParameterError(f"--figsize must be two sizes in (0, 1000) inches, got {args.figsize}")
    if args.dpi is not None and not 0 < args.dpi <= 2000:
        raise ParameterError(f"--dpi must be in (0, 2000], got {args.dpi}")
    settings = scenario.settings
    # Scenario and SimulationSettings check themselves: the overrides are validated here
    try:
        return dataclasses.replace(scenario, settings=settings.replace(**overrides))
    except SettingsError as exc:
        raise ParameterError(as_flags(str(exc))) from None


def _window(args, scenario):
    """The time window of the figures and the animation: ``--window`` checked against
    the run's end time, or ``"auto"`` (the motion, as the figures choose it)."""
    if args.window is None:
        return "auto"
    start, end = args.window
    t_final = scenario.settings.t_final
    if not (np.isfinite(start) and np.isfinite(end) and 0 <= start < end <= t_final):
        raise ParameterError(
            f"--window must be two times 0 <= T0 < T1 <= the end time {t_final:g} s, "
            f"got {start:g} {end:g}"
        )
    return (start, end)


MOST_FRAMES = 250
"""Frames of an animation at most, 10 s at 25 frames per second: the paper's case over
its whole 10 s draws them in about 5 s into a 150 kB GIF (default size, 2-core x86_64);
a longer window plays faster than real time."""
OUTPUTS = (
    "trajectory.csv",
    "trajectory.npz",
    "states.png",
    "tip.png",
    "contact.png",
    "animation.gif",
    "animation.mp4",
    "viewer.html",
)
"""Every file ``simulate`` may write into its folder."""


LARGE_CSV = 100e6
"""CSV size [bytes] above which ``simulate`` says that it is writing (about 7 s at the
15 MB/s of NumPy's text output) when no progress bar is shown."""


FLAGS = {
    r"method='(\w+)'": r"--method \1",
    r"\bt_final\b": "--t-final",
    r"\bdt\b": "--dt",
    r"jacobian='(\w+)'": r"--jacobian \1",
    r"\brtol\b": "--rtol",
    r"\batol\b": "--atol",
    r"\bmax_steps\b": "--max-steps",
    r"\bmax_outputs\b": "--max-outputs",
}
"""The Python names of settings, as the command line spells them (patterns of
:func:`~softcurve.cli.in_cli_terms`)."""


def as_flags(text: str) -> str:
    """``text`` (a message or advice of the library) with the settings' Python names
    replaced by the options of ``softcurve simulate`` (``method='bdf'`` -> ``--method
    bdf``, ``max_steps`` -> ``--max-steps``).

    Parameters
    ----------
    text : str
        A message that names settings as Python arguments.
    """
    return in_cli_terms(text, FLAGS)


def _run(args) -> int:
    """Run ``softcurve simulate``; returns the exit code."""
    scenario = _scenario(args)
    window = _window(args, scenario)
    if args.html:
        _options.viewer("--html")
    output = writable_folder(args.output, "--output")  # before any work
    earlier = [output / name for name in OUTPUTS if (output / name).is_file()]
    written: list = []  # the files complete so far
    try:
        return _simulate(args, scenario, output, written, window, earlier)
    except KeyboardInterrupt:
        if not written:
            raise Interrupted(f"nothing written to {output}") from None
        files = ", ".join(str(p) for p in written)
        raise Interrupted(
            f"kept {files} (complete; nothing half-written); run the same command again "
            "for the rest"
        ) from None


def _simulate(args, scenario, output, written: list, window, earlier: list) -> int:
    """Simulate and write into ``output``, appending each file to ``written`` once whole;
    ``window`` is the figures' (``"auto"`` or ``(start, end)`` [s]), ``earlier`` the files
    of an earlier run in ``output``."""
    from softcurve.simulation import CSV_BYTES_PER_VALUE, format_bytes, simulate
    from softcurve.simulation.results import save_trajectory

    say = (lambda *a: None) if args.quiet else print
    show_progress = progress_shown(args)
    start = time.perf_counter()
    model = build_model(scenario.robot, environment=scenario.environment)
    built = time.perf_counter() - start
    q0, qd0, lam0 = scenario.initial_state()
    trajectory = simulate(
        model,
        q0,
        qd0,
        lam0,
        tau=scenario.tau,
        actuator=scenario.actuator() if scenario.inputs is not None else None,
        inputs=scenario.inputs,
        settings=scenario.settings,
        progress=show_progress,
    )
    csv_size = (
        trajectory.t.size
        * (1 + 2 * trajectory.n + trajectory.lam.shape[1] + 3)
        * (CSV_BYTES_PER_VALUE)
    )
    if csv_size > LARGE_CSV and not show_progress and not args.quiet:
        print(
            f"softcurve simulate: writing about {format_bytes(csv_size)} of CSV ...",
            file=sys.stderr,
        )
    written.append(save_trajectory(trajectory, output / "trajectory.csv", progress=show_progress))
    if args.npz:
        written.append(trajectory.save(output / "trajectory.npz"))
    looks = {"figsize": args.figsize, "dpi": args.dpi}
    looks = {k: v for k, v in looks.items() if v is not None}
    if not args.no_figures and trajectory.t.size:
        figures = [
            ("states.png", lambda: trajectory.plot(window=window)),
            ("tip.png", lambda: trajectory.plot_tip(window=window)),
        ]
        if model.environment is not None:
            figures.append(("contact.png", lambda: trajectory.contact().plot()))
        for name, draw in figures:
            written.append(write_figure(draw, output / name, **looks))
    # a run that failed before the window has nothing in it to animate
    reached = trajectory.t.size > 1 and (window == "auto" or window[0] < trajectory.t[-1])
    if args.animate and reached:
        movies = ["animation.gif"] + (["animation.mp4"] if shutil.which("ffmpeg") else [])
        for name in movies:
            written.append(
                _animation(trajectory, output / name, args, show_progress, looks, window)
            )
    if args.html and trajectory.t.size:
        written.append(trajectory.to_html(output / "viewer.html", fps=args.fps))
    total = time.perf_counter() - start
    summary = _summary(scenario, model, trajectory, built, total, written)
    summary += _earlier_lines(earlier, written)
    if trajectory.success:
        say(summary)
        return 0
    print(summary, file=sys.stderr)
    print(
        f"softcurve simulate: integration failed: {as_flags(trajectory.message)}",
        file=sys.stderr,
    )
    return 1


def _animation(trajectory, path, args, show_progress: bool, looks: dict, window):
    """Write one animation over ``window``, at most ``MOST_FRAMES`` frames, saying first
    what it draws."""
    from softcurve.figures.trajectories import frame_samples, motion_window

    start, end = motion_window(trajectory, window)
    end = min(end, float(trajectory.t[-1]))  # a failed run ends early
    speed = max(1.0, (end - start) * args.fps / MOST_FRAMES)
    if not args.quiet:
        frames = frame_samples(trajectory, window=window, fps=args.fps, speed=speed).size
        print(
            f"softcurve simulate: writing {path.name}, {frames} frames of t = {start:.3g} .. "
            f"{end:.3g} s" + (f" at {speed:.3g}x real time" if speed > 1 else "") + " ...",
            file=sys.stderr,
        )
    return trajectory.animate(
        path, fps=args.fps, speed=speed, window=window, progress=show_progress, **looks
    )


def _earlier_lines(earlier: list, written: list) -> str:
    """The summary's lines on the files of an earlier run: those replaced, and those left
    that this run did not write (they belong to the earlier run)."""
    replaced = [p.name for p in earlier if p in written]
    left = [p.name for p in earlier if p not in written]
    lines = ""
    if replaced:
        lines += "\n  replaced    " + ", ".join(replaced) + " of an earlier run"
    if left:
        lines += "\n  left        " + ", ".join(left) + " of an earlier run (not written now)"
    return lines


def _summary(scenario, model, trajectory, built, total, written) -> str:
    stats = trajectory.stats
    energy = trajectory.energy(model) if trajectory.t.size else np.array([np.nan])
    wall = stats["wall_time"]
    simulated = trajectory.t[-1] if trajectory.t.size else 0.0
    fmt = lambda a: "(" + ", ".join(f"{v:.6g}" for v in a) + ")"  # noqa: E731
    robot = model.robot
    lines = [
        f"softcurve simulate: {scenario.source}, {robot.n_segments} {robot.element_word}(s), "
        f"t = 0 .. {simulated:.6g} s, output every {scenario.settings.dt:g} s "
        f"({trajectory.t.size} points)",
        f"  status      {trajectory.status.value}: {as_flags(trajectory.message)}",
        f"  final q     {fmt(trajectory.q[-1])}" if trajectory.t.size else "  final q     -",
        f"  final qd    {fmt(trajectory.qd[-1])}" if trajectory.t.size else "  final qd    -",
        f"  final tip   {fmt(trajectory.tip[-1] * 1e3)} mm" if trajectory.t.size else "",
        f"  energy      {energy[0]:.6g} J -> {energy[-1]:.6g} J",
        _contact_line(model, trajectory),
        f"  integrator  {stats['method']} on route {stats['route']}, rtol {stats['rtol']:g}: "
        f"{stats['steps']} steps, "
        f"{stats['rhs_evaluations']} rhs and {stats['jacobian_evaluations']} Jacobian evaluations",
        f"  wall time   {1e3 * wall:.1f} ms integrating"
        + (f" ({rate_text(simulated / wall)}x real time)" if wall > 0 and simulated > 0 else "")
        + f" with the integrator's set-up, {built:.2f} s model setup, {total:.2f} s in total",
        "  wrote       " + ", ".join(str(p) for p in written),
    ]
    return "\n".join(line for line in lines if line)


def _contact_line(model, trajectory) -> str:
    """The largest force of each obstacle, or nothing without an environment."""
    if model.environment is None or not trajectory.t.size:
        return ""
    largest = trajectory.contact().magnitude.max(axis=0)
    return "  contact     max |F| " + ", ".join(f"{f:.4g} N" for f in largest) + " (per obstacle)"


COMMAND = Command(
    "simulate",
    help="simulate a robot (default: the paper's section 4.2 case) and write data and figures",
    description="Simulate a soft robot from a TOML scenario (schema: docs/configuration.md, "
    "examples in examples/) or, without one, the paper's case: preset ifac2020, "
    "q0 = (0.064, 25, 0), qd0 = (0, 0, 1500), 10 s, output every 1 ms. Writes "
    "trajectory.csv, states.png and tip.png into the output folder. Exit code 0: "
    "success; 1: the integrator failed (partial results written); 2: bad arguments "
    "or configuration.",
    add_arguments=_add_arguments,
    run=_run,
)
