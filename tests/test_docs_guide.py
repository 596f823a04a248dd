"""The guide (``docs/*.md``) describes what holds now, not a run history: no page names a
date, a clock time of a run, the project's internal notes, people or work sessions.
History goes to ``CHANGELOG.md``, which is not a guide page."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

DOCS = Path(__file__).resolve().parents[1] / "docs"
PAGES = sorted(DOCS.glob("*.md"))

#: What marks a page as a lab notebook rather than a guide, each with what it catches.
NOTEBOOK = {
    "a date": re.compile(r"\b\d{4}-\d{2}-\d{2}\b"),
    "a clock time": re.compile(r"\b\d{1,2}:\d{2}\s*UTC\b"),
    "a link to the project's internal notes": re.compile(r"shared/design"),
    "a person": re.compile(r"\bthe lead\b", re.IGNORECASE),
    "a work session": re.compile(r"\bstop\)"),
    "an issue number": re.compile(r"\bissues? \d+", re.IGNORECASE),
    "who owns a section": re.compile(r"\bhelper\b|\bowned by\b", re.IGNORECASE),
    "an account of the machine's load": re.compile(
        r"load average|\bat (a )?load \d|\b(quiet|idle|busy|loaded|shared),? "
        r"(2-core |x86_64 )?machine\b|busy cores|nothing else running|shared with other jobs|"
        r"machine's (load|noise)",
        re.IGNORECASE,
    ),
}


def _findings(text: str) -> list[str]:
    """Every notebook mark in ``text``, as ``line N: what: the line``."""
    found = []
    for number, line in enumerate(text.splitlines(), start=1):
        for what, pattern in NOTEBOOK.items():
            if pattern.search(line):
                found.append(f"line {number}: {what}: {line.strip()}")
    return found


def test_the_guide_has_pages():
    assert len(PAGES) > 10, PAGES


@pytest.mark.parametrize("page", PAGES, ids=[page.name for page in PAGES])
def test_a_page_reads_as_a_guide(page):
    findings = _findings(page.read_text(encoding="utf-8"))
    assert not findings, f"{page.name} carries run history:\n" + "\n".join(findings)


@pytest.mark.parametrize(
    "line",
    [
        "measured on 2026-12-01",
        "at 05:22 UTC",
        "see shared/design/MODEL.md",
        "The lead's runs",
        "(third stop)",
        "These are still open in issue 13:",
        "<!-- BEGIN section owned by the statics helper -->",
        "best of 5; two cores, shared with other jobs, load average about 5",
        "Measured on a quiet machine with `python benchmarks/bench_contact.py`",
        "1 s simulated in 0.10 s on a loaded machine",
        "measured on a shared, loaded 2-core machine",
        "8.5 s for three on an idle machine",
        "90 s for ten, on two busy cores",
        "10 s at load 4",
    ],
)
def test_each_mark_is_caught(line):
    assert _findings(line), line


def test_a_guide_line_passes():
    line = "`python benchmarks/bench_simulate.py --quick`: 3.35 ms, x86_64, 2 cores, rtol 1e-6"
    assert not _findings(line)


def _load(path: Path):
    import importlib.util

    spec = importlib.util.spec_from_file_location(path.stem, path)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def _gallery_table() -> dict:
    return _load(DOCS / "_ext" / "softcurve_docs.py").GALLERY_FIGURES


LARGEST = _load(DOCS / "gallery_figures.py").LARGEST


def _examples() -> list[str]:
    folder = DOCS.parent / "examples"
    return sorted(
        p.name for p in folder.iterdir() if p.suffix in (".py", ".toml") and p.name[0] != "_"
    )


def gallery_problems(
    table: dict, examples: list[str], figures: Path, largest: int = LARGEST
) -> list[str]:
    """What keeps a gallery page from showing its example's figures, or the figures from
    being redrawn by docs/gallery_figures.py: an example without an entry or without a
    figure, an entry for no example, a figure missing from docs/figures, a command that
    does not run the example or writes nowhere, a figure larger than ``largest`` bytes."""
    problems = [
        f"{name}: no gallery figure" for name in examples if not table.get(name, ("", {}))[1]
    ]
    problems += [f"{name}: no such example" for name in table if name not in examples]
    for name, (command, made) in table.items():
        if f"examples/{name}" not in command or "{out}" not in command:
            problems.append(f"{name}: the command {command!r} does not run it into {{out}}")
        if command.split()[0] not in ("python", "softcurve"):
            problems.append(f"{name}: the command {command!r} is not python or softcurve")
        problems += [
            f"{name}: docs/figures/{f} is missing" for f in made if not (figures / f).is_file()
        ]
        problems += [
            f"{name}: docs/figures/{f} is larger than {largest} bytes"
            for f in made
            if (figures / f).is_file() and (figures / f).stat().st_size > largest
        ]
    return problems


def test_every_example_page_has_a_figure_that_can_be_redrawn():
    """The README promises "the examples with their figures": each example of examples/
    has at least one figure in the gallery, on disk, with the command that redraws it
    (before: 11 of 19 pages had none)."""
    table = _gallery_table()
    assert gallery_problems(table, _examples(), DOCS / "figures") == []
    # the check fails where it should: an example left out, a figure deleted
    fewer = {k: v for k, v in table.items() if k != "hanging.toml"}
    assert gallery_problems(fewer, _examples(), DOCS / "figures") == [
        "hanging.toml: no gallery figure"
    ]
    renamed = {**table, "hanging.toml": (table["hanging.toml"][0], {"gone.png": "states.png"})}
    assert gallery_problems(renamed, _examples(), DOCS / "figures") == [
        "hanging.toml: docs/figures/gone.png is missing"
    ]
    only = {"hanging.toml": table["hanging.toml"]}
    size = (DOCS / "figures" / "hanging_states.png").stat().st_size
    assert gallery_problems(only, ["hanging.toml"], DOCS / "figures", largest=size - 1) == [
        f"hanging.toml: docs/figures/hanging_states.png is larger than {size - 1} bytes"
    ]
