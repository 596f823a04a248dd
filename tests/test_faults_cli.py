"""Faults of the command line (issue 29, items 5, 8 and 9): Ctrl-C, exit codes, the order
of checks, input files and the messages a command-line user meets.

Each case asserts the exit code (2: bad input, checked before any work; 1: failure;
130: Ctrl-C), the key words of the one line printed, no traceback, and that no output
file was left half-written.
"""

from __future__ import annotations

import errno
import json
import os
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import softcurve as sc
from softcurve.base.validation import ParameterError
from tests.test_faults import SWEEP_TOML, alive, descendants, leftovers, run, working

ENV = {**os.environ, "PYTHONPATH": str(Path(__file__).resolve().parents[1] / "src")}


@pytest.fixture
def compiled(paper_model):
    """The paper's model, compiled once per session (the CLI reuses the library)."""
    return paper_model


# -- item 5: Ctrl-C --------------------------------------------------------------------------
class Command:
    """``softcurve argv`` in its own session (so that a Ctrl-C reaches it and its workers,
    as a terminal's does), its stderr collected as it comes."""

    def __init__(self, argv):
        self.process = subprocess.Popen(
            [sys.executable, "-m", "softcurve", *map(str, argv)],
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            start_new_session=True,
            env=ENV,
        )
        self.err = bytearray()
        self.reader = threading.Thread(target=self._read, daemon=True)
        self.reader.start()

    def _read(self):
        while chunk := self.process.stderr.read1(4096):
            self.err.extend(chunk)

    def wait_for(self, text: str, timeout: float = 120) -> None:
        deadline = time.monotonic() + timeout
        while text.encode() not in self.err:
            assert self.process.poll() is None, f"ended early: {self.err.decode()}"
            assert time.monotonic() < deadline, f"no {text!r} in {self.err.decode()}"
            time.sleep(0.05)

    def ctrl_c(self, timeout: float = 30) -> tuple[int, str, float]:
        """Send SIGINT to the process group; ``(exit code, stderr, seconds to exit)``."""
        start = time.monotonic()
        os.killpg(self.process.pid, signal.SIGINT)
        code = self.process.wait(timeout=timeout)
        took = time.monotonic() - start
        self.reader.join(timeout=10)
        return code, self.err.decode(errors="replace"), took

    def kill(self):
        """End it if it still runs, and close its stderr."""
        if self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait()
        self.reader.join(timeout=10)
        self.process.stderr.close()


def test_ctrl_c_during_a_long_csv_write_stops_at_once(compiled, tmp_path):
    out = tmp_path / "out"
    # 1e6 rows, 300 MB of CSV: seconds of writing
    command = Command(
        ["simulate", "-o", out, "--t-final", "100", "--dt", "1e-4", "--no-figures", "--progress"]
    )
    try:
        command.wait_for("writing trajectory.csv")
        time.sleep(0.3)  # inside the first blocks of rows
        code, err, took = command.ctrl_c()
    finally:
        command.kill()
    assert code == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    assert "softcurve simulate: interrupted: nothing written to" in err
    assert took < 10  # a generous bound: it stops between two blocks of rows
    assert leftovers(out) == [] and not (out / "trajectory.csv").exists()


def test_ctrl_c_in_a_sweep_keeps_the_chunks_and_says_how_to_resume(compiled, tmp_path):
    pytest.importorskip("pyarrow")
    config = tmp_path / "sweep.toml"
    config.write_text(SWEEP_TOML.format(t_final=1000.0, points=8))  # runs for minutes
    out = tmp_path / "out"
    command = Command(["sweep", config, "-o", out, "--workers", "2", "--no-progress"])
    workers: set[int] = set()
    try:
        deadline = time.monotonic() + 120
        while not working(command.process.pid) and time.monotonic() < deadline:
            assert command.process.poll() is None, command.err.decode()
            time.sleep(0.2)
        workers = descendants(command.process.pid)
        code, err, _ = command.ctrl_c()
        deadline = time.monotonic() + 30
        while alive(workers) and time.monotonic() < deadline:
            time.sleep(0.1)
        assert alive(workers) == set(), "worker processes outlived the interrupted sweep"
    finally:
        command.kill()
        for pid in alive(workers):
            os.kill(pid, signal.SIGKILL)
    assert code == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err  # nor from a worker
    assert "softcurve sweep: interrupted: the chunks written are kept" in err
    assert "run the same command to resume" in err
    assert leftovers(out) == []


def test_evaluations_along_a_trajectory_are_short_calls(compiled, monkeypatch):
    """A Ctrl-C is seen between two compiled calls: the tip of a long trajectory is
    computed in calls of at most POINTS_PER_CALL points, not in one (a minute for 1e7
    points), with the same values."""
    from softcurve.compiled import functions

    q = np.c_[np.linspace(0.05, 0.08, 2500), np.linspace(-30, 30, 2500), np.zeros(2500)]
    widths = []
    real = functions.CompiledFunctions.cached

    def counting(self, key, build):
        value = real(self, key, build)
        if key[0] == "map":
            function, mapped = value

            def call(*args):
                widths.append(mapped.size2_in(0))
                return mapped(*args)

            return function, call
        return value

    monkeypatch.setattr(functions.CompiledFunctions, "cached", counting)
    rotation, tip = compiled.evaluate_along("pose", q, 1.0)
    assert len(widths) >= 3 and max(widths) <= functions.POINTS_PER_CALL
    assert tip.shape == (2500, 3) and rotation.shape == (2500, 9)
    for k in (0, 1023, 1024, 2499):
        np.testing.assert_allclose(tip[k], compiled.tip_pose(q[k]).position, rtol=1e-12)
