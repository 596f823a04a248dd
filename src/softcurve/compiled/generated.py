"""CasADi functions other than the model's, generated as C, compiled and cached on disk
with the model's compiler and cache (:mod:`softcurve.compiled.build`): the
identification's sensitivity equations, the stepper's period, an actuator's force.
"""

from __future__ import annotations

import hashlib
import subprocess
import sys

import casadi as ca

from softcurve.compiled import build

FUNCTION_FLAGS = ("-O1",)
"""Optimization flags of :func:`compile_function` (``-march=native`` is added unless
``SOFTCURVE_PORTABLE`` is set). Its functions are large (the identification's
sensitivity equations of the paper robot are 75,000 operations), and GCC 12 compiles
them at ``-O1`` in seconds where ``-O2`` and ``-O3`` take minutes for little more speed.
``-march=native`` is the flag that pays: ``benchmarks/bench_compile_flags.py`` prints,
per function, every flag set's compile time and speed (2026-11-30, best of 3 alternating
runs on a noisy 2-core machine): ``-march=native`` made the sensitivity function 1.29x,
the stepper's period 1.10-1.56x and the model's right-hand side 1.18-1.20x faster than
plain ``-O1``; GCC's straight-line vectorizer and second scheduling pass added nothing
measurable."""


def compile_function(function: ca.Function, flags: tuple[str, ...] | None = None, load=None):
    """``function`` generated as C, compiled, cached on disk by its content and loaded.

    For CasADi functions built on a model's expressions (the identification's
    sensitivity equations, say) that are evaluated often: the same compiler and cache as
    :class:`~softcurve.compiled.model.Model`, keyed by the serialized function, so a
    second process loads it. A cached library is verified and, if damaged, rebuilt once
    as the model's (with a :class:`~softcurve.compiled.build.CacheWarning`).

    Parameters
    ----------
    function : casadi.Function
        An SX or MX function without Python callbacks.
    flags : tuple of str, optional
        The compiler's optimization flags (default :data:`FUNCTION_FLAGS`);
        ``-march=native`` is added unless ``SOFTCURVE_PORTABLE`` is set, and dropped again
        if the compiler refuses it.

    load : callable, optional
        ``load(path, name)`` opens the compiled library (e.g. as a
        :class:`~softcurve.compiled.native.NativeFunction`, called without CasADi and
        without the GIL); default: CasADi's ``external``.

    Returns
    -------
    casadi.Function or object
        The compiled function as a CasADi ``external`` (derivatives by finite
        differences) or what ``load`` returned, or ``function`` itself when no C compiler
        works (then it runs in CasADi's virtual machine).
    """
    compiler = build._compiler()
    if compiler is None:
        return function
    flags = FUNCTION_FLAGS if flags is None else tuple(flags)
    digest = hashlib.sha256(function.serialize().encode())
    digest.update(f"{ca.__version__} {sys.platform} {compiler} {flags}".encode())
    if build._native_flags():
        digest.update(build._cpu_identity().encode())
    digest.update(build._FUNCTION_CACHE_FORMAT.encode())
    library = build.cache_directory() / f"function_{digest.hexdigest()[:24]}.so"
    name = function.name()

    try:
        return build._load_or_build(
            library,
            lambda path: build._compile_for_this_cpu(
                {name: function}, compiler, path, flags, ("-fPIC",)
            ),
            (lambda path: ca.external(name, str(path), {"enable_fd": True}))
            if load is None
            else (lambda path: load(path, name)),
            stacklevel=2,
        )
    except (OSError, subprocess.CalledProcessError):
        return function
