"""Hand-written C compiled next to the generated code, and the one loader of compiled
libraries: :func:`compile_source` (a source that Python fills in), :func:`compile_files`
(C files shipped with the package), :func:`load_library`, :func:`load_function`,
:func:`load_external` and :func:`exact_external`.

The compiler, flags, checksum files and on-disk cache are those of
``softcurve.compiled._build`` and ``softcurve.compiled._cache``; a library's cache
key holds the content of every source it is built from, so a library built from a
source that has since changed is never loaded.
"""

from __future__ import annotations

import ctypes
import subprocess
import tempfile
from collections.abc import Sequence
from pathlib import Path

import casadi as ca

from softcurve.base.docs import parameters_from
from softcurve.compiled import _build as build
from softcurve.compiled._cache import load_or_build
from softcurve.compiled._native import NativeFunction

_loaded = parameters_from(
    {
        "path": ("str or pathlib.Path", "The compiled library."),
        "name": ("str", "The function's name in it."),
    }
)


class Library(ctypes.CDLL):
    """A loaded shared library that knows its file, ``path`` (worker processes load the
    same file again)."""

    def __init__(self, path):
        super().__init__(str(path))
        self.path = Path(path).resolve()


def load_library(path) -> Library:
    """The shared library at ``path``, loaded.

    Parameters
    ----------
    path : str or pathlib.Path
        The library.

    Returns
    -------
    Library

    Raises
    ------
    OSError
        If it cannot be loaded.
    """
    return Library(path)


@_loaded
def load_function(path, name: str) -> NativeFunction:
    """The CasADi-generated function ``name`` of the library at ``path``, called through
    ctypes.

    Parameters
    ----------
    %(path)s
    %(name)s

    Returns
    -------
    NativeFunction
    """
    return NativeFunction(load_library(path), name)


@_loaded
def load_with_path(path, name: str) -> tuple:
    """``(path, name, the loaded function)``: the path (absolute: a worker process may
    start elsewhere) and name travel to worker processes, the loaded function stays.

    Parameters
    ----------
    %(path)s
    %(name)s

    Returns
    -------
    tuple
        ``(absolute path as str, name, NativeFunction)``.
    """
    return (str(Path(path).resolve()), name, load_function(path, name))


@_loaded
def load_external(path, name: str) -> ca.Function:
    """The function ``name`` of the compiled library ``path`` as a CasADi ``external``
    (derivatives by finite differences): :func:`~softcurve.compiled.compile_function`'s
    default loader.

    Parameters
    ----------
    %(path)s
    %(name)s
    """
    return ca.external(name, str(path), {"enable_fd": True})


@_loaded
def exact_external(path, name: str) -> ca.Function:
    """The function ``name`` of the compiled library ``path`` as a CasADi ``external``
    whose derivatives are the library's own ``fwd1_<name>`` and ``adj1_<name>`` (and the
    second ones, :func:`~softcurve.compiled.compile_function` with ``derivatives`` 1 to
    3).

    Parameters
    ----------
    %(path)s
    %(name)s
    """
    return ca.external(name, str(path))


def _compiled(stem: str, key_parts: tuple, write, arguments: Sequence[str], symbols: tuple):
    """The library ``stem`` built by the compiler with ``arguments`` in a folder where
    ``write(folder)`` put its sources, cached under the key of ``key_parts`` and the
    flags, defining ``symbols``; loaded, or None when it is not cached and cannot be
    built."""
    compiler = build.find_compiler()
    flags = build.compile_flags()

    def compile_() -> bytes:
        command = [*build.require_compiler(compiler), *flags, "-shared"]
        with tempfile.TemporaryDirectory() as tmp:
            write(Path(tmp))
            build.run_compiler([*command, *arguments, "-o", f"{stem}.so", "-lm"], tmp)
            return Path(tmp, f"{stem}.so").read_bytes()

    key = build.cache_key(stem, *key_parts, flags)
    try:
        what = f"softcurve's {stem}"
        return load_or_build(
            stem, key, compile_, load_library, stacklevel=3, symbols=tuple(symbols), what=what
        )[1]
    except (build.NoCompiler, OSError, subprocess.CalledProcessError):
        return None


def compile_source(stem: str, source: str, link: tuple[str, ...] = (), symbols=()):
    """A C ``source`` compiled to a shared library, cached on disk by its content, loaded.

    Parameters
    ----------
    stem : str
        Start of the library's file name in the cache (and of the C file's).
    source : str
        The C source.
    link : tuple of str
        Further arguments of the compiler's link step (``-L``, ``-l``, ``-Wl,-rpath``),
        part of the cache key.
    symbols : sequence of str
        Names the library must define (its entry points): a cached library that lacks
        them is another's, and is rebuilt.

    Returns
    -------
    ctypes.CDLL or None
        The loaded library; None when it is not cached and no C compiler works, or the
        build fails (the caller then falls back to CasADi's own functions).
    """
    return _compiled(
        stem,
        (source, tuple(link)),
        lambda folder: (folder / f"{stem}.c").write_text(source),
        [f"{stem}.c", *link],
        symbols,
    )


def compile_files(
    stem: str, folder, link: tuple[str, ...] = (), defines: tuple[str, ...] = (), symbols=()
):
    """Every ``.c`` file of ``folder`` compiled into one shared library (its headers found
    in ``folder``), cached on disk by the content of every ``.c`` and ``.h`` file there,
    loaded.

    Parameters
    ----------
    stem : str
        Start of the library's file name in the cache.
    folder : str or pathlib.Path
        The folder of the C files (the package's data).
    link : tuple of str
        Further arguments of the link step, part of the cache key.
    defines : tuple of str
        Macros defined on the command line (``-D``), part of the cache key.
    symbols : sequence of str
        As :func:`compile_source`'s.

    Returns
    -------
    ctypes.CDLL or None
        As :func:`compile_source`.
    """
    folder = Path(folder).resolve()
    sources = sorted(folder.glob("*.c"))
    contents = tuple(
        (path.name, path.read_bytes()) for path in sorted([*sources, *folder.glob("*.h")])
    )
    arguments = [f"-I{folder}", *(f"-D{name}" for name in defines), *map(str, sources), *link]
    key_parts = (contents, tuple(link), tuple(defines))
    return _compiled(stem, key_parts, lambda _: None, arguments, symbols)
