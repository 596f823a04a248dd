"""Robust fits: a trial point the model cannot evaluate is a rejected step; predicting
from a failed fit raises; multi-start reports the spread of its optima."""

import os

import numpy as np
import pytest

import softcurve as sc
import softcurve.identification.fits._dynamic as dynamic
from softcurve.base.status import Status
from softcurve.identification.experiments._loading import Experiment
from softcurve.identification.fits import _solve as solve
from softcurve.identification.fits._dynamic import fit_trajectory, predict_trajectory
from softcurve.identification.fits._joint import evaluate_all
from softcurve.identification.fits._parameters import Free
from softcurve.identification.fits._report import FitError, FitWarning
from softcurve.identification.fits._solve import robust_least_squares, starting_points
from softcurve.identification.maps import bending_angle_map
from softcurve.simulation.batch._workers import WorkerDied
from softcurve.simulation.sensitivity._sensitivity import SensitivityEvaluator
from softcurve.simulation.solvers import _driver as native

SEG = "segments[0]."
LENGTH = 0.064


def _rosenbrock(fail_at):
    """Rosenbrock's residuals; the evaluations numbered in ``fail_at`` raise."""
    calls = []

    def residual_and_jacobian(z):
        calls.append(z.copy())
        if len(calls) in fail_at:
            raise RuntimeError("CVode returned CV_CONV_FAILURE (forced)")
        r = np.array([10.0 * (z[1] - z[0] ** 2), 1.0 - z[0]])
        jac = np.array([[-20.0 * z[0], 10.0], [-1.0, 0.0]])
        return r, jac

    return residual_and_jacobian, calls


def test_a_failed_trial_point_is_rejected_and_the_fit_converges():
    bounds = (np.full(2, -5.0), np.full(2, 5.0))
    clean = robust_least_squares(_rosenbrock(())[0], [-1.2, 1.0], *bounds, 200)
    assert clean.status is Status.SUCCESS and clean.rejected == 0
    # the first trial point after the start, and a later one, cannot be evaluated
    function, calls = _rosenbrock((2, 6))
    solution = robust_least_squares(function, [-1.2, 1.0], *bounds, 200)
    assert solution.status is Status.SUCCESS, solution.message
    assert solution.rejected == 2 and "2 trial point(s) could not be evaluated" in solution.message
    np.testing.assert_allclose(solution.z, [1.0, 1.0], atol=1e-8)
    # after the first rejection the next trial is within a quarter of the failed step
    failed = np.max(np.abs(calls[1] - calls[0]))
    assert np.max(np.abs(calls[2] - calls[0])) <= 0.25 * failed * (1 + 1e-12)
    assert solution.n_evaluations == len(calls) < 200


def test_a_model_that_cannot_be_evaluated_at_the_start_reports_the_start():
    function, _ = _rosenbrock(range(1, 100))
    solution = robust_least_squares(function, [0.5, 0.5], np.full(2, -5.0), np.full(2, 5.0), 50)
    assert solution.status is Status.NOT_CONVERGED and solution.residuals is None
    assert "cannot be evaluated at the starting values" in solution.message
    np.testing.assert_array_equal(solution.z, [0.5, 0.5])


def test_a_worker_that_dies_ends_the_fit_with_the_best_point_found():
    """A dead worker process is the machine's fault, not the trial point's: no rejected
    step and no retry, but the end of the run with the best point so far."""
    clean, calls = _rosenbrock(())

    def dies_at_the_fifth(z):
        if len(calls) == 4:
            raise WorkerDied("a worker process died (forced)")
        return clean(z)

    bounds = (np.full(2, -5.0), np.full(2, 5.0))
    solution = robust_least_squares(dies_at_the_fifth, [-1.2, 1.0], *bounds, 200)
    assert solution.status is Status.INTERRUPTED and solution.rejected == 0
    assert solution.message.startswith("stopped: a worker process died (forced)")
    assert solution.n_evaluations == 5 and len(calls) == 4
    costs = [0.5 * np.sum(clean(z)[0] ** 2) for z in list(calls)]  # clean appends
    assert solution.cost == pytest.approx(min(costs), rel=1e-12)


def test_a_killed_worker_process_is_reported_as_worker_died():
    """A real worker process that exits while it holds its task (os._exit in the worker)."""
    with pytest.raises(WorkerDied, match="a worker process died"):
        evaluate_all([os._exit, os._exit], [3, 3], processes=2)


def test_a_fit_whose_worker_died_is_interrupted_and_warns_on_prediction(oscillation, monkeypatch):
    model, x0, data = oscillation
    evaluate = dynamic.trajectory_sensitivities
    calls = []

    def build(*args, **kwargs):
        inner = evaluate(*args, **kwargs)

        def dying(theta):
            calls.append(theta)
            if len(calls) == 3:
                raise WorkerDied("a worker process died (forced)")
            return inner(theta)

        return dying

    monkeypatch.setattr(dynamic, "trajectory_sensitivities", build)
    report = fit_trajectory(model, data, output=bending_angle_map(), x0=x0, free=FREE, starts=2)
    assert report.status is Status.INTERRUPTED, report.message
    assert "stopped: a worker process died" in report.message
    assert "best point found before" in report.message
    assert len(calls) == 3  # two evaluated, the third died; the estimate not simulated again
    monkeypatch.undo()
    with pytest.warns(FitWarning, match="stopped before it finished"):
        predict_trajectory(model, data, report, output=bending_angle_map(), x0=x0)
    # dead at the first evaluation: no point to predict from, and the status says why
    calls.clear()
    monkeypatch.setattr(dynamic, "trajectory_sensitivities", build)
    calls.extend([None, None])  # the next call is the third
    first = fit_trajectory(model, data, output=bending_angle_map(), x0=x0, free=FREE)
    assert first.status is Status.INTERRUPTED and "best point" not in first.message
    monkeypatch.undo()
    with pytest.raises(FitError, match="cannot predict from a failed fit"):
        predict_trajectory(model, data, first, output=bending_angle_map(), x0=x0)


def test_starting_points_are_seeded_and_within_bounds():
    lower, upper = np.array([0.0, -np.inf]), np.array([2.0, np.inf])
    points = starting_points(np.array([1.0, 3.0]), lower, upper, 5, seed=3)
    again = starting_points(np.array([1.0, 3.0]), lower, upper, 5, seed=3)
    np.testing.assert_array_equal(points, again)
    np.testing.assert_array_equal(points[0], [1.0, 3.0])
    assert np.all((points[:, 0] >= 0) & (points[:, 0] <= 2))
    assert np.all(np.abs(points[:, 1] - 3.0) <= 1.5)


@pytest.fixture(scope="module")
def oscillation():
    segment = sc.Segment(
        rest_length=LENGTH,
        mass=0.017,
        radius=0.013,
        elongation_stiffness=sc.LinearStiffness(1000.0),
        bending_stiffness=sc.LinearStiffness(0.008),
        damping=[0.5, 4e-7, 4e-7],
    )
    model = sc.Model(sc.Robot(segments=(segment,)), quadrature_nodes=4)
    x0 = np.array([LENGTH, np.radians(20.0) / LENGTH, 0.0, 0.0, 0.0, 0.0])
    t = np.arange(0.0, 0.3 + 1e-12, 2e-3)
    template = Experiment(t, {"beta": np.zeros_like(t)}, units={"beta": "deg"})
    clean = fit_trajectory(model, template, output=bending_angle_map(), x0=x0, free=[])
    return model, x0, template.with_signals(beta=clean.predicted[:, 0])


FREE = [
    Free(SEG + "bending_stiffness.k0", 1e-4, 1.0, initial=0.012),
    Free(SEG + "damping[1,1]", 1e-9, 1e-4, initial=1e-6),
]


def _failing(fail_at):
    """``trajectory_sensitivities`` whose evaluators raise at the calls in ``fail_at``."""
    original = dynamic.trajectory_sensitivities

    def build(*args, **kwargs):
        evaluate, calls = original(*args, **kwargs), []

        def flaky(theta):
            calls.append(theta)
            if len(calls) in fail_at:
                raise RuntimeError('CVode returned "CV_ERR_FAILURE" (forced)')
            return evaluate(theta)

        return flaky

    return build


def test_a_fit_survives_a_trial_point_where_the_integrator_fails(oscillation, monkeypatch):
    model, x0, data = oscillation
    monkeypatch.setattr(dynamic, "trajectory_sensitivities", _failing({2}))
    report = fit_trajectory(model, data, output=bending_angle_map(), x0=x0, free=FREE)
    assert report.success, report.message
    assert "1 trial point(s) could not be evaluated and were rejected" in report.message
    np.testing.assert_allclose(report.values, [0.008, 4e-7], rtol=1e-5)


def test_predicting_from_a_failed_fit_raises(oscillation, monkeypatch):
    model, x0, data = oscillation
    with monkeypatch.context() as patch:
        patch.setattr(dynamic, "trajectory_sensitivities", _failing(set(range(1, 99))))
        failed = fit_trajectory(model, data, output=bending_angle_map(), x0=x0, free=FREE)
    assert failed.status is Status.NOT_CONVERGED
    assert "cannot be evaluated at the starting values" in failed.message
    np.testing.assert_array_equal(failed.values, [0.012, 1e-6])
    with pytest.raises(FitError, match="cannot predict from a failed fit"):
        predict_trajectory(model, data, failed, output=bending_angle_map(), x0=x0)
    early = fit_trajectory(
        model, data, output=bending_angle_map(), x0=x0, free=FREE, max_evaluations=2
    )
    assert early.status is Status.EVALUATION_LIMIT
    with pytest.warns(FitWarning, match="ran out of evaluations"):
        predict_trajectory(model, data, early, output=bending_angle_map(), x0=x0)


def test_multi_start_reports_the_spread_of_its_optima(oscillation):
    model, x0, data = oscillation
    report = fit_trajectory(
        model, data, output=bending_angle_map(), x0=x0, free=FREE, starts=3, seed=2
    )
    assert report.success, report.message
    assert report.optima.shape == (3, 2) and report.optimum_costs.shape == (3,)
    # the starts differ (uniform within the bounds) but reach the same minimum
    np.testing.assert_allclose(report.values, [0.008, 4e-7], rtol=1e-5)
    assert np.all(report.spread() <= 1e-5 * np.abs(report.values))
    assert "multi-start: 3 starts" in report.table()
    # the report's outputs are those of the best start's optimum (unit weights), not
    # those of the last point evaluated
    cost = 0.5 * np.sum(report.residuals**2)
    assert cost == pytest.approx(report.optimum_costs.min(), rel=1e-12)
    assert not np.all(report.optimum_costs == report.optimum_costs.min())
    with pytest.raises(sc.ParameterError, match="starts must be an integer"):
        fit_trajectory(model, data, output=bending_angle_map(), x0=x0, free=FREE, starts=0)


def test_a_fit_creeping_to_its_optimum_stops_once_the_steps_left_are_negligible():
    """A Jacobian whose first column is five times too large (as an inexact sensitivity
    can be) makes every step a fifth of the Gauss-Newton one: the fit creeps, and SciPy's
    tolerances stop it only after 63 evaluations. The stopping test on the remaining step
    against the standard errors ends it as converged within the budget, at a point within
    a thousandth of a standard error of the optimum."""
    from softcurve.identification.fits._solve import SETTLED, standard_errors

    rng = np.random.default_rng(0)
    x = np.linspace(0.0, 1.0, 200)
    y = 2.0 * x + 0.5 + 0.1 * rng.standard_normal(x.size)

    def residual_and_jacobian(z):
        return z[0] * x + z[1] - y, np.column_stack([5.0 * x, np.ones_like(x)])

    bounds = np.full(2, -np.inf), np.full(2, np.inf)
    creeping = robust_least_squares(residual_and_jacobian, [0.0, 0.0], *bounds, 55)
    assert creeping.status is Status.EVALUATION_LIMIT
    settled = robust_least_squares(residual_and_jacobian, [0.0, 0.0], *bounds, 55, settle=SETTLED)
    assert settled.status is Status.SUCCESS and "standard error" in settled.message
    optimum = np.polyfit(x, y, 1)
    exact = np.column_stack([x, np.ones_like(x)])
    errors = standard_errors(exact, exact @ optimum - y)
    assert np.all(np.abs(settled.z - optimum) < SETTLED * errors)


def test_with_the_residuals_alone_the_jacobian_is_evaluated_only_where_a_step_is_taken():
    """Given the residuals alone, trial points are evaluated by them and the Jacobian
    only where the solver steps: the same optimum in the same evaluations, fewer
    Jacobians (Rosenbrock's valley rejects some) for less work in all, the best point's
    Jacobian exact."""
    bounds = (np.full(2, -5.0), np.full(2, 5.0))
    full, full_calls = _rosenbrock(())
    both, alone_calls = _rosenbrock(())

    def residual(z):
        return both(z)[0]

    plain = robust_least_squares(_rosenbrock(())[0], [-1.2, 1.0], *bounds, 200)
    split = robust_least_squares(full, [-1.2, 1.0], *bounds, 200, residual=residual)
    assert split.status is Status.SUCCESS, split.message
    np.testing.assert_allclose(split.z, plain.z, atol=1e-10)
    assert split.n_evaluations == plain.n_evaluations == plain.n_jacobians
    assert split.n_jacobians == len(full_calls) < plain.n_jacobians
    work = len(full_calls) + solve.RESIDUAL_SHARE * len(alone_calls)
    assert work < plain.n_jacobians
    np.testing.assert_array_equal(split.jacobian, _rosenbrock(())[0](split.z)[1])
    # a point whose residuals can be evaluated but not its Jacobian is a rejected step
    failing, _ = _rosenbrock((3,))
    rejected = robust_least_squares(failing, [-1.2, 1.0], *bounds, 200, residual=residual)
    assert rejected.status is Status.SUCCESS and rejected.rejected == 1
    np.testing.assert_allclose(rejected.z, [1.0, 1.0], atol=1e-8)


def test_where_the_solver_steps_to_most_points_they_are_evaluated_with_the_jacobian():
    """Where the solver steps to more than 1 - RESIDUAL_SHARE of the points, the points
    are evaluated with their Jacobian at once: by the residuals alone first only while
    the count (from one of one) says otherwise, after the first point the next five."""
    calls = {"alone": 0}

    def residual_and_jacobian(z):
        return np.exp(z) - np.array([2.0, 3.0]), np.diag(np.exp(z))

    def residual(z):
        calls["alone"] += 1
        return residual_and_jacobian(z)[0]

    bounds = (np.full(2, -10.0), np.full(2, 10.0))
    plain = robust_least_squares(residual_and_jacobian, [4.0, -3.0], *bounds, 200)
    split = robust_least_squares(
        residual_and_jacobian, [4.0, -3.0], *bounds, 200, residual=residual
    )
    np.testing.assert_allclose(split.z, np.log([2.0, 3.0]), atol=1e-10)
    # every point is a step: (k + 1) / (k + 2) exceeds 1 - RESIDUAL_SHARE from k = 6 on
    assert split.n_evaluations == split.n_jacobians == plain.n_evaluations == 9
    assert calls["alone"] == 5


def test_a_trajectory_fit_evaluates_its_trial_points_without_the_jacobian(oscillation, monkeypatch):
    """On the driver's route a fit evaluates trial points by the outputs alone and the
    Jacobian where it steps: the estimate and intervals of a fit that evaluates every
    point with its Jacobian."""
    model, x0, data = oscillation
    if native.problem(model) is None:
        pytest.skip("softcurve's CVODES driver is not available here (no C compiler)")
    counts = {"outputs": 0, "call": 0}
    call, outputs = SensitivityEvaluator.__call__, SensitivityEvaluator.outputs

    def counted_call(self, theta):
        counts["call"] += 1
        return call(self, theta)

    def counted_outputs(self, theta):
        counts["outputs"] += 1
        return outputs(self, theta)

    monkeypatch.setattr(SensitivityEvaluator, "__call__", counted_call)
    monkeypatch.setattr(SensitivityEvaluator, "outputs", counted_outputs)
    start = [Free(SEG + "bending_stiffness.k0", 1e-4, 1.0, initial=0.002), FREE[1]]
    kwargs = dict(output=bending_angle_map(), x0=x0, free=start)
    split = fit_trajectory(model, data, **kwargs)
    assert split.success, split.message
    assert counts["outputs"] > 0 and split.n_jacobians == counts["call"] <= split.n_evaluations
    monkeypatch.setattr(SensitivityEvaluator, "outputs_alone", property(lambda self: False))
    counts.update(outputs=0, call=0)
    plain = fit_trajectory(model, data, **kwargs)
    assert counts["outputs"] == 0 and counts["call"] == plain.n_evaluations == plain.n_jacobians
    np.testing.assert_allclose(split.values, plain.values, rtol=1e-6)
    np.testing.assert_allclose(split.standard_errors, plain.standard_errors, rtol=1e-4)


def test_looser_tolerances_are_checked_at_the_estimate(oscillation, monkeypatch):
    """With looser integrator tolerances a fit integrates its estimate once more at the
    default ones and reports the largest change of an output relative to the residuals'
    RMS: small for rtol 1e-6, and said in the message (tighten them) for rtol 1e-2; the
    default tolerances report nothing."""
    model, x0, data = oscillation
    if native.problem(model) is None:
        pytest.skip("softcurve's CVODES driver is not available here (no C compiler)")
    rng = np.random.default_rng(7)
    noisy = data.with_signals(beta=data.signals["beta"] + 0.05 * rng.standard_normal(data.t.size))
    kwargs = dict(output=bending_angle_map(), x0=x0, free=FREE)
    default = fit_trajectory(model, noisy, **kwargs)
    assert "integration_error" not in default.extra
    loose = fit_trajectory(
        model, noisy, integrator_options={"reltol": 1e-6, "abstol": 1e-8}, **kwargs
    )
    assert 0 < loose.extra["integration_error"] < dynamic.INTEGRATION_SHARE
    assert "tighten" not in loose.message
    np.testing.assert_allclose(loose.values, default.values, rtol=1e-3)
    coarse = fit_trajectory(
        model, noisy, integrator_options={"reltol": 1e-2, "abstol": 1e-2}, **kwargs
    )
    assert coarse.extra["integration_error"] > dynamic.INTEGRATION_SHARE
    assert "to rtol 1e-08, atol 1e-10: tighten them" in coarse.message
    # a check that cannot integrate (CVODES fails at the tighter tolerances) keeps the
    # fit's estimate and says so
    outputs = SensitivityEvaluator.outputs

    def failing(self, theta, tolerances=None):
        if tolerances is not None:
            raise RuntimeError("CVode returned CV_TOO_MUCH_WORK (forced)")
        return outputs(self, theta)

    monkeypatch.setattr(SensitivityEvaluator, "outputs", failing)
    options = {"reltol": 1e-6, "abstol": 1e-8}
    kept = fit_trajectory(model, noisy, integrator_options=options, **kwargs)
    assert kept.extra["integration_error"] is None
    assert "the integration at the estimate was not checked: CVode returned" in kept.message
    np.testing.assert_allclose(kept.values, loose.values, rtol=1e-12)
    # mixed: the check takes the tighter of each tolerance
    assert dynamic._looser_tolerances({"reltol": 1e-10, "abstol": 1e-8}) == (1e-10, 1e-10)
    assert dynamic._looser_tolerances({"reltol": 1e-9}) is None
