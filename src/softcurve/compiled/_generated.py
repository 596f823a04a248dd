"""CasADi functions other than the model's, generated as C, compiled and cached on disk
with the model's compiler and cache (``softcurve.compiled._build``): the
identification's sensitivity equations, the stepper's period, an actuator's force.
"""

from __future__ import annotations

import functools
import os
import subprocess
import warnings
from concurrent.futures import ThreadPoolExecutor

import casadi as ca

from softcurve.base.validation import ParameterError
from softcurve.compiled import _build as build
from softcurve.compiled import _cache as cache
from softcurve.compiled._source import exact_external, load_external


def compile_function(
    function: ca.Function,
    flags: tuple[str, ...] | None = None,
    load=None,
    build_new=True,
    derivatives: int = 0,
):
    """``function`` generated as C, compiled, cached on disk by its content and loaded.

    For CasADi functions built on a model's expressions (the identification's
    sensitivity equations, say) that are evaluated often: the same compiler and cache as
    :class:`~softcurve.compiled.Model`, keyed by the serialized function and the
    flags asked for, so a second process loads it, with or without a compiler. A cached
    library is checked and, if damaged or another's, rebuilt once as the model's (with
    a :class:`~softcurve.compiled.CacheWarning`).

    Parameters
    ----------
    function : casadi.Function
        An SX or MX function without Python callbacks.
    flags : tuple of str, optional
        The compiler's optimization flags (default: those of the model library,
        ``FUNCTION_FLAGS``, or ``PORTABLE_FUNCTION_FLAGS`` where the compiler refuses
        them);
        ``-march=native`` is added unless ``SOFTCURVE_PORTABLE`` is set, and dropped again
        if the compiler refuses it.

    load : callable, optional
        ``load(path, name)`` opens the compiled library (e.g. as a
        :class:`~softcurve.compiled.NativeFunction`, called without CasADi and
        without the GIL); default: :func:`load_external`, CasADi's ``external``.
    build_new : bool
        Compile it when the cache does not hold it (default); with False, return None
        instead (nothing is built).
    derivatives : {0, 1, 2, 3}
        Derivatives compiled with it, which an ``external`` of the library calls instead
        of finite differences: 1 its first, forward and reverse (CasADi's
        ``fwd1_<name>`` and ``adj1_<name>``, what an integrator's adjoint sensitivities
        and a constraint Jacobian need); 2 also the forward derivative of the reverse one
        (``fwd1_adj1_<name>``, what an exact Hessian needs); 3 also that of the forward
        one (``fwd1_fwd1_<name>``, what an integrator's forward sensitivities need); each
        level compiles longer. With 1 or more the default loader loads it without finite
        differences.

    Returns
    -------
    casadi.Function or object
        The compiled function as a CasADi ``external`` (derivatives by finite
        differences, or the compiled ones with ``derivatives``) or what ``load``
        returned, or ``function`` itself when it is not cached and there is no C
        compiler, or None when it is not cached and ``build_new`` is False, or (with a
        :class:`~softcurve.compiled.CompilerWarning`) when the build fails: then it
        runs in CasADi's virtual machine.
    """
    compiler = build.find_compiler()
    name = function.name()
    asked = None if flags is None else tuple(flags)

    if derivatives not in (0, 1, 2, 3):
        raise ParameterError(f"derivatives must be 0, 1, 2 or 3, got {derivatives!r}")
    functions = {name: function}
    if derivatives:
        forward = function.forward(1)
        reverse = function.reverse(1)
        second = (reverse.forward(1), forward.forward(1))[: derivatives - 1]
        extra = (forward, reverse, *second)
        functions.update((f.name(), f) for f in extra)
    loader = load or (exact_external if derivatives else load_external)

    def make() -> bytes:
        build.require_compiler(compiler)
        return build.compile_generated(functions, compiler, asked, ("-fPIC",))

    key = _function_key(function, asked, tuple(functions)[1:])
    if not build_new and cache.cached_library("function", key, tuple(functions)) is None:
        return None
    try:
        _, loaded = cache.load_or_build(
            "function",
            key,
            make,
            lambda path: loader(path, name),
            stacklevel=2,
            symbols=tuple(functions),
            what=f"the function {name}",
        )
    except build.NoCompiler:
        return function
    except (OSError, subprocess.CalledProcessError) as exc:
        detail = str(getattr(exc, "stderr", None) or exc).strip()[:400]
        warnings.warn(
            f"compiling {name} with {compiler[0]} failed ({detail}): it runs in CasADi's "
            "virtual machine",
            build.CompilerWarning,
            stacklevel=2,
        )
        return function
    return loaded


def _function_key(
    function: ca.Function, asked: tuple[str, ...] | None, derivatives: tuple[str, ...] = ()
) -> str:
    """The cache key of ``function`` compiled with the flags ``asked`` (None: the
    default) and the derivatives named ``derivatives`` beside it: the flags asked for,
    not those a compiler accepted, so the key holds no compiler."""
    flags_key = asked if asked is not None else ("default", build.FUNCTION_FLAGS)
    return build.cache_key("function", function.serialize(), flags_key, *derivatives)


def compile_functions(functions, flags: tuple[str, ...] | None = None, load=None) -> list:
    """:func:`compile_function` of each function, the builds in parallel (one compiler
    process per function, at most one per core) where CasADi's symbolic objects are
    thread-safe (built with ``CASADI_WITH_THREADSAFE_SYMBOLICS``, as the 3.8.2 wheel
    is), else one after another.

    Parameters
    ----------
    functions : sequence of casadi.Function
        As :func:`compile_function`'s ``function``.
    flags : tuple of str, optional
        As :func:`compile_function`'s.
    load : callable, optional
        As :func:`compile_function`'s.

    Returns
    -------
    list
        What :func:`compile_function` returns for each, in order.
    """
    functions = list(functions)
    workers = min(len(functions), os.cpu_count() or 1)
    if "CASADI_WITH_THREADSAFE_SYMBOLICS" not in ca.CasadiMeta.compiler_flags():
        workers = 1  # serializing and generating shares CasADi's symbolic objects
    build_one = functools.partial(compile_function, flags=flags, load=load)
    if workers <= 1:
        return [build_one(f) for f in functions]
    with ThreadPoolExecutor(max_workers=workers) as pool:
        return list(pool.map(build_one, functions))
