"""The stepper's period as lanes: ``softcurve.compiled._lanes.LANE_WIDTH`` members
advanced at once in vector instructions, one C call per thread's share.

The members of a fixed-step method take the same steps, so they run the same
instructions in lock-step; ``softcurve.compiled._lanes`` generates the state
derivative, the observation and the Newton matrix's factorization over lanes of
members, and ``softcurve.simulation.stepper._lane_stages`` writes the method's steps
around them from its coefficients. A thread's whole share of the members is one call:
no Python per member.
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from functools import partial

import numpy as np

from softcurve.compiled import (
    LANE_WIDTH,
    c_template,
    compile_lanes,
    lanes_function,
    lanes_prelude,
    lanes_work,
)
from softcurve.simulation.stepper._lane_stages import explicit_step, rosenbrock_step
from softcurve.simulation.stepper._methods import METHODS, ExplicitTableau
from softcurve.simulation.stepper._observe import observer
from softcurve.simulation.stepper._scheme import jacobian_pattern, state_derivative, state_scale
from softcurve.simulation.stepper._threads import MemberShares

ENTRY = "softcurve_lanes_period"
"""The C entry point: ``(x, u, p, period, out, start, stop)`` on rows ``start:stop``."""


def period_source(model, inputs, substeps: int, method: str, vector_math: bool, every=None):
    """The C source of :data:`ENTRY`: ``substeps`` steps of ``method`` over the period,
    then the observation, for rows ``start:stop`` of ``x`` (N, n_x) and ``u`` (N, m)
    into ``out`` (N, n_x + 6), all row-major float64, with ``p`` and ``period`` shared;
    a last share shorter than a vector repeats its last member in the unused lanes. The
    entry is the template ``stepper_period.c`` (:func:`~softcurve.compiled.c_template`)
    filled in with the sizes, the lanes functions and the method's step.

    Parameters
    ----------
    model : Model
        The compiled model.
    inputs : ActuatorInput or None
        The actuator's inputs (None: generalized forces).
    substeps : int
        Steps per period.
    method : str
        A key of ``softcurve.simulation.stepper._methods.METHODS``.
    vector_math : bool
        Use glibc's vector math library where compiled for AVX2 (see
        :func:`~softcurve.compiled.lanes_prelude`).
    every : int, optional
        Steps between fresh Newton matrices of a Rosenbrock method (default
        ``substeps``).

    Returns
    -------
    str
        The C source.

    Raises
    ------
    NotImplementedError
        If the model's expressions have an operation without lanes code.
    """
    f = state_derivative(model, inputs, True).expand()
    observe = observer(model, True)
    n_x, n_u, n_obs = f.size1_in(0), f.size1_in(1), observe.size1_out(0)
    tableau = METHODS[method]
    if isinstance(tableau, ExplicitTableau):
        step = explicit_step(tableau, n_x)
    else:
        pattern, scale = jacobian_pattern(model, inputs), state_scale(model, inputs)
        step = rosenbrock_step(tableau, n_x, pattern, scale, every or substeps)
    functions = [
        (f, "sc_xdot", (False, False, True)),
        (observe, "sc_observe", (False, True)),
        *step.functions,
    ]
    work = max(lanes_work(function) for function, _, _ in functions)
    sizes = {"SC_NX": n_x, "SC_NU": n_u, "SC_NOBS": n_obs, "SC_SUBSTEPS": substeps}
    return "\n".join(
        [
            lanes_prelude(LANE_WIDTH, vector_math),
            *(lanes_function(*function) for function in functions),
            c_template(
                "stepper_period.c",
                {
                    "SC_ENTRY": ENTRY,
                    **sizes,
                    "SC_WORK": work,
                    "SC_SCRATCH": step.scratch,
                    "SC_STEP_DECLARATIONS": step.declarations,
                    "SC_STEP_LINES": step.lines,
                },
            ),  # fmt: skip
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
        Whether it was linked with glibc's vector math library (whose functions it uses
        where compiled for AVX2, not with ``SOFTCURVE_PORTABLE``).
    sizes : tuple of int
        Entries of a member's state, of its inputs, of the parameter vector and of a
        member's output row: ``(n_x, n_u, n_p, n_out)``.
    """

    entry: object
    library: str
    vector_math: bool
    sizes: tuple


def lanes_period(model, inputs, substeps: int, method: str, every: int | None = None):
    """The compiled :func:`period_source`, kept with the model: with glibc's vector math
    where it is available and links
    (``softcurve.compiled._lanes.vector_math_available``), else with the C
    library's scalar functions.

    Parameters
    ----------
    model : Model
        The compiled model.
    inputs : ActuatorInput or None
        The actuator's inputs.
    substeps : int
        Steps per period.
    method : str
        A key of ``softcurve.simulation.stepper._methods.METHODS``.
    every : int, optional
        Steps between fresh Newton matrices of a Rosenbrock method (default
        ``substeps``; ignored by explicit methods).

    Returns
    -------
    LanesPeriod or None
        None where no C compiler builds it, or the model has an operation without lanes
        code (the caller then calls the scalar period per member).
    """
    explicit = isinstance(METHODS[method], ExplicitTableau)
    every = None if explicit else min(every or substeps, substeps)

    def build():
        f = state_derivative(model, inputs, True)
        n_x = f.size1_in(0)
        sizes = (n_x, f.size1_in(1), f.size1_in(2), n_x + observer(model, True).size1_out(0))
        source = partial(period_source, model, inputs, substeps, method, every=every)
        argtypes = [ctypes.c_void_p] * 5 + [ctypes.c_long] * 2
        built = compile_lanes("stepper_lanes", source, ENTRY, argtypes)
        if built is None:
            return None
        return LanesPeriod(built.entry, str(built.library.path), built.vector_math, sizes)

    key = ("stepper-lanes", substeps, method, every, None if inputs is None else inputs.key)
    return model.cached(key, build)


class LanesMembers(MemberShares):
    """The compiled lanes period on every member, one C call per thread's share (shares
    of whole vectors of ``softcurve.compiled._lanes.LANE_WIDTH`` members).

    A lanes period cannot fail but for want of memory for its work array: a state that
    leaves the domain shows in ``out``, which the stepper checks.

    Parameters
    ----------
    period : LanesPeriod
        The compiled period.
    threads : int
        Threads over the members.
    """

    granularity = LANE_WIDTH

    def __init__(self, period: LanesPeriod, threads: int):
        super().__init__(threads)
        self._period = period

    def _arrays(self, x, u, p, period, out) -> list:
        """The arrays as C-contiguous float64, their shapes checked (the compiled code
        reads and writes them whole)."""
        n_x, n_u, n_p, n_out = self._period.sizes
        if np.ndim(x) != 2:
            raise ValueError(f"x must be 2-D (members, {n_x}), got shape {np.shape(x)}")
        count = np.shape(x)[0]
        arrays = super()._arrays(x, u, p, period, out)
        expected = [(count, n_x), (count, n_u), (n_p,), (1,)]
        for name, a, shape in zip(("x", "u", "p", "period"), arrays, expected, strict=True):
            if a.shape != shape:
                raise ValueError(f"{name} must have shape {shape}, got {a.shape}")
        if out.shape != (count, n_out) or out.dtype != np.float64:
            raise ValueError(f"out must be float64 of shape {(count, n_out)}, got {out.shape}")
        if not (out.flags.c_contiguous and out.flags.writeable):
            raise ValueError("out must be a writeable C-contiguous array")
        return arrays

    def _share(self, arrays, out, start: int, stop: int) -> list:
        pointers = [a.ctypes.data for a in (*arrays, out)]
        if self._period.entry(*pointers, start, stop):
            return [(i, "no memory for the period's work array") for i in range(start, stop)]
        return []
