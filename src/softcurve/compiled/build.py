"""Compiling CasADi functions to C and keeping the libraries on disk.

The one place that knows about code generation, compilers and the on-disk cache: the
library of a model is cached under a key made of its structure, the sources of the
symbolic layer, CasADi's version and the compiler command, so a second process with a
robot of the same structure (any parameter values) starts without compiling.
"""

from __future__ import annotations

import hashlib
import os
import platform
import shlex
import shutil
import subprocess
import sys
import tempfile
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import casadi as ca


class CompilerWarning(UserWarning):
    """No C compiler was found or it failed: the model runs in CasADi's virtual machine."""


_COMPILE_FLAGS = ("-O2", "-fPIC", "-fvisibility=hidden", "-DGCC_HASCLASSVISIBILITY")
_NATIVE_FLAGS = ("-march=native",)
"""Added when the compiler accepts them and ``SOFTCURVE_PORTABLE`` is not set: the code
then uses this CPU's vector and fused multiply-add instructions, 9-16 % faster
(``benchmarks/bench_model.py``). The cache key holds the CPU's identity, so a cache
shared by different machines keeps one library per CPU type. Results then differ
between CPU types at round-off (as NumPy's, whose BLAS also picks kernels per CPU);
``SOFTCURVE_PORTABLE=1`` builds portable, bitwise reproducible code instead."""


def cache_directory() -> Path:
    """Where compiled models are kept: ``$SOFTCURVE_CACHE_DIR``, else the user cache."""
    env = os.environ.get("SOFTCURVE_CACHE_DIR")
    if env:
        return Path(env)
    base = os.environ.get("XDG_CACHE_HOME") or Path.home() / ".cache"
    return Path(base) / "softcurve"


def _compiler() -> list[str] | None:
    env = os.environ.get("CC")
    if env:
        return shlex.split(env)
    for name in ("cc", "gcc", "clang"):
        path = shutil.which(name)
        if path:
            return [path]
    return None


def _cpu_identity() -> str:
    """The CPU model and instruction-set flags (Linux), else what the platform reports."""
    try:
        with open("/proc/cpuinfo", encoding="utf-8", errors="replace") as cpuinfo:
            first = cpuinfo.read().split("\n\n")[0]
    except OSError:
        return f"{platform.machine()} {platform.processor()}"
    fields = {}
    for line in first.splitlines():
        key, _, value = line.partition(":")
        fields[key.strip()] = value.strip()
    keys = ("vendor_id", "model name", "flags", "Features", "CPU part")
    return f"{platform.machine()} " + " ".join(fields.get(k, "") for k in keys)


def _compile_flags() -> tuple[str, ...]:
    """The model's compiler flags: :data:`_COMPILE_FLAGS`, plus :data:`_NATIVE_FLAGS`
    unless ``SOFTCURVE_PORTABLE`` is set (to anything but "0")."""
    if os.environ.get("SOFTCURVE_PORTABLE", "0") not in ("", "0"):
        return _COMPILE_FLAGS
    return _COMPILE_FLAGS + _NATIVE_FLAGS


COMPILED_FUNCTIONS = (
    "dynamics_terms",
    "potential_energy",
    "creep_rate",
    "rhs",
    "pose",
    "jacobian",
)
"""Compiled to C: every term of the equation of motion comes from ``dynamics_terms`` and
the accelerations from ``rhs``, so the large expressions are compiled twice, not once per
method; ``coriolis_matrix`` (for analysis, several times larger than ``C qd``) runs in
CasADi's virtual machine. The other entries of ``symbolic`` are for users who build on
CasADi (optimal control, code generation)."""
_SYMBOLIC_SOURCES = (
    "base/smooth.py",
    "description/materials.py",
    "description/layout.py",
    "symbolic/kinematics.py",
    "symbolic/dynamics.py",
    "symbolic/functions.py",
    "compiled/build.py",
)
"""The sources the generated code depends on, relative to the package folder."""


def _cache_key(structure: tuple, quadrature_nodes: int, command: list[str]) -> str:
    """Everything the generated code depends on: structure, node count, the source of the
    symbolic layer, CasADi's version, the compiler command and flags, and the CPU when the
    code is built for it."""
    digest = hashlib.sha256()
    flags = _compile_flags()
    digest.update(repr((structure, quadrature_nodes, command, flags)).encode())
    if _NATIVE_FLAGS[0] in flags:
        digest.update(_cpu_identity().encode())
    digest.update(f"{ca.__version__} {sys.platform} {sys.implementation.cache_tag}".encode())
    package = Path(__file__).parent.parent
    for name in _SYMBOLIC_SOURCES:
        digest.update((package / name).read_bytes())
    return digest.hexdigest()[:24]


def compiled_library(structure, quadrature_nodes, symbolic) -> Path | None:
    """The cached library for this structure, compiling it first if needed; None on failure.

    Parameters
    ----------
    structure : tuple
        :meth:`Robot.structure`.
    quadrature_nodes : int
        Gauss-Legendre nodes per segment, part of the cache key.
    symbolic : callable
        Returns the structure's functions by name (called only when compiling).
    """
    compiler = _compiler()
    if compiler is None:
        warnings.warn(
            "no C compiler found (set CC, or install gcc or clang): softcurve runs in "
            "CasADi's virtual machine, about 10x slower to simulate",
            CompilerWarning,
            stacklevel=3,
        )
        return None
    library = cache_directory() / f"model_{_cache_key(structure, quadrature_nodes, compiler)}.so"
    if library.exists():
        return library
    try:
        functions = symbolic()
        selected = {name: functions[name] for name in COMPILED_FUNCTIONS}
        try:
            _compile(selected, compiler, library, _compile_flags())
        except subprocess.CalledProcessError:
            if _compile_flags() == _COMPILE_FLAGS:
                raise
            _compile(selected, compiler, library)  # a compiler without -march=native
    except (OSError, subprocess.CalledProcessError) as exc:
        detail = getattr(exc, "stderr", None) or str(exc)
        warnings.warn(
            f"compiling the model with {compiler[0]} failed ({str(detail).strip()[:400]}): "
            "softcurve runs in CasADi's virtual machine",
            CompilerWarning,
            stacklevel=3,
        )
        return None
    return library


def _compile(
    functions: dict[str, ca.Function],
    compiler: list[str],
    library: Path,
    flags: tuple[str, ...] = _COMPILE_FLAGS,
) -> None:
    """One C file per function, compiled in parallel, linked into ``library`` atomically."""
    library.parent.mkdir(parents=True, exist_ok=True)
    with tempfile.TemporaryDirectory() as tmp:
        jobs = []
        for name, f in functions.items():
            generator = ca.CodeGenerator(f"{name}.c", {"with_header": False})
            generator.add(f)
            generator.generate(tmp + os.sep)
            jobs.append([*compiler, *flags, "-c", f"{name}.c", "-o", f"{name}.o"])
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
            list(pool.map(lambda job: _run(job, tmp), jobs))
        partial = Path(tmp, "model.so")
        objects = [f"{name}.o" for name in functions]
        _run([*compiler, "-shared", "-o", str(partial), *objects, "-lm"], tmp)
        staged = library.parent / f".{library.name}.{os.getpid()}"
        shutil.copyfile(partial, staged)
        os.replace(staged, library)  # atomic: other processes see all or nothing


def compile_function(function: ca.Function, optimization: str = "-O1") -> ca.Function:
    """``function`` generated as C, compiled, cached on disk by its content and loaded.

    For CasADi functions built on a model's expressions (the identification's
    sensitivity equations, say) that are evaluated often: the same compiler and cache as
    :class:`Model`, keyed by the serialized function, so a second process loads it.

    Parameters
    ----------
    function : casadi.Function
        An SX or MX function without Python callbacks.
    optimization : str
        The compiler's optimization flag; ``-O1`` compiles large generated files several
        times faster than ``-O2`` at a small cost in speed.

    Returns
    -------
    casadi.Function
        The compiled function as a CasADi ``external`` (derivatives by finite
        differences), or ``function`` itself when no C compiler works (then it runs in
        CasADi's virtual machine).
    """
    compiler = _compiler()
    if compiler is None:
        return function
    digest = hashlib.sha256(function.serialize().encode())
    digest.update(f"{ca.__version__} {sys.platform} {compiler} {optimization}".encode())
    library = cache_directory() / f"function_{digest.hexdigest()[:24]}.so"
    if not library.exists():
        try:
            _compile({function.name(): function}, compiler, library, (optimization, "-fPIC"))
        except (OSError, subprocess.CalledProcessError):
            return function
    return ca.external(function.name(), str(library), {"enable_fd": True})


def _run(command: list[str], directory: str) -> None:
    subprocess.run(command, cwd=directory, check=True, capture_output=True, text=True)
