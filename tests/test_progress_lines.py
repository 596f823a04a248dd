"""What softcurve says while it works, from Python and outside a terminal.

A compile says on its first build what it compiles, where it caches it and how long it
took, through the logger ``softcurve.compiled`` (a plain script sees it on stderr, a
configured application through its configuration, once; silenced by the logger's
level); a small sweep runs in this process; a sweep and ``codegen --check`` whose stderr
is a pipe print lines of progress.
"""

from __future__ import annotations

import logging
import os
import subprocess
import sys
import textwrap

import pytest

import softcurve as sc
from softcurve.base import progress
from tests.test_faults import SWEEP_TOML


@pytest.fixture
def empty_cache(tmp_path, monkeypatch):
    """An empty cache folder for this test."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(folder))
    return folder


def test_a_model_says_its_first_compile_and_only_that(empty_cache, caplog):
    """Before: ``sc.Model(robot)`` compiled in silence (30 s to minutes)."""
    caplog.set_level(logging.INFO, logger="softcurve")
    model = sc.Model(sc.presets.ifac2020())
    said = [r for r in caplog.records if r.name == "softcurve.compiled"]
    assert [r.levelno for r in said] == [logging.INFO, logging.INFO]
    begin, end = (r.getMessage() for r in said)
    assert begin.startswith("compiling the model of 1 segment (C, cached in ")
    assert str(empty_cache) in begin and "for later runs" in begin
    assert end.startswith("compiled the model of 1 segment in ")
    assert end.endswith(model.compiled_library.name)
    caplog.clear()
    sc.Model(sc.presets.ifac2020(damping=False))  # the same structure: loaded, not compiled
    assert [r for r in caplog.records if r.name.startswith("softcurve")] == []


SCRIPT = textwrap.dedent(
    """
    import logging, sys
    import casadi as ca
    from softcurve.compiled import compile_function

    mode = sys.argv[1]
    if mode == "silenced":
        logging.getLogger("softcurve").setLevel(logging.WARNING)
    elif mode == "progress":
        from softcurve.base import log

        logging.getLogger("softcurve").setLevel(logging.DEBUG)
        log.LINE_EVERY = 1e-3
    elif mode == "configured":
        logging.basicConfig(format="app %(name)s %(message)s", level=logging.INFO)
    x = ca.SX.sym("x")
    compile_function(ca.Function("tiny", [x], [2 * ca.sin(x)]))
    """
)


def _script(mode: str, cache) -> list[str]:
    """The lines on stderr of :data:`SCRIPT` in ``mode`` with an empty cache ``cache``."""
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT, mode],
        capture_output=True,
        text=True,
        env={**os.environ, "SOFTCURVE_CACHE_DIR": str(cache)},
        timeout=600,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    assert any(cache.glob("function_*.so")), done.stderr  # it compiled, whatever it said
    return done.stderr.splitlines()


def test_a_plain_script_sees_the_compile_on_stderr(tmp_path):
    lines = _script("plain", tmp_path / "cache")
    assert len(lines) == 2, lines
    assert lines[0].startswith("softcurve: compiling the function tiny (C, cached in ")
    assert lines[1].startswith("softcurve: compiled the function tiny in ")


def test_the_logger_level_silences_it_or_adds_the_seconds(tmp_path):
    assert _script("silenced", tmp_path / "silenced") == []
    lines = _script("progress", tmp_path / "progress")
    so_far = [line for line in lines if line.startswith("softcurve: compiling the function")]
    assert len(so_far) >= 2 and all("s so far" in line for line in so_far[1:]), lines
    assert lines[-1].startswith("softcurve: compiled the function tiny in ")


def test_a_configured_application_gets_each_record_once(tmp_path):
    lines = _script("configured", tmp_path / "cache")
    assert len(lines) == 2, lines
    assert all(line.startswith("app softcurve.compiled compil") for line in lines), lines


# -- sweeps: their workers, their lines outside a terminal --------------------------------
def test_a_pool_pays_only_for_enough_work_on_one_thread():
    from softcurve.simulation.batch import POOL_START, pool_pays

    cores = 2
    assert not pool_pays(wall=1.0, cpu=2.0, remaining=1000, processes=cores)  # on 2 threads
    assert pool_pays(wall=1.0, cpu=1.0, remaining=1000, processes=cores)  # on one thread
    few = int(POOL_START)  # one-thread work of fewer seconds than a pool takes to start
    assert not pool_pays(wall=1.0, cpu=1.0, remaining=few, processes=cores)
    assert not pool_pays(wall=100.0, cpu=100.0, remaining=1, processes=cores)
    assert not pool_pays(wall=100.0, cpu=100.0, remaining=50, processes=1)


def test_a_small_sweep_runs_in_this_process(tmp_path):
    """Before: its default, a pool of one worker per core, took 14.4 s where this process
    took 7.5 s (``examples/sweep_grid.toml``)."""
    pytest.importorskip("pyarrow")
    from softcurve.scenarios.sweep import run_sweep

    config = tmp_path / "sweep.toml"
    config.write_text(SWEEP_TOML.format(t_final=0.05, points=4))
    result = run_sweep(config, tmp_path / "out")
    assert result.success and result.chunks_run == 4
    assert result.stats["workers"] == 0
    explicit = run_sweep(config, tmp_path / "explicit", workers=0, restart=True)
    assert explicit.stats["workers"] == 0 and explicit.table.equals(result.table)


class Pipe:
    """A text stream that is not a terminal and keeps what it was given."""

    def __init__(self):
        self.text = ""

    def write(self, text: str) -> int:
        self.text += text
        return len(text)

    def flush(self) -> None:
        pass

    def isatty(self) -> bool:
        return False


def test_outside_a_terminal_progress_is_a_line_per_tenth(monkeypatch):
    monkeypatch.setattr(progress, "LINE_EVERY", 1e9)  # the tenths alone
    stream = Pipe()
    bar = progress.ProgressLine(100, unit="rows", stream=stream)
    for done in range(1, 101):
        bar.update(done)
    bar.close()
    lines = stream.text.splitlines()
    assert len(lines) == 11 and "\r" not in stream.text  # 0/100, then each tenth
    assert lines[-1].startswith("[") and "100/100 rows" in lines[-1]


def test_outside_a_terminal_progress_is_a_line_per_interval(monkeypatch):
    """No unit finishes: a line every ``LINE_EVERY`` seconds all the same."""
    monkeypatch.setattr(progress, "LINE_EVERY", 1e-3)
    stream = Pipe()
    bar = progress.ProgressLine(2, unit="chunks", stream=stream, beat=True)
    while stream.text.count("\n") < 3:  # the first line and two of the interval
        bar.stop.wait(1e-3)
    bar.close()
    assert all(line.startswith("[") and "0/2 chunks" in line for line in stream.text.splitlines())


def _softcurve(*argv, cwd) -> subprocess.CompletedProcess:
    """``softcurve argv`` with its stdout and stderr pipes (not terminals)."""
    cli = "import sys; from softcurve.cli import main; sys.exit(main())"
    return subprocess.run(
        [sys.executable, "-c", cli, *map(str, argv)],
        capture_output=True,
        text=True,
        cwd=cwd,
        timeout=600,
        check=False,
    )


def test_a_sweep_into_a_pipe_prints_its_progress_as_lines(tmp_path):
    """Before: nothing on stderr until the end, outside a terminal."""
    pytest.importorskip("pyarrow")
    config = tmp_path / "sweep.toml"
    config.write_text(SWEEP_TOML.format(t_final=0.05, points=3))
    done = _softcurve("sweep", config, "-o", tmp_path / "out", cwd=tmp_path)
    assert done.returncode == 0, done.stderr
    lines = [line for line in done.stderr.splitlines() if " chunks, " in line]
    assert [line.split("] ")[1].split()[0] for line in lines] == ["0/3", "1/3", "2/3", "3/3"]
    assert "\r" not in done.stderr
    quiet = _softcurve("sweep", config, "-o", tmp_path / "quiet", "-q", cwd=tmp_path)
    assert quiet.returncode == 0 and quiet.stderr == "", quiet.stderr


def test_codegen_check_into_a_pipe_says_what_it_runs(tmp_path):
    """Before: nothing until the test program had been compiled and run."""
    done = _softcurve("codegen", "-o", tmp_path / "c", "--check", cwd=tmp_path)
    if done.returncode != 0 and "test FAILED" in done.stderr:
        pytest.skip(f"no working C compiler: {done.stderr}")
    assert done.returncode == 0, done.stderr
    said = "softcurve codegen: compiling and running the test program ..."
    assert done.stderr.splitlines()[:1] == [said], done.stderr
