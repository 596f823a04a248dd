"""Compiling CasADi functions to C: the compiler, its flags, the cache keys.

The one place that knows about code generation and compilers: the library of a model is
cached (``softcurve.compiled._cache``) under a key made of its structure, the sources
of the symbolic layer, CasADi's version, the flags and (for code built for this CPU) the
CPU, so a second process with a robot of the same structure (any parameter values)
starts without compiling. The key does not hold the compiler: a library is what it
computes, whichever compiler built it, and a filled cache needs no compiler at all.
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
from typing import NamedTuple

import casadi as ca

from softcurve.base.docs import parameters_from
from softcurve.compiled._cache import CacheWarning as CacheWarning
from softcurve.compiled._cache import cache_directory as cache_directory
from softcurve.compiled._cache import cached_library, load_or_build
from softcurve.compiled._cache import checksum_file as checksum_file
from softcurve.compiled._cache import library_problem as library_problem


class CompilerWarning(UserWarning):
    """No C compiler was found or it failed: the model runs in CasADi's virtual machine."""


class NoCompiler(OSError):
    """A library must be built and no C compiler was found (``CC``, ``cc``, ``gcc``,
    ``clang`` on ``PATH``)."""


_CACHE_FORMAT = "keyed-2"
"""Part of every cache key: libraries cached before checksum files recorded their key
are not looked up (nor taken for damaged ones)."""


_COMPILE_FLAGS = ("-O2", "-fPIC", "-fvisibility=hidden", "-DGCC_HASCLASSVISIBILITY")
"""The flags of hand-written C (``softcurve.compiled.compile_source``): small files, for
which GCC's ``-O2`` costs nothing to speak of."""

_LIBRARY_FLAGS = ("-fPIC", "-fvisibility=hidden", "-DGCC_HASCLASSVISIBILITY")
"""Beside :data:`FUNCTION_FLAGS`, the model library's: position-independent code that
exports CasADi's entry points alone."""

FUNCTION_FLAGS = (
    "-O2",
    "-fno-gcse",
    "-fno-tree-pre",
    "-fno-code-hoisting",
    "-fira-algorithm=priority",
)
"""Optimization flags of the C that CasADi generates: the model library and
:func:`softcurve.compiled.compile_function` (``-march=native`` is added unless
``SOFTCURVE_PORTABLE`` is set). Generated functions are large straight-line code (the
two-segment model's right-hand side is 29,700 operations, the identification's
sensitivity equations of the paper robot 75,000), on which three passes that ``-O2``
adds to ``-O1`` cost much and give nothing: GCC 12's partial-redundancy elimination and
code hoisting take minutes on the largest (72-95 s with either on, against 7-10 s with
both off), and global common-subexpression elimination makes the code slower (10.2-10.5
us with it against 8.9-10.0 us without, in a C loop over 64 states); CasADi has already
shared the common subexpressions. The sensitivity function then compiles in 8.4 s
against ``-O1``'s 6.5 s and evaluates in 9.86 us against 11.77 us (``python
benchmarks/bench_compile_flags.py --only sensitivity --quick``, best of 5 alternating
runs, ``-march=native`` on both). The two-segment model's right-hand side compiles in
6.9 s against 10.7 s at plain ``-O2`` (1.8 s at ``-O1``) and evaluates in 4.07 us
against 3.99 us (4.97 us at ``-O1``), its ``dynamics_terms`` in 3.3 s against 7.2 s at
the same speed (``python benchmarks/bench_compile_flags.py --robot two-segment``). They
are GCC's (8 and later); a compiler that refuses them builds with
:data:`PORTABLE_FUNCTION_FLAGS`.

``-fira-algorithm=priority`` (GCC's register allocator by priority colouring instead
of Chaitin-Briggs) makes the generated straight-line code faster at the same compile
time (``python benchmarks/bench_compile_flags.py --only
sensitivity --quick --repeat 3`` and ``--only rhs,dynamics_terms --repeat 3``, at the
flags without and with it): the paper robot's sensitivity equations 12.50 -> 11.05 us,
its right-hand side 1.62 -> 1.52 us, its forward dynamics in a C loop 1.63 -> 1.50 us
(``benchmarks/bench_model.inside_c``), the two-segment robot's right-hand side 4.74 ->
4.57 us; ``simulate`` of the paper case 3.41-3.43 -> 3.34-3.36 ms of integration
(``python benchmarks/bench_revisions.py`` of the two flag sets)."""

PORTABLE_FUNCTION_FLAGS = ("-O1",)
"""The flags of generated C for a compiler that refuses :data:`FUNCTION_FLAGS` (clang has
no ``-fno-tree-pre``, GCC before 8 no ``-fno-code-hoisting``): every C compiler takes
them, and they compile as fast."""

_NATIVE_FLAGS = ("-march=native",)
"""Added when the compiler accepts them and ``SOFTCURVE_PORTABLE`` is not set: the code
then uses this CPU's vector and fused multiply-add instructions, 9-16 % faster
(``benchmarks/bench_model.py``). The cache key holds the CPU's identity, so a cache
shared by different machines keeps one library per CPU type. Results then differ
between CPU types at round-off (as NumPy's, whose BLAS also picks kernels per CPU);
``SOFTCURVE_PORTABLE=1`` builds portable, bitwise reproducible code instead."""


def find_compiler() -> list[str] | None:
    """The C compiler's command: ``$CC`` (split as a shell would), else the first of
    ``cc``, ``gcc``, ``clang`` on ``PATH``.

    Returns
    -------
    list of str or None
        The command; None when there is none.
    """
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


def compile_flags() -> tuple[str, ...]:
    """The compiler flags of every library softcurve builds: :data:`_COMPILE_FLAGS` and
    :func:`_native_flags`.

    Returns
    -------
    tuple of str
    """
    return _COMPILE_FLAGS + _native_flags()


JACOBIAN_FUNCTIONS = ("rhs_jacobian",)
"""The library of the model's exact Jacobian (:mod:`softcurve.symbolic.derivatives`),
compiled apart from the model's on first use (``Model.rhs_jacobian``, ``simulate`` with
``jacobian="exact"``): at eight segments it takes 3.9 times the model's compile time
(``benchmarks/bench_jacobian.py``), and forward differences serve the default routes."""

COMPILED_FUNCTIONS = (
    "dynamics_terms",
    "potential_energy",
    "creep_rate",
    "rhs",
    "pose",
    "jacobian",
    "domain",
)
"""Compiled to C: every term of the equation of motion comes from ``dynamics_terms`` and
the accelerations from ``rhs``, so the large expressions are compiled twice, not once per
method; ``coriolis_matrix`` (for analysis, several times larger than ``C qd``) runs in
CasADi's virtual machine; ``domain`` is the elements' domain, which the C driver calls at
its outputs. The other entries of ``symbolic`` are for users who build on CasADi
(optimal control, code generation)."""

EXACT_FLAGS = ("-ffp-contract=off",)
"""Added to the flags of the functions of :data:`EXACT_FUNCTIONS`: no fused multiply-add,
so that the C rounds every operation as NumPy does and the compiled rule decides as the
Python one, bit for bit, up to its boundary (``tests/test_domain.py``)."""

EXACT_FUNCTIONS = ("domain",)
"""The generated functions built with :data:`EXACT_FLAGS` (where the compiler takes them):
those whose result Python must reproduce exactly."""

_SYMBOLIC_SOURCES = (
    "base/smooth.py",
    "description/materials.py",
    "description/layout.py",
    "description/kind.py",
    "description/elements.py",
    "description/curvature.py",
    "description/strain.py",
    "description/rigid.py",
    "symbolic/*.py",
    "compiled/_build.py",
)
"""The sources the generated code depends on, relative to the package folder (patterns:
the symbolic layer is every module of its folder, so that a new one is in the key)."""


def require_compiler(compiler: list[str] | None) -> list[str]:
    """``compiler``, or :class:`NoCompiler` when None: what every build calls first, so
    only a build needs a compiler, a cached library none.

    Parameters
    ----------
    compiler : list of str or None
        The command of the compiler found (``CC``, else ``cc``, ``gcc`` or ``clang``
        on ``PATH``).

    Returns
    -------
    list of str
        ``compiler``.
    """
    if compiler is None:
        raise NoCompiler("no C compiler found (set CC, or install gcc or clang)")
    return compiler


def cache_key(kind: str, *parts) -> str:
    """The full cache key (64 hex digits) of a library of ``kind`` built from ``parts``.

    What every cached library's code depends on besides ``parts`` (what it is generated
    from and the flags asked for): CasADi's version, the platform and Python, whether the
    code is built for this CPU and then the CPU. Not the compiler: any C compiler with
    these flags builds the same functions, so a cache filled on one machine serves a
    worker without a compiler.

    Parameters
    ----------
    kind : str
        ``"model"``, ``"function"`` or a C source's stem.
    *parts
        Their ``repr`` is hashed (strings, bytes, tuples of them).

    Returns
    -------
    str
    """
    digest = hashlib.sha256()
    native = _native_flags()
    digest.update(repr((kind, parts, native, _CACHE_FORMAT)).encode())
    if native:
        digest.update(_cpu_identity().encode())
    digest.update(f"{ca.__version__} {sys.platform} {sys.implementation.cache_tag}".encode())
    return digest.hexdigest()


def key_sources() -> list[Path]:
    """The files of :data:`_SYMBOLIC_SOURCES`, in the order they are hashed.

    Returns
    -------
    list of pathlib.Path
    """
    package = Path(__file__).parent.parent
    return [path for pattern in _SYMBOLIC_SOURCES for path in sorted(package.glob(pattern))]


class _Library(NamedTuple):
    """A kind of model library: its functions, what it is called and what runs without
    it (in :func:`compiled_library`'s warning; ``slower`` where there is no compiler)."""

    names: tuple[str, ...]
    called: str
    without: str
    slower: str = ""


_LIBRARIES = {
    "model": _Library(
        COMPILED_FUNCTIONS,
        "the model",
        "softcurve runs in CasADi's virtual machine",
        ", about 10x slower to simulate",
    ),
    "jacobian": _Library(
        JACOBIAN_FUNCTIONS,
        "the model's exact Jacobian",
        "the driver's Newton matrix takes forward differences",
    ),
}


def _cache_key(structure: tuple, quadrature_nodes: int, kind: str = "model") -> str:
    """A model library's :func:`cache_key`: structure, node count, the flags and the
    source of the symbolic layer."""
    package = Path(__file__).parent.parent
    sources = hashlib.sha256()
    for path in key_sources():
        sources.update(path.relative_to(package).as_posix().encode())
        sources.update(path.read_bytes())
    flags = (*FUNCTION_FLAGS, *_LIBRARY_FLAGS, EXACT_FUNCTIONS, EXACT_FLAGS)
    return cache_key(kind, structure, quadrature_nodes, flags, sources.hexdigest())


def cached_model_library(structure, quadrature_nodes) -> Path | None:
    """The cached library :func:`compiled_library` would load for this structure without
    compiling, or None when it would compile; nothing is built, loaded or compiled.

    Parameters
    ----------
    structure : tuple
        :meth:`Robot.structure` (with the environment's part, as for
        :func:`compiled_library`).
    quadrature_nodes : int
        Gauss-Legendre nodes per segment, part of the cache key.

    Returns
    -------
    pathlib.Path or None
        The intact library recording this structure's key, or None.
    """
    return cached_library("model", _cache_key(structure, quadrature_nodes), COMPILED_FUNCTIONS)


def compiled_library(
    structure, quadrature_nodes, symbolic, load=None, what: str = "the model", kind: str = "model"
):
    """The cached library for this structure, checked and loaded, compiling it first if
    needed (or if the cached one is damaged or another's); None on failure.

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
    what : str
        What it is, in words, for the line that says it is compiled (``"the model of 2
        segments"``).
    kind : {"model", "jacobian"}
        The model's library (:data:`COMPILED_FUNCTIONS`) or its exact Jacobian's
        (:data:`JACOBIAN_FUNCTIONS`).

    Returns
    -------
    tuple of (pathlib.Path, object) or None
        The library's path and what ``load`` returned; None (with a
        :class:`CompilerWarning`) when it is not cached and no compiler works: the model
        then runs in CasADi's virtual machine.
    """
    compiler = find_compiler()
    library = _LIBRARIES[kind]
    names = library.names

    def build() -> bytes:
        functions = symbolic()
        selected = {name: functions[name] for name in names}
        return compile_generated(selected, require_compiler(compiler), tail=_LIBRARY_FLAGS)

    key = _cache_key(structure, quadrature_nodes, kind)
    try:
        return load_or_build(
            kind,
            key,
            build,
            load or (lambda path: path),
            stacklevel=3,
            symbols=names,
            what=what,
        )
    except NoCompiler as exc:
        message = f"{exc}: {library.without}{library.slower}"
    except (OSError, subprocess.CalledProcessError) as exc:
        detail = str(getattr(exc, "stderr", None) or exc).strip()[:400]
        message = f"compiling {library.called} with {compiler[0]} failed ({detail}): "
        message += library.without
    warnings.warn(message, CompilerWarning, stacklevel=3)
    return None


def _compile(
    functions: dict[str, ca.Function],
    compiler: list[str],
    flags: tuple[str, ...] = _COMPILE_FLAGS,
) -> bytes:
    """The shared library of ``functions``: one C file per function, compiled in
    parallel, linked in a temporary folder."""
    with tempfile.TemporaryDirectory() as tmp:
        jobs = []
        for name, f in functions.items():
            generator = ca.CodeGenerator(f"{name}.c", {"with_header": False})
            generator.add(f)
            generator.generate(tmp + os.sep)
            exact = name in EXACT_FUNCTIONS and accepts(compiler, EXACT_FLAGS)
            more = EXACT_FLAGS if exact else ()
            jobs.append([*compiler, *flags, *more, "-c", f"{name}.c", "-o", f"{name}.o"])
        with ThreadPoolExecutor(max_workers=os.cpu_count() or 1) as pool:
            list(pool.map(lambda job: run_compiler(job, tmp), jobs))
        partial = Path(tmp, "model.so")
        objects = [f"{name}.o" for name in functions]
        run_compiler([*compiler, "-shared", "-o", str(partial), *objects, "-lm"], tmp)
        return partial.read_bytes()


_ACCEPTED: dict[tuple[tuple[str, ...], tuple[str, ...]], bool] = {}
"""Whether a compiler command takes a set of flags, asked once per process
(:func:`accepts`)."""


def accepts(compiler, flags) -> bool:
    """Whether ``compiler`` compiles with ``flags``, asked once per process with an empty
    file (a compiler that refuses a flag refuses it on any file; this one takes
    milliseconds) and remembered in :data:`_ACCEPTED`. A probe rather than a fallback
    after a failed build: a build that fails for another reason (a full disk, a
    compiler killed) does not mark the flags as refused for the rest of the process, and
    a refused flag costs no failed compile of a large generated file.

    Parameters
    ----------
    compiler : list of str
        The compiler's command (:func:`find_compiler`).
    flags : tuple of str
        The flags.

    Returns
    -------
    bool
    """
    key = (tuple(compiler), tuple(flags))
    if key not in _ACCEPTED:
        with tempfile.TemporaryDirectory() as tmp:
            Path(tmp, "probe.c").touch()
            try:
                # -Werror: clang takes GCC's optimization flags it lacks with a warning
                command = [*compiler, *flags, "-Werror", "-c", "probe.c", "-o", "probe.o"]
                run_compiler(command, tmp)
                _ACCEPTED[key] = True
            except (OSError, subprocess.CalledProcessError):
                _ACCEPTED[key] = False
    return _ACCEPTED[key]


_BUILD_PARAMETERS = {
    "functions": ("dict of str to casadi.Function", "The functions, by name."),
    "compiler": ("list of str", "The compiler's command (:func:`find_compiler`)."),
    "tail": ("tuple of str", "Flags after the optimization and native ones."),
}
"""The arguments that the two builders of generated code share."""


@parameters_from(_BUILD_PARAMETERS, returns=("bytes", "The library's content."))
def compile_for_this_cpu(functions, compiler, flags, tail=()) -> bytes:
    """The shared library of ``functions`` (:func:`_compile`) with ``(*flags, *native,
    *tail)``, ``native`` from :func:`_native_flags`, left out where the compiler refuses
    them (:func:`accepts`).

    Parameters
    ----------
    %(functions)s
    %(compiler)s
    flags : tuple of str
        The flags asked for.
    %(tail)s
    """
    native = _native_flags()
    wanted = native if native and accepts(compiler, native) else ()
    return _compile(functions, compiler, (*flags, *wanted, *tail))


@parameters_from(_BUILD_PARAMETERS, returns=("bytes", "The library's content."))
def compile_generated(functions, compiler, flags=None, tail=()) -> bytes:
    """The shared library of CasADi's generated ``functions``
    (:func:`compile_for_this_cpu`) with ``flags``, by default :data:`FUNCTION_FLAGS`, or
    :data:`PORTABLE_FUNCTION_FLAGS` where the compiler refuses those (:func:`accepts`).

    Parameters
    ----------
    %(functions)s
    %(compiler)s
    flags : tuple of str, optional
        Optimization flags asked for instead of the default ones.
    %(tail)s
    """
    if flags is None:
        flags = FUNCTION_FLAGS if accepts(compiler, FUNCTION_FLAGS) else PORTABLE_FUNCTION_FLAGS
    return compile_for_this_cpu(functions, compiler, tuple(flags), tail)


def run_compiler(command: list[str], directory: str) -> None:
    """Run a compiler's ``command`` in ``directory``, its output captured.

    Parameters
    ----------
    command : list of str
        The command and its arguments.
    directory : str
        The working directory.

    Raises
    ------
    subprocess.CalledProcessError
        If the command fails (its ``stderr`` says why).
    """
    subprocess.run(command, cwd=directory, check=True, capture_output=True, text=True)
