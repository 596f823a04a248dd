"""Quasi-static maps of a pressure-driven robot: pressure sweeps and inverse statics.

A *pressure sweep* follows the equilibrium ``N(q) = H(q) p`` (plus any other load of
:class:`~softcurve.loads.StaticLoad`) along a path of pressures by continuation:
each point starts Newton's method from the previous one, so the branch is followed
and its stability is tracked (compare the paper's Fig. 3, which maps pressure to
deformation through the fitted stiffness). *Inverse statics* finds the bounded
pressures that put the tip closest to a target point, as the nonlinear program
``min |p_tip(q) - target|^2`` subject to the equilibrium and the pressure bounds,
solved by IPOPT on the exact CasADi derivatives.
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
from softcurve.base.validation import ParameterError, real_array
from softcurve.description.actuators import Actuator


@dataclass(frozen=True, eq=False)
class PressureSweep:
    """Equilibria along a path of pressures.

    Attributes
    ----------
    pressures : ndarray, shape (k, m)
        [Pa].
    q : ndarray, shape (k, n)
    tip : ndarray, shape (k, 3)
        World tip positions [m].
    converged : ndarray, shape (k,), bool
    stability : tuple of str
        Classification of each point (see :mod:`softcurve.statics`).
    status, message : str
        ``"ok"`` when every point converged, else ``"failed"`` and where.
    """

    pressures: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    converged: np.ndarray
    stability: tuple[str, ...]
    status: str
    message: str

    @property
    def curvature(self) -> np.ndarray:
        """Net curvature (k, N) [1/m] of each segment."""
        return np.hypot(self.q[:, 1::3], self.q[:, 2::3])

    def plot(self, abscissa=None, label: str = "pressure [kPa]"):
        """Tip position and curvature against ``abscissa`` (default: the pressure that
        varies most, in kPa); returns the Matplotlib figure."""
        import matplotlib.pyplot as plt

        if abscissa is None:
            column = int(np.argmax(np.ptp(self.pressures, axis=0)))
            abscissa = self.pressures[:, column] / 1e3
            label = f"p{column + 1} [kPa]"
        fig, (ax_tip, ax_k) = plt.subplots(1, 2, figsize=(9, 3.5), constrained_layout=True)
        for i, name in enumerate("xyz"):
            ax_tip.plot(abscissa, 1e3 * self.tip[:, i], label=f"tip {name}")
        ax_tip.set_xlabel(label)
        ax_tip.set_ylabel("tip position [mm]")
        ax_tip.legend()
        for j in range(self.curvature.shape[1]):
            ax_k.plot(abscissa, self.curvature[:, j], label=f"segment {j}")
        unstable = np.array([s != "stable" for s in self.stability])
        if unstable.any():
            ax_k.plot(abscissa[unstable], self.curvature[unstable, 0], "rx", label="not stable")
        ax_k.set_xlabel(label)
        ax_k.set_ylabel("curvature |kappa| [1/m]")
        ax_k.legend()
        return fig


def pressure_sweep(model, actuator: Actuator, pressures, *, q_start=None, **loads):
    """Follow the equilibrium along ``pressures`` (k, m) by continuation.

    Parameters
    ----------
    model : Model
    actuator : Actuator
    pressures : array_like, shape (k, m)
        Path of pressures [Pa], within the bounds.
    q_start : array_like, shape (n,), optional
        Guess for the first point (default: the rest configuration).
    **loads
        Further loads of :class:`~softcurve.loads.StaticLoad` (``gravity``, ``tip_force``...).
    """
    pressures = np.asarray(pressures, dtype=np.float64)
    if pressures.ndim != 2 or pressures.shape[1] != actuator.n_inputs:
        raise ParameterError(
            f"pressures must have shape (k, {actuator.n_inputs}), got {pressures.shape}"
        )
    q = (
        rest_configuration(model.robot)
        if q_start is None
        else real_array("q_start", q_start, (model.n,))
    )
    qs, tips, converged, stability = [], [], [], []
    for p in pressures:
        e = equilibrium(model, q, actuator=actuator, pressures=p, **loads)
        if e.converged:
            q = e.q
        qs.append(e.q)
        tips.append(e.tip_position)
        converged.append(e.converged)
        stability.append(e.stability)
    converged = np.array(converged)
    failed = np.flatnonzero(~converged)
    message = (
        f"{len(pressures)} equilibria followed"
        if not failed.size
        else f"{failed.size} of {len(pressures)} points did not converge (first: {failed[0]})"
    )
    return PressureSweep(
        pressures=pressures,
        q=np.array(qs),
        tip=np.array(tips),
        converged=converged,
        stability=tuple(stability),
        status="ok" if not failed.size else "failed",
        message=message,
    )


@dataclass(frozen=True, eq=False)
class InverseStatics:
    """Bounded pressures whose equilibrium puts the tip closest to a target.

    Attributes
    ----------
    pressures : ndarray, shape (m,)
        [Pa], within the actuator's bounds.
    q : ndarray, shape (n,)
        The equilibrium they produce.
    tip : ndarray, shape (3,)
        Its tip position [m]; ``target`` the point asked for.
    distance : float
        ``|tip - target|`` [m].
    stability : str
        Of the equilibrium, see :mod:`softcurve.statics`.
    saturated : ndarray, shape (m,), bool
        Pressures at a bound (a target beyond reach saturates some).
    status : str
        ``"ok"``, or ``"failed"`` when IPOPT failed or the equilibrium did not verify.
    message : str
    """

    pressures: np.ndarray
    q: np.ndarray
    tip: np.ndarray
    target: np.ndarray
    distance: float
    stability: str
    saturated: np.ndarray
    status: str
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


def inverse_statics(
    model, actuator: Actuator, target, *, starts: int = 3, max_iterations: int = 200, **loads
) -> InverseStatics:
    """The bounded pressures that put the tip closest to ``target`` at equilibrium.

    Solves ``min |p_tip(q) - target|^2`` over ``(q, p)`` subject to the equilibrium
    ``N(q) = H(q) p + other loads``, ``lower <= p <= upper`` and ``q`` within
    :func:`~softcurve.statics.default_bounds`, from ``starts`` initial guesses (IPOPT,
    exact derivatives), keeping the stable solution closest to the target when there is
    one. The equilibrium is then re-solved at the optimal pressures and classified.

    Parameters
    ----------
    model : Model
    actuator : Actuator
    target : array_like, shape (3,)
        World point [m].
    starts : int
        Number of initial guesses (rest, then arcs bending toward the target).
    max_iterations : int
        IPOPT iteration budget per start.
    **loads
        Further loads (``gravity``, ``tip_force``...; not ``pressures``).
    """
    target = real_array("target", target, (3,))
    if "pressures" in loads or "actuator" in loads:
        raise ParameterError("inverse_statics chooses the pressures: do not pass them")
    load = StaticLoad(
        model, actuator=actuator, pressures=actuator.clip(np.zeros(actuator.n_inputs)), **loads
    )
    function = static_function(model, actuator)
    bounds = default_bounds(model.robot)
    args = load.arguments()

    opti = ca.Opti()
    q, p = opti.variable(model.n), opti.variable(actuator.n_inputs)
    scale = np.maximum(np.abs(actuator.upper), np.abs(actuator.lower))
    residual, _, _, tip = function(q, args[0], args[1], p, args[3], args[4])
    length = model.robot.rest_length
    opti.minimize(ca.sumsqr(tip - target) / length**2)
    # the equilibrium in the scaled residual units of softcurve.statics
    unit = coordinate_scale(model.robot) / residual_reference(model)
    opti.subject_to(unit * residual == 0)
    opti.subject_to(opti.bounded(actuator.lower / scale, p / scale, actuator.upper / scale))
    opti.subject_to(opti.bounded(bounds[:, 0], q, bounds[:, 1]))
    opti.solver(
        "ipopt",
        {"print_time": False, "expand": True},
        {"print_level": 0, "sb": "yes", "max_iter": max_iterations, "tol": 1e-12},
    )
    best = None
    for guess in _guesses(model, target, starts):
        opti.set_initial(q, guess)
        opti.set_initial(p, 0.5 * (actuator.lower + actuator.upper))
        try:
            solution = opti.solve()
            stats = solution.stats()
            q_opt, p_opt = solution.value(q), solution.value(p)
        except RuntimeError:
            stats = opti.stats()
            q_opt, p_opt = opti.debug.value(q), opti.debug.value(p)
        p_opt = actuator.clip(np.atleast_1d(p_opt))
        e = equilibrium(model, np.atleast_1d(q_opt), actuator=actuator, pressures=p_opt, **loads)
        candidate = (
            not e.converged,
            e.stability != "stable",
            float(np.linalg.norm(e.tip_position - target)),
            e,
            p_opt,
            stats.get("return_status", "unknown"),
        )
        if best is None or candidate[:3] < best[:3]:
            best = candidate
    _, _, distance, e, p_opt, ipopt_status = best
    ok = e.converged and ipopt_status in ("Solve_Succeeded", "Solved_To_Acceptable_Level")
    saturated = (p_opt <= actuator.lower) | (p_opt >= actuator.upper)
    message = (
        f"IPOPT: {ipopt_status}; tip {1e3 * distance:.3g} mm from the target; equilibrium "
        f"{e.stability}; {int(saturated.sum())} pressure(s) at a bound"
    )
    return InverseStatics(
        pressures=p_opt,
        q=e.q,
        tip=e.tip_position,
        target=target,
        distance=distance,
        stability=e.stability,
        saturated=saturated,
        status="ok" if ok else "failed",
        message=message,
    )
