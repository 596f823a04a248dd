"""Static fit of a stiffness law to quasi-static data (paper, section 3.1).

The fit is a bounded least-squares problem of ``softcurve.identification.fits._report``
and returns its :class:`~softcurve.identification.fits.FitReport`; trajectory and
equilibrium fits of a whole robot are in :mod:`softcurve.identification.fits`.
"""

from __future__ import annotations

import numpy as np
import scipy.optimize

from softcurve.base.status import Status
from softcurve.base.validation import ParameterError
from softcurve.description.materials import (
    LAW_UNITS,
    STIFFNESS_LAWS,
    LinearStiffness,
    TanhStiffness,
)
from softcurve.identification.fits._report import FitReport, check_confidence, summarize
from softcurve.identification.fits._solve import robust_least_squares

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


BEND_GRID = np.logspace(-2.0, 3.0, 51)
"""The starting values of ``|a3|`` times the largest strain searched before a tanh fit:
from a law that hardly bends over the data (0.01, a cubic to 1e-4) to one that has
bent within the first 1/1000 of it (1000)."""

STARTS = 3
"""Starting points of a tanh fit: the best of :data:`BEND_GRID`'s local minima."""

TOGETHER = 0.999
"""A correlation beyond which two estimates are reported as determined only together."""


def _units(x: np.ndarray, f: np.ndarray) -> tuple[float, float]:
    """The largest ``|strain|`` and ``|force|``: the units the fit runs in; refused
    (:class:`ParameterError`, naming the data's range) where a stiffness ``force /
    strain`` or ``1 / strain`` in them would leave the range of normal floats."""
    x_unit, f_unit = float(np.max(np.abs(x))), float(np.max(np.abs(f)))
    if not (x_unit > 0 and f_unit > 0):
        raise ParameterError(
            "the data do not show a positive stiffness (force against strain): "
            f"largest |strain| {x_unit:g}, largest |force| {f_unit:g}"
        )
    tiny, huge = np.finfo(np.float64).tiny, np.finfo(np.float64).max
    with np.errstate(over="ignore", under="ignore"):
        scales = (f_unit / x_unit, 1.0 / x_unit)
    if not all(tiny <= value <= huge for value in scales):
        raise ParameterError(
            f"the data's range, |strain| up to {x_unit:.3g} and |force| up to {f_unit:.3g}, "
            f"gives stiffnesses of about {scales[0]:.3g} (force / strain) and {scales[1]:.3g} "
            f"(1 / strain), outside the range of floats ({tiny:.3g} to {huge:.3g}): give "
            "strain and force in other units"
        )
    return x_unit, f_unit


def _tanh_starts(x: np.ndarray, f: np.ndarray, w: np.ndarray) -> list[np.ndarray]:
    """Starting points ``(k(0), k(inf), |a3|)`` of a tanh fit to ``f`` (N,) against
    ``x`` (N,), in units of the largest ``|x|`` and ``|f|``, weights ``w`` (N,).

    For a given ``a3`` the force ``k(0) x (1 - tanh^2) + k(inf) x tanh^2`` is linear in
    the two stiffnesses, whose best non-negative values are a small least-squares
    problem: solved over :data:`BEND_GRID`, the best :data:`STARTS` local minima of the
    cost are the starts, wherever the law bends.
    """
    rows = []
    for c in BEND_GRID:
        th2 = np.tanh(c * x) ** 2
        basis = w[:, None] * np.column_stack([x * (1.0 - th2), x * th2])
        stiffness, cost = scipy.optimize.nnls(basis, w * f)
        rows.append((cost, stiffness[0], stiffness[1], c))
    cost = np.array([row[0] for row in rows])
    padded = np.r_[np.inf, cost, np.inf]
    minima = np.flatnonzero((cost <= padded[:-2]) & (cost <= padded[2:]))
    best = minima[np.argsort(cost[minima], kind="stable")][:STARTS]
    return [np.array(rows[i][1:]) for i in best]


def _failure(kind, names, status, corr, count, budget, starts, message, given) -> str:
    """The message of a fit that did not succeed, in the library's words: what happened,
    which estimates the data determine only together, and what to try (``given``: the
    start was the user's law, not the library's search)."""
    what = {
        Status.EVALUATION_LIMIT: "ran out of evaluations",
        Status.NOT_CONVERGED: "did not converge",
    }.get(status, "did not determine the law")
    text = (
        f"the {kind} law's fit {what} after {count} evaluations of the residuals "
        f"(max_evaluations = {budget} from each of {starts} starting point(s))"
    )
    if "not identifiable" in message:
        text += "; " + message[message.index("not identifiable") :]
    # not the diagonal, nor the inf or NaN of a parameter the data do not determine
    off = ~np.eye(len(names), dtype=bool) & np.isfinite(corr)
    together = np.abs(np.where(off, corr, 0.0))
    if together.size > 1 and together.max() > TOGETHER:
        i, j = np.unravel_index(np.argmax(together), together.shape)
        text += (
            f"; the data determine {names[i]} and {names[j]} only together (correlation "
            f"{corr[i, j]:+.4f})"
        )
    search = f"law='{kind}' (a search from the data) instead of the law given, " if given else ""
    return text + (
        ": the data hardly show where the stiffness changes. What to try: "
        f"{search}more data over the strains where it changes, the linear law "
        "(law='linear', the CLI's --law linear), or a larger max_evaluations"
    )


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
    mode: str | None = None,
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
        Name of the strain, for the report's figure; its unit from ``mode`` is added
        unless the label ends in one (``"beta [rad]"``).
    force_unit : str
        Unit of the force, for the report's figure (default: from ``mode``).
    mode : {"elongation", "bending"}, optional
        Which strain the data are: the elongation [m] under a force [N], or the bending
        angle [rad] under a moment [N m]. It gives the units of the strain, the force and
        the parameters in the report and its figure; without it they are written as
        either (``"m or rad"``).

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
    if mode not in (None, "elongation", "bending"):
        raise ParameterError(f"mode must be 'elongation', 'bending' or None, got {mode!r}")
    kind = law if isinstance(law, str) else law.kind
    if kind not in ("tanh", "linear"):
        raise ParameterError(f"law must be 'tanh', 'linear' or a law instance, got {law!r}")
    if mode is None:  # either strain: each unit written as both
        elongation, bending = LAW_UNITS["elongation_stiffness"], LAW_UNITS["bending_stiffness"]
        law_units = {k: f"{elongation[k]} or {bending[k]}" for k in elongation}
    else:
        law_units = LAW_UNITS[f"{mode}_stiffness"]
    units = _units(x, f)
    # the fit runs in units of the data's largest strain and force: it sees the same
    # numbers whatever units the data come in (SciPy's tolerances are absolute)
    xs, fs = x / units[0], f / units[1]
    k_secant = float(np.sum(w * xs * fs) / np.sum(w * xs * xs))
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
    # alpha = unit * alpha_s: a stiffness is force / strain, a3 is 1 / strain
    stiffness_unit = units[1] / units[0]
    unit = np.array([stiffness_unit] if kind == "linear" else [stiffness_unit] * 2 + [1 / units[0]])

    if kind == "linear":
        names = ("k0",)
        starts = [np.array([law.k0 / stiffness_unit if not isinstance(law, str) else k_secant])]
        to_alpha = np.eye(1)
    else:
        names = ("a1", "a2", "a3")
        # alpha = to_alpha @ phi with phi = (k(0), k(inf), |a3|)
        to_alpha = np.array([[0.0, 1.0, 0.0], [-1.0, 1.0, 0.0], [0.0, 0.0, 1.0]])
        if isinstance(law, TanhStiffness):
            given = np.array([law.a1, law.a2, abs(law.a3)]) / unit
            starts = [np.array([given[0] - given[1], given[0], given[2]])]
        else:
            starts = _tanh_starts(xs, fs, w)
    scale = np.abs(starts[0]) + (starts[0] == 0)

    def residual_and_jacobian(z):
        alpha = to_alpha @ (z * scale)
        model, jac = _law_force_and_jacobian(kind, alpha, xs)
        return w * (model - fs), (w[:, None] * jac) @ to_alpha * scale

    lower = np.zeros(len(names))
    upper = np.full(len(names), np.inf)
    runs = [
        robust_least_squares(
            residual_and_jacobian, start / scale, lower, upper, max_evaluations, gtol=None
        )
        for start in starts
    ]
    best = min(runs, key=lambda run: run.cost)
    r = best.residuals if best.residuals is not None else np.full(f.size, np.nan)
    status, count = best.status, sum(run.n_evaluations for run in runs)
    alpha_s = to_alpha @ (best.z * scale)
    fitted, jac_alpha = _law_force_and_jacobian(kind, alpha_s, xs)
    errors, corr, identifiable, status, message = summarize(
        names, alpha_s, w[:, None] * jac_alpha, r, status, best.message
    )
    if status is not Status.SUCCESS:
        message = _failure(
            kind, names, status, corr, count, max_evaluations, len(starts), message,
            given=not isinstance(law, str),
        )  # fmt: skip
    alpha, errors = alpha_s * unit, errors * unit
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
        predicted=fitted[:, None] * units[1],
        signals=("force",),
        units=(force_unit or law_units["force"],),
        abscissa_label=label if label.endswith("]") else f"{label} [{law_units['strain']}]",
        parameter_units=tuple(law_units[q] for q in STIFFNESS_LAWS[kind].parameter_quantities),
        confidence=confidence,
        n_evaluations=count,
        n_jacobians=sum(run.n_jacobians for run in runs),
        identifiable=identifiable,
        extra={"law": fitted_law, "weights": w},
    )
