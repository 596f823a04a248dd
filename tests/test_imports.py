"""What starting softcurve imports: ``import softcurve`` and ``softcurve --help`` must not
load heavy modules that only a few functions use (``scipy.stats`` alone took half a
second to import, eight on a busy machine). Checked on the modules loaded, in a fresh
interpreter, never on time."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

HEAVY = ("scipy.stats",)
"""Imported where used (the starts of ``equilibria``, a fit's confidence intervals)."""

LOADED = """
import json, sys
{code}
print(json.dumps(sorted(sys.modules)))
"""


def _modules_after(code: str) -> set[str]:
    run = subprocess.run(
        [sys.executable, "-c", LOADED.format(code=code)], capture_output=True, text=True
    )
    assert run.returncode == 0, run.stderr
    return set(json.loads(run.stdout.splitlines()[-1]))


@pytest.mark.parametrize(
    "code",
    [
        "import softcurve",
        "from softcurve.cli import main\ntry:\n    main(['--help'])\nexcept SystemExit:\n    pass",
        "from softcurve.cli import main\ntry:\n    main(['simulate', '--t-final', '-1'])\n"
        "except SystemExit:\n    pass",
    ],
    ids=["import", "help", "bad-input"],
)
def test_starting_softcurve_loads_no_heavy_module(code):
    loaded = _modules_after(code)
    heavy = sorted(m for m in loaded if any(m == h or m.startswith(h + ".") for h in HEAVY))
    assert not heavy, f"{code!r} imports {heavy[:5]}: import them where they are used"


def test_the_check_sees_a_heavy_import():
    assert "scipy.stats" in _modules_after("import scipy.stats")
