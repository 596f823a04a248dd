"""Cost of ``sc.equilibrium`` on robots of many segments: the static balance in CasADi's
virtual machine, then compiled once it has paid for its compile.

For robots of N paper segments (``presets.ifac2020().with_segments(N)``, upright under
their own weight, from the rest configuration; the model's library built before and not
counted) it prints, per N, the wall time of ``sc.equilibrium(model, q0)``:

- ``first [s]``: the first equilibrium in a fresh process whose cache holds the model's
  library but nothing of the statics (the static balance built, evaluated in the
  virtual machine);
- ``again [s]``: the same equilibrium again on the same model, best of three (still in
  the virtual machine: fewer evaluations than ``COMPILE_AFTER``);
- ``compiling [s]``: the next one with ``COMPILE_AFTER`` set to 0, so that it compiles
  the balance first (what the equilibrium after ``COMPILE_AFTER`` evaluations waits);
- ``in C [s]``: the same equilibrium again, best of three, on the compiled balance;
- ``cached [s]``: the first equilibrium in another fresh process on the cache the first
  one filled (the symbolic model built, the balance's library found and loaded at once).

Each N gets its own cache folder (a temporary copy of the model's library), so the
figures do not depend on what the shared cache holds. With ``--before SRC`` the first
and again columns are measured first with the package at ``SRC`` (another checkout's
``src`` folder, e.g. the code before a change) and printed beside. With
``--virtual-machine`` the models are built with ``compile=False``: every function, the
static balance included, in CasADi's virtual machine (the compile columns are empty).

Run: ``python benchmarks/bench_statics_chain.py [--segments 1 2 4 10 20] [--before SRC]
[--virtual-machine]``
"""

from __future__ import annotations

import argparse
import json
import os
import shutil
import subprocess
import sys
import tempfile
import time
from pathlib import Path

REPEAT = 3
"""Warm equilibria timed per robot, the best reported."""


def child(segments: int, compiled: bool) -> None:
    """One process's equilibria (``--child``): prints the figures as JSON."""
    from _timing import best_of  # benchmarks/_timing.py: a helper, not a benchmark

    import softcurve as sc

    robot = sc.presets.ifac2020().with_segments(segments)
    model = sc.Model(robot, compile=compiled)
    q0 = [v for s in robot.segments for v in (s.rest_length, 0.0, 0.0)]
    start = time.perf_counter()
    first = sc.equilibrium(model, q0)
    first_time = time.perf_counter() - start
    warm, again = best_of(REPEAT, lambda: sc.equilibrium(model, q0))
    if not (first.success and again.success):
        raise SystemExit(f"{segments} segments: {first.message}")
    figures = {"first": first_time, "warm": warm, "stability": first.stability}
    try:  # the balance's rule, where the package has it (not before it)
        from softcurve.analysis import loads

        balance = loads.static_balance(loads.StaticLoad(model))
    except AttributeError:
        balance = None
    if compiled and balance is not None and not balance.in_c:
        loads.COMPILE_AFTER = 0
        start = time.perf_counter()
        sc.equilibrium(model, q0)
        figures["compiling"] = time.perf_counter() - start
        figures["in_c"] = best_of(REPEAT, lambda: sc.equilibrium(model, q0))[0]
    print(json.dumps(figures))


def run(segments: int, cache: Path | None, source: str | None, vm: bool = False) -> dict:
    """The figures of :func:`child` in a fresh process on ``cache`` (default: the shared
    one), the package imported from ``source`` (default: as this process imports it)."""
    env = dict(os.environ)
    if cache is not None:
        env["SOFTCURVE_CACHE_DIR"] = str(cache)
    if source is not None:
        env["PYTHONPATH"] = source
    out = subprocess.run(
        [sys.executable, __file__, "--child", str(segments), *(["--virtual-machine"] * vm)],
        env=env,
        cwd=Path(__file__).parent,
        capture_output=True,
        text=True,
    )
    if out.returncode != 0:
        raise SystemExit(f"{segments} segments, {source or 'this'} package:\n{out.stderr}")
    return json.loads(out.stdout.splitlines()[-1])


def measure(segments: int, library: Path, source: str | None, vm: bool) -> tuple:
    """``(first, cached)`` figures of ``segments``: a fresh process on a cache holding
    ``library`` alone, and another on the cache it filled."""
    with tempfile.TemporaryDirectory() as folder:
        for path in (library, library.with_name(library.name + ".sha256")):
            shutil.copy2(path, folder)
        first = run(segments, Path(folder), source, vm)
        return first, run(segments, Path(folder), source, vm)


def _seconds(figures: dict, name: str) -> str:
    return f"{figures[name]:.3f}" if name in figures else "-"


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segments", type=int, nargs="+", default=[1, 2, 4, 10, 20])
    parser.add_argument("--before", help="src folder of the package to compare with")
    parser.add_argument(
        "--virtual-machine", action="store_true", help="models built with compile=False"
    )
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        child(args.child, not args.virtual_machine)
        return
    import softcurve as sc

    before = None if not args.before else str(Path(args.before).resolve())
    head = "N    first [s]  again [s]  compiling [s]  in C [s]  cached [s]"
    print(head + ("  |  before: first [s]  again [s]" if before else "") + "  stability")
    for n in args.segments:
        model = sc.Model(sc.presets.ifac2020().with_segments(n))  # built here, not timed
        if model.compiled_library is None:
            raise SystemExit("the model is not compiled: the figures need a C compiler")
        first, cached = measure(n, model.compiled_library, None, args.virtual_machine)
        line = (
            f"{n:<3d}  {first['first']:9.3f}  {first['warm']:9.3f}  "
            f"{_seconds(first, 'compiling'):>13s}  {_seconds(first, 'in_c'):>8s}  "
            f"{cached['first']:10.3f}"
        )
        if before:
            old, _ = measure(n, model.compiled_library, before, args.virtual_machine)
            line += f"  |  {old['first']:17.3f}  {old['warm']:9.3f}"
        print(line + f"  {first['stability']}", flush=True)


if __name__ == "__main__":
    main()
