"""The fixed-step scheme of :class:`~softcurve.simulation.stepper.Stepper`, as one CasADi
function per member, compiled.

A control period of length ``T`` is split into ``substeps`` equal steps ``h`` of the
two-stage Rosenbrock-W method ROS2 of Verwer, Spee, Blom and Hundsdorfer (SIAM J. Sci.
Comput. 20(4), 1999), for ``x' = f(x)`` with the input held over the period::

    (I - gamma h J) k1 = f(x_n)
    (I - gamma h J) k2 = f(x_n + h k1) - 2 k1
    x_{n+1} = x_n + h (3 k1 + k2) / 2,        gamma = 1 + 1/sqrt(2)

It is of order 2 for *any* matrix ``J`` (a W-method), and L-stable when ``J`` is the
exact Jacobian: the stiff elongation, creep, actuator-lag and penalty-contact modes are
damped, never amplified, whatever ``h``. So ``J`` is the exact Jacobian at the start of
the period, reused by every substep (one factorization of ``I - gamma h J`` per period,
a sparse QR written out by CasADi, no inverse). The state layout is simulate's: ``(q, qd,
lam)`` then, with an actuator that has a ``time_constant``, its lagging inputs
(:class:`~softcurve.simulation.integrators.ActuatorInput`).
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from softcurve.compiled.build import compile_function
from softcurve.simulation.engine import nominal_scale
from softcurve.simulation.integrators import ActuatorInput

GAMMA = 1.0 + 1.0 / math.sqrt(2.0)
"""ROS2's ``gamma``: with it the method is L-stable (Verwer et al. 1999)."""


def state_derivative(model, inputs: ActuatorInput | None) -> ca.Function:
    """``(x, u, p) -> xdot`` on the model's compiled ``rhs`` (an ``external``; its symbolic
    form without a compiled library), the actuator's force ``H(q) u`` and lag in CasADi's
    virtual machine (a few dozen operations), kept with the model.

    Parameters
    ----------
    model : Model
        The model.
    inputs : ActuatorInput or None
        The actuator's input, or None for generalized forces.
    """

    def build():
        rhs = model.function("rhs")
        n, n_state = model.n, model.n_state
        extra = 0 if inputs is None else inputs.n_states
        x = ca.MX.sym("x", n_state + extra)
        u = ca.MX.sym("u", model.n if inputs is None else inputs.n_inputs)
        p = ca.MX.sym("p", model.parameters.size)
        rates = []
        if inputs is None:
            tau = u
        else:
            command = ca.fmin(ca.fmax(u, ca.DM(inputs.lower)), ca.DM(inputs.upper))
            if inputs.time_constant is None:
                tau = inputs.force(x[:n], command)
            else:
                lagging = x[n_state:]
                tau = inputs.force(x[:n], lagging)
                rates = [(command - lagging) / inputs.time_constant]
        xdot = ca.vertcat(rhs(x[:n_state], tau, p), *rates)
        return ca.Function("softcurve_xdot", [x, u, p], [xdot], ["x", "u", "p"], ["xdot"])

    return model.cached(("stepper-xdot", None if inputs is None else inputs.key), build)


def state_scale(model, inputs: ActuatorInput | None) -> np.ndarray:
    """The natural size of every state (n_state [+ m],): the geometric floors of
    :func:`~softcurve.simulation.engine.nominal_scale`, and the larger bound of each
    lagging input (as ``simulate`` scales them).

    Parameters
    ----------
    model : Model
        The model.
    inputs : ActuatorInput or None
        The actuator's input, or None for generalized forces.
    """
    floor = nominal_scale(model, np.zeros(model.n_state))
    if inputs is None or not inputs.n_states:
        return floor
    return np.concatenate([floor, np.maximum(np.abs(inputs.lower), np.abs(inputs.upper))])


DIFFERENCE_STEP = 1.5e-8
"""Forward-difference step of the Jacobian relative to ``max(|x_j|, scale_j)``
(:func:`state_scale`): the square root of the machine epsilon, where truncation and
round-off errors of a forward difference balance. Any matrix keeps ROS2 of order 2; the
error of the differences (~1e-8 relative) only perturbs its stability function."""


def newton_matrix(model, inputs, x, u, p, gamma_h):
    """``I - gamma_h J`` (MX) with ``J`` the Jacobian of :func:`state_derivative` at
    ``x`` by forward differences (one batched call of ``n_state + 1`` evaluations), and
    the derivative at ``x``.

    Parameters
    ----------
    model : Model
        The model.
    inputs : ActuatorInput or None
        The actuator's input, or None for generalized forces.
    x, u, p : casadi.MX
        State, inputs and robot parameters.
    gamma_h : float
        ``gamma h`` [s].
    """
    f = state_derivative(model, inputs)
    size = x.shape[0]
    scale = ca.DM(state_scale(model, inputs))
    steps = DIFFERENCE_STEP * ca.fmax(ca.fabs(x), scale)
    points = ca.horzcat(x, ca.repmat(x, 1, size) + ca.diag(steps))
    values = f.map(size + 1)(points, u, p)
    f0 = values[:, 0]
    jacobian = (values[:, 1:] - ca.repmat(f0, 1, size)) / ca.repmat(steps.T, size, 1)
    return ca.MX.eye(size) - gamma_h * jacobian, f0


LINEAR_SOLVER = "qr"
"""CasADi's linear solver of the Newton systems (dense ``n_state`` x ``n_state``)."""


def period_function(model, inputs, period: float, substeps: int) -> ca.Function:
    """``(x, u, p) -> (x_next, tip, contact_force)`` stacked (``n_state + 6``) for one
    member: ``substeps`` ROS2 steps over ``period`` [s] with the Newton matrix of the
    period's start, then the observation at the end; kept with the model.

    Parameters
    ----------
    model : Model
        The model.
    inputs : ActuatorInput or None
        The actuator's input, or None for generalized forces.
    period : float
        The period [s].
    substeps : int
        ROS2 steps per period.
    """

    def build():
        f = state_derivative(model, inputs)
        x = ca.MX.sym("x", f.size1_in(0))
        u = ca.MX.sym("u", f.size1_in(1))
        p = ca.MX.sym("p", f.size1_in(2))
        h = period / substeps
        matrix, f0 = newton_matrix(model, inputs, x, u, p, GAMMA * h)
        y, slope = x, f0
        for i in range(substeps):
            if i:
                slope = f(y, u, p)
            k1 = ca.solve(matrix, slope, LINEAR_SOLVER)
            k2 = ca.solve(matrix, f(y + h * k1, u, p) - 2 * k1, LINEAR_SOLVER)
            y = y + h * (1.5 * k1 + 0.5 * k2)
        out = ca.vertcat(y, observer(model)(y[: model.n_state], p))
        return ca.Function("softcurve_stepper", [x, u, p], [out], ["x", "u", "p"], ["out"])

    key = ("stepper-period", period, substeps, None if inputs is None else inputs.key)
    return model.cached(key, build)


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


def observer(model) -> ca.Function:
    """``(x, p) -> (tip position, total contact force)`` stacked (6,), world frame, for
    ``x = (q, qd, lam)``: the model's compiled ``pose`` without environment; with one, the
    contact's sum compiled (cached on disk by content), kept with the model.

    Parameters
    ----------
    model : Model
        The model.
    """

    def build():
        x = ca.SX.sym("x", model.n_state)
        p = ca.SX.sym("p", model.parameters.size)
        if model.environment is None:
            pose = model.function("pose")
            xm, pm = ca.MX.sym("x", model.n_state), ca.MX.sym("p", p.shape[0])
            out = ca.vertcat(pose(xm[: model.n], 1.0, pm)[1], ca.MX.zeros(3))
            return ca.Function("softcurve_observe", [xm, pm], [out])
        out = ca.cse(ca.vertcat(*observation(model, x, p)))
        return compile_function(ca.Function("softcurve_observe", [x, p], [out]))

    return model.cached(("stepper-observe",), build)
