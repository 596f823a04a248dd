"""Identification: the fit report and the static fit of a stiffness law (paper, section 3.1).

Every fit here is a bounded nonlinear least-squares problem solved by SciPy's
trust-region reflective method with an exact Jacobian. At the optimum the
Jacobian gives the usual asymptotic covariance ``s^2 (J^T J)^-1`` (``s^2`` the
residual variance), from which the report draws standard errors, confidence
intervals (Student t) and the correlation matrix. A parameter whose Jacobian
column is (numerically) a combination of the others is reported as not
identifiable with an infinite standard error instead of a misleading number.

Trajectory and equilibrium fits of a whole robot are in
:mod:`softcurve.identify_dynamic`; they return the same :class:`FitReport`.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
import scipy.optimize
import scipy.stats

from softcurve.base.validation import ParameterError
from softcurve.description.materials import LinearStiffness, TanhStiffness


@dataclass(frozen=True, eq=False)
class FitReport:
    """The result of a least-squares fit.

    Attributes
    ----------
    status : str
        ``"converged"``, ``"max_evaluations"`` or ``"failed"``.
    message : str
        What the optimiser said, and any identifiability warning.
    names : tuple of str
        Fitted parameters.
    values, standard_errors : ndarray, shape (P,)
        Estimates and their asymptotic standard errors (inf when not identifiable).
    correlation : ndarray, shape (P, P)
        Correlation matrix of the estimates (NaN rows for non-identifiable ones).
    abscissa : ndarray, shape (T,)
        Time [s] or strain of each data point, for plots.
    measured, predicted : ndarray, shape (T, k)
        Data and the model at the estimate, one column per signal.
    signals : tuple of str
        Column names; ``units`` their units.
    confidence : float
        Level of the intervals (default 0.95).
    n_evaluations : int
        Residual evaluations used.
    extra : dict
        Fit-specific results (the fitted law, robot, initial state...).
    """

    status: str
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

    @property
    def success(self) -> bool:
        return self.status == "converged"

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
        """The estimate of one parameter."""
        if name not in self.names:
            raise KeyError(f"{name!r} was not fitted; fitted: {list(self.names)}")
        return float(self.values[self.names.index(name)])

    def table(self) -> str:
        """A plain-text table of estimates, intervals and the largest correlations."""
        pct = int(round(100 * self.confidence))
        lines = [
            f"status: {self.status} ({self.message})",
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

    def plot(self, axes=None, title: str | None = None):
        """Measured against fitted signals, and residuals below; returns the figure."""
        import matplotlib.pyplot as plt

        k = len(self.signals)
        if axes is None:
            fig, axes = plt.subplots(2, k, figsize=(5 * k, 5), squeeze=False, sharex="col")
        else:
            axes = np.asarray(axes).reshape(2, k)
            fig = axes[0, 0].figure
        order = np.argsort(self.abscissa, kind="stable")
        x = self.abscissa[order]
        style = "-" if self.abscissa_label.startswith("t [") else "."  # time series as lines
        for j, name in enumerate(self.signals):
            unit = self.units[j] if j < len(self.units) else ""
            top, bottom = axes[0, j], axes[1, j]
            top.plot(x, self.measured[order, j], "k" + style, ms=3, lw=1, label="measured")
            top.plot(x, self.predicted[order, j], "C1-", lw=1.5, label="model")
            top.set_ylabel(f"{name} [{unit}]" if unit else name)
            top.legend(loc="best", fontsize=8)
            bottom.plot(x, self.residuals[order, j], "C3" + style, ms=2, lw=1)
            bottom.axhline(0.0, color="0.5", lw=0.5)
            bottom.set_ylabel("model - measured")
            bottom.set_xlabel(self.abscissa_label)
        if title:
            fig.suptitle(title)
        fig.tight_layout()
        return fig


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
    """Correlation from a covariance; NaN where a variance is inf or zero."""
    sd = np.sqrt(np.diag(cov))
    with np.errstate(invalid="ignore", divide="ignore"):
        c = cov / np.outer(sd, sd)
    c[~np.isfinite(c)] = np.nan
    np.fill_diagonal(c, np.where(np.isfinite(sd) & (sd > 0), 1.0, np.nan))
    return c


def solve_least_squares(residual_and_jacobian, z0, lower, upper, max_evaluations):
    """Run SciPy's bounded trust-region reflective solver on scaled variables ``z``.

    ``residual_and_jacobian(z) -> (r (N,), J (N, P))`` is evaluated once per point.
    Returns ``(z, r, J, status, message, n_evaluations)``.
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
        return z0, r, jac, "failed", f"the model could not be evaluated: {exc}", count
    status = "converged" if result.status > 0 else "max_evaluations"
    if result.status < 0:
        status = "failed"
    r, jac = both(result.x)
    return result.x, r, jac, status, str(result.message), count


def summarise(names, values, jac_theta, weighted_residuals, status, message):
    """Standard errors, correlation and identifiability from the Jacobian in ``theta``."""
    cov, identifiable = covariance(jac_theta, weighted_residuals)
    if not identifiable.all():
        bad = [n for n, ok in zip(names, identifiable, strict=True) if not ok]
        message += f"; not identifiable from these data (fix them): {bad}"
    return np.sqrt(np.diag(cov)), correlation_matrix(cov), identifiable, message


# -- static identification of a stiffness law ---------------------------------------


def _law_force_and_jacobian(kind: str, alpha: np.ndarray, x: np.ndarray):
    """``k(x) x`` and its Jacobian w.r.t. ``alpha`` (a1, a2, a3) or (k0,)."""
    if kind == "linear":
        return alpha[0] * x, x[:, None]
    a1, a2, a3 = alpha
    th = np.tanh(a3 * x)
    force = (a1 + a2 * (th**2 - 1.0)) * x
    jac = np.column_stack([x, (th**2 - 1.0) * x, a2 * 2.0 * th * (1.0 - th**2) * x * x])
    return force, jac


def fit_stiffness(
    strain,
    force,
    law: str | LinearStiffness | TanhStiffness = "tanh",
    *,
    weights=None,
    max_evaluations: int = 200,
    confidence: float = 0.95,
    label: str = "strain",
    force_unit: str = "",
) -> FitReport:
    """Fit a stiffness law to quasi-static data: ``force = k(strain) * strain``.

    This is the regression of the paper's Fig. 3. For the tanh law the search runs
    over ``(k(0), k(inf), |a3|) = (a1 - a2, a1, |a3|)``, all bounded below by zero,
    so every iterate and the result satisfy the well-posedness condition
    ``a1 > 0, a1 > a2``; several starting points guard against local minima.

    Parameters
    ----------
    strain : array_like, shape (N,)
        Elongation [m] or bending angle [rad].
    force : array_like, shape (N,)
        Generalized elastic force [N or N m] at each strain.
    law : "tanh", "linear", or a law instance (used as the starting point)
    weights : array_like, shape (N,), optional
        Residual weights (e.g. to favour positive strains, as the paper does).
    label, force_unit : str
        For the report's figure.

    Returns
    -------
    FitReport
        Names ``("a1", "a2", "a3")`` or ``("k0",)``; ``extra["law"]`` is the fitted law.
    """
    x = np.asarray(strain, dtype=np.float64).ravel()
    f = np.asarray(force, dtype=np.float64).ravel()
    if x.shape != f.shape or x.size < 2:
        raise ParameterError(
            f"strain and force must be vectors of one length >= 2, got {x.shape} and {f.shape}"
        )
    if not (np.all(np.isfinite(x)) and np.all(np.isfinite(f))):
        raise ParameterError("strain and force must be finite (no NaN or inf)")
    w = np.ones_like(x) if weights is None else np.asarray(weights, dtype=np.float64).ravel()
    if w.shape != x.shape or not np.all(w >= 0):
        raise ParameterError("weights must be non-negative with the shape of strain")
    kind = law if isinstance(law, str) else law.kind
    if kind not in ("tanh", "linear"):
        raise ParameterError(f"law must be 'tanh', 'linear' or a law instance, got {law!r}")
    k_secant = float(np.sum(w * x * f) / np.sum(w * x * x))
    if not k_secant > 0:
        raise ParameterError("the data do not show a positive stiffness (force against strain)")
    x_max = float(np.max(np.abs(x)))

    if kind == "linear":
        names = ("k0",)
        starts = [np.array([law.k0 if not isinstance(law, str) else k_secant])]
        to_alpha = np.eye(1)
        offset = np.zeros(1)
    else:
        names = ("a1", "a2", "a3")
        # alpha = to_alpha @ phi with phi = (k(0), k(inf), |a3|)
        to_alpha = np.array([[0.0, 1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        offset = np.zeros(3)
        if isinstance(law, TanhStiffness):
            starts = [np.array([law.a1 - law.a2, law.a1, abs(law.a3)])]
        else:
            starts = [
                np.array([k_secant * a, k_secant * b, c / x_max])
                for a in (0.5, 1.0)
                for b in (0.5, 2.0, 5.0)
                for c in (0.5, 2.0)
            ]
    scale = np.abs(starts[0]) + (starts[0] == 0)

    def residual_and_jacobian(z):
        alpha = to_alpha @ (z * scale) + offset
        model, jac = _law_force_and_jacobian(kind, alpha, x)
        return w * (model - f), (w[:, None] * jac) @ to_alpha * scale

    lower = np.zeros(len(names))
    upper = np.full(len(names), np.inf)
    best = None
    for start in starts:
        run = solve_least_squares(
            residual_and_jacobian, start / scale, lower, upper, max_evaluations
        )
        if run[1] is not None and (best is None or run[1] @ run[1] < best[1] @ best[1]):
            best = run
    z, r, _, status, message, count = best
    alpha = to_alpha @ (z * scale) + offset
    fitted, jac_alpha = _law_force_and_jacobian(kind, alpha, x)
    errors, corr, identifiable, message = summarise(
        names, alpha, w[:, None] * jac_alpha, r, status, message
    )
    try:
        fitted_law = LinearStiffness(*alpha) if kind == "linear" else TanhStiffness(*alpha)
    except ParameterError as exc:
        status, fitted_law = "failed", None
        message += f"; the estimate is not a well-posed law: {exc}"
    return FitReport(
        status=status,
        message=message,
        names=names,
        values=alpha,
        standard_errors=errors,
        correlation=corr,
        abscissa=x,
        measured=f[:, None],
        predicted=fitted[:, None],
        signals=("force",),
        units=(force_unit,),
        abscissa_label=label,
        confidence=confidence,
        n_evaluations=count,
        identifiable=identifiable,
        extra={"law": fitted_law, "weights": w},
    )
