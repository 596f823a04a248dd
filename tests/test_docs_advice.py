"""Set-up advice in the README, docs and examples that works where it is followed."""

from __future__ import annotations

import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
CPU_INDEX = "--index-url https://download.pytorch.org/whl/cpu"
"""PyTorch's own index of CPU builds: the advice holds without a local wheel."""


def _advised_files():
    yield ROOT / "README.md"
    yield from sorted((ROOT / "docs").glob("*.md"))
    yield from sorted((ROOT / "examples").glob("*.py"))


def test_every_torch_install_names_pytorchs_cpu_index():
    advice = [
        (path.name, line.strip())
        for path in _advised_files()
        for line in path.read_text(encoding="utf-8").splitlines()
        if re.search(r"pip install\s+[\"']?torch\b", line)
    ]
    assert advice, "the training example's set-up advice is gone"
    assert all(CPU_INDEX in line and "==" not in line for _, line in advice), advice
