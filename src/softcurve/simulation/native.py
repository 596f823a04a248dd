"""CVODES driven from C: softcurve's own driver (:mod:`softcurve.simulation.cvodes_driver`)
of the SUNDIALS CVODES that ships inside CasADi, on the model's compiled right-hand side.

Why not CasADi's ``integrator``: on the paper's 10 s case it spends more time around the
right-hand side than in it (``docs/performance.md``): every evaluation goes through
CasADi's virtual machine (the scaled DAE is an MX graph around the compiled ``rhs``) and
reads the process CPU clock (a system call; threads of one process contend for it), and
the Newton matrix's Jacobian is recomputed by finite differences at every linear-solver
setup. The driver calls the compiled function directly, keeps the Jacobian while CVODES
allows (``jok``), factors the Newton matrix itself and integrates every member of a batch
in one call, on threads that do not contend.

:func:`problem` describes a model (and optionally an actuator's force) to the driver;
:func:`integrate` runs it. Both return None / are unused where the driver cannot be built
(no C compiler, an uncompiled model, a CasADi whose SUNDIALS has another interface) or
``SOFTCURVE_NATIVE_CVODES=0`` is set: the engines then use CasADi's integrator.
"""

from __future__ import annotations

import ctypes
import os
import threading
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import casadi as ca
import numpy as np

from softcurve.compiled.native import NativeFunction
from softcurve.compiled.source import compile_source
from softcurve.simulation.cvodes_driver import DRIVER_SOURCE

PLUGIN = "libcasadi_integrator_cvodes.so"
"""CasADi's CVODES plugin, which holds SUNDIALS CVODES (the 2.x interface: ``CVSpgmr``)."""

STATISTICS = ("steps", "rhs_evaluations", "jacobian_evaluations", "linear_solver_setups",
              "error_test_failures", "newton_failures")  # fmt: skip
"""The counters the driver returns per member, in its order."""

FLAGS = {
    -1: "CV_TOO_MUCH_WORK", -2: "CV_TOO_MUCH_ACC", -3: "CV_ERR_FAILURE",
    -4: "CV_CONV_FAILURE", -5: "CV_LINIT_FAIL", -6: "CV_LSETUP_FAIL", -7: "CV_LSOLVE_FAIL",
    -8: "CV_RHSFUNC_FAIL", -9: "CV_FIRST_RHSFUNC_ERR", -10: "CV_REPTD_RHSFUNC_ERR",
    -11: "CV_UNREC_RHSFUNC_ERR", -20: "CV_MEM_FAIL", -22: "CV_ILL_INPUT",
    -27: "CV_TOO_CLOSE", -100: "the solver could not be set up",
}  # fmt: skip
"""CVODES's return flags (SUNDIALS 2.x ``cvodes.h``) by value."""

CHUNKS_PER_THREAD = 4
"""Members of a batch are handed to the threads in this many chunks per thread, taken as
threads finish: members differ in cost (a violent transient takes more steps)."""


class _Function(ctypes.Structure):
    _fields_ = [
        ("f", ctypes.c_void_p),
        ("force", ctypes.c_void_p),
        ("nx", ctypes.c_int),
        ("nu", ctypes.c_int),
        ("np", ctypes.c_int),
        ("m", ctypes.c_int),
        ("lag", ctypes.c_int),
        ("sz_arg", ctypes.c_longlong),
        ("sz_res", ctypes.c_longlong),
        ("sz_iw", ctypes.c_longlong),
        ("sz_w", ctypes.c_longlong),
        ("lower", ctypes.c_void_p),
        ("upper", ctypes.c_void_p),
        ("time_constant", ctypes.c_double),
    ]


_DRIVER: list = []  # [the loaded driver or None], once per process
_LOCK = threading.Lock()


def driver():
    """The driver's entry point ``softcurve_cvodes`` (ctypes), built and loaded once per
    process; None where it cannot be (see the module notes)."""
    with _LOCK:
        if not _DRIVER:
            _DRIVER.append(_load())
        return _DRIVER[0]


def _load():
    if os.environ.get("SOFTCURVE_NATIVE_CVODES", "1") in ("0", ""):
        return None
    directory = Path(ca.__file__).parent
    plugin = directory / PLUGIN
    try:
        if not hasattr(ctypes.CDLL(str(plugin)), "CVSpgmr"):  # SUNDIALS >= 3: other API
            return None
    except OSError:
        return None
    link = (f"-L{directory}", f"-l:{PLUGIN}", f"-Wl,-rpath,{directory}")
    library = compile_source("cvodes_driver", DRIVER_SOURCE, link)
    if library is None:
        return None
    function = library.softcurve_cvodes
    pointer = ctypes.c_void_p
    function.argtypes = [ctypes.POINTER(_Function), ctypes.c_int] + [pointer] * 6 + [
        ctypes.c_int, ctypes.c_double, ctypes.c_double, ctypes.c_long, ctypes.c_int,
    ] + [pointer] * 4  # fmt: skip
    function.restype = ctypes.c_int
    return function


class Problem:
    """A model's right-hand side (and an actuator's force) described to the driver.

    Parameters
    ----------
    rhs : NativeFunction
        The model's compiled ``rhs(x, tau, p)``.
    n_state, n, n_parameters : int
        Sizes of ``x``, ``tau`` and ``p``.
    force : NativeFunction, optional
        ``H(q) v`` of an actuator, compiled.
    inputs : ActuatorInput, optional
        The actuator's input (bounds, lag), with ``force``.
    """

    def __init__(self, rhs, n_state, n, n_parameters, force=None, inputs=None):
        functions = [rhs] if force is None else [rhs, force]
        self._keep = functions  # the ctypes functions and the bounds must outlive the struct
        lag = inputs is not None and inputs.time_constant is not None
        self.bounds = (
            (np.array(inputs.lower, dtype=np.float64), np.array(inputs.upper, dtype=np.float64))
            if inputs is not None
            else (np.zeros(1), np.zeros(1))
        )
        self.struct = _Function(
            ctypes.cast(rhs._function, ctypes.c_void_p).value,
            None if force is None else ctypes.cast(force._function, ctypes.c_void_p).value,
            n_state,
            n,
            n_parameters,
            0 if inputs is None else inputs.n_inputs,
            int(lag),
            max(f._sz_arg for f in functions),
            max(f._sz_res for f in functions),
            max(f._sz_iw for f in functions),
            max(f._sz_w for f in functions),
            self.bounds[0].ctypes.data,
            self.bounds[1].ctypes.data,
            inputs.time_constant if lag else 1.0,
        )


def problem(model, inputs=None) -> Problem | None:
    """The :class:`Problem` of ``model`` driven by forces or by ``inputs`` (an
    :class:`~softcurve.simulation.integrators.ActuatorInput`, whose force ``H(q) u`` is
    compiled once per actuator and cached on disk), cached with the model; None where the
    driver is not available.

    Parameters
    ----------
    model : Model
        The model.
    inputs : ActuatorInput, optional
        The actuator's input, or None for forces.
    """
    if driver() is None or model._native is None or "rhs" not in model._native:
        return None

    def build():
        force = None
        if inputs is not None:
            force = _compiled_force(inputs.force)
            if force is None:
                return None
        rhs = model._native["rhs"]
        return Problem(rhs, model.n_state, model.n, model.parameters.size, force, inputs)

    return model.cached(("native problem", None if inputs is None else inputs.key), build)


def _compiled_force(force: ca.Function) -> NativeFunction | None:
    """``force`` generated as C, compiled (cached on disk by its code) and loaded, or None."""
    generator = ca.CodeGenerator("force.c", {"with_header": False})
    generator.add(force)
    library = compile_source("actuator_force", generator.dump())
    return None if library is None else NativeFunction(library, force.name())


def integrate(problem, lmm, x0, u, p, nominal, times, tolerances, threads=1) -> tuple:
    """Integrate members from ``x0`` at time 0 to ``times``, each with a constant input.

    Parameters
    ----------
    problem : Problem
        What to integrate.
    lmm : ndarray of int, shape (B,)
        Family per member: 1 Adams, 2 BDF.
    x0 : ndarray, shape (B, N)
        Initial states (``N`` = n_state, plus the lagging inputs).
    u : ndarray, shape (B, k)
        Input per member: forces [N, N m^2, N m^2] or the actuator's inputs (commands).
    p : ndarray, shape (B, n_p)
        Parameter vector per member.
    nominal : ndarray, shape (B, N)
        State scales (> 0).
    times : ndarray, shape (T,)
        Output times [s] after time 0, increasing.
    tolerances : tuple
        ``(rtol, abstol of the scaled state, max_steps per output, max_order)``.
    threads : int
        Threads over the members.

    Returns
    -------
    tuple
        ``(states (B, T, N), reached (B,), flags (B,), counts (B, 6))``: outputs, how
        many were computed, CVODES's flag (0: success; :data:`FLAGS`), and the counters
        of :data:`STATISTICS`.
    """
    count, width = x0.shape
    arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (x0, u, p, nominal, times)]
    lmm = np.ascontiguousarray(lmm, dtype=np.int32)
    out = np.zeros((count, times.size, width))
    reached = np.zeros(count, dtype=np.int32)
    flags = np.zeros(count, dtype=np.int32)
    counts = np.zeros((count, len(STATISTICS)), dtype=np.int64)
    call = driver()
    rtol, abstol, max_steps, max_order = tolerances

    def run(a: int, b: int) -> None:
        pointers = [arr[a:b].ctypes.data for arr in (lmm, *arrays[:4])]
        call(ctypes.byref(problem.struct), b - a, *pointers, arrays[4].ctypes.data,
             times.size, rtol, abstol, max_steps, max_order or 0, out[a:b].ctypes.data,
             reached[a:b].ctypes.data, flags[a:b].ctypes.data, counts[a:b].ctypes.data)  # fmt: skip

    threads = max(1, min(threads, count))
    if threads == 1:
        run(0, count)
    else:
        bounds = np.linspace(0, count, min(count, CHUNKS_PER_THREAD * threads) + 1).astype(int)
        with ThreadPoolExecutor(threads) as pool:
            list(pool.map(run, bounds[:-1], bounds[1:]))
    return out, reached, flags, counts


def reason(flag: int) -> str:
    """CVODES's ``flag`` as the name :func:`~softcurve.simulation.engine.cvodes_reason`
    explains.

    Parameters
    ----------
    flag : int
        A negative return flag of CVODES.
    """
    return FLAGS.get(int(flag), f"CVODES flag {int(flag)}")
