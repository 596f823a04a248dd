"""The compiled model: cache, fallback without a compiler, the native call path."""

from __future__ import annotations

import ctypes
import os
import shutil
import warnings
from pathlib import Path

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.compiled import _build as model_module
from softcurve.compiled import _generated as generated
from softcurve.simulation.solvers import _driver as driver_library
from softcurve.simulation.solvers import _driver as native

from .conftest import assert_close, compiler_refusing


def test_second_model_reuses_the_cached_library(paper_model):
    library = paper_model.compiled_library
    assert library is not None and library.exists()
    stamp = os.stat(library).st_mtime_ns
    again = sc.Model(sc.presets.ifac2020(creep=True).replace(gravity=[0.0, 0.0, 9.81]))
    assert again.compiled_library == library  # parameters differ, structure does not
    assert os.stat(library).st_mtime_ns == stamp


def test_robots_of_one_segment_structure_share_one_library(two_segment_model, rng):
    """The segments' Functions take each segment's numbers as inputs: two robots of two
    segments with other lengths, masses, radii and stiffnesses per segment load the one
    library, and each computes its own dynamics with it."""
    robot = two_segment_model.robot
    first, second = robot.segments
    other = robot.replace(
        segments=(
            first.replace(rest_length=0.05, mass=0.03, radius=0.02),
            second.replace(rest_length=0.09, mass=0.07, radius=0.03),
        )
    )
    library = sc.Model(robot).compiled_library
    stamp = os.stat(library).st_mtime_ns
    again = sc.Model(other)
    assert again.compiled_library == library
    assert os.stat(library).st_mtime_ns == stamp
    vm = sc.Model(other, compile=False)
    q, qd = np.array([0.05, 20.0, -5.0, 0.09, -10.0, 8.0]), rng.normal(size=6)
    assert_close(again.mass_matrix(q), vm.mass_matrix(q), rtol=1e-13, what="D")
    assert_close(again.forward_dynamics(q, qd), vm.forward_dynamics(q, qd), rtol=1e-12)
    assert not np.allclose(again.mass_matrix(q), two_segment_model.mass_matrix(q), rtol=0.1)


def test_parameters_are_bound_at_run_time(paper_model):
    hanging = sc.Model(sc.presets.ifac2020().replace(gravity=[0.0, 0.0, 9.81]))
    q = np.array([0.064, 0.0, 0.0])
    assert_close(hanging.gravity_force(q), -paper_model.gravity_force(q), rtol=1e-15)


def test_without_a_compiler_the_model_warns_once_and_still_works(monkeypatch, tmp_path):
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path))
    monkeypatch.setattr(model_module, "find_compiler", lambda: None)
    with pytest.warns(sc.CompilerWarning, match="no C compiler found"):
        model = sc.Model(sc.presets.ifac2020())
    assert model.compiled_library is None
    q, qd = np.array([0.064, 25.0, 0.0]), np.array([0.0, 0.0, 1500.0])
    assert np.all(np.isfinite(model.forward_dynamics(q, qd)))
    assert list(tmp_path.iterdir()) == []


def test_a_failing_compiler_falls_back_with_its_message(monkeypatch, tmp_path):
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CC", "false")  # exists and fails
    with pytest.warns(sc.CompilerWarning, match="compiling the model with false failed"):
        model = sc.Model(sc.presets.ifac2020())
    assert model.compiled_library is None
    assert not any(path.suffix == ".so" for path in tmp_path.iterdir())


def test_code_is_built_for_this_cpu_unless_portable_is_asked(monkeypatch):
    monkeypatch.delenv("SOFTCURVE_PORTABLE", raising=False)
    structure = sc.presets.ifac2020().structure()
    native = model_module._cache_key(structure, 11)
    assert "-march=native" in model_module.compile_flags()
    monkeypatch.setenv("SOFTCURVE_PORTABLE", "1")
    assert model_module.compile_flags() == model_module._COMPILE_FLAGS
    assert model_module._cache_key(structure, 11) != native  # one library each


def test_a_compiler_without_march_native_builds_portable_code(monkeypatch, tmp_path):
    wrapper = compiler_refusing(tmp_path, "-march=native")
    if wrapper is None:
        pytest.skip("no C compiler")
    monkeypatch.delenv("SOFTCURVE_PORTABLE", raising=False)
    monkeypatch.setenv("CC", str(wrapper))
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "cache"))
    with warnings.catch_warnings():
        warnings.simplefilter("error", sc.CompilerWarning)
        model = sc.Model(sc.presets.ifac2020())
    assert model.compiled_library is not None
    x = np.array([0.064, 20.0, -5.0, 0.1, 3.0, 2.0, 1e-3, 2e-3, -1e-3])
    virtual = np.array(model.symbolic["rhs"](x, np.zeros(3), model.parameters)).ravel()
    compiled = model.state_derivative(x, np.zeros(3))
    assert_close(compiled, virtual, rtol=1e-12, scale=np.linalg.norm(virtual))


def test_native_and_virtual_machine_agree_on_every_compiled_function(paper_model, rng):
    vm = paper_model.symbolic
    q = np.array([0.066, 17.0, -9.0])
    args = {
        "dynamics_terms": (q, rng.normal(size=3), rng.normal(size=3)),
        "potential_energy": (q,),
        "creep_rate": (rng.normal(size=3), rng.normal(size=3)),
        "rhs": (rng.normal(size=9) * 0.01 + np.r_[q, np.zeros(6)], rng.normal(size=3) * 1e-3),
        "pose": (q, 0.7),
        "jacobian": (q, 0.7),
        "domain": (q,),
    }
    assert set(args) == set(model_module.COMPILED_FUNCTIONS)
    for name, inputs in args.items():
        native = paper_model._native[name](*inputs, paper_model.parameters)
        reference = vm[name](*inputs, paper_model.parameters)
        reference = reference if isinstance(reference, tuple) else (reference,)
        for a, b in zip(native, reference, strict=True):
            b = np.array(b)
            b = b.ravel() if b.shape[1] == 1 else b
            assert_close(a, b, rtol=1e-13, scale=np.abs(b).max() + 1e-300, what=name)


def test_native_call_checks_sizes(paper_model):
    with pytest.raises(ValueError, match="input 0 needs 3 numbers, got 2"):
        paper_model._native["pose"]([0.064, 0.0], 0.5, paper_model.parameters)


def test_scipy_rhs_and_state_derivative(paper_model):
    x = np.array([0.064, 25.0, 0.0, 0.0, 0.0, 1500.0, 0.0, 0.0, 0.0])
    f = paper_model.rhs()
    xdot = f(0.0, x)
    assert xdot.shape == (9,) and xdot.dtype == np.float64
    assert_close(xdot[:3], x[3:6], rtol=0, atol=0)
    assert_close(xdot[3:6], paper_model.forward_dynamics(x[:3], x[3:6]), rtol=1e-15)
    casadi_rhs = paper_model.casadi_rhs()
    assert_close(
        np.array(casadi_rhs(x, np.zeros(3), paper_model.parameters)).ravel(),
        xdot,
        rtol=1e-13,
        scale=np.abs(xdot).max(),
    )


def test_results_are_independent_of_later_calls(paper_model):
    """Native buffers are reused between calls; results handed out must not be."""
    q = np.array([0.066, 12.0, -9.0])
    first = paper_model.elastic_force(q)
    kept = first.copy()
    d_first = paper_model.mass_matrix(q)
    paper_model.elastic_force(q + [1e-3, 5.0, 0.0])
    paper_model.mass_matrix(q + [1e-3, 5.0, 0.0])
    np.testing.assert_array_equal(first, kept)
    np.testing.assert_array_equal(d_first, paper_model.mass_matrix(q))
    x = np.r_[q, np.zeros(6)]
    a = paper_model.state_derivative(x)
    b = paper_model.state_derivative(x + 0.01)
    assert not np.array_equal(a, b)


def _small_function():
    x = ca.SX.sym("x", 3)
    return ca.Function("softcurve_test_small", [x], [ca.vertcat(ca.sin(x[0]) * x[1], x[2] ** 3)])


def test_compile_function_agrees_with_the_function_and_is_cached(monkeypatch, tmp_path):
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path))
    function = _small_function()
    compiled = generated.compile_function(function)
    assert compiled.class_name() == "External"
    libraries = list(tmp_path.glob("function_*.so"))
    assert len(libraries) == 1
    x = np.array([0.3, -2.0, 1.5])
    np.testing.assert_allclose(np.array(compiled(x)), np.array(function(x)), rtol=1e-15)
    stamp = libraries[0].stat().st_mtime_ns
    generated.compile_function(function)
    assert libraries[0].stat().st_mtime_ns == stamp  # loaded, not compiled again


def test_compile_function_builds_for_this_cpu_and_falls_back_without_march_native(
    monkeypatch, tmp_path
):
    real = shutil.which("cc") or shutil.which("gcc")
    if real is None:
        pytest.skip("no C compiler")
    log = tmp_path / "flags.log"
    wrapper = tmp_path / "cc-logging"
    wrapper.write_text(f'#!/bin/sh\necho "$@" >> {log}\nexec {real} "$@"\n')
    wrapper.chmod(0o755)
    monkeypatch.delenv("SOFTCURVE_PORTABLE", raising=False)
    monkeypatch.setenv("CC", str(wrapper))
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "native"))
    function = _small_function()
    generated.compile_function(function)
    flags = list(model_module.FUNCTION_FLAGS)
    assert " ".join([*flags, "-march=native"]) in log.read_text()
    monkeypatch.setenv("SOFTCURVE_PORTABLE", "1")
    generated.compile_function(function)  # another cache entry: built again, portable
    assert len(list((tmp_path / "native").glob("function_*.so"))) == 2
    assert log.read_text().splitlines()[-2].split()[: len(flags) + 1] == [*flags, "-fPIC"]

    refused = tmp_path / "refused.log"
    refusing = compiler_refusing(tmp_path, "-march=native", log=refused)
    monkeypatch.delenv("SOFTCURVE_PORTABLE")
    monkeypatch.setenv("CC", str(refusing))
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "refused"))
    monkeypatch.setattr(model_module, "_ACCEPTED", {})
    compiled = generated.compile_function(function)
    assert compiled.class_name() == "External"  # compiled, without -march=native
    x = np.array([0.3, -2.0, 1.5])
    np.testing.assert_allclose(np.array(compiled(x)), np.array(function(x)), rtol=1e-15)
    assert model_module._ACCEPTED[((str(refusing),), model_module._NATIVE_FLAGS)] is False
    x = ca.SX.sym("x")
    generated.compile_function(ca.Function("softcurve_test_other", [x], [ca.cos(x)]))
    assert refused.read_text().count("x") == 1  # the probe; remembered: asked no more


def test_compile_function_without_a_working_compiler_returns_the_function(monkeypatch, tmp_path):
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path))
    monkeypatch.setenv("CC", "false")
    monkeypatch.setattr(model_module, "_ACCEPTED", {})
    function = _small_function()
    with pytest.warns(model_module.CompilerWarning, match="virtual machine"):
        assert generated.compile_function(function) is function
    monkeypatch.setattr(model_module, "find_compiler", lambda: None)
    assert generated.compile_function(function) is function  # no compiler: said elsewhere


def test_the_model_library_is_compiled_with_the_function_flags(monkeypatch, tmp_path, paper_model):
    """The model's generated C takes the flags of every generated function (-O2 without
    the passes that cost seconds on straight-line code), and the portable ones where the
    compiler refuses them."""
    refusing = compiler_refusing(tmp_path, "-fno-code-hoisting")
    if refusing is None:
        pytest.skip("no C compiler")
    built = paper_model.compiled_library.read_bytes()
    asked = []

    def fake_compile(functions, compiler, flags=model_module._COMPILE_FLAGS):
        asked.append((sorted(functions), flags))
        return built

    monkeypatch.setattr(model_module, "_compile", fake_compile)
    monkeypatch.setattr(model_module, "_ACCEPTED", {})
    monkeypatch.delenv("SOFTCURVE_PORTABLE", raising=False)
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "good"))
    sc.Model(sc.presets.ifac2020())
    ((names, flags),) = asked
    assert names == sorted(model_module.COMPILED_FUNCTIONS)
    native = model_module._native_flags()
    assert flags == (*model_module.FUNCTION_FLAGS, *native, *model_module._LIBRARY_FLAGS)

    asked.clear()
    monkeypatch.setenv("CC", str(refusing))
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "refusing"))
    model = sc.Model(sc.presets.ifac2020())
    ((_, flags),) = asked  # one build: the flags were probed, not tried on the model
    assert flags == (*model_module.PORTABLE_FUNCTION_FLAGS, *native, *model_module._LIBRARY_FLAGS)
    assert model.compiled_library is not None


def test_a_failed_build_does_not_mark_the_flags_as_refused(monkeypatch, tmp_path):
    """A build that fails for another reason than its flags (here every compile of the
    library fails once) leaves the compiler's flags as they were: the next build in the
    process takes FUNCTION_FLAGS again (before, a failure marked the compiler as refusing
    them, and every later model of the process was built at -O1)."""
    import subprocess

    if model_module.find_compiler() is None:
        pytest.skip("no C compiler")
    real_compile, calls = model_module._compile, []

    def failing_once(functions, compiler, flags=model_module._COMPILE_FLAGS):
        calls.append(flags)
        if len(calls) == 1:
            raise subprocess.CalledProcessError(1, compiler, stderr="disk full")
        return real_compile(functions, compiler, flags)

    monkeypatch.setattr(model_module, "_compile", failing_once)
    monkeypatch.setattr(model_module, "_ACCEPTED", {})
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path))
    with pytest.warns(model_module.CompilerWarning, match="failed"):
        assert generated.compile_function(_small_function()).class_name() != "External"
    x = ca.SX.sym("x")
    generated.compile_function(ca.Function("softcurve_test_other", [x], [ca.cos(x)]))
    assert all(
        flags[: len(model_module.FUNCTION_FLAGS)] == model_module.FUNCTION_FLAGS for flags in calls
    )
    assert len(calls) == 2


def test_a_compiler_refusing_the_function_flags_builds_with_the_portable_ones(
    monkeypatch, tmp_path
):
    """clang has no -fno-tree-pre, GCC before 8 no -fno-code-hoisting: the function is
    still compiled, with PORTABLE_FUNCTION_FLAGS, and the flags are probed once."""
    refused = tmp_path / "refused.log"
    refusing = compiler_refusing(tmp_path, "-fno-code-hoisting", log=refused)
    if refusing is None:
        pytest.skip("no C compiler")
    monkeypatch.setenv("CC", str(refusing))
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "cache"))
    monkeypatch.setattr(model_module, "_ACCEPTED", {})
    function = _small_function()
    compiled = generated.compile_function(function)
    assert compiled.class_name() == "External"
    x = np.array([0.3, -2.0, 1.5])
    np.testing.assert_allclose(np.array(compiled(x)), np.array(function(x)), rtol=1e-15)
    assert model_module._ACCEPTED[((str(refusing),), model_module.FUNCTION_FLAGS)] is False
    x = ca.SX.sym("x")
    generated.compile_function(ca.Function("softcurve_test_other", [x], [ca.cos(x)]))
    assert refused.read_text().count("x") == 1  # the probe alone, once for both


def test_the_cached_library_has_a_checksum_beside_it(paper_model):
    library = paper_model.compiled_library
    checksum = model_module.checksum_file(library)
    assert checksum.name == library.name + ".sha256"
    assert checksum.read_text().split()[::2] == ["sha256", "size", "key"]
    key = model_module._cache_key(paper_model._cache_structure(), paper_model.quadrature_nodes)
    assert checksum.read_text().split()[5] == key
    assert model_module.library_problem(library, key) is None


def test_the_cvodes_driver_builds_wherever_its_prerequisites_hold():
    """The driver's tests skip where it cannot be built (no C compiler, a CasADi whose
    SUNDIALS has another interface); a C source that no longer compiles would make them
    all skip too, silently: here it fails."""
    if model_module.find_compiler() is None:
        pytest.skip("no C compiler")
    if os.environ.get("SOFTCURVE_NATIVE_CVODES", "1") in ("0", ""):
        pytest.skip("the driver is switched off (SOFTCURVE_NATIVE_CVODES)")
    plugin = Path(ca.__file__).parent / driver_library.PLUGIN
    try:
        if not hasattr(ctypes.CDLL(str(plugin)), "CVSpgmr"):
            pytest.skip("CasADi's SUNDIALS has another interface")
    except OSError:
        pytest.skip("CasADi has no CVODES plugin here")
    assert native.driver() is not None, (
        "the driver's C files (driver_library.C_FOLDER) failed to build"
    )


def test_the_cache_key_holds_every_module_of_the_symbolic_layer():
    """A module added to the symbolic layer (the segment's Functions, the chain
    algorithms) changes what the generated code computes: it is in the key."""
    package = Path(sc.__file__).parent
    hashed = set(model_module.key_sources())
    assert set((package / "symbolic").glob("*.py")) <= hashed
    assert {package / "symbolic" / name for name in ("segment.py", "chain.py")} <= hashed
