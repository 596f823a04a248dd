"""Static fit of a stiffness law to quasi-static data (paper, section 3.1).

The fit is a bounded least-squares problem of :mod:`softcurve.identification.report`
and returns its :class:`~softcurve.identification.report.FitReport`; trajectory and
equilibrium fits of a whole robot are in :mod:`softcurve.identification.dynamic`.
"""

from __future__ import annotations

import numpy as np

from softcurve.base.status import Status
from softcurve.base.validation import ParameterError
from softcurve.description.materials import LinearStiffness, TanhStiffness
from softcurve.identification.report import FitReport, check_confidence, summarize
from softcurve.identification.solve import robust_least_squares

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
    law : {"tanh", "linear"} or LinearStiffness or TanhStiffness
        The law's kind, or an instance used as the starting point.
    weights : array_like, shape (N,), optional
        Residual weights (e.g. to favor positive strains, as the paper does),
        dimensionless.
    max_evaluations : int
        Budget of residual evaluations per starting point.
    confidence : float
        Confidence level of the report's intervals, a probability in (0, 1).
    label : str
        Name and unit of the strain, for the report's figure.
    force_unit : str
        Unit of the force, for the report's figure.

    Returns
    -------
    FitReport
        Names ``("a1", "a2", "a3")`` or ``("k0",)``; ``extra["law"]`` is the fitted law.

    Raises
    ------
    ParameterError
        Bad data or options, before any work: fewer data points than the law's
        parameters plus one, ``confidence`` outside (0, 1), non-finite data.

    Examples
    --------
    >>> import numpy as np
    >>> import softcurve as sc
    >>> strain = np.linspace(-0.5, 0.5, 21)
    >>> report = sc.fit_stiffness(strain, 0.01 * strain, "linear")
    >>> report.success, round(report.value("k0"), 6)
    (True, 0.01)
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
    check_confidence(confidence)
    unknowns = 1 if kind == "linear" else 3
    if x.size <= unknowns:  # an exact fit leaves no residual to estimate the errors from
        raise ParameterError(
            f"the {kind} law has {unknowns} parameter(s): fitting it needs at least "
            f"{unknowns + 1} data points (more than the parameters, for the intervals), "
            f"got {x.size}"
        )
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
    runs = [
        robust_least_squares(residual_and_jacobian, start / scale, lower, upper, max_evaluations)
        for start in starts
    ]
    best = min(runs, key=lambda run: run.cost)
    r = best.residuals if best.residuals is not None else np.full(f.size, np.nan)
    status, message, count = best.status, best.message, sum(run.n_evaluations for run in runs)
    alpha = to_alpha @ (best.z * scale) + offset
    fitted, jac_alpha = _law_force_and_jacobian(kind, alpha, x)
    errors, corr, identifiable, status, message = summarize(
        names, w[:, None] * jac_alpha, r, status, message
    )
    try:
        fitted_law = LinearStiffness(*alpha) if kind == "linear" else TanhStiffness(*alpha)
    except ParameterError as exc:
        status, fitted_law = Status.INFEASIBLE, None
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
