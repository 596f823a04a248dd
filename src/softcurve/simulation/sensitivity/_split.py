"""The sensitivity columns' right-hand side in two parts for two threads.

``S' = f_x S + f_d`` is, by the Jacobian's column blocks, the sum of
``f_x[:, A] S[A, :] + f_d`` and ``f_x[:, B] S[B, :]`` for any split of the states into
``A`` and ``B``. Each part is compiled on its own; softcurve's CVODES driver evaluates the
first on its own thread and the second on a helper thread
(the driver's ``parts.c``), so that an evaluation takes about as long
as the larger part instead of the whole.

:func:`assembled` joins the compiled parts into the augmented system of CasADi's CVODES,
the route of a process without the driver.

Almost all of the work is the Jacobian's columns of the coordinates ``q`` (the
kinematics' higher derivatives at every quadrature node): on the paper robot
(``benchmarks/bench_identification.py``'s case, 75,024 operations in all) the columns of
``q`` take 64,801 operations with ``f``, those of the rates and creep states with
``f_d`` 20,973, and a single coordinate's column about 29,000-30,600. The split gives
``B`` the last two thirds of the coordinates and ``A`` the rest with every other state
and ``f_d``: 42,480 and 45,912 operations there (the rest of the operations shared by
both parts, computed twice). Other splits of that robot are less even (``A`` = the first
two coordinates and ``f_d``: 48,095 and 40,723).
"""

from __future__ import annotations

import casadi as ca

SPLIT_OF_COORDINATES = 3
"""``B`` holds the coordinates from ``n // SPLIT_OF_COORDINATES`` on (at least the last
one): the paper robot's two bending curvatures, ``A`` its length and the rest."""


def split_states(n_coordinates: int, n_states: int) -> tuple[list[int], list[int]]:
    """``(A, B)``: the states of the two parts (``A`` gets ``f_d`` too).

    Parameters
    ----------
    n_coordinates : int
        Coordinates ``q`` (the first states), >= 1.
    n_states : int
        All states (``q``, rates, creep states, lagged inputs).
    """
    first = max(1, n_coordinates // SPLIT_OF_COORDINATES) if n_coordinates > 1 else 0
    second = list(range(first, n_coordinates))
    return [i for i in range(n_states) if i not in second], second


def column_parts(f, xs, us, ds, sens, scales, f_d, n_coordinates: int) -> list[ca.Function]:
    """The two parts ``(x;vec(S), u, d;scale) -> vec(part)`` that sum to ``vec(f_x S + f_d)``.

    Parameters
    ----------
    f : casadi.SX, shape (n_x, 1)
        The state's right-hand side in ``xs``, ``us`` and ``ds``.
    xs, us, ds : casadi.SX
        Symbols of the state, the inputs and the parameters ``d``.
    sens : casadi.SX, shape (n_x, m)
        Symbols of the sensitivity columns.
    scales : casadi.SX, shape (m, 1)
        Symbols of the column scales.
    f_d : casadi.SX, shape (n_x, m)
        ``f``'s derivative along the columns' parameters, scaled.
    n_coordinates : int
        Coordinates ``q`` among the states.

    Returns
    -------
    list of casadi.Function
        The parts ``A`` (with ``f_d``) and ``B``, dense outputs of ``n_x m`` entries.
    """
    inputs = [ca.vertcat(xs, ca.vec(sens)), us, ca.vertcat(ds, scales)]
    parts = []
    for k, states in enumerate(split_states(n_coordinates, xs.shape[0])):
        product = ca.jacobian(f, xs[states]) @ sens[states, :]
        part = product + f_d if k == 0 else product
        parts.append(
            ca.Function(
                f"softcurve_sensitivity_part{k}", inputs, [ca.densify(ca.cse(ca.vec(part)))]
            )
        )
    return parts


def assembled(state: ca.Function, parts, n_parameters: int) -> ca.Function:
    """``(x;vec(S), u, d;scale) -> f;vec(S')`` from the compiled state function
    ``f(x, u, d)`` and the parts: the augmented system for CasADi's CVODES, referring to
    the compiled libraries by path (so it pickles small), for a process that evaluates
    a split evaluator without softcurve's driver.

    Parameters
    ----------
    state : casadi.Function
        ``f(x, u, d)``, compiled (an ``external``).
    parts : sequence of casadi.Function
        The parts of :func:`column_parts`, compiled.
    n_parameters : int
        Entries of ``d`` (the scales follow them in the third argument).
    """
    n_x = state.size1_in(0)
    width = parts[0].size1_in(0)
    x, u = ca.MX.sym("x", width), ca.MX.sym("u", state.size1_in(1))
    d = ca.MX.sym("d", parts[0].size1_in(2))
    columns = sum(part(x, u, d) for part in parts)
    rhs = ca.vertcat(state(x[:n_x], u, d[:n_parameters]), columns)
    return ca.Function("softcurve_sensitivity_assembled", [x, u, d], [rhs])
