"""Quasi-static maps of an actuated robot: input sweeps and inverse statics.

An *input sweep* follows the equilibrium ``N(q) = H(q) u`` (plus any other load of
:class:`~softcurve.analysis.loads.StaticLoad`) along a path of actuator inputs ``u``
(pressures, tensions) by continuation: each point starts the equilibrium solver from the
previous one, so the branch is followed and its stability is tracked (compare the
paper's Fig. 3, which maps pressure to deformation through the fitted stiffness).
*Inverse statics* finds the bounded inputs that put the tip closest to a target point,
as the nonlinear program ``min |p_tip(q) - target|^2`` subject to the equilibrium and
the input bounds, solved by IPOPT on the exact CasADi derivatives.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.analysis.loads import (
    StaticLoad,
    coordinate_scale,
    residual_reference,
    rest_configuration,
    static_function,
)
from softcurve.analysis.statics import default_bounds, equilibrium
from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError, real_array, real_scalar
from softcurve.description.actuator import Actuator
from softcurve.figures import plot_input_sweep

IPOPT_SOLVED = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
IPOPT_ITERATION_LIMIT = "Maximum_Iterations_Exceeded"


@dataclass(frozen=True, eq=False)
class InputSweep(Result):
    """Equilibria along a path of actuator inputs.

    Attributes
    ----------
    inputs : ndarray, shape (k, m)
        The path [the actuator's ``input_unit``, e.g. Pa].
    q : ndarray, shape (k, n)
        Equilibria [m, 1/m, 1/m].
    tip : ndarray, shape (k, 3)
        World tip positions [m].
    converged : ndarray, shape (k,), bool
        Whether each point met the solver's tolerance.
    stability : tuple of str
        Classification of each point (see :mod:`softcurve.analysis.statics`).
    status : Status
        SUCCESS when every point converged, PARTIAL when some did not, NOT_CONVERGED
        when none did.
    message : str
        How many points failed, and the first.
    """

    inputs: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    converged: np.ndarray
    stability: tuple[str, ...]
    status: Status
    message: str

    @property
    def curvature(self) -> np.ndarray:
        """Net curvature (k, N) [1/m] of each segment."""
        return np.hypot(self.q[:, 1::3], self.q[:, 2::3])

    def plot(self, ax=None, *, x=None, x_label: str | None = None):
        """Tip position and curvature along the sweep, points that are not stable marked.

        Parameters
        ----------
        ax : None or sequence of matplotlib.axes.Axes, shape (2,)
            Panels for the tip position and the curvature; None draws a new figure.
        x : array_like, shape (k,), optional
            The abscissa (default: the input that varies most, pressures in kPa).
        x_label : str, optional
            Label of the abscissa, with its unit (default: the input's name, or none for
            a given ``x``).

        Returns
        -------
        matplotlib.figure.Figure
            Write it with :func:`softcurve.figures.save_figure`.
        """
        return plot_input_sweep(self, ax, x=x, x_label=x_label)


def input_sweep(model, actuator: Actuator, inputs, *, q0=None, **loads) -> InputSweep:
    """Follow the equilibrium along a path of actuator ``inputs`` (k, m) by continuation.

    Parameters
    ----------
    model : Model
        The compiled model.
    actuator : Actuator
        The actuator the inputs drive.
    inputs : array_like, shape (k, m)
        Path of inputs [the actuator's ``input_unit``, e.g. Pa], within its bounds.
    q0 : array_like, shape (n,), optional
        Initial guess for the first point [m, 1/m, 1/m] (default: the rest
        configuration).
    **loads
        Further loads of :class:`~softcurve.analysis.loads.StaticLoad` (``gravity``,
        ``tip_force``...).
    """
    path = np.asarray(inputs, dtype=np.float64)
    if path.ndim != 2 or path.shape[1] != actuator.n_inputs:
        raise ParameterError(f"inputs must have shape (k, {actuator.n_inputs}), got {path.shape}")
    q = rest_configuration(model.robot) if q0 is None else real_array("q0", q0, (model.n,))
    qs, tips, converged, stability = [], [], [], []
    for u in path:
        e = equilibrium(model, q, actuator=actuator, inputs=u, **loads)
        if e.success:
            q = e.q
        qs.append(e.q)
        tips.append(e.tip_position)
        converged.append(e.success)
        stability.append(e.stability)
    converged = np.array(converged)
    failed = np.flatnonzero(~converged)
    if not failed.size:
        status, message = Status.SUCCESS, f"{len(path)} equilibria followed"
    else:
        status = Status.PARTIAL if failed.size < len(path) else Status.NOT_CONVERGED
        message = f"{failed.size} of {len(path)} points did not converge (first: {failed[0]})"
    return InputSweep(
        inputs=path,
        q=np.array(qs),
        tip=np.array(tips),
        converged=converged,
        stability=tuple(stability),
        status=status,
        message=message,
    )


@dataclass(frozen=True, eq=False)
class InverseStatics(Result):
    """Bounded actuator inputs whose equilibrium puts the tip closest to a target.

    Attributes
    ----------
    inputs : ndarray, shape (m,)
        The inputs found [the actuator's ``input_unit``], within their bounds.
    q : ndarray, shape (n,)
        The equilibrium they produce [m, 1/m, 1/m].
    tip : ndarray, shape (3,)
        Its tip position [m].
    target : ndarray, shape (3,)
        The point asked for [m].
    distance : float
        ``|tip - target|`` [m].
    stability : str
        Of the equilibrium, see :mod:`softcurve.analysis.statics`.
    saturated : ndarray, shape (m,), bool
        Inputs at a bound (a target beyond reach saturates some).
    status : Status
        SUCCESS when the tip reaches the target; INFEASIBLE when the input bounds keep
        it away (the closest point is returned); NOT_CONVERGED or EVALUATION_LIMIT when
        IPOPT or the equilibrium check failed.
    message : str
        IPOPT's status, the distance, the stability and the saturated inputs.
    """

    inputs: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    target: np.ndarray
    distance: float
    stability: str
    saturated: np.ndarray
    status: Status
    message: str


def _guesses(model, target, starts: int):
    """The rest configuration and arcs bending toward the target's azimuth."""
    rest = rest_configuration(model.robot)
    guesses = [rest]
    azimuth = np.arctan2(target[1], target[0])
    for k in range(1, starts):
        kappa = k / (starts * model.robot.rest_length)
        q = rest.copy()
        q[1::3], q[2::3] = kappa * np.cos(azimuth), kappa * np.sin(azimuth)
        guesses.append(q)
    return guesses


def _status(e, ipopt_status: str, distance: float, tolerance: float) -> Status:
    if not e.success:
        return e.status
    if ipopt_status == IPOPT_ITERATION_LIMIT:
        return Status.EVALUATION_LIMIT
    if ipopt_status not in IPOPT_SOLVED:
        return Status.NOT_CONVERGED
    return Status.SUCCESS if distance <= tolerance else Status.INFEASIBLE


def inverse_statics(
    model,
    actuator: Actuator,
    target,
    *,
    starts: int = 3,
    max_iterations: int = 200,
    tolerance: float = 1e-6,
    **loads,
) -> InverseStatics:
    """The bounded actuator inputs that put the tip closest to ``target`` at equilibrium.

    Solves ``min |p_tip(q) - target|^2`` over ``(q, u)`` subject to the equilibrium
    ``N(q) = H(q) u + other loads``, ``lower <= u <= upper`` and ``q`` within
    :func:`~softcurve.analysis.statics.default_bounds`, from ``starts`` initial guesses
    (IPOPT, exact derivatives), keeping the stable solution closest to the target when
    there is one. The equilibrium is then re-solved at the optimal inputs and classified.

    Parameters
    ----------
    model : Model
        The compiled model.
    actuator : Actuator
        The actuator whose inputs are chosen.
    target : array_like, shape (3,)
        World point [m].
    starts : int
        Number of initial guesses (rest, then arcs bending toward the target).
    max_iterations : int
        IPOPT iteration budget per start.
    tolerance : float
        A tip closer than ``tolerance`` times the robot's rest length to the target
        reaches it (dimensionless); farther is INFEASIBLE.
    **loads
        Further loads (``gravity``, ``tip_force``...; not ``inputs``).
    """
    target = real_array("target", target, (3,))
    tolerance = real_scalar("tolerance", tolerance, positive=True)
    if "inputs" in loads or "actuator" in loads:
        raise ParameterError("inverse_statics chooses the actuator inputs: do not pass them")
    load = StaticLoad(model, actuator=actuator, inputs=actuator.rest_inputs(), **loads)
    function = static_function(model, actuator)
    bounds = default_bounds(model.robot)
    args = load.arguments()

    opti = ca.Opti()
    q, u = opti.variable(model.n), opti.variable(actuator.n_inputs)
    scale = np.maximum(np.abs(actuator.upper), np.abs(actuator.lower))
    residual, _, _, tip = function(q, args[0], args[1], u, args[3], args[4])
    length = model.robot.rest_length
    opti.minimize(ca.sumsqr(tip - target) / length**2)
    # the equilibrium in the scaled residual units of softcurve.analysis.solver
    unit = coordinate_scale(model.robot) / residual_reference(model)
    opti.subject_to(unit * residual == 0)
    opti.subject_to(opti.bounded(actuator.lower / scale, u / scale, actuator.upper / scale))
    opti.subject_to(opti.bounded(bounds[:, 0], q, bounds[:, 1]))
    opti.solver(
        "ipopt",
        {"print_time": False, "expand": True},
        {"print_level": 0, "sb": "yes", "max_iter": max_iterations, "tol": 1e-12},
    )
    best = None
    for guess in _guesses(model, target, starts):
        opti.set_initial(q, guess)
        opti.set_initial(u, 0.5 * (actuator.lower + actuator.upper))
        try:
            solution = opti.solve()
            stats = solution.stats()
            q_opt, u_opt = solution.value(q), solution.value(u)
        except RuntimeError:
            stats = opti.stats()
            q_opt, u_opt = opti.debug.value(q), opti.debug.value(u)
        u_opt = actuator.clip(np.atleast_1d(u_opt))
        e = equilibrium(model, np.atleast_1d(q_opt), actuator=actuator, inputs=u_opt, **loads)
        candidate = (
            not e.success,
            e.stability != "stable",
            float(np.linalg.norm(e.tip_position - target)),
            e,
            u_opt,
            stats.get("return_status", "unknown"),
        )
        if best is None or candidate[:3] < best[:3]:
            best = candidate
    _, _, distance, e, u_opt, ipopt_status = best
    saturated = (u_opt <= actuator.lower) | (u_opt >= actuator.upper)
    status = _status(e, ipopt_status, distance, tolerance * length)
    message = (
        f"IPOPT: {ipopt_status}; tip {1e3 * distance:.3g} mm from the target; equilibrium "
        f"{e.stability}; {int(saturated.sum())} input(s) at a bound"
    )
    if status is Status.INFEASIBLE:
        message += "; the target is out of reach within the input bounds"
    return InverseStatics(
        inputs=u_opt,
        q=e.q,
        tip=e.tip_position,
        target=target,
        distance=distance,
        stability=e.stability,
        saturated=saturated,
        status=status,
        message=message,
    )
