"""The compiled-library cache survives damage (issue 11, case 2; issue 44, item 4).

A library truncated to 0 bytes, overwritten with random bytes, truncated to half (which
crashed the process with SIGBUS inside the dynamic loader), or missing its checksum file
is detected before it is loaded, replaced by a fresh build with a ``CacheWarning`` naming
the file, and the model gives the same numbers as an undamaged one.

One library is compiled per session (in a private cache) and copied into a fresh cache
folder per case. The in-process cases rebuild by returning the known-good bytes from the
compile step (the cache installs them with its own writer), which keeps them fast; the
subprocess cases rebuild with the real compiler.

Issue 44: a library truncated and given a checksum file that matches it (the checksum
proves only that the bytes are those it was computed on) crashed the process with SIGBUS
inside the dynamic loader; a foreign library with a matching checksum file was loaded
and failed with "AttributeError: undefined symbol" naming no cache. Both are now refused
from their bytes before they are loaded (cut short; lacks the model's symbols) and
rebuilt with a warning naming the file.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import struct
import subprocess
import sys
import warnings
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.compiled import _build as build
from softcurve.compiled import _cache as cache_module
from softcurve.compiled import _generated as generated
from softcurve.compiled._cache import CacheWarning, checksum_file, library_problem
from softcurve.compiled._elf import image_problem

from .conftest import assert_close

COMPILER = shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")
pytestmark = pytest.mark.skipif(COMPILER is None, reason="no C compiler found")

Q = np.array([0.066, 12.0, -7.0])
QD = np.array([0.01, 3.0, 250.0])
CHILD = """
import json, sys, warnings
import numpy as np, softcurve as sc
warnings.simplefilter("always")
model = sc.Model(sc.presets.ifac2020(creep=False), quadrature_nodes=int(sys.argv[2]))
q, qd = json.loads(sys.argv[1])
print(json.dumps(model.forward_dynamics(np.array(q), np.array(qd)).tolist()))
"""


NODES = 3
"""Quadrature nodes of the models here (the child's too): a smaller library than the
default's, which compiles sooner; what the cache does with it is the same."""


def robot() -> sc.Robot:
    """A small robot (one segment, no creep) whose library compiles quickly."""
    return sc.presets.ifac2020(creep=False)


@pytest.fixture(scope="module")
def intact(tmp_path_factory):
    """``(model, library bytes)``: compiled once in a private cache."""
    folder = tmp_path_factory.mktemp("intact-cache")
    with pytest.MonkeyPatch.context() as patch:
        patch.setenv("SOFTCURVE_CACHE_DIR", str(folder))
        model = sc.Model(robot(), quadrature_nodes=NODES)
    assert model.compiled_library is not None and library_problem(model.compiled_library) is None
    return model, model.compiled_library.read_bytes()


@pytest.fixture
def cache(intact, tmp_path, monkeypatch):
    """A fresh private cache holding a copy of the intact library and its checksum file."""
    model, data = intact
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path))
    library = tmp_path / model.compiled_library.name
    shutil.copyfile(model.compiled_library, library)
    shutil.copyfile(checksum_file(model.compiled_library), checksum_file(library))
    return library


@pytest.fixture
def rebuilds(intact, monkeypatch):
    """Every rebuild in this test, made fast: the known-good bytes (the cache installs
    them with its own writer); the list holds each rebuild's cache folder."""
    built = []

    def fake_compile(functions, compiler, flags=build._COMPILE_FLAGS):
        built.append(cache_module.cache_directory())
        return intact[1]

    monkeypatch.setattr(build, "_compile", fake_compile)
    return built


def _reinstall(library, data):
    """``data`` installed as ``library`` by the cache's writer, under the key its checksum
    file records: a file with a right checksum."""
    key = checksum_file(library).read_text().split()[5]
    cache_module.install(library, data, key)


def _zero(library):
    library.write_bytes(b"")


def _random(library):
    size = library.stat().st_size
    library.write_bytes(np.random.default_rng(11).bytes(size))


def _half(library):
    os.truncate(library, library.stat().st_size // 2)


def _no_checksum(library):
    checksum_file(library).unlink()


DAMAGE = {"zero_bytes": _zero, "random_bytes": _random, "half": _half, "no_checksum": _no_checksum}


@pytest.mark.parametrize("damage", DAMAGE)
def test_a_damaged_library_is_rebuilt_with_a_warning(intact, cache, rebuilds, damage):
    DAMAGE[damage](cache)
    assert library_problem(cache) is not None
    with pytest.warns(CacheWarning, match=re.escape(str(cache)) + ".*replacing it"):
        model = sc.Model(robot(), quadrature_nodes=NODES)
    assert model.compiled_library == cache and rebuilds == [cache.parent]
    assert library_problem(cache) is None and cache.read_bytes() == intact[1]
    expected = intact[0].forward_dynamics(Q, QD)
    assert_close(model.forward_dynamics(Q, QD), expected, rtol=1e-12, what=damage)


@pytest.mark.parametrize(
    ("damage", "reason"),
    [
        (_zero, r"has 0 bytes where its checksum file records \d+ \(partial copy\?\)"),
        (_half, r"has \d+ bytes where its checksum file records \d+"),
        (_random, r"does not match its checksum \(damaged\)"),
        (_no_checksum, r"has no checksum file \(model_\w+\.so\.sha256\)"),
    ],
)
def test_the_reason_is_named(cache, damage, reason):
    damage(cache)
    assert re.match(reason, library_problem(cache))


def test_an_intact_library_is_loaded_without_a_rebuild(cache, rebuilds):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        model = sc.Model(robot(), quadrature_nodes=NODES)
    assert model.compiled_library == cache and rebuilds == []


def test_a_library_is_verified_once_per_process_while_unchanged(cache, rebuilds, monkeypatch):
    checked = []
    monkeypatch.setattr(cache_module, "library_problem", lambda path, *_: checked.append(path))
    sc.Model(robot(), quadrature_nodes=NODES)
    sc.Model(robot(), quadrature_nodes=NODES)
    assert checked == [cache]  # the second model skips the read
    _reinstall(cache, cache.read_bytes())  # replaced (a new file, same bytes)
    sc.Model(robot(), quadrature_nodes=NODES)
    assert checked == [cache, cache] and rebuilds == []


def test_a_library_that_fails_to_load_is_rebuilt(intact, cache, rebuilds):
    """Right checksum, wrong content (not a library): the loader's OSError triggers it."""
    _reinstall(cache, b"not an ELF file" * 100)
    assert library_problem(cache) is None
    with pytest.warns(CacheWarning, match=re.escape(str(cache)) + " failed to load"):
        model = sc.Model(robot(), quadrature_nodes=NODES)
    assert rebuilds == [cache.parent] and cache.read_bytes() == intact[1]
    assert_close(model.forward_dynamics(Q, QD), intact[0].forward_dynamics(Q, QD), rtol=1e-12)


def test_a_failing_rebuild_falls_back_to_the_virtual_machine(intact, cache, monkeypatch):
    def failing_compile(functions, compiler, flags=build._COMPILE_FLAGS):
        raise subprocess.CalledProcessError(1, compiler, stderr="cc: out of disk space")

    monkeypatch.setattr(build, "_compile", failing_compile)
    _zero(cache)
    with pytest.warns(CacheWarning, match=re.escape(str(cache))):
        with pytest.warns(sc.CompilerWarning, match="out of disk space"):
            model = sc.Model(robot(), quadrature_nodes=NODES)
    assert model.compiled_library is None
    assert_close(model.forward_dynamics(Q, QD), intact[0].forward_dynamics(Q, QD), rtol=1e-12)


def test_a_damaged_function_library_is_rebuilt(tmp_path, monkeypatch):
    """Built in one cache, copied and damaged in another: a library this process has
    loaded is never damaged in place (that would crash it whatever the cache does)."""
    x = ca.SX.sym("x", 2)
    square = ca.Function("square_for_cache_test", [x], [ca.sumsqr(x) + ca.sin(x[0])])
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "first"))
    first = generated.compile_function(square)
    (built,) = (tmp_path / "first").glob("function_*.so")
    shutil.copytree(tmp_path / "first", tmp_path / "second")
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "second"))
    library = tmp_path / "second" / built.name
    assert library_problem(library) is None
    _half(library)
    with pytest.warns(CacheWarning, match=re.escape(str(library))):
        again = generated.compile_function(square)
    assert library_problem(library) is None
    assert float(again([0.5, -2.0])) == pytest.approx(float(first([0.5, -2.0])), rel=1e-15)


def _child(cache):
    """The forward dynamics computed in a child process on ``cache``'s folder (a crash shows
    as its exit code, not as pytest's), which must exit 0."""
    env = {**os.environ, "SOFTCURVE_CACHE_DIR": str(cache.parent)}
    child = subprocess.run(
        [sys.executable, "-c", CHILD, json.dumps([Q.tolist(), QD.tolist()]), str(NODES)],
        env=env,
        capture_output=True,
        text=True,
        timeout=600,
    )
    assert child.returncode == 0, f"exit {child.returncode}: {child.stderr[-2000:]}"
    return child


def test_a_half_truncated_library_in_a_child_process(intact, cache):
    """The case that crashed with SIGBUS, with the real compiler, in a child process (a
    crash would show as its exit code, not kill pytest)."""
    _half(cache)
    child = _child(cache)
    assert "CacheWarning" in child.stderr and str(cache) in child.stderr
    assert library_problem(cache) is None
    result = json.loads(child.stdout.strip().splitlines()[-1])
    assert_close(result, intact[0].forward_dynamics(Q, QD), rtol=1e-12, what="child")


def test_a_truncated_library_with_a_matching_checksum_in_a_child_process(intact, cache):
    """Before: the child died of SIGBUS (exit -7; 135 from a shell) with no message: the
    checksum matched, and the loader mapped segments past the end of the file."""
    data = cache.read_bytes()
    _reinstall(cache, data[: len(data) // 2])
    assert library_problem(cache, None) is not None  # found from the bytes alone
    child = _child(cache)
    assert f"CacheWarning: softcurve cache: the compiled library {cache} is cut short" in (
        child.stderr
    )
    assert library_problem(cache) is None and cache.read_bytes() == data
    result = json.loads(child.stdout.strip().splitlines()[-1])
    assert_close(result, intact[0].forward_dynamics(Q, QD), rtol=1e-12, what="child")


@pytest.mark.parametrize("kept", [0.999, 0.9, 0.5, 0.1, 0.001])
def test_a_library_cut_short_is_refused_from_its_bytes(intact, kept):
    data = intact[1]
    assert image_problem(data) is None
    assert image_problem(data[: int(len(data) * kept)]).startswith("is cut short: its ")


def test_a_foreign_library_with_a_matching_checksum_is_rebuilt(
    intact, cache, rebuilds, tmp_path, monkeypatch
):
    """A shared library that is not the model's (``tests/c/planted.c``), installed with a
    checksum file matching it and recording the model's key. Before: loaded (its
    constructor ran), then "AttributeError: ...: undefined symbol: dynamics_terms"."""
    foreign = tmp_path / "foreign.so"
    planted = Path(__file__).parent / "c" / "planted.c"
    command = [COMPILER, "-shared", "-fPIC", "-DSYMBOL=softcurve_foreign", str(planted)]
    subprocess.run([*command, "-o", str(foreign)], check=True, capture_output=True)
    _reinstall(cache, foreign.read_bytes())
    monkeypatch.setenv("SOFTCURVE_TEST_MARKER", str(tmp_path / "marker"))
    reason = " lacks the symbols dynamics_terms, potential_energy"
    with pytest.warns(CacheWarning, match=re.escape(str(cache) + reason)):
        model = sc.Model(robot(), quadrature_nodes=NODES)
    assert not (tmp_path / "marker").exists()  # refused before the loader opened it
    assert rebuilds == [cache.parent] and cache.read_bytes() == intact[1]
    assert_close(model.forward_dynamics(Q, QD), intact[0].forward_dynamics(Q, QD), rtol=1e-12)


def test_symbol_names_outside_their_string_table_are_no_symbols(intact):
    """An ELF64 library whose dynamic string table is cut to one byte in its section
    header: the names point past it. Before: ValueError from the bytes' search."""
    data = bytearray(intact[1])
    shoff, shentsize, shnum = (
        struct.unpack_from("<Q", data, 0x28)[0],
        *struct.unpack_from("<HH", data, 0x3A),
    )
    for i in range(shnum):
        header = shoff + i * shentsize
        if struct.unpack_from("<I", data, header + 4)[0] == 11:  # SHT_DYNSYM
            link = struct.unpack_from("<I", data, header + 40)[0]
            struct.pack_into("<Q", data, shoff + link * shentsize + 32, 1)  # its sh_size
    assert image_problem(bytes(data), ("dynamics_terms",)).startswith(
        "lacks the symbols dynamics_terms"
    )
