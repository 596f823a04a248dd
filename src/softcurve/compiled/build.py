"""Compiling CasADi functions to C and keeping the libraries on disk.

The one place that knows about code generation, compilers and the on-disk cache: the
library of a model is cached under a key made of its structure, the sources of the
symbolic layer, CasADi's version and the compiler command, so a second process with a
robot of the same structure (any parameter values) starts without compiling.

Every library has a checksum file beside it (``<library>.sha256``: its SHA-256 and size).
A cached library is verified before it is loaded, so a damaged or partly copied file
never reaches the dynamic loader (a truncated library would crash the process with
SIGBUS); one that fails its checksum, has none or fails to load is rebuilt once, with a
:class:`CacheWarning` naming the file and the reason.
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
from collections.abc import Callable
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import casadi as ca

from softcurve.base.docs import parameters_from
from softcurve.base.files import atomic_write


class CompilerWarning(UserWarning):
    """No C compiler was found or it failed: the model runs in CasADi's virtual machine."""


class CacheWarning(UserWarning):
    """A cached compiled library was damaged (checksum, size) or failed to load, and was
    replaced by a fresh build."""


_CHECKSUM_SUFFIX = ".sha256"
_LOAD_ERRORS = (OSError, RuntimeError)
"""What loading a library raises: ``ctypes.CDLL`` an OSError, CasADi's ``external`` a
RuntimeError."""
_FUNCTION_CACHE_FORMAT = "checksummed-1"
"""Part of :func:`compile_function`'s cache key, so libraries cached before checksum
files existed are not taken for damaged ones."""


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


def _native_flags() -> tuple[str, ...]:
    """:data:`_NATIVE_FLAGS`, or none where ``SOFTCURVE_PORTABLE`` is set (to anything but
    "0")."""
    if os.environ.get("SOFTCURVE_PORTABLE", "0") not in ("", "0"):
        return ()
    return _NATIVE_FLAGS


def _compile_flags() -> tuple[str, ...]:
    """The model's compiler flags: :data:`_COMPILE_FLAGS` and :func:`_native_flags`."""
    return _COMPILE_FLAGS + _native_flags()


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


_library_docs = parameters_from(
    {"library": ("str or os.PathLike", "A compiled library in the cache (a ``.so`` file).")}
)


@_library_docs
def checksum_file(library) -> Path:
    """The checksum file beside a cached library: ``<library>.sha256``.

    Parameters
    ----------
    %(library)s

    Returns
    -------
    pathlib.Path
        Its checksum file, one line ``sha256 <hex digest> size <bytes>``.
    """
    library = Path(library)
    return library.with_name(library.name + _CHECKSUM_SUFFIX)


def _checksum_line(data: bytes) -> str:
    return f"sha256 {hashlib.sha256(data).hexdigest()} size {len(data)}\n"


@_library_docs
def library_problem(library) -> str | None:
    """Why a cached library must not be loaded, or None when it matches its checksum file.

    The size is compared first (a partial copy fails without being read), then the
    SHA-256 of the content: one read of the file (about 0.1-0.5 MB).

    Parameters
    ----------
    %(library)s

    Returns
    -------
    str or None
        The reason in words ("has no checksum file ...", "has 0 bytes ..."), or None.
    """
    library, checksum = Path(library), checksum_file(library)
    try:
        fields = checksum.read_text(encoding="ascii").split()
    except FileNotFoundError:
        return f"has no checksum file ({checksum.name})"
    except (OSError, UnicodeDecodeError) as exc:
        return f"has an unreadable checksum file ({checksum.name}: {exc})"
    if len(fields) != 4 or fields[0] != "sha256" or fields[2] != "size" or not fields[3].isdigit():
        return f"has a malformed checksum file ({checksum.name})"
    try:
        size = library.stat().st_size
        if size != int(fields[3]):
            return f"has {size} bytes where its checksum file records {fields[3]} (partial copy?)"
        data = library.read_bytes()
    except OSError as exc:
        return f"cannot be read ({exc})"
    if hashlib.sha256(data).hexdigest() != fields[1]:
        return "does not match its checksum (damaged)"
    return None


_VERIFIED: dict[Path, tuple[int, int, int, int]] = {}
"""The libraries this process verified and loaded, with the (device, inode, size,
modification time) they had: a later model of the same structure skips the read while
the file is unchanged (a replaced or rewritten file is verified again)."""


def _identity(path: Path) -> tuple[int, int, int, int] | None:
    try:
        stat = path.stat()
    except FileNotFoundError:
        return None
    return stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns


class _UnusableLibrary(OSError):
    """A freshly built library failed to load."""


def _load_or_build(library: Path, build: Callable[[Path], None], load: Callable, stacklevel: int):
    """``load(library)``, building the library first when it is missing; a cached one that
    fails :func:`library_problem` or fails to load is replaced by a fresh build once,
    with a :class:`CacheWarning`. Raises what ``build`` raises, or :class:`_UnusableLibrary`
    when the fresh build fails to load too."""
    identity = _identity(library)
    if identity is not None:
        problem = None if _VERIFIED.get(library) == identity else library_problem(library)
        if problem is None:  # checked before dlopen: a truncated file would SIGBUS in it
            try:
                loaded = load(library)
            except _LOAD_ERRORS as exc:
                problem = f"failed to load ({str(exc).strip()[:300]})"
            else:
                _VERIFIED[library] = identity
                return loaded
        warnings.warn(
            f"softcurve cache: the compiled library {library} {problem}; replacing it with a "
            "fresh build (a shared cache needs atomic renames: see docs/sweeps.md)",
            CacheWarning,
            stacklevel=stacklevel + 1,
        )
    build(library)
    try:
        return load(library)
    except _LOAD_ERRORS as exc:
        raise _UnusableLibrary(f"{library} failed to load after a fresh build: {exc}") from exc


def compiled_library(structure, quadrature_nodes, symbolic, load=None):
    """The cached library for this structure, verified and loaded, compiling it first if
    needed (or if the cached one is damaged); None on failure.

    Parameters
    ----------
    structure : tuple
        :meth:`Robot.structure`.
    quadrature_nodes : int
        Gauss-Legendre nodes per segment, part of the cache key.
    symbolic : callable
        Returns the structure's functions by name (called only when compiling).
    load : callable, optional
        ``load(path)`` opens the library (``ctypes.CDLL``, say) and raises OSError or
        RuntimeError when it cannot; default: return the path unchanged.

    Returns
    -------
    tuple of (pathlib.Path, object) or None
        The library's path and what ``load`` returned; None (with a
        :class:`CompilerWarning`) when no compiler works: the model then runs in CasADi's
        virtual machine.
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

    def build(path: Path) -> None:
        functions = symbolic()
        selected = {name: functions[name] for name in COMPILED_FUNCTIONS}
        _compile_for_this_cpu(selected, compiler, path, _COMPILE_FLAGS)

    try:
        loaded = _load_or_build(library, build, load or (lambda path: path), stacklevel=3)
    except (OSError, subprocess.CalledProcessError) as exc:
        detail = getattr(exc, "stderr", None) or str(exc)
        warnings.warn(
            f"compiling the model with {compiler[0]} failed ({str(detail).strip()[:400]}): "
            "softcurve runs in CasADi's virtual machine",
            CompilerWarning,
            stacklevel=3,
        )
        return None
    return library, loaded


def _compile(
    functions: dict[str, ca.Function],
    compiler: list[str],
    library: Path,
    flags: tuple[str, ...] = _COMPILE_FLAGS,
) -> None:
    """One C file per function, compiled in parallel, linked, then written by :func:`_install`."""
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
        _install(library, partial.read_bytes())


_REFUSING_NATIVE: set[tuple[str, ...]] = set()
"""Compiler commands that refused :data:`_NATIVE_FLAGS` in this process: later builds go
without them at once, instead of failing first (a failed compile of a large generated
file costs as much as a good one)."""


def _compile_for_this_cpu(functions, compiler, library, flags, tail=()) -> None:
    """:func:`_compile` with ``(*flags, *native, *tail)``, ``native`` from
    :func:`_native_flags`; again without them where the compiler refuses them (remembered
    in :data:`_REFUSING_NATIVE`)."""
    wanted = () if tuple(compiler) in _REFUSING_NATIVE else _native_flags()
    try:
        _compile(functions, compiler, library, (*flags, *wanted, *tail))
    except subprocess.CalledProcessError:
        if not wanted:
            raise
        _compile(functions, compiler, library, (*flags, *tail))
        _REFUSING_NATIVE.add(tuple(compiler))  # built without them: they were refused


def _install(library: Path, data: bytes) -> None:
    """Write ``data`` as ``library`` with its checksum file, each renamed into place whole.

    The checksum file comes first, so a reader never finds the new library without it; a
    checksum file without its library only means the library is built again. Two
    processes installing at once write the same bytes (the build is deterministic)."""
    atomic_write(checksum_file(library), _checksum_line(data).encode("ascii"))
    atomic_write(library, data)


def _run(command: list[str], directory: str) -> None:
    subprocess.run(command, cwd=directory, check=True, capture_output=True, text=True)
