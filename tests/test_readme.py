"""The README's quickstart runs as written."""

from __future__ import annotations

import re
import subprocess
import sys
from pathlib import Path

import matplotlib.pyplot as plt
import pytest

README = Path(__file__).resolve().parents[1] / "README.md"


def test_quickstart_runs(capsys):
    match = re.search(r"## Quickstart\n\n```python\n(.*?)```", README.read_text(), re.S)
    assert match, "README.md has no Python quickstart block"
    namespace: dict = {}
    exec(compile(match.group(1), "README quickstart", "exec"), namespace)
    assert namespace["trajectory"].success
    assert "[[" in capsys.readouterr().out  # the mass matrix was printed
    plt.close("all")


SCRIPTS = sorted(
    str(p.relative_to(README.parent))
    for folder in ("examples", "benchmarks")
    for p in (README.parent / folder).glob("*.py")
    if not p.name.startswith("_")  # helpers the scripts import, not scripts
)


@pytest.mark.parametrize("script", SCRIPTS)
def test_every_example_and_benchmark_starts(script):
    """Each script the README names imports the current API and parses its options (a
    renamed function fails here, not in a user's hands)."""
    done = subprocess.run(
        [sys.executable, script, "--help"],
        capture_output=True, text=True, timeout=120, cwd=README.parent,
    )  # fmt: skip
    assert done.returncode == 0, done.stderr[-2000:]
    assert "usage:" in done.stdout


@pytest.mark.parametrize(
    ("command", "field"),
    [
        (["benchmarks/bench_planning.py", "--tendons", "--segments", "3"], "--segments"),
        (["benchmarks/bench_planning.py", "--tendons", "--effort-weight", "0"], "--effort-weight"),
        (["benchmarks/study_implicit_dynamics.py", "--segments", "5"], "--segments"),
        (["benchmarks/study_rest_at_end.py", "--horizon", "-1"], "--horizon"),
    ],
)
def test_the_planning_studies_refuse_a_bad_option_before_any_work(command, field):
    """An odd chain, a weight or horizon that is not positive: exit 2 naming the option."""
    done = subprocess.run(
        [sys.executable, *command], capture_output=True, text=True, timeout=120,
        cwd=README.parent,
    )  # fmt: skip
    assert done.returncode == 2 and field in done.stderr, done.stderr[-2000:]
