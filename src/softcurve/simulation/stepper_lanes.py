"""The explicit stepper's period as lanes: :data:`~softcurve.compiled.lanes.LANE_WIDTH`
members advanced at once in vector instructions, one C call per thread's share.

The members of a fixed-step explicit method take the same steps, so they run the same
instructions in lock-step; :mod:`softcurve.compiled.lanes` generates the state
derivative and the observation over lanes of members, and this module writes the
method's stages around them from the tableau's coefficients. A thread's whole share of
the members is one call: no Python per member.
"""

from __future__ import annotations

import ctypes
import threading
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass

import numpy as np

from softcurve.compiled.lanes import (
    LANE_WIDTH,
    VECTOR_MATH_LIBRARY,
    lanes_function,
    lanes_prelude,
    vector_math_available,
)
from softcurve.compiled.source import compile_source
from softcurve.simulation.stepper_methods import ExplicitTableau
from softcurve.simulation.stepper_observe import observer
from softcurve.simulation.stepper_scheme import state_derivative

ENTRY = "softcurve_lanes_period"
"""The C entry point: ``(x, u, p, period, out, start, stop)`` on rows ``start:stop``."""


def _combination(terms) -> str:
    """``c0 * k0[j] + c1 * k1[j] + ...`` over the nonzero coefficients, in order."""
    return " + ".join(f"{c!r} * k{i}[j]" for i, c in terms)


def period_source(model, inputs, substeps: int, tableau: ExplicitTableau, vector_math: bool):
    """The C source of :data:`ENTRY`: ``substeps`` steps of ``tableau`` over the period,
    then the observation, for rows ``start:stop`` of ``x`` (N, n_x) and ``u`` (N, m)
    into ``out`` (N, n_x + 6), all row-major float64, with ``p`` and ``period`` shared;
    a last share shorter than a vector repeats its last member in the unused lanes.

    Parameters
    ----------
    model : Model
        The compiled model.
    inputs : ActuatorInput or None
        The actuator's inputs (None: generalized forces).
    substeps : int
        Steps per period.
    tableau : ExplicitTableau
        The method.
    vector_math : bool
        Use glibc's vector math library where compiled for AVX2 (see
        :func:`~softcurve.compiled.lanes.lanes_prelude`).
    """
    f = state_derivative(model, inputs, True).expand()
    observe = observer(model, True)
    n_x, n_u, n_obs = f.size1_in(0), f.size1_in(1), observe.size1_out(0)
    n_out = n_x + n_obs
    stages = []
    for i, row in enumerate(tableau.a):
        shift = [(j, a) for j, a in enumerate(row[:i]) if a]
        if shift:
            stages.append(
                f"for (int j = 0; j < {n_x}; j++) z[j] = y[j] + h * ({_combination(shift)});"
            )
        stages.append(f"sc_xdot({'z' if shift else 'y'}, U, p, k{i});")
    weights = [(i, b) for i, b in enumerate(tableau.b) if b]
    count = len(tableau.b)
    return "\n".join(
        [
            lanes_prelude(LANE_WIDTH, vector_math),
            lanes_function(f, "sc_xdot", (False, False, True)),
            lanes_function(observe, "sc_observe", (False, True)),
            f'__attribute__((visibility("default"))) int {ENTRY}(',
            "    const double* x, const double* u, const double* p,",
            "    const double* period, double* out, long start, long stop) {",
            f"  const sc_v h = sc_broadcast(period[0] / {substeps});",
            f"  sc_v y[{n_x}], U[{max(n_u, 1)}], z[{n_x}], o[{n_obs}];",
            *(f"  sc_v k{i}[{n_x}];" for i in range(count)),
            "  for (long i = start; i < stop; i += SC_W) {",
            "    for (int l = 0; l < SC_W; l++) {",
            "      long r = i + l < stop ? i + l : stop - 1;",
            f"      for (int j = 0; j < {n_x}; j++) y[j][l] = x[r * {n_x} + j];",
            f"      for (int j = 0; j < {n_u}; j++) U[j][l] = u[r * {n_u} + j];",
            "    }",
            f"    for (int s = 0; s < {substeps}; s++) {{",
            *(f"      {line}" for line in stages),
            f"      for (int j = 0; j < {n_x}; j++) y[j] = y[j] + h * ({_combination(weights)});",
            "    }",
            "    sc_observe(y, p, o); /* reads the model's states, the first of y */",
            "    for (int l = 0; l < SC_W && i + l < stop; l++) {",
            f"      for (int j = 0; j < {n_x}; j++) out[(i + l) * {n_out} + j] = y[j][l];",
            f"      for (int j = 0; j < {n_obs}; j++)",
            f"        out[(i + l) * {n_out} + {n_x} + j] = o[j][l];",
            "    }",
            "  }",
            "  return 0;",
            "}",
        ]
    )


@dataclass(frozen=True)
class LanesPeriod:
    """A compiled lanes period.

    Parameters
    ----------
    entry : ctypes function
        :data:`ENTRY`.
    library : str
        The shared library's path.
    vector_math : bool
        Whether it was built with glibc's vector math (used where compiled for AVX2).
    """

    entry: object
    library: str
    vector_math: bool


def lanes_period(model, inputs, substeps: int, tableau: ExplicitTableau):
    """The compiled :func:`period_source` as a :class:`LanesPeriod`, kept with the model: with
    glibc's vector math where it is available and links
    (:func:`~softcurve.compiled.lanes.vector_math_available`), else with the C
    library's scalar functions;
    None where no C compiler builds it (the caller then calls the scalar period per
    member).

    Parameters
    ----------
    model : Model
        The compiled model.
    inputs : ActuatorInput or None
        The actuator's inputs.
    substeps : int
        Steps per period.
    tableau : ExplicitTableau
        The method.
    """

    def build():
        attempts = [(True, VECTOR_MATH_LIBRARY)] if vector_math_available() else []
        for vector_math, link in [*attempts, (False, ())]:
            source = period_source(model, inputs, substeps, tableau, vector_math)
            library = compile_source("stepper_lanes", source, link)
            if library is not None:
                entry = getattr(library, ENTRY)
                entry.restype = ctypes.c_int
                entry.argtypes = [ctypes.c_void_p] * 5 + [ctypes.c_long] * 2
                return LanesPeriod(entry, library._name, vector_math)
        return None

    key = ("stepper-lanes", substeps, tableau.name, None if inputs is None else inputs.key)
    return model.cached(key, build)


class LanesMembers:
    """The compiled lanes period on every member, one C call per thread's share
    (ctypes releases the GIL during the call).

    Parameters
    ----------
    period : LanesPeriod
        The compiled period.
    threads : int
        Threads over the members.
    """

    def __init__(self, period: LanesPeriod, threads: int):
        self._entry = period.entry
        self._threads = threads
        self._pool: ThreadPoolExecutor | None = None
        self._lock = threading.Lock()

    def __call__(self, x, u, p, period, out) -> list:
        """Fill ``out`` (N, n_x + 6); return ``[]`` (a lanes period cannot fail: a state
        that leaves the domain shows in ``out``, which the stepper checks).

        Parameters
        ----------
        x : ndarray, shape (N, n_x)
            States.
        u : ndarray, shape (N, m)
            Inputs.
        p : ndarray, shape (n_p,)
            The robot's parameter vector.
        period : ndarray, shape (1,)
            The control period [s].
        out : ndarray, shape (N, n_x + 6)
            Where the outputs go.
        """
        arrays = [np.ascontiguousarray(a, dtype=np.float64) for a in (x, u, p, period)]
        if not (out.flags.c_contiguous and out.flags.writeable and out.dtype == np.float64):
            raise ValueError("out must be a writeable C-contiguous float64 array")
        pointers = [a.ctypes.data for a in (*arrays, out)]
        count = x.shape[0]

        def run(a: int, b: int) -> None:
            self._entry(*pointers, a, b)

        vectors = -(-count // LANE_WIDTH)
        chunks = min(self._threads, vectors)
        if chunks <= 1:
            run(0, count)
            return []
        bounds = np.minimum(np.linspace(0, vectors, chunks + 1).astype(int) * LANE_WIDTH, count)
        with self._lock:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(self._threads, "softcurve-lanes")
        list(self._pool.map(run, bounds[:-1], bounds[1:]))
        return []
