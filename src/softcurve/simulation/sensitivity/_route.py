"""The driver's route of the identification's forward sensitivities: what an evaluator
carries into worker processes, and the one call into softcurve's CVODES driver
(``softcurve_sensitivities``, ``sensitivity.c`` of
``softcurve.simulation.solvers._library.C_FOLDER``).

The driver integrates the state by Adams-Newton (or BDF, :attr:`DriverSettings.family`)
on its own Newton matrix and the sensitivity columns ``S' = f_x S + f_d`` by CVODES's
staggered corrector, evaluating the identification's compiled
``fs(x;vec(S), u, d;scale) -> f;vec(S')``, or two compiled parts that sum to ``vec(S')``
(``softcurve.simulation.sensitivity._split``), the second on a helper thread.
"""

from __future__ import annotations

import ctypes
from typing import NamedTuple

import numpy as np

from softcurve.simulation.solvers import (
    driver_library,
    driver_options,
)


class DriverSettings(NamedTuple):
    """How the driver integrates (CVODES's settings of :func:`integrate_sensitivities`)."""

    rtol: float
    """Relative tolerance."""
    atol: float
    """Absolute tolerance, in the state's units."""
    max_steps: int
    """Steps allowed per output interval."""
    family: int
    """1 Adams, 2 BDF."""
    columns_tested: bool
    """The sensitivity columns in the error test too (``fsens_err_con``)."""


HELPER_MODES = ("none", "shared")
"""Who evaluates the second of two parts (:func:`integrate_sensitivities`): ``"none"``
the driver's own thread; ``"shared"`` whichever of the driver and a helper thread claims
it first (the driver never waits for a helper that has not started). Which thread wins
is the scheduler's choice."""


class DriverRoute(NamedTuple):
    """What a sensitivity evaluator needs for the driver's route, and carries into worker
    processes: the compiled libraries by ``(path, name)``, not their functions."""

    state: tuple[str, str]
    """``f(x, u, d)``: its library's absolute path and the function's name."""
    columns: tuple[tuple[str, str], ...]
    """The columns' right-hand side by path and name: ``fs(x;vec(S), u, d;scale) ->
    f;vec(S')``, or its two parts (:func:`integrate_sensitivities`)."""
    sizes: tuple[int, int, int]
    """``(nx, nu, n_d)`` of ``f``."""
    times: np.ndarray
    """Output times [s], shape (T,)."""
    table: np.ndarray
    """The inputs per interval, shape (T, k) or (T, 2 k) (:func:`integrate_sensitivities`)."""
    linear: bool
    """The inputs are linear between samples (else held)."""
    settings: DriverSettings
    """CVODES's settings."""
    helper: str
    """Who evaluates the second of two parts, one of :data:`HELPER_MODES`."""


SENSITIVITY_STATISTICS = ("steps", "rhs_evaluations", "jacobian_evaluations",
                          "linear_solver_setups", "error_test_failures",
                          "sensitivity_evaluations", "helper_evaluations")  # fmt: skip
"""The counters :func:`integrate_sensitivities` returns, in the driver's order: CVODES's
steps, right-hand sides (not those of the finite-difference Newton matrices), Newton
matrices, linear-solver setups and error-test failures, the evaluations of the columns'
right-hand side, and of those the second parts the helper thread evaluated (the driver
evaluates the others itself)."""


def integrate_sensitivities(
    problem,
    columns,
    start,
    d,
    d_scaled,
    times,
    table,
    linear,
    settings,
    helper="none",
    library=None,
):
    """States and forward sensitivities over ``times`` in one call into the driver.

    Parameters
    ----------
    problem : softcurve.simulation.DriverProblem
        ``f(x, u, d)`` of the state (no actuator).
    columns : sequence of NativeFunction
        ``[fs]``, ``fs(x;vec(S), u, d;scale) -> f;vec(S')`` for ``m`` columns, or two
        parts of the same arguments whose outputs sum to ``vec(S')``
        (``softcurve.simulation.sensitivity._split.column_parts``).
    start : ndarray, shape (W,)
        ``(x0, vec(S0))`` with ``W = nx (1 + m)``, at ``times[0]``.
    d : ndarray, shape (n_d,)
        The parameters of ``f``.
    d_scaled : ndarray, shape (n_d + m,)
        ``(d, scale)``: the parameters of ``fs`` with its column scales.
    times : ndarray, shape (T,)
        Output times [s], increasing.
    table : ndarray, shape (T, k) or (T, 2 k)
        Row ``i``: the inputs on ``(times[i-1], times[i]]``, or the line ``(a, b)`` of
        ``u = a + b t`` there with ``linear``.
    linear : bool
        Inputs continuous (integrated through) or held (a restart at every sample).
    settings : DriverSettings
        CVODES's settings.
    helper : {"none", "shared"}
        With two parts, who evaluates the second (:data:`HELPER_MODES`).
    library : ctypes.CDLL, optional
        A build of the driver (:func:`softcurve.simulation.solvers.driver_library`; default the
        product's, without defines).

    Returns
    -------
    tuple
        ``(out (T, W), reached, flag, counts)``: the outputs (rows after ``reached`` are
        zero), how many were computed (``start`` included), 0 or CVODES's negative flag
        (``softcurve.simulation.solvers._driver.FLAGS``) and the counters of
        :data:`SENSITIVITY_STATISTICS`.
    """
    if helper not in HELPER_MODES:
        raise ValueError(f"helper must be one of {HELPER_MODES}, got {helper!r}")
    out = np.zeros((times.size, start.size))
    out[0] = start
    arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (d, d_scaled, times, table)]
    sizes = np.array([c.work_sizes for c in columns], np.int64)
    pointers = (ctypes.c_void_p * len(columns))(*(c.address for c in columns))
    counts = np.zeros(len(SENSITIVITY_STATISTICS), dtype=np.int64)
    reached = ctypes.c_int(0)
    n_x = problem.struct.nx
    m = start.size // n_x - 1
    leading = n_x if len(columns) == 1 else 0  # fs's f before vec(S'); the parts have none
    call = (library or driver_library()).softcurve_sensitivities
    chosen = driver_options(
        settings.rtol, settings.atol, settings.max_steps, family=settings.family,
        columns_tested=settings.columns_tested, helper=helper == "shared",
    )  # fmt: skip
    flag = call(
        ctypes.byref(problem.struct), ctypes.byref(chosen), pointers, sizes.ctypes.data,
        len(columns), leading, m, arrays[0].ctypes.data, arrays[1].ctypes.data,
        arrays[2].ctypes.data, times.size, arrays[3].ctypes.data, int(linear), out.ctypes.data,
        counts.ctypes.data, ctypes.byref(reached),
    )  # fmt: skip
    return out, reached.value, flag, dict(zip(SENSITIVITY_STATISTICS, counts.tolist(), strict=True))
