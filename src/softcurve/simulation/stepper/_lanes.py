"""The stepper's period as lanes: ``softcurve.compiled._lanes.LANE_WIDTH`` members
advanced at once in vector instructions, one C call per thread's share.

The members of a fixed-step method take the same steps, so they run the same
instructions in lock-step; ``softcurve.compiled._lanes`` generates the state
derivative and the observation over lanes of members, the period template
(``stepper_period.c``) factors the Newton matrix, and this module writes the method's
steps around them from its coefficients: the operations of the scalar scheme of
``softcurve.simulation.stepper._scheme``, in its order, but for the Newton matrix's QR
(the same solves up to round-off, in loops). A thread's whole share of the members is
one call: no Python per member.

The step writers (:func:`explicit_step`, :func:`rosenbrock_step`) return
:class:`StepSource`: declarations, the lines of one step (inside the loop over the steps
``s``, on the state ``y``, inputs ``U``, parameters ``p`` and step ``h``, with the
functions' work array ``w``), and the heap it needs (``scratch``)."""

from __future__ import annotations

import ctypes
from dataclasses import dataclass
from functools import partial

import casadi as ca
import numpy as np

from softcurve.compiled import (
    LANE_WIDTH,
    c_template,
    compile_lanes,
    lanes_function,
    lanes_prelude,
    lanes_work,
)
from softcurve.simulation.solvers import actuated_passes
from softcurve.simulation.stepper._methods import METHODS, ExplicitTableau, Tableau
from softcurve.simulation.stepper._scheme import (
    DIFFERENCE_STEP,
    MemberShares,
    checked_jacobian,
    observer,
    rest_scale,
    state_derivative,
)
from softcurve.symbolic.derivatives import DIRECTIONS

ENTRY = "softcurve_lanes_period"
"""The C entry point: ``(x, u, p, period, out, start, stop)`` on rows ``start:stop``."""


@dataclass(frozen=True)
class ExactJacobian:
    """The lanes functions of the exact Jacobian.

    Parameters
    ----------
    functions : tuple
        ``(function, name, shared)`` for :func:`~softcurve.compiled.lanes_function`:
        ``sc_passes`` (:func:`~softcurve.simulation.solvers.actuated_passes`, SX with the
        chain's calls), then one ``sc_tangent_<kind>`` per kind of direction
        (``softcurve.symbolic.derivatives.JacobianPasses``).
    shared : tuple of int
        The sizes of the passes' values, which the tangents take.
    """

    functions: tuple
    shared: tuple


def lanes_jacobian(model, inputs) -> ExactJacobian:
    """The exact Jacobian's lanes functions, kept with the model. The step calls the
    tangents once per coordinate in a loop: code of ``O(N)``, where one function of
    every direction's call was one GCC took minutes over at four segments (alias walking
    over the calls' arguments)."""

    def build():
        passes = model.jacobian_passes()
        at_state = actuated_passes(model, inputs, passes.at_state).expand()
        functions = [(at_state, "sc_passes", (False, False, True))]
        for kind in DIRECTIONS:
            tangent = passes.tangents[kind]
            functions.append((tangent, f"sc_tangent_{kind}", (False,) * tangent.n_in()))
        shared = tuple(at_state.nnz_out(k) for k in range(passes.n_shared))
        return ExactJacobian(tuple(functions), shared)

    return model.cached(("stepper-lanes-jacobian", None if inputs is None else inputs.key), build)


def period_source(
    model, inputs, substeps: int, method: str, vector_math: bool, every=None,
    jacobian: str = "differences",
):  # fmt: skip
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
    jacobian : {"differences", "exact"}
        The Newton matrix's Jacobian: forward differences of the state derivative, or the
        exact one (:func:`lanes_jacobian`, solved by the template's Cholesky loops).

    Returns
    -------
    str
        The C source.

    Raises
    ------
    NotImplementedError
        If the model's expressions have an operation without lanes code, or a Rosenbrock
        method's state derivative does not begin with ``q' = qd``.
    """
    f = state_derivative(model, inputs, True).expand()
    observe = observer(model, True)
    n_x, n_u, n_obs = f.size1_in(0), f.size1_in(1), observe.size1_out(0)
    tableau, exact = METHODS[method], None
    if isinstance(tableau, ExplicitTableau):
        step = explicit_step(tableau, n_x)
    else:
        if not rates_follow_coordinates(f, model.n):
            raise NotImplementedError("the Newton solve eliminates q' = qd")
        scale = rest_scale(model, inputs)
        exact = lanes_jacobian(model, inputs) if jacobian == "exact" else None
        shared = None if exact is None else exact.shared
        step = rosenbrock_step(tableau, n_x, model.n, scale, every or substeps, shared)
    functions = [
        (f, "sc_xdot", (False, False, True)),
        (observe, "sc_observe", (False, True)),
        *(() if exact is None else exact.functions),
    ]
    work = max(lanes_work(function) for function, _, _ in functions)
    sizes = {
        "SC_NX": n_x,
        "SC_NQ": model.n,
        "SC_NU": n_u,
        "SC_NOBS": n_obs,
        "SC_SUBSTEPS": substeps,
    }
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


def lanes_period(
    model, inputs, substeps: int, method: str, every: int | None = None,
    jacobian: str = "differences",
):  # fmt: skip
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
    jacobian : {"differences", "exact"}
        A Rosenbrock method's Jacobian (:func:`period_source`).

    Returns
    -------
    LanesPeriod or None
        None where no C compiler builds it, the model has an operation without lanes
        code, or a Rosenbrock method's state derivative does not begin with ``q' = qd``
        (the caller then calls the scalar period per member).
    """
    checked_jacobian(jacobian)
    explicit = isinstance(METHODS[method], ExplicitTableau)
    every = None if explicit else min(every or substeps, substeps)

    def build():
        f = state_derivative(model, inputs, True)
        n_x = f.size1_in(0)
        sizes = (n_x, f.size1_in(1), f.size1_in(2), n_x + observer(model, True).size1_out(0))
        source = partial(
            period_source, model, inputs, substeps, method, every=every, jacobian=jacobian
        )
        argtypes = [ctypes.c_void_p] * 5 + [ctypes.c_long] * 2
        built = compile_lanes("stepper_lanes", source, ENTRY, argtypes)
        if built is None:
            return None
        return LanesPeriod(built.entry, str(built.library.path), built.vector_math, sizes)

    inputs_key = None if inputs is None else inputs.key
    key = ("stepper-lanes", substeps, method, every, inputs_key, None if explicit else jacobian)
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


@dataclass(frozen=True)
class StepSource:
    """The C of one step over lanes.

    Parameters
    ----------
    declarations : tuple of str
        Lines before the loop over the members.
    lines : tuple of str
        One step, from ``y`` to ``y``.
    scratch : int
        Vectors of heap the step needs besides the lanes functions' work (``scratch``).
    """

    declarations: tuple
    lines: tuple
    scratch: int = 0


def rates_follow_coordinates(f: ca.Function, n_q: int) -> bool:
    """Whether the first ``n_q`` entries of ``f(x, ...)`` are ``x[n_q:2 n_q]`` (``q' = qd``).

    Parameters
    ----------
    f : casadi.Function
        ``(x, u, p) -> xdot`` (SX).
    n_q : int
        Coordinates.

    Returns
    -------
    bool
        True where the rows of ``q' = qd`` are the rates' symbols themselves, as the
        lanes' Newton solve assumes (``sc_newton_solve`` of ``stepper_period.c``).
    """
    x = ca.SX.sym("x", f.size1_in(0))
    xdot = f(x, *(ca.SX.sym(f"in{k}", f.sparsity_in(k)) for k in range(1, f.n_in())))
    return bool(ca.is_equal(xdot[:n_q], x[n_q : 2 * n_q], 1))


def _combination(terms) -> str:
    """``c0 * k0[j] + c1 * k1[j] + ...`` over ``terms`` ``[(i, c_i), ...]`` (stage index
    and nonzero coefficient), in order."""
    return " + ".join(f"{float(c)!r} * k{i}[j]" for i, c in terms)


def _each(n_x: int, statement: str) -> str:
    return f"for (int j = 0; j < {n_x}; j++) {statement}"


def explicit_step(tableau: ExplicitTableau, n_x: int) -> StepSource:
    """One step of an explicit Runge-Kutta method (as
    ``softcurve.simulation.stepper._scheme.explicit_step``).

    Parameters
    ----------
    tableau : ExplicitTableau
        The method.
    n_x : int
        States.
    """
    lines = []
    for i, row in enumerate(tableau.a):
        shift = [(j, a) for j, a in enumerate(row[:i]) if a]
        if shift:
            lines.append(_each(n_x, f"z[j] = y[j] + h * ({_combination(shift)});"))
        lines.append(f"sc_xdot({'z' if shift else 'y'}, U, p, k{i}, w);")
    weights = [(i, b) for i, b in enumerate(tableau.b) if b]
    lines.append(_each(n_x, f"y[j] = y[j] + h * ({_combination(weights)});"))
    declarations = [f"sc_v z[{n_x}];", *(f"sc_v k{i}[{n_x}];" for i in range(len(tableau.b)))]
    return StepSource(tuple(declarations), tuple(lines))


def rosenbrock_step(
    tableau: Tableau, n_x: int, n_q: int, scale: np.ndarray, every: int, shared=None
) -> StepSource:
    """One step of a Rosenbrock method with a fresh Newton matrix at every ``every``-th
    step (as ``softcurve.simulation.stepper._scheme.newton_matrix`` and
    ``softcurve.simulation.stepper._scheme.rosenbrock_step``), the matrix factored by the
    period template's loops (``sc_newton_factor``, ``sc_newton_solve``: the rows of
    ``q' = qd`` eliminated, the rest by Householder QR), where the scalar scheme calls
    CasADi's sparse QR of the whole matrix written out as straight-line code: the same
    solves up to round-off, in code that does not grow with the states. The Jacobian is
    forward differences of ``sc_xdot``, or, given the sizes of the exact Jacobian's
    ``shared`` values, the functions of :func:`lanes_jacobian`: ``sc_passes`` once,
    the tangents along each coordinate in a loop, the accelerations' rows solved by the
    mass matrix's Cholesky factor (``sc_cholesky``, ``sc_cholesky_solve``).

    Parameters
    ----------
    tableau : Tableau
        The method.
    n_x : int
        States.
    n_q : int
        Coordinates ``q``, the first states, whose rates ``qd`` are the next ``n_q``.
    scale : ndarray, shape (n_x,)
        The states' natural sizes
        (``softcurve.simulation.stepper._scheme.rest_scale``).
    every : int
        Steps between fresh Newton matrices.
    shared : sequence of int, optional
        The sizes of ``sc_passes``'s values: the exact Jacobian in place of differences.
    """
    a, _, _, gamma = tableau.transformed()
    n_r = n_x - n_q
    if shared is not None:  # G - dID/dx and D by coordinate, then D^-1 column by column
        n_rest = n_x - 2 * n_q
        values = ", ".join(f"S{k}" for k in range(len(shared)))
        columns = [
            f"  sc_passes(y, U, p, {values}, G, R, w);",
            f"  for (int k = 0; k < {n_q}; k++) {{",
            f"    for (int i = 0; i < {n_q}; i++) e[i] = sc_broadcast(i == k ? 1.0 : 0.0);",
            f"    sc_tangent_q({values}, e, col, w);",
            f"    for (int i = 0; i < {n_q}; i++) G[k * {n_q} + i] -= col[i];",
            f"    sc_tangent_qd({values}, e, col, w);",
            f"    for (int i = 0; i < {n_q}; i++) G[({n_q} + k) * {n_q} + i] -= col[i];",
            f"    sc_tangent_qdd({values}, e, D + k * {n_q}, w);",
            "  }",
            "  sc_cholesky(D);",
            f"  for (int c = 0; c < {n_x}; c++) {{",
            f"    sc_cholesky_solve(D, G + c * {n_q}, A[c]);",
            f"    for (int i = 0; i < {n_q}; i++) A[c][i] = -(gh * A[c][i]);",
            f"    for (int i = 0; i < {n_rest}; i++)",
            f"      A[c][{n_q} + i] = -(gh * R[c * {n_rest} + i]);",
        ]
        own = [
            f"sc_v *G = scratch + {n_x * n_r}, *D = G + {n_q * n_x}, *R = D + {n_q * n_q};",
            f"sc_v e[{n_q}], col[{n_q}];",
        ]
        start = n_x * n_r + n_q * n_x + n_q * n_q + n_rest * n_x
        for k, size in enumerate(shared):
            own.append(f"sc_v *S{k} = scratch + {start};")
            start += size
        scratch = start
    else:
        columns = [
            "  " + _each(n_x, f"step[j] = {DIFFERENCE_STEP!r} * sc_fmax(sc_fabs(y[j]), "),
            "      sc_broadcast(sc_scale[j]));",
            f"  for (int c = 0; c < {n_x}; c++) {{",
            "    " + _each(n_x, "z[j] = y[j];"),
            "    z[c] = y[c] + step[c];",
            "    sc_xdot(z, U, p, fj, w);",
            f"    for (int i = 0; i < {n_r}; i++)",
            f"      A[c][i] = -(gh * ((fj[{n_q} + i] - f0[{n_q} + i]) / step[c]));",
        ]
        values = ", ".join(repr(float(v)) for v in scale)
        own = [
            f"static const double sc_scale[{n_x}] = {{{values}}};",
            f"sc_v fj[{n_x}], step[{n_x}];",
        ]
        scratch = n_x * n_r
    lines = [
        f"if (s % {every} == 0) {{",
        "  sc_xdot(y, U, p, f0, w);",
        *columns,
        f"    if (c >= {n_q}) A[c][c - {n_q}] = sc_broadcast(1.0) + A[c][c - {n_q}];",
        "  }",
        "  sc_newton_factor(&A[0][0], gh, beta, rdiag);",
        "} else {",
        "  sc_xdot(y, U, p, f0, w);",
        "}",
        *_stages(tableau, n_x),
    ]
    declarations = [
        *own,
        f"const sc_v gh = sc_broadcast({float(gamma)!r}) * h;",
        f"sc_v z[{n_x}], f0[{n_x}], slope[{n_x}];",
        f"sc_v beta[{n_r}], rdiag[{n_r}];",
        f"sc_v (*A)[{n_r}] = (sc_v (*)[{n_r}])scratch; /* column c: A[c] */",
        *(f"sc_v k{i}[{n_x}];" for i in range(a.shape[0])),
    ]
    return StepSource(tuple(declarations), tuple(lines), scratch)


def _stages(tableau: Tableau, n_x: int) -> list:
    """The lines of a Rosenbrock step's stages and update, from ``f0`` and the factored
    Newton matrix ``A``."""
    a, c, m, _ = tableau.transformed()
    lines = []
    for i in range(a.shape[0]):
        shift = [(j, a[i, j]) for j in range(i) if a[i, j]]
        if i == 0 or not shift:
            lines.append(_each(n_x, "slope[j] = f0[j];"))
        else:
            lines.append(_each(n_x, f"z[j] = y[j] + h * ({_combination(shift)});"))
            lines.append("sc_xdot(z, U, p, slope, w);")
        for j in range(i):
            if c[i, j]:
                lines.append(_each(n_x, f"slope[j] = slope[j] + {float(c[i, j])!r} * k{j}[j];"))
        lines.append(f"sc_newton_solve(&A[0][0], gh, beta, rdiag, slope, k{i});")
    weights = [(i, m[i]) for i in range(len(m)) if m[i]]
    lines.append(_each(n_x, f"y[j] = y[j] + h * ({_combination(weights)});"))
    return lines
