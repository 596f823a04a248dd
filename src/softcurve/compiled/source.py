"""Hand-written C compiled next to the generated code: :func:`compile_source`.

For small C sources that are not CasADi-generated (the driver of the SUNDIALS library
that ships with CasADi, :mod:`softcurve.simulation.native`): the compiler, flags,
checksum files and on-disk cache of :mod:`softcurve.compiled.build`, keyed by the
source's content.
"""

from __future__ import annotations

import ctypes
import hashlib
import subprocess
import sys
import tempfile
from pathlib import Path

import casadi as ca

from softcurve.compiled.build import (
    _NATIVE_FLAGS,
    _compile_flags,
    _compiler,
    _cpu_identity,
    _install,
    _load_or_build,
    _run,
    cache_directory,
)


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
        The loaded library; None when no C compiler works or the build fails (the caller
        then falls back to CasADi's own functions).
    """
    compiler = _compiler()
    if compiler is None:
        return None
    flags = _compile_flags()
    digest = hashlib.sha256(source.encode())
    digest.update(repr((compiler, flags, link, ca.__version__, sys.platform)).encode())
    if _NATIVE_FLAGS[0] in flags:
        digest.update(_cpu_identity().encode())
    library = cache_directory() / f"{stem}_{digest.hexdigest()[:24]}.so"

    def build(path: Path) -> None:
        path.parent.mkdir(parents=True, exist_ok=True)
        with tempfile.TemporaryDirectory() as tmp:
            Path(tmp, f"{stem}.c").write_text(source)
            partial = Path(tmp, f"{stem}.so")
            command = [*compiler, *flags, "-shared", f"{stem}.c", "-o", str(partial)]
            _run([*command, *link, "-lm"], tmp)
            _install(path, partial.read_bytes())

    try:
        return _load_or_build(library, build, ctypes.CDLL, stacklevel=2)
    except (OSError, subprocess.CalledProcessError):
        return None
