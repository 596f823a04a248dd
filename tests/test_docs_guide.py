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
    ],
)
def test_each_mark_is_caught(line):
    assert _findings(line), line


def test_a_guide_line_passes():
    line = "`python benchmarks/bench_simulate.py --quick`: 3.35 ms, x86_64, 2 cores, rtol 1e-6"
    assert not _findings(line)
