"""The fit report and the least-squares machinery shared by every fit.

Every fit is a bounded nonlinear least-squares problem solved by SciPy's trust-region
reflective method with an exact Jacobian, where a point the model cannot evaluate is a
rejected step (``softcurve.identification.fits._solve.robust_least_squares``).
At the optimum
the Jacobian gives the usual asymptotic covariance ``s^2 (J^T J)^-1`` (``s^2`` the
residual variance), from which the report draws standard errors, confidence intervals
(Student t) and the correlation matrix (:func:`summarize`). A parameter whose Jacobian
column is (numerically) a combination of the others is reported as not identifiable
with an infinite standard error instead of a misleading number.
"""

from __future__ import annotations

import math
import warnings
from dataclasses import dataclass, field, replace

import numpy as np

from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError
from softcurve.figures import plot_fit

CORRELATED = 1e-3
"""Two estimates whose correlation is within this of +-1 are not separately determined:
the data fix a combination of them (a product, a sum), and the fit moves along the other
direction by rounding or to a bound. A covariance this close to singular passes the rank
test of :func:`covariance` yet gives intervals that mean nothing."""

DETERMINED = 1e-3
"""A pair whose standard errors are both under this fraction of their values is
determined however strongly the two correlate: clean data fix even a nearly degenerate
pair (the tanh law of ``examples/bending_moment.csv`` comes back to 1e-7 of its values
with correlations of 0.9999), and it is the width of the intervals, not the correlation
alone, that makes a pair not separately determined."""

SPREAD_COST = 1.01
"""Optima of a multi-start within this factor of the best cost count as the same
minimum in the spread of the report (1 % more cost)."""


class FitError(ParameterError):
    """A prediction was asked of a fit that failed (its values are not an estimate)."""


class FitWarning(UserWarning):
    """A prediction uses a fit that stopped early (its values are the best point found)."""


@dataclass(frozen=True, eq=False)
class FitReport(Result):
    """The result of a least-squares fit.

    Attributes
    ----------
    status : Status
        SUCCESS; EVALUATION_LIMIT when the budget ran out first; NOT_IDENTIFIABLE when
        the covariance is singular (some parameters are not determined by the data) or
        two estimates correlate within ``CORRELATED`` (1e-3) of +-1 (the data determine
        only a combination of them; the message names the pairs);
        NOT_CONVERGED when the solver or the model failed; INFEASIBLE when the estimate
        is not an admissible law or robot.
    message : str
        What the optimizer said, and any identifiability warning.
    names : tuple of str
        Fitted parameters.
    parameter_units : tuple of str
        Unit of each parameter, in order (``""`` when it has none or is unknown; empty
        when no fit recorded them); the table prints them beside the names.
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
    n_jacobians : int
        Of them, those with the Jacobian. A trajectory fit on softcurve's CVODES driver
        evaluates its trial points by the outputs alone (about a seventh of the cost on
        the paper robot) and the Jacobian only at the points it steps to; other fits
        evaluate every point with it.
    identifiable : ndarray of bool, shape (P,)
        False for parameters the data do not determine.
    parts : tuple of (str, int)
        Experiment name and number of samples, in the order their rows are stacked in
        ``abscissa``, ``measured`` and ``predicted`` (one entry for a single experiment;
        empty for fits not made of experiments). :meth:`part` gives one of them.
    optima : ndarray, shape (K, P) or None
        With a multi-start (``starts=K``), the optimum reached from each start, in the
        unit of each parameter; the table shows their spread.
    optimum_costs : ndarray, shape (K,) or None
        Half the sum of squared weighted residuals at each of them.
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
    parameter_units: tuple[str, ...] = ()
    confidence: float = 0.95
    n_evaluations: int = 0
    n_jacobians: int = 0
    identifiable: np.ndarray = field(default_factory=lambda: np.zeros(0, bool))
    parts: tuple = ()
    optima: np.ndarray | None = None
    optimum_costs: np.ndarray | None = None
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
        """Confidence intervals, shape (P, 2), Student t with ``N - P`` degrees of freedom.

        They assume independent residuals: for a time series, whose residuals are
        correlated, read them as lower bounds (docs/identify.md).
        """
        from scipy.stats import t  # half a second to import: only here

        dof = max(self.measured.size - len(self.names), 1)
        half = t.ppf(0.5 + self.confidence / 2, dof) * self.standard_errors
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

    def part(self, name: str) -> FitReport:
        """The rows of one experiment, as a report with the same estimates.

        Parameters
        ----------
        name : str
            One of the experiment names in :attr:`parts`.
        """
        start = 0
        for label, count in self.parts:
            if label == name:
                rows = slice(start, start + count)
                return replace(
                    self,
                    abscissa=self.abscissa[rows],
                    measured=self.measured[rows],
                    predicted=self.predicted[rows],
                    parts=((label, count),),
                )
            start += count
        raise KeyError(f"no experiment {name!r} in this fit; it has {[p[0] for p in self.parts]}")

    def spread(self) -> np.ndarray | None:
        """Range (max - min) of each parameter over the multi-start optima whose cost is
        within 1 % of the best, shape (P,); None without a multi-start."""
        if self.optima is None:
            return None
        best = np.min(self.optimum_costs)
        near = self.optima[self.optimum_costs <= best * SPREAD_COST + 1e-300]
        return np.ptp(near, axis=0)

    def table(self) -> str:
        """A plain-text table of estimates, intervals and the largest correlations."""
        pct = int(round(100 * self.confidence))
        lines = [
            f"status: {self.status.value} ({self.message})",
            f"{'parameter':44s} {'estimate':>12s} {'std err':>10s}   {pct}% interval",
        ]
        units = self.parameter_units or ("",) * len(self.names)
        for name, unit, v, se, (lo, hi) in zip(
            self.names, units, self.values, self.standard_errors, self.intervals, strict=True
        ):
            name = f"{name} [{unit}]" if unit else name
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
        if len(self.parts) > 1:
            for label, _ in self.parts:
                rms = ", ".join(f"{v:.4g}" for v in self.part(label).rms)
                lines.append(f"experiment {label}: RMS {rms} ({', '.join(self.signals)})")
        if self.optima is not None:
            costs = self.optimum_costs
            near = int(np.sum(costs <= np.min(costs) * SPREAD_COST + 1e-300))
            lines.append(
                f"multi-start: {len(costs)} starts, {near} reached the best cost "
                f"{np.min(costs):.4g} (within 1 %), worst {np.max(costs):.4g}"
            )
            for name, value, width in zip(self.names, self.values, self.spread(), strict=True):
                lines.append(f"  spread of {name}: {width:.3g} (estimate {value:.5g})")
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
    p = jacobian.shape[1]
    # samples with weight zero carry no information: they are not degrees of freedom
    n = int(np.count_nonzero(np.any(jacobian != 0, axis=1) | (residuals != 0)))
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


def usable_fit(fit: FitReport) -> FitReport:
    """``fit`` if its values can be predicted from, else :class:`FitError`.

    A fit that failed (NOT_CONVERGED: no point could be evaluated, or the model fails
    at the estimate; INFEASIBLE: the estimate is not an admissible robot) raises; one
    that ran out of evaluations or was stopped (INTERRUPTED: a worker process died)
    warns (:class:`FitWarning`): its values are the best point found, not a converged
    estimate.

    Parameters
    ----------
    fit : FitReport
        The fit to predict from.
    """
    nothing = fit.status is Status.INTERRUPTED and not np.isfinite(fit.predicted).any()
    if fit.status in (Status.NOT_CONVERGED, Status.INFEASIBLE) or nothing:
        raise FitError(
            f"fit: cannot predict from a failed fit (status {fit.status.value}: "
            f"{fit.message}); {fit.status.advice}"
        )
    unfinished = {
        Status.EVALUATION_LIMIT: (
            "ran out of evaluations",
            "raise max_evaluations or start closer",
        ),
        Status.INTERRUPTED: ("was stopped before it finished", "run the fit again from them"),
    }
    if fit.status in unfinished:
        what, advice = unfinished[fit.status]
        warnings.warn(
            f"predicting from a fit that {what} ({fit.message}): its values are the best "
            f"point found; {advice}",
            FitWarning,
            stacklevel=3,
        )
    return fit


def summarize(names, theta, jac_theta, weighted_residuals, status: Status, message: str):
    """Standard errors, correlation and identifiability from the Jacobian in ``theta``.

    Parameters
    ----------
    names : sequence of str, shape (P,)
        The fitted parameters.
    theta : ndarray, shape (P,)
        Their estimates, each in its unit.
    jac_theta : ndarray, shape (N, P)
        Jacobian of the weighted residuals with respect to them.
    weighted_residuals : ndarray, shape (N,)
        At the estimate.
    status : Status
        The solver's; a converged fit whose covariance is singular, or in which two
        estimates correlate within :data:`CORRELATED` of +-1 while one of them has a
        standard error of :data:`DETERMINED` of its value or more, becomes
        NOT_IDENTIFIABLE.
    message : str
        The solver's; the names not identifiable, and the pairs not separately
        determined, are appended with what to do.

    Returns
    -------
    tuple
        ``(standard_errors, correlation, identifiable, status, message)``.
    """
    cov, identifiable = covariance(jac_theta, weighted_residuals)
    correlation = correlation_matrix(cov)
    if not identifiable.all():
        bad = [n for n, ok in zip(names, identifiable, strict=True) if not ok]
        message += f"; not identifiable from these data (fix them): {bad}"
        if status is Status.SUCCESS:
            status = Status.NOT_IDENTIFIABLE
    errors = np.sqrt(np.diag(cov))
    with np.errstate(divide="ignore", invalid="ignore"):
        loose = ~(errors < DETERMINED * np.abs(theta))
    pairs = [
        f"{names[j]} ~ {names[i]} ({correlation[i, j]:+.4f})"
        for i in range(len(names))
        for j in range(i)
        # NaN (a parameter not identifiable, already named) compares False
        if abs(correlation[i, j]) > 1 - CORRELATED and (loose[i] or loose[j])
    ]
    if pairs:
        message += (
            f"; not separately determined by these data, only together: {', '.join(pairs)}; "
            "fix one of each pair at a known value, or add experiments that move them apart"
        )
        if status is Status.SUCCESS:
            status = Status.NOT_IDENTIFIABLE
    return errors, correlation, identifiable, status, message
