"""The driver's adjoints: the gradient of a function of the states at output times, along
the initial state, the held inputs and the parameters, in one forward pass that tapes
the steps and one backward pass per scalar. Two of them:

- the discrete adjoint of the driver's Radau IIA (``c/adjoint.c``: :func:`adjoint_forward`
  and :func:`adjoint_backward`), below;
- the continuous adjoint on CVODES (``c/adams_adjoint.c``: :func:`adams_forward` and
  :func:`adams_backward`): the adjoint equations integrated backward by CVODES's Adams
  (or BDF) over the forward pass's taped steps, each step's polynomial taped as CVODES
  interpolates over it, the integrals along the inputs and the
  parameters integrated with the adjoint outside the error test, as CVODES integrates
  quadratures without error control. It is the gradient of the flow to about the
  tolerance, not of the computed numbers.

The discrete adjoint of Radau IIA:

It differentiates the scheme rather than the equations: the numbers the forward pass
returned, with its step sizes held (as CVODES holds its own) and its stages taken as
converged. The step sizes move with the start, inputs and parameters all the same, so
the gradient is that of the computed numbers only as far as the tolerance is tight (on
the paper robot at rtol 1e-6 within 5e-6 of central differences of those numbers), and
the gradient of the exact flow as far as the states are accurate. The backward pass costs
one reverse-mode evaluation of the right-hand side per stage and iteration of a
transposed simplified Newton iteration on the forward pass's own Newton matrices
(``c/adjoint.c`` has the equations).
"""

from __future__ import annotations

import ctypes
from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.simulation.solvers import _driver as c_driver
from softcurve.simulation.solvers._policy import MAX_ORDER, RESTART_INTERVAL
from softcurve.simulation.solvers._radau import radau_constants

ADJOINT_STATISTICS = ("vjp_evaluations", "iterations", "factorizations", "fresh_jacobians")
"""The backward pass's counters, in the driver's order: reverse-mode evaluations of the
right-hand side (three per iteration), iterations of the transposed simplified Newton
iteration (the first solve of each step included), factorizations of the transposed
Newton matrices, Jacobians computed afresh where the taped one did not converge."""

TAPE_GROWTH = 4
"""Where the tape is full the forward pass runs again with this many times the room of
what filled (steps or Jacobians): at most ``log_4`` of the steps over the first room
runs, where doubling would take twice as many."""

FIRST_ROOM = (1024, 2, 64)
"""The first forward pass's room: ``a + b (T - 1)`` steps for ``T`` output times, and
``c`` Jacobians. The paper robot's 10 s swing at rtol 1e-6 takes 701, 776 and about 1,500
steps at 1, 100 and 1,000 output intervals (``benchmarks/bench_gradient.py``), and 56
Jacobians over 6,702 steps of a violent 0.5 s start: each in one pass."""


def vjp_function(rhs: ca.Function) -> ca.Function:
    """``vjp(x, u, p, v) -> (f_x^T v, f_u^T v, f_p^T v)``: the reverse mode of ``rhs(x,
    u, p) -> f``, what the backward pass evaluates at every stage.

    Parameters
    ----------
    rhs : casadi.Function
        The actuated right-hand side, three inputs and one output.

    Returns
    -------
    casadi.Function
        SX where ``rhs`` is SX.
    """
    if rhs.n_in() != 3 or rhs.n_out() != 1:
        raise ValueError(f"rhs must be (x, u, p) -> f, got {rhs}")
    symbols = [rhs.sx_in(i) if rhs.is_a("SXFunction") else rhs.mx_in(i) for i in range(3)]
    f = rhs(*symbols)
    v = type(f).sym("v", f.shape[0])
    products = [ca.densify(ca.jtimes(f, s, v, True)) for s in symbols]
    return ca.Function("softcurve_vjp", [*symbols, v], products)


@dataclass(frozen=True)
class Taped:
    """A forward pass of :func:`adjoint_forward` or :func:`adams_forward`, its arrays
    read-only (the backward pass reads them again).

    Attributes
    ----------
    scheme : {"radau", "adams"}
        Which forward pass taped it, and so which backward pass takes it
        (:func:`adjoint_backward` or :func:`adams_backward`).
    states : ndarray, shape (T, n)
        The physical state at every output time (rows from ``reached`` on are zero).
    reached : int
        Outputs filled, the first included.
    flag : int
        0, or the driver's flag of the failure (``softcurve.simulation.solvers.DRIVER_FLAGS``).
    counts : dict
        The driver's counters (``softcurve.simulation.solvers._driver.STATISTICS``).
    steps : int
        Steps taped (points: steps and starts, for ``"adams"``).
    tape : ndarray, shape (room, entry)
        The taped steps, the first ``steps`` rows (``softcurve_driver.h``'s layouts:
        ``TAPE_HEAD + 4 n`` doubles a step for ``"radau"``, ``ADAMS_HEAD + (max_order +
        1) n`` a point for ``"adams"``).
    jacobians : ndarray, shape (J, n, n)
        The Jacobians the steps iterated on, by their taped index (none for ``"adams"``).
    arguments : tuple
        The forward pass's arguments, which the backward pass takes again: ``(problem,
        settings, u, p, nominal, times, owner, abscissa)`` for ``"radau"`` (the last two
        say which taped step gave each output, and where in it), ``(problem, settings, u,
        p, nominal, times, stops)`` for ``"adams"``.
    """

    scheme: str
    states: np.ndarray
    reached: int
    flag: int
    counts: dict
    steps: int
    tape: np.ndarray
    jacobians: np.ndarray
    arguments: tuple


def adjoint_forward(problem, x0, u, p, nominal, times, rtol, atol, max_steps, stops=None):
    """One member integrated by the driver's Radau IIA over the output times, each step
    taped for :func:`adjoint_backward`.

    Parameters
    ----------
    problem : DriverProblem
        The model and actuator (``softcurve.simulation.solvers.driver_problem``).
    x0 : ndarray, shape (n,)
        The physical initial state (the lagging inputs last).
    u : ndarray, shape (T, k)
        Row ``i`` the inputs held over ``[times[i], times[i + 1])``.
    p : ndarray, shape (n_p,)
        The parameter vector.
    nominal : ndarray, shape (n,)
        The state scales (the integrated state is ``x / nominal``).
    times : ndarray, shape (T,)
        Output times [s], increasing.
    rtol, atol : float
        Radau IIA's tolerances, ``atol`` of the scaled state.
    max_steps : int
        Steps allowed per output interval.
    stops : ndarray of bool, shape (T,), optional
        The output times where the steps end (default every one): where the input
        changes, and at every sample where the derivative along the inputs is asked
        (row ``i``'s derivative is that of its own interval). The others come from the
        collocation polynomial of the step that passes them; the last is a stop anyway.

    Returns
    -------
    Taped
    """
    arrays = tuple(np.array(a, dtype=np.float64, order="C") for a in (u, p, nominal, times))
    x0 = np.asarray(x0, dtype=np.float64)
    n, count = x0.size, arrays[3].size
    stops = np.ones(count, np.int32) if stops is None else np.array(stops, np.int32)
    _check_problem(problem, x0.shape, arrays, stops)
    owner, abscissa = np.zeros(count, np.int64), np.zeros(count)
    entry = c_driver.DECLARATIONS.constants["TAPE_HEAD"] + 4 * n
    settings = c_driver.options(rtol, atol, max_steps, family=3, radau=radau_constants())
    room, jacobian_room = FIRST_ROOM[0] + FIRST_ROOM[1] * (count - 1), FIRST_ROOM[2]
    call = c_driver.entry("softcurve_adjoint_forward")
    while True:
        out = np.zeros((count, n))
        out[0] = x0
        try:
            tape, jacobians = np.empty((room, entry)), np.empty((jacobian_room, n, n))
        except MemoryError:  # a tape beyond memory: the pass cannot be set up
            return _frozen_taped("radau", out, 1, OUT_OF_MEMORY, {}, 0, np.empty((0, entry)),
                                 np.empty((0, n, n)), (problem, settings, *arrays, owner,
                                                       abscissa))  # fmt: skip
        used, stats = np.zeros(2, np.int64), np.zeros(len(c_driver.STATISTICS), np.int64)
        reached = ctypes.c_int(0)
        flag = call(
            ctypes.byref(problem.struct), ctypes.byref(settings), arrays[0].ctypes.data,
            arrays[1].ctypes.data, arrays[2].ctypes.data, arrays[3].ctypes.data, count,
            stops.ctypes.data, out.ctypes.data, owner.ctypes.data, abscissa.ctypes.data,
            tape.ctypes.data, room, jacobians.ctypes.data, jacobian_room,
            used.ctypes.data, stats.ctypes.data, ctypes.byref(reached),
        )  # fmt: skip
        if flag != c_driver.DECLARATIONS.constants["TAPE_FULL"]:
            break
        if used[0] >= room:
            room *= TAPE_GROWTH
        else:
            jacobian_room *= TAPE_GROWTH
    counts = dict(zip(c_driver.STATISTICS, stats.tolist(), strict=True))
    kept = jacobians[: max(int(used[1]), 1)].copy()
    return _frozen_taped("radau", out, reached.value, int(flag), counts, int(used[0]), tape, kept,
                         (problem, settings, *arrays, owner, abscissa))  # fmt: skip


OUT_OF_MEMORY = -100
"""The flag of a pass that could not be set up (the driver's own, ``FLAGS`` of
``softcurve.simulation.solvers``): here its tape does not fit in memory."""


def _frozen_taped(scheme, out, reached, flag, counts, steps, tape, jacobians,
                  arguments) -> Taped:  # fmt: skip
    """A :class:`Taped` whose arrays are read-only."""
    for array in (out, tape, jacobians, *arguments[2:]):
        array.setflags(write=False)
    return Taped(scheme, out, reached, flag, dict(counts), steps, tape, jacobians, arguments)


def _check_problem(problem, x0_shape: tuple, arrays, stops) -> None:
    """Refuse what the driver would read or write out of bounds, and the problems the
    backward pass cannot differentiate (an actuator's force or lag outside ``f``)."""
    fn = problem.struct
    if fn.force or fn.lag:
        raise ValueError(
            "the driver's adjoints take a problem whose f is the whole right-hand side "
            "(no actuator's force or lag beside it): compile the actuated right-hand side"
        )
    u, p, nominal, times = arrays
    count = times.size
    expected = {"x0": ((fn.nx,), x0_shape),
                "u": ((count, fn.nu), u.shape),
                "p": ((fn.np,), p.shape), "nominal": ((fn.nx,), nominal.shape),
                "stops": ((count,), stops.shape)}  # fmt: skip
    for name, (shape, got) in expected.items():
        if shape != got:
            raise ValueError(f"{name} must have shape {shape}, got {got}")
    if count < 2 or not np.all(np.diff(times) > 0) or not np.all(np.isfinite(times)):
        raise ValueError("times must be at least two increasing output times")


def _checked_seeds(taped: Taped, scheme: str, vjp, seeds) -> np.ndarray:
    """``seeds`` as a C array, after refusing another scheme's tape, a failed forward
    pass, seeds of another shape and a vjp of other shapes than the problem's."""
    if taped.scheme != scheme:
        raise ValueError(f"a tape of the {taped.scheme!r} forward pass: pass it to its own "
                         "backward pass")  # fmt: skip
    u, p, nominal, times = taped.arguments[2:6]
    seeds = np.ascontiguousarray(seeds, dtype=np.float64)
    if taped.flag or taped.reached != times.size:
        raise ValueError(f"the forward pass failed (flag {taped.flag}): nothing to send back")
    if seeds.shape != taped.states.shape:
        raise ValueError(f"seeds must have shape {taped.states.shape}, got {seeds.shape}")
    shapes = ((nominal.size, 1), (u.shape[1], 1), (p.size, 1))
    if vjp.n_in != 4 or vjp.shapes[1] != shapes:
        raise ValueError(f"vjp must be (x, u, p, v) -> outputs of shapes {shapes}")
    return seeds


def adjoint_backward(taped: Taped, vjp, seeds) -> tuple:
    """The derivative of a scalar along the initial state, the inputs and the parameters,
    from its derivative along the states at the output times, by the discrete adjoint of
    the taped forward pass.

    Parameters
    ----------
    taped : Taped
        A forward pass that succeeded (else ValueError).
    vjp : NativeFunction
        :func:`vjp_function` of the problem's actuated right-hand side, compiled.
    seeds : ndarray, shape (T, n)
        The scalar's derivative along the physical state at every output time.

    Returns
    -------
    tuple
        ``(flag, d_x0 (n,), d_u (T, k), d_p (n_p,), counts)``: 0 or the driver's flag, the
        derivatives (``d_u`` on the row each step held: the first of the rows between
        two stops; the last row zero, as that input acts on nothing) and the counters of
        :data:`ADJOINT_STATISTICS`.
    """
    seeds = _checked_seeds(taped, "radau", vjp, seeds)
    problem, settings, u, p, nominal, times, owner, abscissa = taped.arguments
    lam, d_u, d_p = np.zeros(nominal.size), np.zeros_like(u), np.zeros(p.size)
    sizes = np.array(vjp.work_sizes, np.int64)
    stats = np.zeros(len(ADJOINT_STATISTICS), np.int64)
    flag = c_driver.entry("softcurve_adjoint_backward")(
        ctypes.byref(problem.struct), ctypes.byref(settings), ctypes.c_void_p(vjp.address),
        sizes.ctypes.data, u.ctypes.data, p.ctypes.data, nominal.ctypes.data, times.size,
        owner.ctypes.data, abscissa.ctypes.data, taped.tape.ctypes.data, taped.steps,
        taped.jacobians.ctypes.data, seeds.ctypes.data, lam.ctypes.data, d_u.ctypes.data,
        d_p.ctypes.data, stats.ctypes.data,
    )  # fmt: skip
    counts = dict(zip(ADJOINT_STATISTICS, stats.tolist(), strict=True))
    return int(flag), lam, d_u, d_p, counts


ADAMS_STATISTICS = ("steps", "vjp_evaluations", "jacobians", "factorizations",
                    "error_test_failures", "starts")  # fmt: skip
"""The continuous adjoint's backward counters, in the driver's order: CVODES's steps,
reverse-mode evaluations of the right-hand side (one per right-hand side of the adjoint
equations with its integrals), Jacobians at the forward states, linear-solver setups,
error-test failures, and starts (afresh at every segment's end, at every output time
whose seed is not zero, where the adjoint jumps, and every ``RESTART_INTERVAL``); summed
over its passes, whose count :func:`adams_backward` adds as ``passes``."""

ADAMS_ATOL = 0.1
"""The first backward pass's absolute tolerance of the adjoint, over the forward pass's
of the scaled state, in the units of the largest seed (``max |nominal seed|``). The
adjoint of a state whose seed is far below the largest (the elongation's under a tip's
height) is then still resolved. ``python benchmarks/bench_gradient.py --adams-atol``:
on pressures changing every 25 ms and a cost reading every output time
(``tests/test_gradient.py``'s case) at rtol 1e-7, the gradient lies 3.5e-4, 2.6e-5 and
3.3e-6 from CVODES's adjoint at 1e-12 with 1, 0.1 and 0.01, while the paper robot's
10 s swing takes 20.2, 18.3 and 31.4 ms (867, 866 and 1,814 backward steps)."""

ADAMS_DECAYED = 1e-2
"""Where the adjoint at the start has decayed below this fraction of the largest seed
(``max |nominal lambda_0| < ADAMS_DECAYED max |nominal seed|``), the backward pass runs
again with its absolute tolerance scaled by that ratio, so that it resolves the adjoint
relative to the size it decays to: the gradient of a cost read at the end of a swing
that has damped out. ``python benchmarks/bench_gradient.py --adams-atol``: the tip's
height after 1 s of the paper swing lies 6.2e-2 (along x0) and 4.3e-3 (the parameters)
from CVODES's adjoint at 1e-12 after one pass, 1.9e-5 and 4.7e-6 after two (the discrete
adjoint: 3.1e-5 and 1.1e-5); a cost that stays large, as the integral of
``bench_gradient.py``'s swing, runs one pass."""

ADAMS_DECAYED_FLOOR = 1e-8
"""The smallest scale of the second pass's absolute tolerance, over the first's: below
it the gradient along the initial state is noise for either adjoint (the tip's height
after 2 s of the paper swing: 30 and 35 % from CVODES's at 1e-12 for the continuous and
the discrete adjoint, ``--adams-atol``), while the parameters' still converge (3.7e-8
and 2.1e-8)."""


ADAMS_FIRST_ROOM = (16384, 16)
"""The first room of :func:`adams_forward`'s tape: ``a + b (T - 1)`` points for ``T``
output times. A tape that fills runs the forward pass again on four times the room (the
paper robot's 10 s swing takes 1,200 to 1,400 points, ``benchmarks/bench_gradient.py
--adams``), while the room costs nothing until written (NumPy's large arrays are mapped
lazily): 16,384 points of the paper robot at order 5 (``ADAMS_HEAD + 6 n`` doubles, n =
10) are 8.3 MB of address space."""


def adams_forward(problem, x0, u, p, nominal, times, rtol, atol, max_steps, stops=None,
                  family=1, max_order=MAX_ORDER):  # fmt: skip
    """One member integrated by the driver's CVODES over the output times, the end of each
    internal step taped for :func:`adams_backward`.

    Parameters
    ----------
    problem : DriverProblem
        The model and actuator, its ``f`` the whole right-hand side.
    x0 : ndarray, shape (n,)
        The physical initial state.
    u : ndarray, shape (T, k)
        Row ``i`` the inputs held over ``[times[i], times[i + 1])``.
    p : ndarray, shape (n_p,)
        The parameter vector.
    nominal : ndarray, shape (n,)
        The state scales (the integrated state is ``x / nominal``).
    times : ndarray, shape (T,)
        Output times [s], increasing.
    rtol, atol : float
        CVODES's tolerances, ``atol`` of the scaled state; the backward pass's relative
        one too, its absolute one :data:`ADAMS_ATOL` times ``atol`` in the units of the
        largest seed.
    max_steps : int
        Steps allowed per output interval.
    stops : ndarray of bool, shape (T,), optional
        The output times where CVODES starts afresh (default every one): where the input
        changes. CVODES passes through the others (the backward pass still gives each
        sample its own derivative), and starts afresh at the first step's end after
        every ``RESTART_INTERVAL`` of time, as ``simulate`` does at the first output time
        after it (``softcurve.simulation.solvers.RESTART_INTERVAL``).
    family : int
        1 Adams, 2 BDF (``softcurve_driver.h``'s ``FAMILY_ADAMS``, ``FAMILY_BDF``).
    max_order : int
        The method's largest order, from 1 (Adams: to 12, BDF: to 5); each point of the
        tape holds a polynomial of up to this order.

    Returns
    -------
    Taped
        Its ``tape`` holds the points (``ADAMS_HEAD + (max_order + 1) n`` doubles each:
        time, input row, order, the polynomial's Taylor coefficients), ``jacobians`` none,
        and ``arguments`` are
        ``(problem, settings, u, p, nominal, times, stops)``.
    """
    arrays = tuple(np.array(a, dtype=np.float64, order="C") for a in (u, p, nominal, times))
    x0 = np.asarray(x0, dtype=np.float64)
    n, count = x0.size, arrays[3].size
    stops = np.ones(count, np.int32) if stops is None else np.array(stops, np.int32)
    _check_problem(problem, x0.shape, arrays, stops)
    if family not in (1, 2):
        raise ValueError(f"family must be 1 (Adams) or 2 (BDF), got {family}")
    if not 1 <= max_order <= (12 if family == 1 else 5):
        raise ValueError(f"max_order must be in [1, {12 if family == 1 else 5}], got {max_order}")
    entry = c_driver.DECLARATIONS.constants["ADAMS_HEAD"] + (max_order + 1) * n
    settings = c_driver.options(rtol, atol, max_steps, max_order=max_order, family=family)
    room = ADAMS_FIRST_ROOM[0] + ADAMS_FIRST_ROOM[1] * (count - 1)
    call = c_driver.entry("softcurve_adams_forward")
    while True:
        out = np.zeros((count, n))
        out[0] = x0
        try:
            tape = np.empty((room, entry))
        except MemoryError:
            arguments = (problem, settings, *arrays, stops)
            return _frozen_taped("adams", out, 1, OUT_OF_MEMORY, {}, 0, np.empty((0, entry)),
                                 np.empty((0, n, n)), arguments)  # fmt: skip
        used, stats = ctypes.c_long(0), np.zeros(len(c_driver.STATISTICS), np.int64)
        reached = ctypes.c_int(0)
        flag = call(
            ctypes.byref(problem.struct), ctypes.byref(settings), RESTART_INTERVAL,
            arrays[0].ctypes.data, arrays[1].ctypes.data, arrays[2].ctypes.data,
            arrays[3].ctypes.data, count, stops.ctypes.data, out.ctypes.data,
            tape.ctypes.data, room, ctypes.byref(used), stats.ctypes.data,
            ctypes.byref(reached),
        )  # fmt: skip
        if flag != c_driver.DECLARATIONS.constants["TAPE_FULL"]:
            break
        room *= TAPE_GROWTH
    counts = dict(zip(c_driver.STATISTICS, stats.tolist(), strict=True))
    return _frozen_taped("adams", out, reached.value, int(flag), counts, used.value, tape,
                         np.empty((0, n, n)), (problem, settings, *arrays, stops))  # fmt: skip


def adams_backward(taped: Taped, vjp, seeds) -> tuple:
    """:func:`adjoint_backward` for a forward pass of :func:`adams_forward`: the adjoint
    equations integrated backward by the same method and relative tolerance, with the
    absolute one of :data:`ADAMS_ATOL`, and once more with it scaled down where the
    adjoint has decayed (:data:`ADAMS_DECAYED`). Where that second pass fails (its
    tighter tolerance can run out of steps), its flag is returned: the first pass's
    gradient is not the one asked for.

    Parameters
    ----------
    taped : Taped
        A forward pass of :func:`adams_forward` that succeeded (else ValueError).
    vjp : NativeFunction
        :func:`vjp_function` of the problem's right-hand side, compiled.
    seeds : ndarray, shape (T, n)
        The scalar's derivative along the physical state at every output time.

    Returns
    -------
    tuple
        ``(flag, d_x0 (n,), d_u (T, k), d_p (n_p,), counts)``: 0 or the driver's flag, the
        derivatives (``d_u`` row ``i`` along the input held over ``[times[i],
        times[i + 1]]``; the last row zero) and the counters of :data:`ADAMS_STATISTICS`
        over both passes, with ``passes``.
    """
    seeds = _checked_seeds(taped, "adams", vjp, seeds)
    nominal = taped.arguments[4]
    scale = np.max(np.abs(nominal * seeds))
    flag, lam, d_u, d_p, counts = _adams_pass(taped, vjp, seeds, ADAMS_ATOL)
    counts["passes"] = 1
    decayed = np.max(np.abs(nominal * lam)) / scale if scale > 0 else 1.0
    if flag == 0 and decayed < ADAMS_DECAYED:
        flag, lam, d_u, d_p, again = _adams_pass(
            taped, vjp, seeds, ADAMS_ATOL * max(decayed, ADAMS_DECAYED_FLOOR)
        )
        counts = {name: value + again.get(name, 0) for name, value in counts.items()}
        counts["passes"] = 2
    return flag, lam, d_u, d_p, counts


def _adams_pass(taped: Taped, vjp, seeds, atol_scale: float) -> tuple:
    """One backward pass of the driver, its absolute tolerance ``atol_scale`` times the
    forward pass's (in the units of the largest seed)."""
    problem, settings, u, p, nominal, times, stops = taped.arguments
    backward = c_driver.options(settings.rtol, atol_scale * settings.atol, settings.max_steps,
                                max_order=settings.max_order, family=settings.family)  # fmt: skip
    lam, d_u, d_p = np.zeros(nominal.size), np.zeros_like(u), np.zeros(p.size)
    sizes = np.array(vjp.work_sizes, np.int64)
    stats = np.zeros(len(ADAMS_STATISTICS), np.int64)
    flag = c_driver.entry("softcurve_adams_backward")(
        ctypes.byref(problem.struct), ctypes.byref(backward), RESTART_INTERVAL,
        ctypes.c_void_p(vjp.address), sizes.ctypes.data, u.ctypes.data, p.ctypes.data,
        nominal.ctypes.data, times.ctypes.data, times.size, stops.ctypes.data,
        taped.tape.ctypes.data, taped.steps, seeds.ctypes.data, lam.ctypes.data,
        d_u.ctypes.data, d_p.ctypes.data, stats.ctypes.data,
    )  # fmt: skip
    return int(flag), lam, d_u, d_p, dict(zip(ADAMS_STATISTICS, stats.tolist(), strict=True))
