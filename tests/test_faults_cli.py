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
import re
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
import pytest

import softcurve as sc
from softcurve import cli
from softcurve.base.validation import ParameterError
from softcurve.cli import main
from tests.conftest import sigint_default
from tests.test_faults import SWEEP_TOML, alive, descendants, leftovers, run, working


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
            preexec_fn=sigint_default,
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

    def ctrl_c(self, timeout: float = 30) -> tuple[int, str, str]:
        """Send SIGINT to the process group; ``(exit code, stderr, stderr before the
        SIGINT)``."""
        before = self.err.decode(errors="replace")
        os.killpg(self.process.pid, signal.SIGINT)
        code = self.process.wait(timeout=timeout)
        self.reader.join(timeout=10)
        return code, self.err.decode(errors="replace"), before

    def kill(self):
        """End it if it still runs, and close its stderr."""
        if self.process.poll() is None:
            os.killpg(self.process.pid, signal.SIGKILL)
            self.process.wait()
        self.reader.join(timeout=10)
        self.process.stderr.close()


def blocks_written(err: str) -> tuple[int, int]:
    """``(blocks written, blocks in all)`` at the last redraw of the progress bar of a CSV
    write in ``err``."""
    counts = re.findall(r"writing trajectory\.csv \[[#.]*\] (\d+)/(\d+) blocks", err)
    assert counts, err
    return int(counts[-1][0]), int(counts[-1][1])


def test_ctrl_c_during_a_long_csv_write_stops_at_once(compiled, tmp_path):
    """It stops within the block of rows it is writing: the progress bar counts no more than
    a block or two beyond what it showed at the SIGINT (of eleven), a budget on work."""
    out = tmp_path / "out"
    # 1e6 rows, 300 MB of CSV: eleven blocks, seconds each
    command = Command(
        ["simulate", "-o", out, "--t-final", "100", "--dt", "1e-4", "--no-figures", "--progress"]
    )
    try:
        command.wait_for(" blocks, ")  # the progress bar of the CSV write, drawn whole
        time.sleep(0.3)  # inside the first blocks of rows
        code, err, before = command.ctrl_c()
    finally:
        command.kill()
    assert code == 130, err
    assert "Traceback" not in err and "KeyboardInterrupt" not in err
    assert "softcurve simulate: interrupted: nothing written to" in err
    # the block being written when the SIGINT came is abandoned; the bar may have counted
    # a block or two more than this process had read when it sent the SIGINT
    (written, blocks), (shown, _) = blocks_written(err), blocks_written(before)
    assert written <= shown + 2 and written < blocks, err
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
    from softcurve.compiled import _model as functions

    q = np.c_[np.linspace(0.05, 0.08, 2500), np.linspace(-30, 30, 2500), np.zeros(2500)]
    widths = []
    real = functions.Model.cached

    def counting(self, key, build):
        value = real(self, key, build)
        if key[0] == "map":
            function, mapped = value

            def call(*args):
                widths.append(mapped.size2_in(0))
                return mapped(*args)

            return function, call
        return value

    monkeypatch.setattr(functions.Model, "cached", counting)
    rotation, tip = compiled.evaluate_along("pose", q, 1.0)
    assert len(widths) >= 3 and max(widths) <= functions.POINTS_PER_CALL
    assert tip.shape == (2500, 3) and rotation.shape == (2500, 9)
    for k in (0, 1023, 1024, 2499):
        np.testing.assert_allclose(tip[k], compiled.tip_pose(q[k]).position, rtol=1e-12)
    assert [a.shape for a in compiled.evaluate_along("pose", q[:0], 1.0)] == [(0, 9), (0, 3)]


# -- item 8: exit codes and the order of checks ---------------------------------------------
@pytest.fixture
def data_csv(tmp_path) -> Path:
    path = tmp_path / "data.csv"
    path.write_text("x,f\n" + "".join(f"{x},{2 * x}\n" for x in np.linspace(-1, 1, 9)))
    return path


@pytest.fixture
def symlink_loop(tmp_path) -> Path:
    (tmp_path / "loop1").symlink_to(tmp_path / "loop2")
    (tmp_path / "loop2").symlink_to(tmp_path / "loop1")
    return tmp_path / "loop1"


@pytest.mark.parametrize("command", ["simulate", "sweep", "equilibria", "codegen"])
def test_symlink_loop_as_input_is_bad_input(symlink_loop, tmp_path, capsys, command):
    output = [] if command == "equilibria" else ["-o", tmp_path / "out"]
    code, out, err = run([command, symlink_loop, *output], capsys)
    assert code == 2 and "loop of symbolic links" in err and str(symlink_loop) in err
    assert "free space" not in err and out == ""
    assert not (tmp_path / "out").exists() or leftovers(tmp_path / "out") == []


@pytest.mark.parametrize("seed", ["-1", "x"])
def test_equilibria_seed_is_checked_before_work(capsys, seed):
    if seed == "x":  # argparse's own check of an integer: exit 2 naming --seed
        with pytest.raises(SystemExit) as caught:
            main(["equilibria", "--seed", seed])
        assert caught.value.code == 2 and "--seed" in capsys.readouterr().err
        return
    code, out, err = run(["equilibria", "--seed", seed], capsys)
    assert code == 2 and "--seed" in err and "integer >= 0" in err and "got -1" in err
    assert out == "" and "ValueError" not in err


@pytest.mark.parametrize("seed", ["x", -1, 1.5, True])
def test_equilibria_seed_is_a_parameter_error_in_the_library(seed):
    model = sc.Model(sc.presets.ifac2020(), compile=False)
    with pytest.raises(ParameterError, match=r"seed must be an integer >= 0"):
        sc.equilibria(model, starts=2, seed=seed)


@pytest.mark.parametrize(
    "argv, option",
    [
        (["fit", "{csv}", "--strain", "x", "--force", "f", "--figure", "{dir}/f.xyz"], "--figure"),
        (["equilibria", "--plot", "{dir}/x.xyz"], "--plot"),
        (["sweep", "{sweep}", "-o", "{dir}/out", "--figure", "s.xyz"], "--figure"),
    ],
)
def test_unsupported_figure_format_is_refused_before_work(data_csv, tmp_path, capsys, argv, option):
    sweep = tmp_path / "sweep.toml"
    sweep.write_text(SWEEP_TOML.format(t_final=0.1, points=2))
    argv = [a.format(csv=data_csv, dir=tmp_path, sweep=sweep) for a in argv]
    code, out, err = run(argv, capsys)
    assert code == 2 and option in err and ".xyz" in err and "'.png'" in err
    assert out == ""  # no table: nothing was computed
    assert not (tmp_path / "out").exists()


def test_codegen_prefix_is_checked_before_the_folder_is_made(tmp_path, capsys):
    out = tmp_path / "c"
    code, _, err = run(["codegen", "--prefix", "1bad", "-o", out], capsys)
    assert code == 2 and "--prefix" in err and "C identifier" in err and "'1bad'" in err
    assert not out.exists()


@pytest.mark.parametrize("option", [["--starts", "0"], ["--starts", "-3"]])
def test_equilibria_starts_is_named_as_the_option(capsys, option):
    code, out, err = run(["equilibria", *option], capsys)
    assert code == 2 and "--starts" in err and "integer >= 1" in err and out == ""


# -- item 9: files and messages --------------------------------------------------------------
def test_csv_with_a_byte_order_mark_is_read(tmp_path, capsys):
    path = tmp_path / "excel.csv"
    rows = "".join(f"{x},{2 * x}\r\n" for x in np.linspace(0.1, 1, 9))
    path.write_bytes("x,f\r\n".encode("utf-8-sig") + rows.encode())
    code, out, err = run(["fit", path, "--strain", "x", "--force", "f", "--law", "linear"], capsys)
    assert code == 0, err
    assert "LinearStiffness(k0=2)" in out


@pytest.mark.parametrize(
    "make, words",
    [
        (lambda tmp: Path("/dev/null"), "is a device, not a file"),
        (lambda tmp: tmp, "is a folder, not a file"),
        (lambda tmp: tmp / "missing.csv", "does not exist"),
    ],
)
@pytest.mark.parametrize("command", ["fit", "simulate"])
def test_input_that_is_not_a_file_is_named(tmp_path, capsys, make, words, command):
    path = make(tmp_path)
    argv = [command, path] + (["--strain", "x", "--force", "f"] if command == "fit" else [])
    code, out, err = run(
        [*argv, *(["-o", tmp_path / "o"] if command == "simulate" else [])], capsys
    )
    assert code == 2 and words in err and str(path) in err and out == ""
    if words != "does not exist":
        assert "does not exist" not in err


def test_a_full_disk_names_the_file(compiled, tmp_path, capsys, monkeypatch):
    from softcurve.simulation.results import _files as trajectory_files

    def full(out, table, name, progress):
        out.write("0,1,2\n")
        raise OSError(errno.ENOSPC, os.strerror(errno.ENOSPC))

    monkeypatch.setattr(trajectory_files, "_write_rows", full)
    out = tmp_path / "out"
    code, _, err = run(["simulate", "-o", out, "--t-final", "0.01", "--no-figures"], capsys)
    assert code == 1 and str(out / "trajectory.csv") in err and "No space left" in err
    assert "free space" in err
    assert leftovers(out) == [] and not (out / "trajectory.csv").exists()


def test_equilibria_advice_names_options_that_exist(capsys):
    code, out, err = run(["equilibria", "--tip-force", "0", "0", "100", "--starts", "8"], capsys)
    assert code == 1, out + err
    assert "none inside the box searched" in out and "--starts" in out and "--tip-force" in out
    assert "widen" not in out + err


@pytest.fixture
def finished_sweep(compiled, tmp_path, capsys):
    pytest.importorskip("pyarrow")
    config = tmp_path / "sweep.toml"
    config.write_text(SWEEP_TOML.format(t_final=0.1, points=2))
    out = tmp_path / "out"
    argv = ["sweep", config, "-o", out, "--workers", "0", "--no-progress", "-q"]
    code, _, err = run(argv, capsys)
    assert code == 0, err
    return argv, out


@pytest.mark.parametrize(
    "damage",
    [
        lambda text: "{}",
        lambda text: "[1, 2]",
        lambda text: text[: len(text) // 2],
        lambda text: json.dumps({**json.loads(text), "fingerprint": None}),
        lambda text: "\0" * len(text),
    ],
)
def test_damaged_sweep_manifest_is_named_damaged(finished_sweep, capsys, damage):
    argv, out = finished_sweep
    manifest = out / "manifest.json"
    manifest.write_text(damage(manifest.read_text()))
    code, _, err = run(argv, capsys)
    assert code == 2 and "damaged sweep manifest" in err and str(manifest) in err
    assert "--restart" in err and "another sweep" not in err
    code, _, err = run([*argv, "--restart"], capsys)  # what the message says works
    assert code == 0, err


def test_sweep_manifest_of_another_configuration_is_another_sweep(finished_sweep, capsys):
    argv, out = finished_sweep
    manifest = out / "manifest.json"
    manifest.write_text(json.dumps({**json.loads(manifest.read_text()), "fingerprint": "0" * 16}))
    code, _, err = run(argv, capsys)
    assert code == 2 and "another sweep" in err and "damaged" not in err


@pytest.mark.parametrize("argv", [["simulate", "--html"], ["equilibria", "--html", "{dir}/v.html"]])
def test_viewer_without_plotly_is_refused_before_work(tmp_path, capsys, monkeypatch, argv):
    from softcurve.cli import _options

    monkeypatch.setattr(_options, "_installed", lambda module: module != "plotly")
    out = tmp_path / "out"
    argv = [a.format(dir=tmp_path) for a in argv]
    code, printed, err = run([*argv, *(["-o", out] if argv[0] == "simulate" else [])], capsys)
    assert code == 2 and "--html" in err and "softcurve[viewer]" in err and printed == ""
    assert not out.exists() and not (tmp_path / "v.html").exists()


def interrupt(*args, **kwargs):
    raise KeyboardInterrupt


def test_ctrl_c_in_any_command_is_one_line_and_130(capsys, monkeypatch):
    from softcurve.analysis import statics

    monkeypatch.setattr(statics, "equilibria", interrupt)
    code, out, err = run(["equilibria", "--starts", "2"], capsys)
    assert code == 130 and out == ""
    assert err.strip() == f"softcurve equilibria: interrupted: {cli.NOTHING_HALF_WRITTEN}"


def test_ctrl_c_while_the_commands_are_imported(capsys, monkeypatch):
    monkeypatch.setattr(cli, "build_parser", interrupt)
    code, _, err = run(["simulate"], capsys)
    assert code == 130 and err.strip() == "softcurve: interrupted before starting: nothing was done"


@pytest.mark.parametrize("under", ["", "sub"])
def test_symlink_loop_as_output_folder_is_named(symlink_loop, capsys, under):
    out = symlink_loop / under if under else symlink_loop
    code, _, err = run(["simulate", "-o", out, "--t-final", "0.01"], capsys)
    assert code == 2 and "--output" in err and "loop of symbolic links" in err
