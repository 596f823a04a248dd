"""The C of one step of each stepper method over lanes of members, for
``softcurve.simulation.stepper._lanes.period_source``: the same operations, in the
same order, as the scalar scheme of ``softcurve.simulation.stepper._scheme``.

Each function returns :class:`StepSource`: declarations, the lines of one step (inside
the loop over the steps ``s``, on the state ``y``, inputs ``U``, parameters ``p`` and
step ``h``, with the functions' work array ``w``), the SX functions it calls besides the
state derivative ``sc_xdot``, and the heap it needs (``scratch``).
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.simulation.stepper._methods import ExplicitTableau, Tableau
from softcurve.simulation.stepper._scheme import DIFFERENCE_STEP, Factorization


@dataclass(frozen=True)
class StepSource:
    """The C of one step over lanes.

    Parameters
    ----------
    declarations : tuple of str
        Lines before the loop over the members.
    lines : tuple of str
        One step, from ``y`` to ``y``.
    functions : tuple of (casadi.Function, str, tuple of bool)
        SX functions to write as lanes: function, C name, which inputs are shared.
    scratch : int
        Vectors of heap the step needs besides the functions' work (``scratch``).
    """

    declarations: tuple
    lines: tuple
    functions: tuple = ()
    scratch: int = 0


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


def _on_nonzeros(function: ca.Function, name: str) -> ca.Function:
    """``function`` with every input and output as the column of its nonzeros."""
    inputs = [ca.SX.sym(f"in{k}", function.sparsity_in(k).nnz()) for k in range(function.n_in())]
    matrices = [ca.SX(function.sparsity_in(k), x) for k, x in enumerate(inputs)]
    outputs = function.call(matrices)
    return ca.Function(name, inputs, [ca.vertcat(*out.nonzeros()) for out in outputs])


def rosenbrock_step(
    tableau: Tableau, n_x: int, pattern: ca.Sparsity, scale: np.ndarray, every: int
) -> StepSource:
    """One step of a Rosenbrock method with a fresh Newton matrix at every ``every``-th
    step (as ``softcurve.simulation.stepper._scheme.newton_matrix``, the QR of
    ``softcurve.simulation.stepper._scheme.Factorization`` and
    ``softcurve.simulation.stepper._scheme.rosenbrock_step``).

    Parameters
    ----------
    tableau : Tableau
        The method.
    n_x : int
        States.
    pattern : casadi.Sparsity
        The Newton matrix's structure
        (``softcurve.simulation.stepper._scheme.jacobian_pattern``).
    scale : ndarray, shape (n_x,)
        The states' natural sizes
        (``softcurve.simulation.stepper._scheme.state_scale``).
    every : int
        Steps between fresh Newton matrices.
    """
    qr = Factorization(pattern)
    factor, solve = _on_nonzeros(qr.factor, "sc_factor"), _on_nonzeros(qr.solve, "sc_solve")
    sizes = [factor.size1_out(k) for k in range(3)]
    a, c, m, gamma = tableau.transformed()
    rows, cols = pattern.get_triplet()
    matrix = [
        f"M[{k}] = "
        + (f"sc_broadcast(1.0) - gh * J[{i}][{j}];" if i == j else f"-(gh * J[{i}][{j}]);")
        for k, (i, j) in enumerate(zip(rows, cols, strict=True))
    ]
    lines = [
        f"if (s % {every} == 0) {{",
        "  sc_xdot(y, U, p, f0, w);",
        "  " + _each(n_x, f"step[j] = {DIFFERENCE_STEP!r} * sc_fmax(sc_fabs(y[j]), "),
        "      sc_broadcast(sc_scale[j]));",
        f"  for (int c = 0; c < {n_x}; c++) {{",
        "    " + _each(n_x, "z[j] = y[j];"),
        "    z[c] = y[c] + step[c];",
        "    sc_xdot(z, U, p, fj, w);",
        "    " + _each(n_x, "J[j][c] = (fj[j] - f0[j]) / step[c];"),
        "  }",
        *(f"  {line}" for line in matrix),
        "  sc_factor(M, V, R, B, w);",
        "} else {",
        "  sc_xdot(y, U, p, f0, w);",
        "}",
    ]
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
        lines.append(f"sc_solve(V, R, B, slope, k{i}, w);")
    weights = [(i, m[i]) for i in range(len(m)) if m[i]]
    lines.append(_each(n_x, f"y[j] = y[j] + h * ({_combination(weights)});"))
    declarations = [
        f"static const double sc_scale[{n_x}] = {{{', '.join(repr(float(v)) for v in scale)}}};",
        f"const sc_v gh = sc_broadcast({float(gamma)!r}) * h;",
        f"sc_v z[{n_x}], f0[{n_x}], fj[{n_x}], step[{n_x}], slope[{n_x}];",
        f"sc_v (*J)[{n_x}] = (sc_v (*)[{n_x}])scratch;",
        f"sc_v M[{pattern.nnz()}], V[{sizes[0]}], R[{sizes[1]}], B[{sizes[2]}];",
        *(f"sc_v k{i}[{n_x}];" for i in range(a.shape[0])),
    ]
    functions = ((factor, "sc_factor", (False,)), (solve, "sc_solve", (False,) * 4))
    return StepSource(tuple(declarations), tuple(lines), functions, n_x * n_x)
