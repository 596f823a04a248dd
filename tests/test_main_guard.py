"""Worker processes are spawned and run the main script again: a script that starts them
outside ``if __name__ == "__main__":`` is stopped before any worker starts, with a
message that says what to write (issue 33, item 1)."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap

import pytest

SCRIPT = """\
import softcurve as sc

print("top level ran", flush=True)
model = sc.Model(sc.presets.ifac2020())
q0 = [[0.064, 5.0, 0.0], [0.064, -5.0, 0.0]]


def run():
    return sc.simulate_batch(model, q0, [0.0, 0.0, 0.0], t_final=0.01, dt=0.01, processes=2)


{call}
"""


def _run(tmp_path, call: str) -> subprocess.CompletedProcess:
    script = tmp_path / "study.py"
    script.write_text(SCRIPT.format(call=textwrap.dedent(call)))
    return subprocess.run(
        [sys.executable, str(script)],
        capture_output=True,
        text=True,
        timeout=300,
        env={**os.environ, "PYTHONWARNINGS": "ignore"},
    )


@pytest.mark.parametrize(
    "call, line",
    [
        ("batch = run()\n", 12),  # a function called from the top level
        ("for _ in range(1):\n    batch = run()\n", 13),  # inside another statement
    ],
)
def test_an_unguarded_script_is_stopped_before_any_worker_starts(tmp_path, call, line):
    done = _run(tmp_path, call)
    assert done.returncode == 1
    assert f"study.py, line {line}: this call starts worker processes" in done.stderr
    assert 'if __name__ == "__main__":' in done.stderr and "processes=1" in done.stderr
    assert done.stdout.count("top level ran") == 1  # no worker ran the script again


def test_a_guarded_script_runs_its_batch_in_workers(tmp_path):
    done = _run(tmp_path, 'if "__main__" == __name__:\n    print(run().success)\n')
    assert done.returncode == 0, done.stderr
    assert done.stdout.splitlines()[-1] == "True"
    # the top level outside the guard still runs in each worker started: that is spawning
    assert done.stdout.count("top level ran") >= 2
