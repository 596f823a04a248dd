"""One version: ``softcurve --version``, ``softcurve.__version__`` and the newest release
of CHANGELOG.md (its first ``## X.Y.Z`` heading) say the same."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import softcurve

CHANGELOG = Path(__file__).resolve().parents[1] / "CHANGELOG.md"
RELEASE = re.compile(r"^## (\d+\.\d+\.\d+)\s*$", re.MULTILINE)


def newest_release(text: str) -> str:
    """The version of the first release heading (``## 0.3.0``) of a changelog."""
    found = RELEASE.search(text)
    assert found, "CHANGELOG.md has no release heading '## X.Y.Z'"
    return found.group(1)


def test_the_command_the_package_and_the_changelog_agree():
    printed = subprocess.run(
        [sys.executable, "-m", "softcurve", "--version"],
        capture_output=True,
        text=True,
        check=True,
    ).stdout.strip()
    released = newest_release(CHANGELOG.read_text(encoding="utf-8"))
    assert printed == f"softcurve {softcurve.__version__}"
    assert softcurve.__version__ == released


def test_unreleased_sections_name_no_version():
    """Work not yet released sits under a bare "## Unreleased" heading above the newest
    release, never under a heading that names a version ("Unreleased (0.3.0)")."""
    text = CHANGELOG.read_text(encoding="utf-8")
    headings = re.findall(r"^## (.+)$", text, re.MULTILINE)
    assert headings[0] in ("Unreleased", newest_release(text)), headings[0]
    assert not [h for h in headings if h.startswith("Unreleased") and h != "Unreleased"]


def test_the_newest_release_is_found_below_unreleased():
    text = "# Changelog\n\n## Unreleased\n\n- a\n\n## 1.2.3\n\n## 1.2.2\n"
    assert newest_release(text) == "1.2.3"
