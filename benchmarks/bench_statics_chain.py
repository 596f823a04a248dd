"""Cost of ``sc.equilibrium`` on robots of many segments: the static balance compiled.

For robots of N paper segments (``presets.ifac2020().with_segments(N)``, upright under
their own weight, from the rest configuration; the model's library built before and not
counted) it prints, per N, the wall time of ``sc.equilibrium(model, q0)``:

- ``cold [s]``: the first equilibrium in a fresh process whose cache holds the model's
  library but nothing of the statics: building the static balance, compiling it
  included;
- ``cached [s]``: the first equilibrium in another fresh process on the cache the cold
  one filled (the symbolic model built, the static balance loaded);
- ``warm [s]``: the same equilibrium again on the same model, best of three.

Each process gets its own cache folder (a temporary copy of the model's library), so
the figures do not depend on what the shared cache holds; with ``--no-cold`` the cold
column is skipped and the others run on the shared cache (a long chain's compile is
minutes: its library may be there already). With ``--before SRC`` the same
columns are measured first with the package at ``SRC`` (another checkout's ``src``
folder, e.g. the code before a change) and printed beside. With ``--virtual-machine``
the models are built with ``compile=False``: every function, the static balance
included, in CasADi's virtual machine.

Run: ``python benchmarks/bench_statics_chain.py [--segments 1 2 4 10 20] [--before SRC]
[--no-cold] [--virtual-machine]``
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
    print(json.dumps({"first": first_time, "warm": warm, "stability": first.stability}))


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


def measure(segments: int, library: Path, source: str | None, cold: bool, vm: bool) -> tuple:
    """``(cold, cached)`` figures of ``segments`` on a cache holding ``library`` alone;
    without ``cold``, ``(None, cached)`` on the shared cache."""
    if not cold:
        return None, run(segments, None, source, vm)
    with tempfile.TemporaryDirectory() as folder:
        for path in (library, library.with_name(library.name + ".sha256")):
            shutil.copy2(path, folder)
        cold = run(segments, Path(folder), source, vm)
        return cold, run(segments, Path(folder), source, vm)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--segments", type=int, nargs="+", default=[1, 2, 4, 10, 20])
    parser.add_argument("--before", help="src folder of the package to compare with")
    parser.add_argument("--no-cold", action="store_true", help="skip the cold column")
    parser.add_argument(
        "--virtual-machine", action="store_true", help="models built with compile=False"
    )
    parser.add_argument("--child", type=int, help=argparse.SUPPRESS)
    args = parser.parse_args()
    if args.child is not None:
        child(args.child, not args.virtual_machine)
        return
    import softcurve as sc

    columns = "cold [s]  cached [s]  warm [s]"
    sides = [None] if not args.before else [str(Path(args.before).resolve()), None]
    names = ["after"] if not args.before else ["before", "after"]
    print("N    " + "  |  ".join(f"{name}: {columns}" for name in names) + "  stability")
    for n in args.segments:
        model = sc.Model(sc.presets.ifac2020().with_segments(n))  # built here, not timed
        if model.compiled_library is None:
            raise SystemExit("the model is not compiled: the figures need a C compiler")
        cells = []
        for name, source in zip(names, sides, strict=True):
            cold, cached = measure(
                n, model.compiled_library, source, not args.no_cold, args.virtual_machine
            )
            first = "-" if cold is None else f"{cold['first']:.3f}"
            cells.append(
                f"{' ' * len(name)}  {first:>8s}  {cached['first']:10.3f}  {cached['warm']:8.3f}"
            )
        print(f"{n:<3d}  " + "  |  ".join(cells) + f"  {cached['stability']}", flush=True)


if __name__ == "__main__":
    main()
