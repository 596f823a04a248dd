"""Issue 29, items 3 and 7: the compiled-library cache proves identity, not only
integrity, and a filled cache needs no compiler.

Item 3: another model's library copied over this one's, with its checksum file, was
loaded silently (another robot's trajectory, or CasADi's and NumPy's errors for one of
other sizes); every cached kind (model, generated function, C source) now checks the key
its checksum file records against the one it computed, and rebuilds a mismatch with a
``CacheWarning``. Item 7: with no compiler the cached library was not even looked at (the
virtual machine, 10x slower); a cache folder that cannot be written lost the build, and
was blamed on the compiler. Now a filled cache runs compiled without a compiler, and an
unwritable folder is found before building, named, and replaced by a temporary folder for
the process.

Two small libraries (one segment, no creep: the default 11 quadrature nodes and 2, same
sizes, other numbers) are compiled once per module; the paper model's (other sizes) comes
from the session. In-process rebuilds return the known-good bytes from the compile step
(the cache installs them itself); the command-line cases build with the real compiler.
"""

from __future__ import annotations

import csv
import os
import re
import shutil
import subprocess
import warnings

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.compiled import _build as build
from softcurve.compiled import _generated as generated
from softcurve.compiled._cache import CacheWarning, checksum_file, library_problem
from softcurve.compiled._source import compile_source
from tests.test_faults import softcurve_process

from .conftest import assert_close

COMPILER = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
pytestmark = pytest.mark.skipif(COMPILER is None, reason="no C compiler found")

Q = np.array([0.066, 12.0, -7.0])
QD = np.array([0.01, 3.0, 250.0])
SCENARIO = """
[robot]
preset = "ifac2020"
creep = false

[simulation]
t_final = 0.05
dt = 1e-3
q0 = [0.066, 12.0, -7.0]
qd0 = [0.01, 3.0, 250.0]
"""
RUN = ["simulate", "--no-figures", "--no-progress"]


def robot() -> sc.Robot:
    """The scenario's robot: one segment, no creep (compiles quickly)."""
    return sc.presets.ifac2020(creep=False)


@pytest.fixture(scope="module")
def built(tmp_path_factory):
    """``{"own": model, "other": model}``: the robot's library and the same robot's with 2
    quadrature nodes (same inputs and outputs, other numbers), compiled once in a private
    cache."""
    folder = tmp_path_factory.mktemp("built-cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("SOFTCURVE_CACHE_DIR", str(folder))
        models = {"own": sc.Model(robot()), "other": sc.Model(robot(), quadrature_nodes=2)}
    assert all(m.compiled_library is not None for m in models.values())
    assert not np.allclose(
        models["own"].forward_dynamics(Q, QD), models["other"].forward_dynamics(Q, QD)
    )
    return models


def _copy(library, folder, name=None):
    """``library`` and its checksum file copied into ``folder`` (as ``name``)."""
    target = folder / (name or library.name)
    shutil.copyfile(library, target)
    shutil.copyfile(checksum_file(library), checksum_file(target))
    return target


@pytest.fixture
def rebuilds(built, monkeypatch):
    """Every model rebuild in this test, made fast: the own library's known-good bytes
    (the list holds each build's functions)."""
    data = built["own"].compiled_library.read_bytes()
    calls = []

    def fake_compile(functions, compiler, flags=build._COMPILE_FLAGS):
        calls.append(functions)
        return data

    monkeypatch.setattr(build, "_compile", fake_compile)
    return calls


def _other_library(case, built, paper_model):
    return {"same_sizes": built["other"], "other_sizes": paper_model}[case].compiled_library


# -- item 3: identity -------------------------------------------------------------------
@pytest.mark.parametrize("case", ["same_sizes", "other_sizes"])
def test_another_models_library_copied_over_is_rebuilt(
    built, paper_model, rebuilds, tmp_path, monkeypatch, case
):
    """Before: loaded silently; the same sizes gave the other model's numbers, other
    sizes a ValueError from the first call."""
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path))
    own = built["own"].compiled_library
    library = _copy(_other_library(case, built, paper_model), tmp_path, own.name)
    with pytest.warns(CacheWarning, match=re.escape(str(library)) + " was built for another key"):
        model = sc.Model(robot())
    assert model.compiled_library == library and len(rebuilds) == 1
    assert library.read_bytes() == own.read_bytes()
    assert checksum_file(library).read_text() == checksum_file(own).read_text()
    expected = built["own"].forward_dynamics(Q, QD)
    assert_close(model.forward_dynamics(Q, QD), expected, rtol=1e-12, what=case)


def test_the_key_is_checked_before_the_bytes_are_read(built, tmp_path):
    own = built["own"].compiled_library
    library = _copy(built["other"].compiled_library, tmp_path, own.name)
    key = checksum_file(own).read_text().split()[5]
    assert library_problem(library) is None  # intact: integrity alone does not see it
    reason = r"was built for another key \(model_\w+\.so\.sha256 records \w{16}\.\.\., "
    reason += rf"this one needs {key[:16]}\.\.\.: another model's"
    assert re.match(reason, library_problem(library, key))


def _function(body: float) -> ca.Function:
    x = ca.SX.sym("x", 2)
    return ca.Function("softcurve_test_identity", [x], [x[0] * body])


def _source(value: int) -> str:
    exported = '__attribute__((visibility("default")))'  # the build hides symbols by default
    return f"{exported} int softcurve_test_identity(void) {{ return {value}; }}\n"


def _compiled_function(value):
    return float(generated.compile_function(_function(value))([1.0, 2.0]))


def _compiled_source(value):
    return compile_source("softcurve_test_identity", _source(value)).softcurve_test_identity()


KINDS = {
    "function": ("function_*.so", _compiled_function),
    "source": ("softcurve_*.so", _compiled_source),
}


@pytest.mark.parametrize("kind", KINDS)
def test_every_kind_of_cached_library_checks_its_key(tmp_path, monkeypatch, kind):
    """A generated function and a hand-written C source of the same name, two bodies,
    built in one cache: the second's library copied over the first's in another is
    refused (before: the first returned the second's value). A fresh folder, since the
    dynamic loader hands out a library it has loaded by its path again."""
    pattern, compiled = KINDS[kind]
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "built"))
    assert compiled(3) == 3
    (first,) = (tmp_path / "built").glob(pattern)
    assert compiled(4) == 4
    (second,) = set((tmp_path / "built").glob(pattern)) - {first}
    (tmp_path / "copied").mkdir()
    copied = _copy(second, tmp_path / "copied", first.name)
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "copied"))
    with pytest.warns(CacheWarning, match=re.escape(str(copied)) + " was built for another key"):
        assert compiled(3) == 3


def _table(folder):
    with open(folder / "trajectory.csv", newline="") as table:
        return [row for row in csv.reader(table) if row and not row[0].startswith("#")]


@pytest.fixture(scope="module")
def filled(built, tmp_path_factory):
    """``(cache folder, scenario, expected table)``: the scenario run once from a cache
    seeded with the own library (the run adds what else it builds, the driver)."""
    folder = tmp_path_factory.mktemp("filled")
    cache = folder / "cache"
    cache.mkdir()
    _copy(built["own"].compiled_library, cache)
    scenario = folder / "small.toml"
    scenario.write_text(SCENARIO)
    code, _, err = softcurve_process(
        *RUN, scenario, "-o", folder / "run", SOFTCURVE_CACHE_DIR=cache
    )
    assert code == 0 and "warning" not in err, err
    return cache, scenario, _table(folder / "run")


def test_the_command_line_rebuilds_another_models_library(built, filled, tmp_path):
    """``softcurve simulate`` with the other model's library copied over the scenario's:
    before, exit 0 with the other model's trajectory."""
    cache, scenario, expected = filled
    shutil.copytree(cache, tmp_path / "cache")
    own = built["own"].compiled_library
    library = _copy(built["other"].compiled_library, tmp_path / "cache", own.name)
    env = {"SOFTCURVE_CACHE_DIR": tmp_path / "cache"}
    code, _, err = softcurve_process(*RUN, scenario, "-o", tmp_path / "run", **env)
    assert code == 0 and err.count("warning: ") == 1, err  # one warning line, and the
    assert err.count("\n") == 3 and "compiled the model of" in err, err  # rebuild's two lines
    assert "warning: " in err and str(library) in err and "built for another key" in err, err
    assert _table(tmp_path / "run") == expected
    assert library_problem(library, checksum_file(own).read_text().split()[5]) is None


# -- item 7: the compiler and the cache -----------------------------------------------------
def test_a_filled_cache_needs_no_compiler(built, tmp_path, monkeypatch):
    """Before: the virtual machine (and a CompilerWarning) although the library was there;
    the same for a generated function and a C source."""
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path))
    library = _copy(built["own"].compiled_library, tmp_path)
    function = _function(3)
    generated.compile_function(function)
    compile_source("softcurve_test_identity", _source(3))
    empty = tmp_path / "empty-path"
    empty.mkdir()
    monkeypatch.delenv("CC", raising=False)
    monkeypatch.setenv("PATH", str(empty))
    assert build.find_compiler() is None
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model = sc.Model(robot())
        compiled = generated.compile_function(function)
        source = compile_source("softcurve_test_identity", _source(3))
    assert model.compiled_library == library and model._native is not None
    assert_close(model.forward_dynamics(Q, QD), built["own"].forward_dynamics(Q, QD), rtol=0)
    assert compiled is not function and compiled.class_name() == "External"
    assert source is not None and source.softcurve_test_identity() == 3
    with pytest.warns(sc.CompilerWarning, match="no C compiler found"):  # not cached: said
        assert sc.Model(robot(), quadrature_nodes=3).compiled_library is None


def test_the_command_line_runs_compiled_without_a_compiler(filled, paper_model, tmp_path):
    """``softcurve simulate`` and ``info`` with ``PATH`` holding no compiler and a filled
    cache: no CompilerWarning, the compiled run's numbers, the cached library reported."""
    cache, scenario, expected = filled
    shutil.copytree(cache, tmp_path / "cache")
    _copy(paper_model.compiled_library, tmp_path / "cache")
    (tmp_path / "empty-path").mkdir()
    env = {"SOFTCURVE_CACHE_DIR": tmp_path / "cache", "PATH": tmp_path / "empty-path", "CC": ""}
    code, _, err = softcurve_process(*RUN, scenario, "-o", tmp_path / "run", **env)
    assert code == 0 and "warning" not in err, err
    assert _table(tmp_path / "run") == expected
    code, out, err = softcurve_process("info", **env)
    assert code == 0 and "warning" not in err, err
    assert f"compiled library: {tmp_path / 'cache' / paper_model.compiled_library.name}" in out


def _a_file(tmp_path):
    (tmp_path / "cache-file").write_text("not a folder")
    return tmp_path / "cache-file", "is not a folder"


def _below_a_file(tmp_path):
    (tmp_path / "file").write_text("not a folder")
    return tmp_path / "file" / "cache", "cannot be written"


def _make_immutable(folder):
    """``folder`` made read-only even for root: the immutable attribute (``chattr +i``);
    the test is skipped where it cannot be set."""
    chattr = shutil.which("chattr")
    if chattr is None or subprocess.run([chattr, "+i", str(folder)]).returncode != 0:
        pytest.skip("no chattr +i here: no read-only folder that root cannot write")


def _immutable(tmp_path):
    folder = tmp_path / "read-only"
    folder.mkdir()
    _make_immutable(folder)
    return folder, "cannot be written"


UNWRITABLE = {"a_file": _a_file, "below_a_file": _below_a_file, "read_only": _immutable}


@pytest.mark.parametrize("case", UNWRITABLE)
def test_an_unwritable_cache_folder_keeps_the_build_for_the_process(
    built, rebuilds, tmp_path, monkeypatch, case
):
    """Before: compiled, then the install failed and was reported as the compiler's
    failure, the model in the virtual machine, and every model compiled again."""
    folder, reason = UNWRITABLE[case](tmp_path)
    try:
        monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(folder))
        fake, order = build._compile, []
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")

            def compile_after_checking(*args, **kwargs):
                order.append(len(caught))
                return fake(*args, **kwargs)

            monkeypatch.setattr(build, "_compile", compile_after_checking)
            model = sc.Model(robot())
            again = sc.Model(robot())
        messages = [str(w.message) for w in caught]
        assert len(messages) == 1 and issubclass(caught[0].category, CacheWarning), messages
        assert order == [1]  # the folder was checked (and named) before compiling
        assert str(folder) in messages[0] and "SOFTCURVE_CACHE_DIR" in messages[0]
        assert reason in messages[0] and "for this process only" in messages[0]
        library = model.compiled_library
        assert library is not None and again.compiled_library == library
        assert str(library.parent) in messages[0] and len(rebuilds) == 1  # built once
        assert library_problem(library) is None
        assert_close(model.forward_dynamics(Q, QD), built["own"].forward_dynamics(Q, QD), rtol=0)
        assert not folder.is_dir() or list(folder.iterdir()) == []
        assert all(f.read_text() == "not a folder" for f in tmp_path.iterdir() if f.is_file())
    finally:
        if case == "read_only":
            subprocess.run(["chattr", "-i", str(folder)], check=True)


def test_a_damaged_library_in_a_read_only_cache_is_replaced_once(
    built, rebuilds, tmp_path, monkeypatch
):
    """A read-only shared cache holding a truncated library: rebuilt once into the
    process's folder, which later models use without a further warning."""
    folder = tmp_path / "shared"
    folder.mkdir()
    library = _copy(built["own"].compiled_library, folder)
    os.truncate(library, library.stat().st_size // 2)
    _make_immutable(folder)
    try:
        monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(folder))
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            models = [sc.Model(robot()) for _ in range(3)]
        messages = [str(w.message) for w in caught]
        assert len(messages) == 2 and "partial copy" in messages[0], messages
        assert "cannot be written" in messages[1] and len(rebuilds) == 1, messages
        assert len({m.compiled_library for m in models}) == 1
        assert models[0].compiled_library.parent != folder
        assert_close(
            models[2].forward_dynamics(Q, QD), built["own"].forward_dynamics(Q, QD), rtol=0
        )
    finally:
        subprocess.run(["chattr", "-i", str(folder)], check=True)


def test_the_command_line_with_a_cache_folder_that_is_a_file(filled, tmp_path):
    """``softcurve simulate`` with ``SOFTCURVE_CACHE_DIR`` a file: one warning naming it,
    the run compiled (before: "compiling the model with cc failed" and the virtual
    machine)."""
    _, scenario, expected = filled
    (tmp_path / "cache").write_text("not a folder")
    env = {"SOFTCURVE_CACHE_DIR": tmp_path / "cache"}
    code, _, err = softcurve_process(*RUN, scenario, "-o", tmp_path / "run", **env)
    lines = err.splitlines()  # one warning, two lines per build (the model's, the driver's)
    assert code == 0 and err.count("warning: ") == 1, err
    assert len(lines) - 1 == 2 * err.count(": compiled ") and "compiled the model" in err, err
    assert "compiling the model of 1 segment (C, kept in " in err, err
    assert "for this process only" in err, err
    assert str(tmp_path / "cache") in err and "SOFTCURVE_CACHE_DIR" in err, err
    assert "virtual machine" not in err and "failed" not in err, err
    assert _table(tmp_path / "run") == expected
    assert (tmp_path / "cache").read_text() == "not a folder"
