"""Redraw the gallery's figures: run each example's command and copy its figures into
docs/figures/.

    python docs/gallery_figures.py [--only EXAMPLE ...] [--list]

The commands and which file of each run is which figure are the table
``GALLERY_FIGURES`` of ``docs/_ext/softcurve_docs.py``, the one the site's gallery reads.
Each command runs from the repository's root in a fresh folder (``{out}``), with this
Python and Matplotlib's Agg backend; a figure is copied into docs/figures/ whole or not
at all, after its command succeeded, as a PNG of at most 256 colours (a figure's lines,
text and colour maps need no more; it keeps each file a third of Matplotlib's size, under
:data:`LARGEST`). Prints each example's time and each figure's size.
The validation examples read their data from ``$SOFTCURVE_DATA`` (or ../shared/data) and
``train_reach.py`` needs PyTorch and Stable-Baselines3 (``pip install "softcurve[rl]"``);
without them those examples are reported and skipped; the last line counts the
examples redrawn, skipped and failed (exit code 1 if any failed).
"""

from __future__ import annotations

import argparse
import functools
import importlib.util
import os
import shlex
import subprocess
import sys
import tempfile
import time
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / "docs" / "figures"
NEEDS = {
    "train_reach.py": ("torch", "stable_baselines3"),
}
"""Python modules an example needs beyond softcurve's own dependencies."""
READS_DATA = ("validate_joint.py", "validate_caasenbrood2021.py")
"""Examples that read the caasenbrood2021 recordings (found as
``examples/validate_caasenbrood2021.py`` finds them)."""
COLOURS = 256
"""Colours of a gallery PNG: the most a PNG palette holds."""
LARGEST = 150 * 1024
"""Bytes a gallery figure may take, so that a page loads at once (checked by
``tests/test_docs_guide.py``)."""


def gallery_table() -> dict:
    """``GALLERY_FIGURES`` of the docs extension (imported from its file)."""
    path = ROOT / "docs" / "_ext" / "softcurve_docs.py"
    spec = importlib.util.spec_from_file_location("softcurve_docs", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.GALLERY_FIGURES


def command_line(command: str, out: Path) -> list[str]:
    """The argument list of a table's command, run with this Python."""
    words = shlex.split(command.format(out=out))
    if words[0] == "python":
        return [sys.executable, *words[1:]]
    if words[0] == "softcurve":
        return [sys.executable, "-m", "softcurve", *words[1:]]
    raise ValueError(f"a gallery command starts with python or softcurve, got {command!r}")


def missing(example: str) -> list[str]:
    """What of :data:`NEEDS` and :data:`READS_DATA` this Python lacks for ``example``."""
    absent = [m for m in NEEDS.get(example, ()) if importlib.util.find_spec(m) is None]
    if example in READS_DATA and _data_directory() is None:
        absent.append("the caasenbrood2021 data (set SOFTCURVE_DATA)")
    return absent


@functools.cache
def _data_directory() -> Path | None:
    path = ROOT / "examples" / "validate_caasenbrood2021.py"
    spec = importlib.util.spec_from_file_location("validate_caasenbrood2021", path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module.data_directory()


def redraw(example: str, command: str, figures: dict, out: Path) -> list[Path]:
    """Run ``command`` into ``out`` and copy its ``figures`` into :data:`FIGURES`."""
    environment = {**os.environ, "MPLBACKEND": "Agg"}
    done = subprocess.run(
        command_line(command, out), cwd=ROOT, env=environment, capture_output=True, text=True
    )
    if done.returncode != 0:
        raise RuntimeError(
            f"{example}: exit code {done.returncode}\n{done.stdout[-2000:]}{done.stderr[-2000:]}"
        )
    written = []
    for name, produced in figures.items():
        source = out / produced
        if not source.is_file():
            raise RuntimeError(f"{example}: the command wrote no {produced} into {out}")
        partial = FIGURES / f".{name}.partial"
        compact(source, partial)
        written.append(partial.replace(FIGURES / name))
    return written


def compact(source: Path, target: Path) -> Path:
    """Write the PNG ``source`` to ``target`` on white with a palette of :data:`COLOURS`
    colours (no dithering, so lines and text stay crisp); returns ``target``."""
    from PIL import Image

    with Image.open(source) as image:
        white = Image.new("RGBA", image.size, "white")
        flat = Image.alpha_composite(white, image.convert("RGBA")).convert("RGB")
    palette = flat.quantize(COLOURS, method=Image.Quantize.MEDIANCUT, dither=Image.Dither.NONE)
    palette.save(target, format="PNG", optimize=True)
    return target


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--only", nargs="+", metavar="EXAMPLE", help="these examples only")
    parser.add_argument("--list", action="store_true", help="list the examples and commands")
    args = parser.parse_args(argv)
    table = gallery_table()
    unknown = sorted(set(args.only or ()) - set(table))
    if unknown:
        parser.error(f"not in the gallery's table: {unknown}; it has {sorted(table)}")
    chosen = [name for name in table if not args.only or name in args.only]
    if args.list:
        for name in chosen:
            print(f"{name}: {table[name][0]}")
        return 0
    failed = skipped = 0
    for name in chosen:
        command, figures = table[name]
        absent = missing(name)
        if absent:
            skipped += 1
            print(f"{name}: skipped, needs {', '.join(absent)}")
            continue
        start = time.perf_counter()
        with tempfile.TemporaryDirectory() as folder:
            try:
                written = redraw(name, command, figures, Path(folder))
            except RuntimeError as exc:
                failed += 1
                print(f"{name}: FAILED\n{exc}")
                continue
        sizes = ", ".join(f"{p.name} ({p.stat().st_size // 1024} KB)" for p in written)
        print(f"{name}: {time.perf_counter() - start:.1f} s, wrote {sizes}")
    print(f"{len(chosen) - failed - skipped} redrawn, {skipped} skipped, {failed} failed")
    return 1 if failed else 0


if __name__ == "__main__":
    sys.exit(main())
