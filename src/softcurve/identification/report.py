"""The fit report and the least-squares machinery shared by every fit.

Every fit is a bounded nonlinear least-squares problem solved by SciPy's trust-region
reflective method with an exact Jacobian (:func:`solve_least_squares`). At the optimum
the Jacobian gives the usual asymptotic covariance ``s^2 (J^T J)^-1`` (``s^2`` the
residual variance), from which the report draws standard errors, confidence intervals
(Student t) and the correlation matrix (:func:`summarize`). A parameter whose Jacobian
column is (numerically) a combination of the others is reported as not identifiable
with an infinite standard error instead of a misleading number.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np
import scipy.optimize
import scipy.stats

from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError
from softcurve.figures import plot_fit


@dataclass(frozen=True, eq=False)
class FitReport(Result):
    """The result of a least-squares fit.

    Attributes
    ----------
    status : Status
        SUCCESS; EVALUATION_LIMIT when the budget ran out first; NOT_IDENTIFIABLE when
        the covariance is singular (some parameters are not determined by the data);
        NOT_CONVERGED when the solver or the model failed; INFEASIBLE when the estimate
        is not an admissible law or robot.
    message : str
        What the optimizer said, and any identifiability warning.
    names : tuple of str
        Fitted parameters.
    values, standard_errors : ndarray, shape (P,)
        Estimates and their asymptotic standard errors (inf when not identifiable),
        each in the unit of its parameter.
    correlation : ndarray, shape (P, P)
        Correlation matrix of the estimates (NaN rows for non-identifiable ones).
    abscissa : ndarray, shape (T,)
        Time [s] or strain of each data point, for plots.
    measured, predicted : ndarray, shape (T, k)
        Data and the model at the estimate, one column per signal, in its unit.
    signals : tuple of str
        Column names.
    units : tuple of str
        Unit of each signal, in order (``""`` when unknown).
    abscissa_label : str
        Name and unit of the abscissa, for plots.
    confidence : float
        Confidence level of the intervals, a probability (default 0.95).
    n_evaluations : int
        Residual evaluations used.
    identifiable : ndarray of bool, shape (P,)
        False for parameters the data do not determine.
    extra : dict
        Fit-specific results (the fitted law, robot, initial state...).
    """

    status: Status
    message: str
    names: tuple[str, ...]
    values: np.ndarray
    standard_errors: np.ndarray
    correlation: np.ndarray
    abscissa: np.ndarray
    measured: np.ndarray
    predicted: np.ndarray
    signals: tuple[str, ...]
    units: tuple[str, ...] = ()
    abscissa_label: str = "t [s]"
    confidence: float = 0.95
    n_evaluations: int = 0
    identifiable: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    extra: dict = field(default_factory=dict)

    def __post_init__(self):
        check_confidence(self.confidence)

    @property
    def residuals(self) -> np.ndarray:
        """``predicted - measured``, shape (T, k)."""
        return self.predicted - self.measured

    @property
    def rms(self) -> np.ndarray:
        """Root-mean-square residual of each signal, shape (k,)."""
        return np.sqrt(np.mean(self.residuals**2, axis=0))

    @property
    def max_error(self) -> np.ndarray:
        """Largest absolute residual of each signal, shape (k,)."""
        return np.max(np.abs(self.residuals), axis=0)

    @property
    def intervals(self) -> np.ndarray:
        """Confidence intervals, shape (P, 2), Student t with ``N - P`` degrees of freedom."""
        dof = max(self.measured.size - len(self.names), 1)
        half = scipy.stats.t.ppf(0.5 + self.confidence / 2, dof) * self.standard_errors
        return np.column_stack([self.values - half, self.values + half])

    def value(self, name: str) -> float:
        """The estimate of one parameter.

        Parameters
        ----------
        name : str
            One of :attr:`names`.
        """
        if name not in self.names:
            raise KeyError(f"{name!r} was not fitted; fitted: {list(self.names)}")
        return float(self.values[self.names.index(name)])

    def table(self) -> str:
        """A plain-text table of estimates, intervals and the largest correlations."""
        pct = int(round(100 * self.confidence))
        lines = [
            f"status: {self.status.value} ({self.message})",
            f"{'parameter':44s} {'estimate':>12s} {'std err':>10s}   {pct}% interval",
        ]
        for name, v, se, (lo, hi) in zip(
            self.names, self.values, self.standard_errors, self.intervals, strict=True
        ):
            lines.append(f"{name:44s} {v:12.5g} {se:10.3g}   [{lo:.5g}, {hi:.5g}]")
        pairs = [
            (abs(self.correlation[i, j]), self.names[i], self.names[j], self.correlation[i, j])
            for i in range(len(self.names))
            for j in range(i)
            if np.isfinite(self.correlation[i, j])
        ]
        for _, a, b, c in sorted(pairs, reverse=True)[:3]:
            lines.append(f"correlation {a} ~ {b}: {c:+.3f}")
        for name, r, m, u in zip(self.signals, self.rms, self.max_error, self.units, strict=False):
            lines.append(f"residual {name}: RMS {r:.4g} {u}, max {m:.4g} {u}")
        return "\n".join(lines)

    def __str__(self) -> str:
        return self.table()

    def plot(self, ax=None, *, title: str | None = None):
        """Each signal measured against the model at the estimate, residuals below: one
        column of two panels per signal.

        Parameters
        ----------
        ax : None or sequence of matplotlib.axes.Axes, shape (2 k,) or (2, k)
            The k signal panels, then the k residual panels; None draws a new figure.
        title : str, optional
            Title of the figure.

        Returns
        -------
        matplotlib.figure.Figure
            Write it with :func:`softcurve.figures.save_figure`.
        """
        return plot_fit(self, ax, title=title)


def check_confidence(confidence) -> float:
    """``confidence`` as a float in (0, 1), or :class:`~softcurve.ParameterError`.

    Parameters
    ----------
    confidence : float
        Confidence level of intervals, a probability (e.g. 0.95 for 95 %).
    """
    try:
        level = float(confidence)
    except (TypeError, ValueError):
        level = math.nan
    if isinstance(confidence, bool) or not 0 < level < 1:
        raise ParameterError(
            f"confidence must be a probability in (0, 1), e.g. 0.95 for 95 % intervals, "
            f"got {confidence!r}"
        )
    return level


def covariance(jacobian: np.ndarray, residuals: np.ndarray):
    """Asymptotic covariance of a least-squares estimate and which parameters it resolves.

    Parameters
    ----------
    jacobian : ndarray, shape (N, P)
        Jacobian of the (weighted) residuals at the optimum.
    residuals : ndarray, shape (N,)
        The (weighted) residuals at the optimum.

    Returns
    -------
    cov : ndarray, shape (P, P)
        ``s^2 (J^T J)^+`` with ``s^2 = |r|^2 / (N - P)``, from the SVD of ``J``;
        rows and columns of non-identifiable parameters are inf.
    identifiable : ndarray of bool, shape (P,)
        False for parameters in the numerical null space of ``J``.
    """
    n, p = jacobian.shape
    s2 = float(residuals @ residuals) / max(n - p, 1)
    # Column equilibration first, so that the rank test does not depend on units.
    norms = np.linalg.norm(jacobian, axis=0)
    norms[norms == 0] = 1.0
    u, sv, vt = np.linalg.svd(jacobian / norms, full_matrices=False)
    tol = sv.max(initial=0.0) * max(n, p) * np.finfo(float).eps * 1e3
    keep = sv > tol
    identifiable = np.ones(p, bool)
    if not keep.all():
        null = vt[~keep]
        identifiable = np.max(np.abs(null), axis=0) < 1e-6
    vk = vt[keep].T / sv[keep]
    cov = s2 * (vk @ vk.T) / np.outer(norms, norms)
    cov[~identifiable, :] = np.inf
    cov[:, ~identifiable] = np.inf
    return cov, identifiable


def correlation_matrix(cov: np.ndarray) -> np.ndarray:
    """Correlation from a covariance; NaN where a variance is inf or zero.

    Parameters
    ----------
    cov : ndarray, shape (P, P)
        Covariance matrix of P estimates.
    """
    sd = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):
        c = cov / np.outer(sd, sd)
    c[~np.isfinite(c)] = np.nan
    np.fill_diagonal(c, np.where(np.isfinite(sd) & (sd > 0), 1.0, np.nan))
    return c


def solve_least_squares(residual_and_jacobian, z0, lower, upper, max_evaluations):
    """Run SciPy's bounded trust-region reflective solver on scaled variables ``z``.

    Parameters
    ----------
    residual_and_jacobian : callable
        ``f(z) -> (r (N,), J (N, P))``, evaluated once per point.
    z0 : array_like, shape (P,)
        Initial guess (scaled, dimensionless).
    lower, upper : ndarray, shape (P,)
        Bounds on ``z``.
    max_evaluations : int
        Budget of residual evaluations.

    Returns
    -------
    tuple
        ``(z, r, J, status, message, n_evaluations)`` with ``status`` a :class:`Status`:
        SUCCESS, EVALUATION_LIMIT or NOT_CONVERGED.
    """
    cache: dict[bytes, tuple[np.ndarray, np.ndarray]] = {}

    def both(z):
        key = np.asarray(z, dtype=np.float64).tobytes()
        if key not in cache:
            cache.clear()
            r, jac = residual_and_jacobian(np.asarray(z, dtype=np.float64))
            if not (np.all(np.isfinite(r)) and np.all(np.isfinite(jac))):
                raise FloatingPointError("the model returned non-finite residuals")
            cache[key] = (r, jac)
        return cache[key]

    count = 0

    def fun(z):
        nonlocal count
        count += 1
        return both(z)[0]

    z0 = np.clip(np.asarray(z0, dtype=np.float64), lower, upper)
    try:
        result = scipy.optimize.least_squares(
            fun,
            z0,
            jac=lambda z: both(z)[1],
            bounds=(lower, upper),
            method="trf",
            max_nfev=max_evaluations,
            x_scale=1.0,
            xtol=1e-10,
            ftol=1e-10,
            gtol=1e-10,
        )
    except (FloatingPointError, RuntimeError) as exc:
        r, jac = cache.get(next(iter(cache)), (None, None)) if cache else (None, None)
        return z0, r, jac, Status.NOT_CONVERGED, f"the model could not be evaluated: {exc}", count
    status = Status.SUCCESS if result.status > 0 else Status.EVALUATION_LIMIT
    if result.status < 0:
        status = Status.NOT_CONVERGED
    r, jac = both(result.x)
    return result.x, r, jac, status, str(result.message), count


def summarize(names, jac_theta, weighted_residuals, status: Status, message: str):
    """Standard errors, correlation and identifiability from the Jacobian in ``theta``.

    Parameters
    ----------
    names : sequence of str, shape (P,)
        The fitted parameters.
    jac_theta : ndarray, shape (N, P)
        Jacobian of the weighted residuals with respect to them.
    weighted_residuals : ndarray, shape (N,)
        At the estimate.
    status : Status
        The solver's; a converged fit whose covariance is singular becomes
        NOT_IDENTIFIABLE.
    message : str
        The solver's; the names not identifiable are appended.

    Returns
    -------
    tuple
        ``(standard_errors, correlation, identifiable, status, message)``.
    """
    cov, identifiable = covariance(jac_theta, weighted_residuals)
    if not identifiable.all():
        bad = [n for n, ok in zip(names, identifiable, strict=True) if not ok]
        message += f"; not identifiable from these data (fix them): {bad}"
        if status is Status.SUCCESS:
            status = Status.NOT_IDENTIFIABLE
    return np.sqrt(np.diag(cov)), correlation_matrix(cov), identifiable, status, message
