"""Hand-written C compiled next to the generated code: :func:`compile_source`.

For small C sources that are not CasADi-generated (the driver of the SUNDIALS library
that ships with CasADi, ``softcurve.simulation.solvers._driver``): the compiler, flags,
checksum files and on-disk cache of ``softcurve.compiled._build`` and
``softcurve.compiled._cache``, keyed by the source's content.
"""

from __future__ import annotations

import ctypes
import subprocess
import tempfile
from pathlib import Path

from softcurve.compiled._build import (
    NoCompiler,
    _compile_flags,
    _compiler,
    _run,
    cache_key,
    require_compiler,
)
from softcurve.compiled._cache import load_or_build


def compile_source(stem: str, source: str, link: tuple[str, ...] = ()):
    """A C ``source`` compiled to a shared library, cached on disk by its content, loaded
    with ``ctypes.CDLL``.

    Parameters
    ----------
    stem : str
        Start of the library's file name in the cache (and of the C file's).
    source : str
        The C source.
    link : tuple of str
        Further arguments of the compiler's link step (``-L``, ``-l``, ``-Wl,-rpath``),
        part of the cache key.

    Returns
    -------
    ctypes.CDLL or None
        The loaded library; None when it is not cached and no C compiler works, or the
        build fails (the caller then falls back to CasADi's own functions).
    """
    compiler = _compiler()
    flags = _compile_flags()

    def build() -> bytes:
        command = [*require_compiler(compiler), *flags, "-shared", f"{stem}.c", "-o", f"{stem}.so"]
        with tempfile.TemporaryDirectory() as tmp:
            Path(tmp, f"{stem}.c").write_text(source)
            _run([*command, *link, "-lm"], tmp)
            return Path(tmp, f"{stem}.so").read_bytes()

    key = cache_key(stem, source, flags, tuple(link))
    try:
        return load_or_build(stem, key, build, ctypes.CDLL, stacklevel=2)[1]
    except (NoCompiler, OSError, subprocess.CalledProcessError):
        return None
