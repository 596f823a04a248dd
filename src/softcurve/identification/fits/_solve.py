"""Bounded least squares that survives points where the model cannot be evaluated.

SciPy's trust-region reflective method (``scipy.optimize.least_squares``, ``"trf"``)
with an exact Jacobian does the work. A trial point where the model cannot be evaluated
(the equilibrium solver or the integrator fails, or the residuals are not finite) is a
*rejected step*: the run stops there and starts again from the best point found so far
confined to a box around it whose half-width is a quarter of the failed step's length
(an outer trust region: a run that stops at the box's edge starts again from there with
a box :data:`GROW` times larger). This repeats until the solver converges inside its
box, the budget of evaluations runs out, or the half-width falls below
:data:`SMALLEST_RADIUS`. A worker process that dies
(:class:`~softcurve.simulation.batch.WorkerDied`) is no rejected step but the end of
the run, with status ``INTERRUPTED``. The result is always the best point evaluated.

:func:`multi_start` runs the same from several seeded starting points (uniform within
finite bounds, else perturbations of the given start) and keeps every optimum, so the
report can show how far apart they are.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import scipy.optimize

from softcurve.base.status import Status
from softcurve.simulation.batch import WorkerDied

EVALUATION_ERRORS = (RuntimeError, FloatingPointError, ArithmeticError, np.linalg.LinAlgError)
"""What a model evaluation raises when the point cannot be evaluated: CasADi's
integrator and the equilibrium solver raise RuntimeError, linear algebra
LinAlgError, non-finite residuals FloatingPointError."""

SHRINK = 0.25
"""Trust radius after a failed trial point, as a fraction of that step's length (the
classical trust-region contraction of a rejected step)."""

GROW = 4.0
"""Growth of the box when a run after a rejected step stops at the box's edge (the
inverse of :data:`SHRINK`: back to the failed step's length in one go)."""

EDGE = 1e-9
"""Relative distance from the box's edge under which a run stopped at it."""

SMALLEST_RADIUS = 1e-8
"""Below this radius (of the scaled variables, whose typical size is 1) the failures are
at the best point itself: the fit stops with NOT_CONVERGED."""

PERTURBATION = 0.5
"""Relative size of the random perturbation of unbounded parameters in a multi-start
(scaled variables: +-50 % of the start, or +-0.5 for a start at zero)."""

TOLERANCE = 1e-10
"""SciPy's ``xtol``, ``ftol`` and ``gtol``: tight, so that fits stop on the cost's
curvature rather than early (the validated fits in ``tests/test_identify.py``)."""


RESIDUAL_SHARE = 0.14
"""The cost of the residuals alone relative to the residuals with the Jacobian, where a
model gives both (``robust_least_squares(residual=...)``): a trajectory fit's outputs
without the sensitivities on the paper robot, 7.2 to 9.9 times cheaper at rtol 1e-8 to
1e-4 (``python benchmarks/study_sensitivity_driver.py``). Evaluating a trial point by
its residuals first pays where the solver rejects more than this share of its points;
where it steps to more, a point is evaluated with its Jacobian at once."""

SETTLED = 1e-3
"""A fit at a best point whose Gauss-Newton step would move every parameter by less than
this many of its standard errors has converged (status SUCCESS), whatever SciPy's
tolerances say: a thousandth of a standard error is far below what the data resolve,
while a fit along a flat valley, or on residuals with the integrator's rounding in them,
would otherwise creep on until its budget ran out and look unfinished
(``tests/test_identification_robust.py``). The full step, not the step taken, is the
test: a step the trust region has shortened says nothing about convergence."""


def standard_errors(jacobian: np.ndarray, residuals: np.ndarray) -> np.ndarray:
    """Asymptotic standard errors ``sqrt(diag(s^2 (J^T J)^+))`` (large along a direction
    the data do not determine), shape (P,).

    Parameters
    ----------
    jacobian : ndarray, shape (N, P)
        Jacobian of the residuals.
    residuals : ndarray, shape (N,)
        The residuals.
    """
    n, p = jacobian.shape
    s2 = float(residuals @ residuals) / max(n - p, 1)
    return np.sqrt(s2 * np.abs(np.diag(np.linalg.pinv(jacobian.T @ jacobian))))


class _Settled(Exception):
    """The Gauss-Newton step from the best point is below ``settle`` standard errors in
    every parameter: converged."""


class _Stopped(Exception):
    """The evaluation cannot go on (a worker process died): end the fit, keep the best."""


class _Failed(Exception):
    """A trial point could not be evaluated."""

    def __init__(self, z, reason):
        super().__init__(reason)
        self.z, self.reason = z, reason


@dataclass(frozen=True)
class Solution:
    """The best point of a robust least-squares run.

    Attributes
    ----------
    z : ndarray, shape (P,)
        Best point (scaled variables).
    residuals : ndarray, shape (N,) or None
        Residuals there (None when no point could be evaluated).
    jacobian : ndarray, shape (N, P) or None
        Jacobian there.
    status : Status
        SUCCESS, EVALUATION_LIMIT or NOT_CONVERGED.
    message : str
        What happened, including rejected points.
    n_evaluations : int
        Residual evaluations (failed ones included).
    rejected : int
        Trial points that could not be evaluated.
    n_jacobians : int
        Evaluations with the Jacobian (failed ones included): all of them without
        ``residual``, those of the accepted points with it.
    """

    z: np.ndarray
    residuals: np.ndarray | None
    jacobian: np.ndarray | None
    status: Status
    message: str
    n_evaluations: int
    rejected: int
    n_jacobians: int = 0

    @property
    def cost(self) -> float:
        """Half the sum of squared residuals (inf when nothing was evaluated)."""
        if self.residuals is None:
            return np.inf
        return 0.5 * float(self.residuals @ self.residuals)


def robust_least_squares(
    residual_and_jacobian,
    z0,
    lower,
    upper,
    max_evaluations,
    on_evaluation=None,
    on_best=None,
    gtol: float | None = TOLERANCE,
    settle: float | None = None,
    residual=None,
) -> Solution:
    """Minimize ``|r(z)|^2 / 2`` within bounds, a failed evaluation being a rejected step.

    Parameters
    ----------
    residual_and_jacobian : callable
        ``f(z) -> (r (N,), J (N, P))``; raises one of :data:`EVALUATION_ERRORS` (or
        returns non-finite values) where the model cannot be evaluated, and
        :class:`~softcurve.simulation.batch.WorkerDied` where it can no longer be
        evaluated at all (the run ends, status ``INTERRUPTED``).
    z0 : array_like, shape (P,)
        Starting point (scaled, dimensionless), clipped into the bounds.
    lower, upper : ndarray, shape (P,)
        Bounds on ``z``.
    max_evaluations : int
        Budget of residual evaluations, failed ones included.
    on_evaluation : callable, optional
        Called with the number of evaluations so far after each one (progress).
    on_best : callable, optional
        Called without arguments right after an evaluation that became the best point
        (to keep what else was computed there).
    gtol : float or None
        SciPy's ``gtol``, a tolerance on the gradient ``J^T r`` (dimensionless: absolute
        in the residuals' own units, unlike ``xtol`` and ``ftol``); None stops on the step
        and the cost only, for residuals whose size says nothing about convergence (residuals of
        clean data are small everywhere near the solution).
    settle : float, optional
        Stop, converged, at a new best point from which the Gauss-Newton step
        ``-J^+ r`` would move every variable by less than ``settle`` times its standard
        error there (:func:`standard_errors`; e.g. :data:`SETTLED`); None: SciPy's
        tests alone.
    residual : callable, optional
        ``r(z) -> r (N,)``, the residuals alone, for a fraction (:data:`RESIDUAL_SHARE`)
        of the cost of ``residual_and_jacobian`` (raising as it does). Given, a trial
        point is evaluated by it, and with the Jacobian only if the solver steps there
        (SciPy asks for no other): a rejected point costs that fraction instead of a
        whole evaluation. While the solver has stepped to more than ``1 -
        RESIDUAL_SHARE`` of the points so far (counted from one of one), the points are
        evaluated with the Jacobian at once. None: every point is evaluated with it.

    Returns
    -------
    Solution
        The best point evaluated, with status and message.
    """
    lower, upper = np.asarray(lower, np.float64), np.asarray(upper, np.float64)
    z0 = np.clip(np.asarray(z0, dtype=np.float64), lower, upper)
    best: list = [None]  # (cost, z, r, J)
    cache: dict = {}
    count = jacobians = 0
    # points evaluated for their residuals, those the solver then stepped to, and the
    # last of them until the solver steps there or moves on
    tried = stepped = 0
    pending = None

    def evaluate(z, jacobian=True):
        """``(r, J)`` at ``z``; ``J`` may be None for ``jacobian=False`` with
        ``residual``. A point evaluated without its Jacobian and then asked for it is
        evaluated again, with it, counted once in the budget (the residuals are the same
        to the model's tolerance)."""
        nonlocal count, jacobians, tried, stepped, pending
        key = z.tobytes()
        stepped += jacobian and key == pending
        pending = None
        if best[0] is not None and key == best[0][1].tobytes():
            return best[0][2], best[0][3]
        if key in cache and (cache[key][1] is not None or not jacobian):
            return cache[key]
        fresh = key not in cache
        count += fresh
        if residual is None:
            jacobian = True
        elif fresh and not jacobian:
            tried += 1
            pending = key
            # with the Jacobian at once where the solver has stepped to most points so
            # far: a point it steps to costs the residuals twice otherwise
            jacobian = count == 1 or (stepped + 1) / (tried + 1) > 1.0 - RESIDUAL_SHARE
        try:
            if jacobian:
                jacobians += 1
                r, jac = residual_and_jacobian(z)
            else:
                r, jac = residual(z), None
            if not (np.all(np.isfinite(r)) and (jac is None or np.all(np.isfinite(jac)))):
                raise FloatingPointError("the model returned non-finite residuals")
        except WorkerDied as exc:  # a RuntimeError, but the machine's fault, not the point's
            raise _Stopped(str(exc)) from None
        except EVALUATION_ERRORS as exc:
            raise _Failed(z.copy(), str(exc).strip().splitlines()[-1][:300]) from None
        finally:
            if on_evaluation is not None:
                on_evaluation(count)
        cache.clear()
        cache[key] = (r, jac)
        cost = 0.5 * float(r @ r)
        if jac is not None and (best[0] is None or cost < best[0][0]):
            best[0] = (cost, z.copy(), r, jac)
            if on_best is not None:
                on_best()
            if settle is not None:
                step = np.linalg.lstsq(jac, -r, rcond=None)[0]
                inside = np.all((z + step >= lower) & (z + step <= upper))
                if inside and np.all(np.abs(step) < settle * standard_errors(jac, r)):
                    raise _Settled
        return r, jac

    rejected, radius, reasons = 0, None, []
    status, message = Status.NOT_CONVERGED, ""
    while count < max_evaluations:
        # First run: from z0 within the bounds. After a rejected step: from the best
        # point within a box of half-width ``radius`` around it (an outer trust region).
        start = z0 if radius is None else best[0][1]
        lo = lower if radius is None else np.maximum(lower, start - radius)
        hi = upper if radius is None else np.minimum(upper, start + radius)
        try:
            result = scipy.optimize.least_squares(
                lambda z: evaluate(z, jacobian=False)[0],
                start,
                jac=lambda z: evaluate(z)[1],
                bounds=(lo, hi),
                method="trf",
                max_nfev=max(max_evaluations - count, 1),
                x_scale=1.0,
                xtol=TOLERANCE,
                ftol=TOLERANCE,
                gtol=gtol,
            )
        except _Stopped as stop:
            status, message = Status.INTERRUPTED, f"stopped: {stop}"
            break
        except _Settled:
            status = Status.SUCCESS
            message = (
                f"the next Gauss-Newton step would move every parameter by less than "
                f"{settle:g} of its standard error"
            )
            break
        except _Failed as failure:
            rejected += 1
            reasons.append(failure.reason)
            if best[0] is None:
                message = f"the model cannot be evaluated at the starting values: {failure.reason}"
                break
            step = float(np.max(np.abs(failure.z - best[0][1])))
            radius = SHRINK * (step if step > 0 else (radius or 1.0))
            if radius < SMALLEST_RADIUS:
                message = f"the model cannot be evaluated next to the best point: {failure.reason}"
                break
            continue
        z = best[0][1]
        edge = (lo > lower) & (z <= lo + EDGE * np.maximum(1.0, np.abs(z)))
        edge |= (hi < upper) & (z >= hi - EDGE * np.maximum(1.0, np.abs(z)))
        if result.status >= 0 and radius is not None and edge.any():
            radius *= GROW  # stopped at the edge of the box, not at a minimum: go on
            continue
        if result.status > 0:
            status, message = Status.SUCCESS, str(result.message)
        else:
            status = Status.EVALUATION_LIMIT if result.status == 0 else Status.NOT_CONVERGED
            message = str(result.message)
        break
    else:
        status, message = Status.EVALUATION_LIMIT, "the budget of evaluations ran out"
    if rejected:
        message += (
            f"; {rejected} trial point(s) could not be evaluated and were rejected "
            f"(the last: {reasons[-1]})"
        )
    if best[0] is None:
        if not message:
            message = "no point could be evaluated"
        if status is not Status.INTERRUPTED:
            status = Status.NOT_CONVERGED
        return Solution(z0, None, None, status, message, count, rejected, jacobians)
    _, z, r, jac = best[0]
    return Solution(z, r, jac, status, message, count, rejected, jacobians)


def starting_points(z0, lower, upper, starts: int, seed) -> np.ndarray:
    """``starts`` starting points: ``z0`` first, then seeded random ones.

    A parameter with finite bounds is drawn uniformly between them, one without is
    ``z0`` perturbed by :data:`PERTURBATION` of its size (then clipped into its bounds).

    Parameters
    ----------
    z0 : ndarray, shape (P,)
        The given start (scaled variables).
    lower, upper : ndarray, shape (P,)
        Bounds on the scaled variables.
    starts : int
        Number of points (>= 1).
    seed : int or None
        Seed of NumPy's random generator.

    Returns
    -------
    ndarray, shape (starts, P)
    """
    rng = np.random.default_rng(seed)
    points = [np.asarray(z0, dtype=np.float64)]
    finite = np.isfinite(lower) & np.isfinite(upper)
    size = np.where(z0 != 0, np.abs(z0), 1.0)
    for _ in range(starts - 1):
        uniform = np.where(finite, lower, 0.0) + np.where(finite, upper - lower, 0.0) * rng.random(
            z0.size
        )
        perturbed = z0 + PERTURBATION * size * rng.uniform(-1.0, 1.0, z0.size)
        points.append(np.clip(np.where(finite, uniform, perturbed), lower, upper))
    return np.array(points)
