"""The fixed-step scheme of :class:`~softcurve.simulation.stepper.Stepper`: one CasADi
function per member that advances a state by one control period, generated as C.

The period is split into ``substeps`` steps ``h`` of one of the methods of
``softcurve.simulation.stepper._methods``, the inputs held: a Rosenbrock-W method
(ROS34PW2 of order 3, or ROS2 of order 2, both L-stable) or the explicit RK4
(:func:`explicit_step`). A W-method keeps its order with any matrix ``J``, so one
forward-difference Jacobian (:func:`newton_matrix`) serves several steps, or the
model's exact one (``jacobian="exact"``: :func:`exact_jacobian`); ``I - gamma h J`` is
factorized by Householder QR (:class:`Factorization`), no inverse. The state layout is
``simulate``'s: ``(q, qd, lam)`` then the actuator's lagging inputs
(:class:`~softcurve.simulation.solvers.ActuatorInput`). docs/stepping.md gives the
accuracy and the cost.

Besides the state, the stepper reports the tip position and the total contact force of
the environment (:func:`observer`), generated with the period function or evaluated on
their own.

The compiled period function is called on many members from Python threads
(:class:`ThreadedMembers`). Why not CasADi's ``map(N, "thread")``: mapped over 256
members of the paper's robot it ran 1.08x faster on two threads than on one on this
project's 2-core machine with nothing else running (``benchmarks/bench_stepper.py``,
section 2), the threads apparently not running the compiled code at the same time. Here
the generated library is opened with ctypes
(:class:`~softcurve.compiled.NativeFunction`, one set of work arrays per thread), which
releases the GIL during the foreign call, and each thread loops over a contiguous chunk
of members."""

from __future__ import annotations

import threading
from concurrent.futures import ThreadPoolExecutor

import casadi as ca
import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.base.shares import run_shares, share_bounds
from softcurve.compiled import NativeFunction, compile_function, load_function
from softcurve.simulation._settings import checked_jacobian
from softcurve.simulation.solvers import ActuatorInput, actuated_derivative, actuated_jacobian
from softcurve.simulation.solvers import state_scale as integration_scale
from softcurve.simulation.stepper._methods import METHODS, ExplicitTableau, Tableau

scheme_parameters = parameters_from(
    {
        "model": ("Model", "The model."),
        "inputs": ("ActuatorInput or None", "The actuator's input, or None for forces."),
        "f": ("casadi.Function", "``(x, u, p) -> xdot``."),
        "h": ("casadi.MX or float", "Step [s]."),
    }
)
"""Substitutes the entries ``model``, ``inputs``, ``f`` and ``h`` shared by this module's
functions."""


@scheme_parameters
def state_derivative(model, inputs: ActuatorInput | None, symbolic: bool) -> ca.Function:
    """``(x, u, p) -> xdot``: the model's ``rhs`` with the actuator's force ``H(q) u`` and
    lag, kept with the model.

    Parameters
    ----------
    %(model)s
    %(inputs)s
    symbolic : bool
        On the model's symbolic ``rhs`` (to be generated as C with the stepper), else on
        its compiled library (an ``external``) with the rest in CasADi's virtual machine.
    """

    def build():
        rhs = model.symbolic["rhs"] if symbolic else model.function("rhs")
        return actuated_derivative(model, inputs, rhs)

    return model.cached(("stepper-xdot", symbolic, None if inputs is None else inputs.key), build)


@scheme_parameters
def exact_jacobian(model, inputs: ActuatorInput | None) -> ca.Function:
    """``(x, u, p) -> J``: the exact Jacobian of :func:`state_derivative` by the state,
    the derivatives of the chain algorithms with the actuator's part
    (:func:`~softcurve.simulation.solvers.actuated_jacobian`), kept with the model;
    symbolic on either route (generated as C with the period, or evaluated in CasADi's
    virtual machine).

    Parameters
    ----------
    %(model)s
    %(inputs)s
    """

    def build():
        return actuated_jacobian(model, inputs, model.jacobian_passes())

    return model.cached(("stepper-jacobian", None if inputs is None else inputs.key), build)


@scheme_parameters
def rest_scale(model, inputs: ActuatorInput | None) -> np.ndarray:
    """The natural size of every state (n_state [+ m],): the integrators' state scale
    (:func:`~softcurve.simulation.solvers.state_scale`) at the rest state, the geometric
    floors and the larger bound of each lagging input.

    Parameters
    ----------
    %(model)s
    %(inputs)s
    """
    return integration_scale(model, np.zeros(model.n_state), inputs)


DIFFERENCE_STEP = 1.5e-8
"""Forward-difference step of the Jacobian relative to ``max(|x_j|, scale_j)``
(:func:`rest_scale`): the square root of the machine epsilon, where truncation and
round-off errors of a forward difference balance. Any matrix keeps ROS2 of order 2; the
error of the differences (~1e-8 relative) only perturbs its stability function."""


@scheme_parameters
def jacobian_pattern(model, inputs) -> ca.Sparsity:
    """The structural sparsity of the Jacobian of :func:`state_derivative` with its
    diagonal (``q' = qd``, creep rates of ``(qd, lam)`` only, lag states diagonal).

    Parameters
    ----------
    %(model)s
    %(inputs)s
    """
    pattern = state_derivative(model, inputs, True).sparsity_jac(0, 0)
    return pattern + ca.Sparsity.diag(pattern.size1())


@scheme_parameters
def difference_jacobian(f, scale, x, u, p):
    """``(J, f(x))``: the Jacobian of ``f`` at ``x`` by forward differences, one batched
    call of ``n_state + 1`` evaluations; symbolic (MX) in the generated period, numeric
    (DM) for ``softcurve.simulation.stepper._stability.fastest_rate``.

    Parameters
    ----------
    %(f)s
    scale : ndarray, shape (n_state [+ m],)
        :func:`rest_scale`.
    x, u, p : casadi.MX or casadi.DM
        State, inputs and robot parameters.
    """
    size = x.shape[0]
    steps = DIFFERENCE_STEP * ca.fmax(ca.fabs(x), ca.DM(scale))
    points = ca.horzcat(x, ca.repmat(x, 1, size) + ca.diag(steps))
    values = f.map(size + 1)(points, u, p)
    f0 = values[:, 0]
    jacobian = (values[:, 1:] - ca.repmat(f0, 1, size)) / ca.repmat(steps.T, size, 1)
    return jacobian, f0


def newton_matrix(f, scale, pattern, x, u, p, gamma_h, jacobian=None):
    """``(I - gamma_h J, f(x))`` (MX): ``J`` the :func:`difference_jacobian` of ``f`` at
    ``x``, or ``jacobian``'s, on its structural ``pattern``.

    Parameters
    ----------
    f : casadi.Function
        ``(x, u, p) -> xdot`` (:func:`state_derivative`).
    scale : ndarray, shape (n_state [+ m],)
        :func:`rest_scale`.
    pattern : casadi.Sparsity
        :func:`jacobian_pattern`.
    x, u, p : casadi.MX
        State, inputs and robot parameters.
    gamma_h : casadi.MX or float
        ``gamma h`` [s].
    jacobian : casadi.Function, optional
        ``(x, u, p) -> J`` (:func:`exact_jacobian`); None takes differences.
    """
    if jacobian is None:
        matrix, f0 = difference_jacobian(f, scale, x, u, p)
    else:
        matrix, f0 = jacobian(x, u, p), f(x, u, p)
    return ca.project(ca.MX.eye(x.shape[0]) - gamma_h * matrix, pattern), f0


class Factorization:
    """Householder QR of a Newton matrix of fixed sparsity as two SX functions: the
    factors once per period, the solve once per stage (CasADi's ``qr_sparse`` and
    ``qr_solve``: no inverse, no pivoting needed for QR).

    Parameters
    ----------
    pattern : casadi.Sparsity
        Sparsity of the Newton matrix (with its diagonal).
    """

    def __init__(self, pattern: ca.Sparsity):
        matrix = ca.SX.sym("M", pattern)
        v, r, beta, prinv, pc = ca.qr_sparse(matrix)
        self.factor = ca.Function("newton_qr", [matrix], [v, r, beta])
        names = ("v", "r", "beta")
        factors = [ca.SX.sym(n, e.sparsity()) for n, e in zip(names, (v, r, beta), strict=True)]
        b = ca.SX.sym("b", pattern.size1())
        x = ca.qr_solve(b, *factors, prinv, pc)
        self.solve = ca.Function("newton_solve", [*factors, b], [x])


STEPPER_FLAGS = ("-O3",)
"""Optimization flags of the compiled period (``-march=native`` is added unless
``SOFTCURVE_PORTABLE`` is set). The period is small (about 1,000 CasADi instructions
calling the right-hand side), so ``-O3`` compiles in about 12 s against 6-8 s at
``-O1`` and pays: one member-period of the paper robot with the bellows took 214-228
us against 267-323 us at ``-O1 -march=native`` (1.17-1.43x, three runs of
``benchmarks/bench_compile_flags.py --only stepper``, alternating
builds)."""


@scheme_parameters
def rosenbrock_step(f, x, u, p, solve, f0, h, tableau: Tableau):
    """One step of ``tableau`` (MX) from ``x`` with the Newton systems solved by
    ``solve`` and ``f0 = f(x)``.

    Parameters
    ----------
    %(f)s
    x, u, p : casadi.MX
        State, inputs, robot parameters.
    solve : callable
        ``solve(b)``: ``(I - gamma h J)^-1 b`` by a factorization.
    f0 : casadi.MX
        ``f(x, u, p)``.
    %(h)s
    tableau : Tableau
        The method.
    """
    a, c, m, _ = tableau.transformed()
    stages = []
    for i in range(a.shape[0]):
        if i == 0:
            slope = f0
        else:
            shift = sum(a[i, j] * stages[j] for j in range(i) if a[i, j])
            slope = f(x + h * shift, u, p) if not isinstance(shift, int) else f0
        for j in range(i):
            if c[i, j]:
                slope = slope + c[i, j] * stages[j]
        stages.append(solve(slope))
    return x + h * sum(m[i] * stages[i] for i in range(len(stages)) if m[i])


@scheme_parameters
def explicit_step(f, x, u, p, h, tableau: ExplicitTableau):
    """One step of the explicit ``tableau`` (MX) from ``x``.

    Parameters
    ----------
    %(f)s
    x, u, p : casadi.MX
        State, inputs, robot parameters.
    %(h)s
    tableau : ExplicitTableau
        The method.
    """
    stages = []
    for row in tableau.a:
        shift = sum(a * k for a, k in zip(row, stages, strict=False) if a)
        stages.append(f(x if isinstance(shift, int) else x + h * shift, u, p))
    return x + h * sum(b * k for b, k in zip(tableau.b, stages, strict=True) if b)


@scheme_parameters
def period_function(
    model,
    inputs,
    substeps: int,
    method: str,
    compiled: bool = True,
    flags=None,
    jacobian_every: int | None = None,
    native: bool = False,
    jacobian: str = "differences",
):
    """``(x, u, p, period) -> (x_next, tip, contact_force)`` stacked (``n_state + 6``) for
    one member: ``substeps`` steps of ``method`` over ``period`` [s] with a fresh Newton
    matrix every ``jacobian_every`` steps, then the observation at the end; kept with the
    model.

    With ``compiled``, the whole period is generated as one C function (the model's
    symbolic right-hand side called in a loop) and compiled with
    :func:`~softcurve.compiled.compile_function` (cached on disk by content: one
    library per robot structure, environment, actuator, method and ``substeps``; any
    period and parameter values); else it runs in CasADi's virtual machine on the
    model's compiled ``rhs``.

    Parameters
    ----------
    %(model)s
    %(inputs)s
    substeps : int
        Steps per period.
    method : str
        A key of :data:`METHODS`.
    compiled : bool
        Generate and compile C (default), or evaluate in CasADi's virtual machine.
    flags : tuple of str, optional
        The compiler's optimization flags (default :data:`STEPPER_FLAGS`).
    jacobian_every : int, optional
        Steps between fresh Jacobians of a Rosenbrock method (default ``substeps``: one
        per period).
    native : bool
        With ``compiled``, return the compiled library's function as a
        :class:`~softcurve.compiled.NativeFunction` (called through ctypes, which
        releases the GIL: threads of Python run members in parallel) instead of a
        CasADi ``external``; None where no compiler works.
    jacobian : str
        The Newton matrix's Jacobian of a Rosenbrock method (:func:`checked_jacobian`).
    """
    checked_jacobian(jacobian)
    tableau = METHODS[method]
    every = substeps if jacobian_every is None else min(jacobian_every, substeps)
    if isinstance(tableau, ExplicitTableau):
        every = None  # no Jacobian

    def graph():
        f = state_derivative(model, inputs, compiled)
        x = ca.MX.sym("x", f.size1_in(0))
        u = ca.MX.sym("u", f.size1_in(1))
        p = ca.MX.sym("p", f.size1_in(2))
        period = ca.MX.sym("period")
        h = period / substeps
        y = x
        if isinstance(tableau, ExplicitTableau):
            for _ in range(substeps):
                y = explicit_step(f, y, u, p, h, tableau)
        else:
            scale, pattern = rest_scale(model, inputs), jacobian_pattern(model, inputs)
            exact = exact_jacobian(model, inputs) if jacobian == "exact" else None
            qr = Factorization(pattern)
            for i in range(substeps):
                if i % every == 0:
                    gamma_h = tableau.gamma[0][0] * h
                    matrix, slope = newton_matrix(f, scale, pattern, y, u, p, gamma_h, exact)
                    factors = qr.factor(matrix)
                else:
                    slope = f(y, u, p)
                y = rosenbrock_step(f, y, u, p, _solver(qr, factors), slope, h, tableau)
        observe = observer(model, compiled)
        out = ca.vertcat(y, observe(y[: model.n_state], p))
        return ca.Function(
            "softcurve_stepper", [x, u, p, period], [out], ["x", "u", "p", "period"], ["out"]
        )

    flags = STEPPER_FLAGS if flags is None else tuple(flags)
    inputs_key = None if inputs is None else inputs.key
    key = ("stepper", substeps, method, compiled, every, inputs_key, jacobian)
    function = model.cached(key, graph)
    if not compiled:
        return function

    def build():
        if not native:
            return compile_function(function, flags)
        loaded = compile_function(function, flags, load=load_function)
        return loaded if isinstance(loaded, NativeFunction) else None

    return model.cached((*key, flags, native), build)


def _solver(qr: Factorization, factors):
    """``b -> (I - gamma h J)^-1 b`` with the factors of one Newton matrix."""
    return lambda b: qr.solve(*factors, b)


def observation(model, x, p):
    """``(tip position (3,), total contact force (3,))`` at the state ``x``, both in the
    world frame, as SX; the force is zero without an environment.

    Parameters
    ----------
    model : Model
        The model.
    x : casadi.SX, shape (n_state,)
        The state ``(q, qd, lam)``.
    p : casadi.SX, shape (n_p,)
        Robot parameters.
    """
    n = model.n
    tip = model.symbolic["pose"](x[:n], 1.0, p)[1]
    if model.environment is None:
        return tip, ca.SX.zeros(3)
    e = model.expressions
    rotation = ca.Function("base_rotation", [e.p], [e.base_rotation])(p)
    per_obstacle = model.symbolic["contact"](x[:n], x[n : 2 * n], p)[2]  # (3, k), base frame
    return tip, rotation @ ca.sum2(per_obstacle)


def observer(model, symbolic: bool) -> ca.Function:
    """``(x, p) -> (tip position, total contact force)`` stacked (6,), world frame, for
    ``x = (q, qd, lam)``: without environment on the model's compiled ``pose``; with one,
    in CasADi's virtual machine (the compiled stepper generates its own; this one serves
    the few states a step does not advance and
    :meth:`~softcurve.simulation.stepper.Stepper.tip`), kept with the model.

    Parameters
    ----------
    model : Model
        The model.
    symbolic : bool
        An SX function (to be generated as C with the stepper).
    """

    def build():
        if symbolic or model.environment is not None:
            x = ca.SX.sym("x", model.n_state)
            p = ca.SX.sym("p", model.parameters.size)
            return ca.Function("observe", [x, p], [ca.vertcat(*observation(model, x, p))])
        pose = model.function("pose")
        x, p = ca.MX.sym("x", model.n_state), ca.MX.sym("p", model.parameters.size)
        out = ca.vertcat(pose(x[: model.n], 1.0, p)[1], ca.MX.zeros(3))
        return ca.Function("softcurve_observe", [x, p], [out])

    return model.cached(("stepper-observe", symbolic), build)


class MemberShares:
    """A compiled period on every member: the members split into one contiguous share per
    thread (a multiple of :attr:`granularity` members, but the last), each share one
    foreign call through ctypes, which releases the GIL
    (:func:`softcurve.base.shares.run_shares`, on a pool kept between periods).
    Subclasses say how a share is called (:meth:`_share`) and check the arrays
    (:meth:`_arrays`).

    Parameters
    ----------
    threads : int
        Threads over the members.
    """

    granularity = 1
    """Members per unit of a share."""

    def __init__(self, threads: int):
        self._threads = threads
        self._pool: ThreadPoolExecutor | None = None
        self._lock = threading.Lock()

    def _arrays(self, x, u, p, period, out) -> list:
        """``(x, u, p, period)`` as C-contiguous float64 arrays."""
        return [np.ascontiguousarray(a, dtype=np.float64) for a in (x, u, p, period)]

    def _share(self, arrays, out, start: int, stop: int) -> list:
        """Fill rows ``start:stop`` of ``out``; the failures as ``[(i, message), ...]``."""
        raise NotImplementedError

    def __call__(self, x, u, p, period, out) -> list:
        """Fill ``out`` (N, n_out); return the members that failed as ``[(i, message),
        ...]`` (their rows are undefined).

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
        out : ndarray, shape (N, n_out)
            Where the outputs go (C-contiguous float64).
        """
        arrays = self._arrays(x, u, p, period, out)
        bounds = share_bounds(out.shape[0], self._threads, self.granularity)
        if len(bounds) == 2:  # one share, on this thread: the one-environment case
            return self._share(arrays, out, 0, out.shape[0])
        with self._lock:
            if self._pool is None:
                self._pool = ThreadPoolExecutor(self._threads, "softcurve-stepper")
        parts = run_shares(lambda a, b: self._share(arrays, out, a, b), bounds, self._threads,
                           self._pool)  # fmt: skip
        return [failure for part in parts for failure in part]


class ThreadedMembers(MemberShares):
    """``function(x_i, u_i, p, period)`` for every member ``i``, one call per member
    (:meth:`~softcurve.compiled.NativeFunction.call_rows`).

    Parameters
    ----------
    function : NativeFunction
        The compiled period function ``(x, u, p, period) -> out``.
    threads : int
        Threads over the members.
    """

    def __init__(self, function: NativeFunction, threads: int):
        super().__init__(threads)
        self._function = function

    def _share(self, arrays, out, start: int, stop: int) -> list:
        return self._function.call_rows(arrays, out, start, stop)
