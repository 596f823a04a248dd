"""The one equilibrium solver of the package: ``r(q) = 0`` in scaled coordinates.

Equilibria (:mod:`softcurve.analysis.statics`), quasi-static maps and the equilibrium
fits of :mod:`softcurve.identification` all solve their static balance here.
Coordinates are scaled to ``z = q / S`` with ``S = (l0, 1/l0, 1/l0)`` per segment
(:func:`~softcurve.analysis.loads.coordinate_scale`) and residuals to ``S r / reference``,
``reference`` the elastic stiffness of each scaled coordinate at rest [J]
(:func:`~softcurve.analysis.loads.residual_reference`): both are then dimensionless and of
order one, and one tolerance fits every robot.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from softcurve.base.docs import parameters_from
from softcurve.base.status import Status

POLISH_STEPS = 2
"""Newton steps after MINPACK's hybrid method: from where it stops, Newton converges
quadratically, so two steps reach round-off."""

STEP_TOLERANCE = 1e-13
"""Relative step tolerance of the hybrid method; the residual test below decides."""

BATCH_NEWTON_STEPS = 6
"""Newton steps of :func:`solve_equilibria` on all columns before solving the rest alone."""

CHORD_STEPS = 16
"""At most this many chord steps (:func:`solve_equilibria` with ``jacobians``) before
Newton's method takes over."""

CHORD_CONTRACTION = 0.5
"""A chord step must shrink every unconverged column's scaled residual by this factor, or
Newton's method takes over (the given Jacobians are then too far from the solutions')."""

MINPACK_EVALUATION_LIMIT = 2
"""``scipy.optimize.root(method="hybr")`` status: the evaluation budget ran out."""


@dataclass(frozen=True)
class Root:
    """What :func:`solve_equilibrium` found (internal to the analyses).

    Attributes
    ----------
    q : ndarray, shape (n,)
        The last iterate [m, 1/m, 1/m].
    status : Status
        SUCCESS, EVALUATION_LIMIT or NOT_CONVERGED.
    message : str
        The scaled residual against the tolerance.
    """

    q: np.ndarray
    status: Status
    message: str

    @property
    def converged(self) -> bool:
        """Whether the scaled residual met the tolerance."""
        return self.status is Status.SUCCESS


_scaling_parameters = parameters_from(
    {
        "scale": ("ndarray, shape (n,)", "``S``: ``q / S`` is dimensionless."),
        "reference": (
            "ndarray, shape (n,)",
            "Unit of the scaled residual ``S r`` [J], per coordinate.",
        ),
    }
)


@_scaling_parameters
def solve_equilibrium(
    system: Callable,
    q0,
    *,
    scale: np.ndarray,
    reference: np.ndarray,
    tol: float,
    max_evaluations: int,
) -> Root:
    """Solve ``r(q) = 0`` from ``q0``: MINPACK's hybrid method in the scaled variables,
    then Newton polishing.

    Parameters
    ----------
    system : callable
        ``system(q) -> (r, K)``: the residual (n,) [N, N m^2] and its Jacobian
        ``K = dr/dq`` (n, n).
    q0 : array_like, shape (n,)
        Initial guess [m, 1/m, 1/m].
    %(scale)s
    %(reference)s
    tol : float
        Acceptance: ``max |S r / reference| <= tol`` (dimensionless).
    max_evaluations : int
        Budget of residual evaluations of the hybrid method.
    """

    def scaled(z):
        r, k = system(z * scale)
        return scale * r / reference, (scale[:, None] * k * scale[None, :]) / reference[:, None]

    solution = scipy.optimize.root(
        scaled,
        np.asarray(q0, dtype=np.float64) / scale,
        jac=True,
        method="hybr",
        options={"maxfev": max_evaluations, "xtol": STEP_TOLERANCE},
    )
    q = solution.x * scale
    for _ in range(POLISH_STEPS):
        r, k = system(q)
        step = np.linalg.lstsq(k, r, rcond=None)[0]
        if not np.all(np.isfinite(step)):
            break
        q = q - step
    r, _ = system(q)
    residual = float(np.max(np.abs(scale * r / reference)))
    converged = bool(np.isfinite(residual) and residual <= tol)
    message = f"scaled residual {residual:.1e} ({'<=' if converged else '>'} tol {tol:.0e})"
    if converged:
        status = Status.SUCCESS
    elif solution.status == MINPACK_EVALUATION_LIMIT:
        status = Status.EVALUATION_LIMIT
        message += f" after {max_evaluations} evaluations"
    else:
        status = Status.NOT_CONVERGED
    return Root(q=q, status=status, message=message)


@_scaling_parameters
def solve_equilibria(
    batch_system: Callable,
    system_of: Callable,
    q0,
    *,
    scale: np.ndarray,
    reference: np.ndarray,
    tol: float,
    max_evaluations: int,
    jacobians=None,
    batch_residual: Callable | None = None,
) -> list[Root]:
    """Many independent equilibria at once, one per column of ``q0``.

    Newton's method runs on all columns together, one batched evaluation per step (the
    columns are usually close to their solutions, e.g. the previous solutions of a
    fit); every column it does not bring within ``tol`` is solved alone by
    :func:`solve_equilibrium` from its own start. The acceptance test is the same.

    With ``jacobians`` near the solutions' (a fit's previous evaluation) and
    ``batch_residual``, chord steps come first: those Jacobians in every step and
    residuals only, a fraction of the cost of a residual with its Jacobian (a fifth on
    one ifac2020 segment and on three, in CasADi's virtual machine). Newton's method
    takes over from where they stop converging (:data:`CHORD_CONTRACTION`). (From a far
    start, as a fit's first guess, the Jacobians there contract too slowly to pay.)

    Parameters
    ----------
    batch_system : callable
        ``batch_system(Q) -> (R, K)`` for ``Q`` (n, T): residuals ``R`` (n, T) and
        Jacobians ``K`` (T, n, n).
    system_of : callable
        ``system_of(j)`` is column ``j``'s ``system(q) -> (r, K)``.
    q0 : array_like, shape (n, T)
        Initial guesses [m, 1/m, 1/m].
    %(scale)s
    %(reference)s
    tol : float
        Acceptance: ``max |S r / reference| <= tol`` per column (dimensionless).
    max_evaluations : int
        Budget of residual evaluations of each single solve.
    jacobians : ndarray, shape (T, n, n), optional
        Jacobians ``dR/dQ`` for the chord steps, one per column.
    batch_residual : callable, optional
        ``batch_residual(Q) -> R``, with ``jacobians``.
    """
    start = np.array(q0, dtype=np.float64)
    q = start.copy()
    if jacobians is not None and batch_residual is not None:
        met = _chord(batch_residual, jacobians, q, scale, reference, tol)
        if met is not None:
            return [_accepted(q[:, j], residual, tol) for j, residual in enumerate(met)]
    done = np.zeros(q.shape[1], dtype=bool)
    for step in range(BATCH_NEWTON_STEPS + 1):
        r, k = batch_system(q)
        residual = _residuals(r, scale, reference)
        done = np.isfinite(residual) & (residual <= tol)
        if done.all() or step == BATCH_NEWTON_STEPS:
            break
        todo = np.flatnonzero(~done & np.all(np.isfinite(r), axis=0))
        try:
            q[:, todo] -= np.linalg.solve(k[todo], r[:, todo].T[..., None])[..., 0].T
        except np.linalg.LinAlgError:
            break
    roots = []
    for j in range(q.shape[1]):
        if done[j]:
            roots.append(_accepted(q[:, j], residual[j], tol))
        else:
            roots.append(
                solve_equilibrium(
                    system_of(j),
                    start[:, j],
                    scale=scale,
                    reference=reference,
                    tol=tol,
                    max_evaluations=max_evaluations,
                )
            )
    return roots


def _residuals(r: np.ndarray, scale: np.ndarray, reference: np.ndarray) -> np.ndarray:
    """Scaled residual per column, ``max_i |S_i r_i / reference_i|`` (NaN stays NaN)."""
    with np.errstate(invalid="ignore"):
        return np.max(np.abs(scale[:, None] * r / reference[:, None]), axis=0)


def _accepted(q: np.ndarray, residual: float, tol: float) -> Root:
    """The root at column ``q`` (n,), accepted with its scaled ``residual``."""
    message = f"scaled residual {residual:.1e} (<= tol {tol:.0e})"
    return Root(q=q.copy(), status=Status.SUCCESS, message=message)


def _chord(batch_residual, jacobians, q, scale, reference, tol) -> np.ndarray | None:
    """Chord steps on ``q`` (n, T), in place, with the fixed ``jacobians``: the scaled
    residuals (T,) once every column meets ``tol``, else None. Stops at a step that does
    not contract every unconverged column by :data:`CHORD_CONTRACTION` (or is not
    finite), and undoes that step."""
    previous = None
    for _ in range(CHORD_STEPS + 1):
        r = batch_residual(q)
        residual = _residuals(r, scale, reference)
        done = np.isfinite(residual) & (residual <= tol)
        if done.all():
            return residual
        if previous is not None and not np.all(
            done | (residual <= CHORD_CONTRACTION * previous[0])
        ):
            q[:] = previous[1]
            return None
        todo = np.flatnonzero(~done)
        try:
            step = np.linalg.solve(jacobians[todo], r[:, todo].T[..., None])[..., 0].T
        except np.linalg.LinAlgError:
            return None
        previous = (residual, q.copy())
        q[:, todo] -= step
    return None
