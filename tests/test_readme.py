"""The README's quickstart runs as written."""

from __future__ import annotations

import re
from pathlib import Path

import matplotlib.pyplot as plt

README = Path(__file__).resolve().parents[1] / "README.md"


def test_quickstart_runs(capsys):
    match = re.search(r"## Quickstart\n\n```python\n(.*?)```", README.read_text(), re.S)
    assert match, "README.md has no Python quickstart block"
    namespace: dict = {}
    exec(compile(match.group(1), "README quickstart", "exec"), namespace)
    assert namespace["trajectory"].success
    assert "[[" in capsys.readouterr().out  # the mass matrix was printed
    plt.close("all")
