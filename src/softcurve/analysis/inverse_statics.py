"""Inverse statics: the bounded actuator inputs whose equilibrium puts the tip closest to
a target point (IPOPT on exact CasADi derivatives) and, when the inputs are redundant
(three or more tendons per segment, say), those of least total input above the lower
bounds among them (:func:`inverse_statics`).
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
from softcurve.figures import plot_configuration
from softcurve.figures.shapes import result_figure_options

IPOPT_SOLVED = ("Solve_Succeeded", "Solved_To_Acceptable_Level")
IPOPT_ITERATION_LIMIT = "Maximum_Iterations_Exceeded"
IPOPT_RELAX = "bound_relax_factor"


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
        Inputs at a bound (a target beyond reach saturates some; the minimum-total rule
        leaves some at their lower bound).
    rule : str
        How redundant inputs were resolved (``redundancy`` of :func:`inverse_statics`).
    total : float
        ``sum(inputs - lower)``, the total input above the lower bounds [the actuator's
        ``input_unit``, e.g. N for tensions].
    status : Status
        SUCCESS when the tip reaches the target; INFEASIBLE when the input bounds keep
        it away (the closest point is returned); NOT_CONVERGED or EVALUATION_LIMIT when
        IPOPT or the equilibrium check failed; LEFT_DOMAIN when the equilibrium lies
        outside the model's or the actuator's domain (the message says where).
    message : str
        IPOPT's status, the distance, the stability, the saturated inputs and the rule.
    """

    inputs: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    target: np.ndarray
    distance: float
    stability: str
    saturated: np.ndarray
    rule: str
    total: float
    status: Status
    message: str

    @result_figure_options
    def plot(self, ax=None, *, model, actuator=None):
        """The backbone at the equilibrium reached, from the side (x-z) and from above
        (x-y), with its tip and the target marked; with the actuator, a third panel of the
        inputs against their bounds, those at a bound crossed.

        Parameters
        ----------
        ax : None or sequence of matplotlib.axes.Axes, shape (2,) or (3,)
            Panels for the side view, the top view and, with ``actuator``, the inputs;
            None draws a new figure.
        %(model)s
        actuator : Actuator, optional
            The actuator whose inputs were chosen.

        """
        return plot_configuration(
            model,
            self.q,
            ax,
            marks={"target": self.target},
            actuator=actuator,
            inputs=None if actuator is None else self.inputs,
            saturated=self.saturated,
            title=f"tip {1e3 * self.distance:.3g} mm from the target ({self.status.value})",
        )


REDUNDANCY_RULES = ("minimum_total", "none")
BOUND_SNAP = 1e-8
"""Inputs within this fraction of their range from a bound are put on it (an interior
point method stops a hair inside an active bound)."""
REACH_SLACK = 1e-6
"""Relative slack of the reach when a stage-2 solution is checked (re-solve round-off)."""


def _guesses(model, target, starts: int):
    """The rest configuration and arcs bending toward the target's azimuth."""
    rest, azimuth = rest_configuration(model.robot), np.arctan2(target[1], target[0])
    guesses = [rest]
    robot = model.robot
    for k in range(1, starts):
        kappa = k / (starts * robot.rest_length)
        parts = [
            s.bent_toward(robot.element_coordinates(rest, i), kappa, azimuth)
            for i, s in enumerate(robot.segments)
        ]
        guesses.append(np.concatenate(parts))
    return guesses


def _status(e, ipopt_status: str, distance: float, tolerance: float) -> Status:
    if not e.success:
        return e.status
    if ipopt_status == IPOPT_ITERATION_LIMIT:
        return Status.EVALUATION_LIMIT
    if ipopt_status not in IPOPT_SOLVED:
        return Status.NOT_CONVERGED
    return Status.SUCCESS if distance <= tolerance else Status.INFEASIBLE


class _Program:
    """One IPOPT problem over ``(q, u)`` under the equilibrium and the bounds: the tip's
    squared distance to the target (stage 1), or with ``reach`` the total input above the
    lower bounds with the tip held within ``reach`` of the target (stage 2; ``reach`` 0:
    on it)."""

    def __init__(self, model, actuator, target, loads, max_iterations, reach=None):
        self.model, self.actuator, self.target, self.loads = model, actuator, target, loads
        args = StaticLoad(model, actuator=actuator, inputs=actuator.rest_inputs(), **loads)
        args, bounds = args.arguments(), default_bounds(model.robot)
        opti = ca.Opti()
        q, u = opti.variable(model.n), opti.variable(actuator.n_inputs)
        lower, upper = actuator.lower, actuator.upper
        scale = np.maximum(np.abs(upper), np.abs(lower))
        residual, _, _, tip = static_function(model, actuator)(q, *args[:2], u, *args[3:5])
        length = model.robot.rest_length
        if reach is None:
            opti.minimize(ca.sumsqr(tip - target) / length**2)
        else:
            opti.minimize(ca.sum1(u - lower) / float(np.sum(upper - lower)))
            if reach == 0:
                opti.subject_to((tip - target) / length == 0)
            else:
                opti.subject_to(ca.sumsqr(tip - target) / reach**2 <= 1)
        # the equilibrium in the scaled residual units of softcurve.analysis.solver
        unit = coordinate_scale(model.robot) / residual_reference(model)
        opti.subject_to(unit * residual == 0)
        opti.subject_to(opti.bounded(lower / scale, u / scale, upper / scale))
        opti.subject_to(opti.bounded(bounds[:, 0], q, bounds[:, 1]))
        # no bound relaxation: inputs at a bound stay inside it (IPOPT's default leaves
        # them 1e-8 of the bound outside)
        options = {"print_level": 0, "sb": "yes", "max_iter": max_iterations, "tol": 1e-12}
        opti.solver("ipopt", {"print_time": False, "expand": True}, {**options, IPOPT_RELAX: 0.0})
        self.opti, self.q, self.u = opti, q, u

    def solve(self, q0, u0) -> tuple:
        """``(ranking key, equilibrium, inputs, IPOPT status)`` from the start ``(q0, u0)``;
        the key orders by converged, stable, then distance to the target."""
        opti, actuator = self.opti, self.actuator
        opti.set_initial(self.q, q0)
        opti.set_initial(self.u, u0)
        try:
            solution = opti.solve()
            stats = solution.stats()
            q_opt, u_opt = solution.value(self.q), solution.value(self.u)
        except RuntimeError:
            stats = opti.stats()
            q_opt, u_opt = opti.debug.value(self.q), opti.debug.value(self.u)
        u_opt = actuator.clip(np.atleast_1d(u_opt))
        near = BOUND_SNAP * (actuator.upper - actuator.lower)
        u_opt = np.where(u_opt <= actuator.lower + near, actuator.lower, u_opt)
        u_opt = np.where(u_opt >= actuator.upper - near, actuator.upper, u_opt)
        q_opt = np.atleast_1d(q_opt)
        e = equilibrium(self.model, q_opt, actuator=actuator, inputs=u_opt, **self.loads)
        distance = float(np.linalg.norm(e.tip_position - self.target))
        key = (not e.success, e.stability != "stable", distance)
        return key, e, u_opt, stats.get("return_status", "unknown")


def inverse_statics(
    model,
    actuator: Actuator,
    target,
    *,
    starts: int = 3,
    max_iterations: int = 200,
    tolerance: float = 1e-6,
    redundancy: str = "minimum_total",
    **loads,
) -> InverseStatics:
    """The bounded actuator inputs that put the tip closest to ``target`` at equilibrium.

    **Stage 1** solves ``min |p_tip(q) - target|^2`` over ``(q, u)`` subject to the
    equilibrium ``N(q) = H(q) u + other loads``, ``lower <= u <= upper`` and ``q`` within
    :func:`~softcurve.analysis.statics.default_bounds`, from ``starts`` initial guesses
    (IPOPT, exact derivatives), keeping the stable solution closest to the target when
    there is one; its distance is ``d*``.

    **Stage 2** (``redundancy="minimum_total"``, the default) resolves redundant inputs.
    With more inputs than the tip has coordinates (two segments with three tendons each:
    six tensions for a 3-D target) many inputs reach ``d*``. The rule: among the inputs
    whose tip is within ``d* + tolerance * l0`` of the target (``l0`` the rest length of
    the whole robot), those of least total
    input above the lower bounds, ``sum(u - lower)`` (for tendons the least total
    tension above the pretensions ``t_min``, for bellows the least total pressure above
    ``p_min``). It is solved as a second IPOPT problem, ``min sum(u - lower)`` under the
    equilibrium, the bounds and ``|p_tip - target| <= d* + tolerance * l0`` (when the
    target is reached, ``d* <= tolerance * l0``, the tip is held on it: ``p_tip =
    target``), started from every stage-1 solution within that reach. A stage-2 solution
    replaces the stage-1 one when IPOPT converged and the equilibrium re-solved at its
    inputs is within the reach (to ``REACH_SLACK``); among them the stable one of least
    total wins. Where the inputs are not redundant the set is one point and stage 2 keeps
    it. Like stage 1 it is local: the least total found from these starts.
    ``redundancy="none"`` returns the stage-1 inputs.

    The equilibrium is re-solved at the chosen inputs (put on a bound when within
    ``BOUND_SNAP`` of their range from it) and classified.

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
        IPOPT iteration budget per start and stage.
    tolerance : float
        A tip closer than ``tolerance`` times the robot's rest length to the target
        reaches it (dimensionless); farther is INFEASIBLE. Also the slack of stage 2.
    redundancy : str
        ``"minimum_total"`` or ``"none"`` (above); the result's ``rule`` says which.
    **loads
        Further loads (``gravity``, ``tip_force``...; not ``inputs``).
    """
    target = real_array("target", target, (3,))
    tolerance = real_scalar("tolerance", tolerance, positive=True)
    if redundancy not in REDUNDANCY_RULES:
        raise ParameterError(f"redundancy must be one of {REDUNDANCY_RULES}, got {redundancy!r}")
    if "inputs" in loads or "actuator" in loads:
        raise ParameterError("inverse_statics chooses the actuator inputs: do not pass them")
    length = model.robot.rest_length
    stage1 = _Program(model, actuator, target, loads, max_iterations)
    middle = 0.5 * (actuator.lower + actuator.upper)
    found = [stage1.solve(guess, middle) for guess in _guesses(model, target, starts)]
    best = min(found, key=lambda c: c[0])
    (key, e, u_opt, ipopt_status), note = best, "none (the first stage's inputs)"
    if redundancy == "minimum_total" and e.success:
        reach = key[2] + tolerance * length  # held on the target (0) when it is reached
        stage2 = _Program(
            model, actuator, target, loads, max_iterations, reach * (key[2] > tolerance * length)
        )
        chosen = (key[:2], float(np.sum(u_opt - actuator.lower)), best)
        for start in found:
            if start[0][0] or start[0][2] > reach:  # not an equilibrium, or out of reach
                continue
            candidate = stage2.solve(start[1].q, start[2])
            (failed, unstable, distance), _, u, status = candidate
            if status in IPOPT_SOLVED and distance <= reach * (1 + REACH_SLACK):
                rank = ((failed, unstable), float(np.sum(u - actuator.lower)), candidate)
                if rank[:2] < chosen[:2]:
                    chosen = rank
        key, e, u_opt, ipopt_status = chosen[2]
        note = f"minimum total {actuator.input_name} above the lower bounds"
        if chosen[2] is best:
            note += " (no second-stage solution of lower total: the first stage's inputs)"
    distance, total = key[2], float(np.sum(u_opt - actuator.lower))
    saturated = (u_opt <= actuator.lower) | (u_opt >= actuator.upper)
    status = _status(e, ipopt_status, distance, tolerance * length)
    unit = f" {actuator.input_unit}" if actuator.input_unit else ""
    message = (
        f"IPOPT: {ipopt_status}; tip {1e3 * distance:.3g} mm from the target; equilibrium "
        f"{e.stability}; {int(saturated.sum())} input(s) at a bound; redundancy: {note}, "
        f"total {total:.6g}{unit}"
    )
    if status is Status.INFEASIBLE:
        message += "; the target is out of reach within the input bounds"
    if status is Status.LEFT_DOMAIN:  # the equilibrium's own domain check says where
        message += f"; {e.message}"
    return InverseStatics(
        inputs=u_opt,
        q=e.q,
        tip=e.tip_position,
        target=target,
        distance=distance,
        stability=e.stability,
        saturated=saturated,
        rule=redundancy,
        total=total,
        status=status,
        message=message,
    )
