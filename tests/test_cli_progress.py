"""A first run says that it compiles the model (issue 31, item 1): what is built, where it
is cached and how long it took, on stderr before the command's own output; a run that
finds the library cached, and ``--quiet``, say nothing about it.

Each test points ``SOFTCURVE_CACHE_DIR`` at an empty folder, so the paper's one-segment
model (the fastest to compile, seconds) is compiled in it once.
"""

from __future__ import annotations

import sys
import time
import warnings

import pytest

import softcurve as sc
from softcurve.base import log, progress
from softcurve.cli import main
from tests.test_faults import SWEEP_TOML

BUILDING = "compiling the model of 1 segment (C, cached in"
BUILT = "compiled the model of 1 segment in"
SUMMARY = "softcurve simulate: built-in paper case"
SIMULATE = ["simulate", "--t-final", "0.05", "--no-figures", "--no-progress"]


class Recorder:
    """A text stream that appends ``(name, text)`` to a list shared with another, so that
    the order of what stdout and stderr were given is kept."""

    def __init__(self, name: str, log: list):
        self.name, self.log = name, log

    def write(self, text: str) -> int:
        self.log.append((self.name, text))
        return len(text)

    def flush(self) -> None:
        pass

    def isatty(self) -> bool:
        return False

    def text(self) -> str:
        return "".join(text for name, text in self.log if name == self.name)


class Terminal(Recorder):
    """A :class:`Recorder` that says it is a terminal (where lines are redrawn)."""

    def isatty(self) -> bool:
        return True


@pytest.fixture
def empty_cache(tmp_path, monkeypatch):
    """An empty cache folder for this test."""
    folder = tmp_path / "cache"
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(folder))
    return folder


def _run(argv, monkeypatch) -> tuple[int, str, str, list]:
    """``(exit code, stdout, stderr, [(stream, text), ...] in order)`` of ``softcurve argv``."""
    log: list = []
    out, err = Recorder("out", log), Recorder("err", log)
    with monkeypatch.context() as patch:
        patch.setattr(sys, "stdout", out)
        patch.setattr(sys, "stderr", err)
        code = main([str(a) for a in argv])
    return code, out.text(), err.text(), log


def test_first_run_says_it_builds_then_a_cached_run_says_nothing(
    empty_cache, tmp_path, monkeypatch
):
    robot = sc.presets.ifac2020()
    assert not sc.Model.is_cached(robot) and sc.Model.cache_folder() == empty_cache
    code, out, err, log = _run([*SIMULATE, "-o", tmp_path / "first"], monkeypatch)
    assert code == 0, err
    assert BUILDING in err and str(empty_cache) in err and BUILT in err
    assert BUILDING not in out and SUMMARY in out and "Traceback" not in err
    said = "".join(text for _, text in log)
    assert said.index(BUILDING) < said.index(BUILT) < said.index(SUMMARY)
    assert sc.Model.is_cached(robot)  # the line said so: it is cached for later runs

    code, out, err, _ = _run([*SIMULATE, "-o", tmp_path / "second"], monkeypatch)
    assert code == 0, err
    assert "compiling" not in err and BUILT not in err and SUMMARY in out


def test_quiet_says_nothing_and_still_caches(empty_cache, tmp_path, monkeypatch):
    code, out, err, _ = _run([*SIMULATE, "-o", tmp_path / "out", "--quiet"], monkeypatch)
    assert code == 0 and out == "" and err == ""
    assert sc.Model.is_cached(sc.presets.ifac2020())


def test_is_cached_is_what_the_model_would_load(empty_cache):
    """True exactly when constructing the model loads the library without compiling: per
    structure (not per parameter values), and not for a damaged library (rebuilt)."""
    robot = sc.presets.ifac2020()
    model = sc.Model(robot)
    assert sc.Model.is_cached(robot)
    assert sc.Model.is_cached(sc.presets.ifac2020(damping=False))  # same structure
    assert not sc.Model.is_cached(robot, quadrature_nodes=model.quadrature_nodes + 1)
    assert not sc.Model.is_cached(robot.with_segments(2))
    library = model.compiled_library  # loaded: replaced by a new file, not written over
    damaged = library.with_name("damaged.so")
    damaged.write_bytes(library.read_bytes()[:-1])
    damaged.replace(library)
    assert not sc.Model.is_cached(robot)  # load_or_build would replace it


def test_sweep_compiles_once_before_its_workers(empty_cache, tmp_path, monkeypatch):
    pytest.importorskip("pyarrow")
    config = tmp_path / "sweep.toml"
    config.write_text(SWEEP_TOML.format(t_final=0.05, points=2))
    argv = ["sweep", config, "-o", tmp_path / "out", "--workers", "0", "--no-progress"]
    code, out, err, _ = _run(argv, monkeypatch)
    assert code == 0, err
    assert err.count("softcurve sweep: " + BUILDING) == 1 and err.count(BUILT) == 1
    assert "softcurve sweep:" in out


def _lines(err: str) -> list[str]:
    """The lines of ``err`` as a terminal shows them: of each, what follows its last
    carriage return (what was redrawn over is gone)."""
    return [line.rpartition("\r")[2] for line in err.split("\n")]


def test_progress_says_the_seconds_so_far_while_compiling(empty_cache, tmp_path, monkeypatch):
    monkeypatch.setattr(log, "LINE_EVERY", 1e-3)  # a line within the seconds of the build
    argv = [*SIMULATE[:-1], "-o", tmp_path / "out", "--progress"]  # not --no-progress
    code, out, err, _ = _run(argv, monkeypatch)
    assert code == 0, err
    lines = err.splitlines()
    building = next(i for i, line in enumerate(lines) if BUILDING in line)
    built = next(i for i, line in enumerate(lines) if BUILT in line)
    so_far = [line for line in lines[building + 1 : built] if "s so far" in line]
    assert so_far and all(
        line.startswith("softcurve simulate: compiling the model") for line in so_far
    )
    assert lines[built].startswith("softcurve simulate: " + BUILT) and "\r" not in err


def test_a_warning_while_compiling_comes_after_the_redrawn_line(monkeypatch):
    """A warning given during the build (a failed compiler's) is shown on a line of its own,
    after the redrawn seconds are erased, through the command's way of showing warnings."""
    monkeypatch.setattr(progress, "TICK", 1e-3)
    log: list = []
    err = Terminal("err", log)
    monkeypatch.setattr(sys, "stderr", err)
    shown = []

    def show(message, *args, **kwargs):  # what was written to stderr before it, and it
        shown.append((len(log), str(message)))

    with warnings.catch_warnings():
        warnings.simplefilter("always")
        monkeypatch.setattr(warnings, "showwarning", show)
        with progress.elapsed_line("softcurve simulate: compiling", True):
            deadline = time.monotonic() + 60  # a bound on a stuck ticker, not a timing
            while "compiling," not in err.text():
                assert time.monotonic() < deadline, "the ticker drew nothing"
                time.sleep(1e-3)
            warnings.warn("the compiler failed", UserWarning, stacklevel=1)
            assert shown == []  # held back while the line is redrawn
    assert shown == [(len(log), "the compiler failed")]  # after the last write: the erasure
    assert _lines(err.text()) == [""]  # nothing left of the redrawn line


@pytest.mark.parametrize(
    ("arguments", "named"),
    [({"robot": 3}, "robot"), ({"quadrature_nodes": 0}, "quadrature_nodes"),
     ({"environment": "wall"}, "environment")],
)  # fmt: skip
def test_is_cached_rejects_what_the_model_rejects(arguments, named):
    """The query checks its arguments as the constructor does, naming the one at fault."""
    given = {"robot": sc.presets.ifac2020(), **arguments}
    robot = given.pop("robot")
    for call in (sc.Model.is_cached, sc.Model):
        with pytest.raises(sc.ParameterError, match=named):
            call(robot, **given)
