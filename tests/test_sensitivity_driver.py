"""The identification's forward sensitivities through softcurve's CVODES driver against
CasADi's CVODES on the augmented system (the route without the driver): both inputs
holds, an input lag, a failure, the evaluator carried into another process, and the
columns' right-hand side in two parts on two threads."""

from __future__ import annotations

import multiprocessing
import pickle
from concurrent.futures import ProcessPoolExecutor

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.identification.experiments import Experiment
from softcurve.identification.fits._parameters import Free, FreeParameters
from softcurve.identification.maps import bellows_input_map, curvature_map
from softcurve.simulation.sensitivity import _sensitivity as sensitivity_module
from softcurve.simulation.sensitivity._sensitivity import (
    SENSITIVITY_CVODES,
    column_parts,
    integrate_sensitivities,
    parameter_seeds,
    split_states,
    tangents,
    trajectory_sensitivities,
)
from softcurve.simulation.solvers import _driver as driver_library
from softcurve.simulation.solvers import _driver as native

SEG = "segments[0]."


@pytest.fixture(scope="module")
def model():
    model = sc.Model(sc.presets.ifac2020(), quadrature_nodes=4)
    if native.problem(model) is None:
        pytest.skip("softcurve's CVODES driver is not available here (no C compiler)")
    return model


def bellows_trial(model, hold, lag=None, options=None, threads=1, experiment=None):
    """Bellows with smooth random pressures for 1.5 s at 12 Hz (or the pressures of
    ``experiment``, with its signals kx and ky); four free parameters."""
    if experiment is None:
        rng = np.random.default_rng(16)
        t = np.arange(0.0, 1.5 + 1e-9, 1 / 12)
        knots = np.linspace(0.0, 1.5, 4)
        pressures = {f"p{i}": np.interp(t, knots, 1e4 + 1e4 * rng.random(4)) for i in range(3)}
        experiment = Experiment(t, {"kx": 0 * t, "ky": 0 * t}, pressures)
    pressures = experiment.inputs
    inputs = bellows_input_map(area=2e-5, distance=0.01)
    free = [
        Free(SEG + "bending_stiffness.a1"),
        Free(SEG + "damping[1,1]"),
        Free("bellows.area"),
        Free("bellows.angle", scale=1.0),
    ]
    extra = dict(inputs.parameters)
    if lag:
        free.append(Free("input_lag", scale=0.01))
        extra["input_lag"] = 0.02
    parameters = FreeParameters(model, free, extra, {}, None)
    x0 = np.zeros(model.n_state + (3 if lag else 0))
    x0[:3] = [0.0644, 1.0, 0.0]
    if lag:
        x0[model.n_state :] = [p[0] for p in pressures.values()]
    evaluate = trajectory_sensitivities(
        model, parameters, curvature_map(), inputs, x0, experiment, options,
        "input_lag" if lag else None, hold, threads,
    )  # fmt: skip
    return evaluate, parameters.theta0


@pytest.mark.parametrize("lag", [None, 1])
def test_the_driver_agrees_with_casadis_cvodes(model, lag):
    evaluate, theta = bellows_trial(model, "linear", lag)
    y, jacobian = evaluate(theta)
    assert evaluate.stats["route"] == "sensitivity-driver"
    assert evaluate.stats["sensitivity_evaluations"] > 0
    with native.casadi_only():
        reference, theta_again = bellows_trial(model, "linear", lag)
        y_ref, jacobian_ref = reference(theta_again)
    assert reference.stats["route"] == "sensitivity-casadi"
    _assert_agree(y, jacobian, y_ref, jacobian_ref, 1e-6)


def test_the_driver_restarts_at_every_held_input(model):
    """Against CasADi's route at rtol 1e-10: at the default tolerances CasADi's route is
    the less accurate of the two across the jumps of held inputs (8e-7 against 8e-10 from
    a reference at 1e-12; CasADi's Adams with functional iteration fails at 1e-12)."""
    evaluate, theta = bellows_trial(model, "constant")
    y, jacobian = evaluate(theta)
    assert evaluate.stats["route"] == "sensitivity-driver"
    with native.casadi_only():
        tight = {"reltol": 1e-10, "abstol": 1e-12, "max_num_steps": 10**6}
        reference, theta_again = bellows_trial(model, "constant", options=tight)
        y_ref, jacobian_ref = reference(theta_again)
    assert reference.stats["route"] == "sensitivity-casadi"
    _assert_agree(y, jacobian, y_ref, jacobian_ref, 1e-7)


def _assert_agree(y, jacobian, y_ref, jacobian_ref, tolerance):
    """Outputs within ``tolerance`` and each Jacobian column within 10 ``tolerance`` of
    the reference's largest entry (the routes integrate at rtol 1e-8)."""
    assert np.abs(y - y_ref).max() <= tolerance * np.abs(y_ref).max()
    for j in range(jacobian.shape[1]):
        column, expected = jacobian[:, j], jacobian_ref[:, j]
        assert np.abs(column - expected).max() <= 10 * tolerance * np.abs(expected).max(), j


UNCONTROLLED = 1000
"""Bound on the sensitivity columns' error outside the error test, in rtol: nothing
controls it, and it follows the build's rounding (with the linear hold on this trial:
2-7e-8 with the sensitivity function at ``-O1``, 1.6e-8 to 1.8e-7 with
``FUNCTION_FLAGS`` and NumPy 2.4, 4.4e-7 with NumPy 2.2, whose Gauss weights differ in
their last bits, and up to 7.9e-7 with weights nudged by a few ulps); a Gauss-Newton
step resolves none of it."""


@pytest.mark.parametrize("hold", ["linear", "constant"])
def test_the_sensitivities_are_as_accurate_as_the_error_test_says(model, hold):
    """Against a reference at rtol 1e-12, at the default rtol 1e-8: the outputs within 2
    rtol, either way; the Jacobian's columns within 5 rtol of each column's largest entry
    with them in the error test (``fsens_err_con``, measured 0.7-1.4 rtol) and within
    :data:`UNCONTROLLED` rtol without (the default)."""
    tight = {"reltol": 1e-12, "abstol": 1e-14, "max_num_steps": 10**6}
    reference, theta = bellows_trial(model, hold, options=tight)
    y_ref, jacobian_ref = reference(theta)
    rtol = SENSITIVITY_CVODES["reltol"]
    for options, bound in ((None, UNCONTROLLED), ({"fsens_err_con": True}, 5)):
        evaluate, theta = bellows_trial(model, hold, options=options)
        y, jacobian = evaluate(theta)
        assert evaluate.stats["route"] == reference.stats["route"] == "sensitivity-driver"
        assert np.abs(y - y_ref).max() <= 2 * rtol * np.abs(y_ref).max()
        error = np.abs(jacobian - jacobian_ref).max(axis=0) / np.abs(jacobian_ref).max(axis=0)
        assert error.max() <= bound * rtol, (options, error)


def test_fsens_err_con_puts_the_columns_in_the_driver_error_test(model):
    evaluate, theta = bellows_trial(model, "linear")
    y, jacobian = evaluate(theta)
    tested, theta_again = bellows_trial(model, "linear", options={"fsens_err_con": True})
    y_tested, jacobian_tested = tested(theta_again)
    assert tested.stats["route"] == "sensitivity-driver"
    # more error to control, more steps; the same trajectory within the tolerances, the
    # columns within what the default leaves uncontrolled
    assert tested.stats["steps"] > evaluate.stats["steps"]
    assert np.abs(y - y_tested).max() <= 1e-7 * np.abs(y_tested).max()
    error = np.abs(jacobian - jacobian_tested).max(axis=0) / np.abs(jacobian_tested).max(axis=0)
    assert error.max() <= UNCONTROLLED * SENSITIVITY_CVODES["reltol"], error


def test_the_driver_counts_every_restart_of_a_held_input(model):
    evaluate, theta = bellows_trial(model, "constant")
    evaluate(theta)
    held = dict(evaluate.stats)
    evaluate, theta = bellows_trial(model, "linear")
    evaluate(theta)
    # 17 restarts (one per sample after the first): more steps than the linear hold's run
    assert held["steps"] > evaluate.stats["steps"] > 0


def test_options_the_driver_does_not_know_select_casadis_route(model):
    evaluate, theta = bellows_trial(model, "linear", options={"max_order": 3})
    evaluate(theta)
    assert evaluate.stats["route"] == "sensitivity-casadi"


@pytest.mark.parametrize("threads", [1, 2])
def test_a_failure_of_the_driver_is_a_runtime_error_naming_cvodes(model, threads):
    evaluate, theta = bellows_trial(model, "linear", options={"max_num_steps": 2}, threads=threads)
    with pytest.raises(RuntimeError, match="CVODES failed after t = 0 s: CV_TOO_MUCH_WORK"):
        evaluate(theta)
    assert evaluate.driven.helper == {1: "none", 2: "shared"}[threads]


def _evaluate_in_this_process(evaluate, theta):
    y, jacobian = evaluate(theta)
    return y, jacobian, evaluate.stats["route"]


@pytest.mark.parametrize("threads", [1, 2])
def test_an_evaluator_carried_to_a_new_process_loads_the_driver_again(model, threads):
    """With two threads, both parts (and CasADi's fallback on them) travel by path."""
    evaluate, theta = bellows_trial(model, "linear", threads=threads)
    y, jacobian = evaluate(theta)
    blob = pickle.dumps(evaluate)
    assert len(blob) < 1_000_000  # the libraries' paths travel, not their functions
    spawn = multiprocessing.get_context("spawn")
    with ProcessPoolExecutor(1, mp_context=spawn) as pool:
        y_new, jacobian_new, route = pool.submit(
            _evaluate_in_this_process, evaluate, theta
        ).result()
    assert route == evaluate.stats["route"]
    assert route == {1: "sensitivity-driver", 2: "sensitivity-driver-split"}[threads]
    np.testing.assert_array_equal(y_new, y)
    np.testing.assert_array_equal(jacobian_new, jacobian)


# -- the columns' right-hand side in two parts (sensitivity_split, sensitivity_parts) --


@pytest.mark.parametrize(("coordinates", "states"), [(1, 3), (3, 9), (6, 18), (9, 30)])
def test_the_split_covers_every_state_once(coordinates, states):
    first, second = split_states(coordinates, states)
    assert sorted(first + second) == list(range(states))
    assert second and set(second) <= set(range(coordinates))  # the costly columns, shared


def test_the_parts_sum_to_the_columns_right_hand_side(model):
    whole, theta = bellows_trial(model, "linear")
    split, _ = bellows_trial(model, "linear", threads=2)
    _, parts = split._route()
    fs = whole.variational
    n_x, m = whole.n_x, len(whole.active)
    rng = np.random.default_rng(7)
    d_value = np.array(whole.direct(theta)[0]).ravel()
    dsc = np.concatenate([d_value, whole.scale])
    for _ in range(5):
        x = np.concatenate([d_value[-n_x:], rng.normal(size=n_x * m)])
        x[:n_x] += rng.normal(0.0, 0.1, n_x) * (np.abs(x[:n_x]) + 1.0)
        u = 1e4 + 1e4 * rng.random(fs.size1_in(1))
        expected = np.array(fs(x, u, dsc)).ravel()[n_x:]
        total = sum(np.asarray(part(x, u, dsc)).ravel() for part in parts)
        assert np.abs(total - expected).max() <= 1e-12 * np.abs(expected).max()


def test_forward_derivatives_through_the_segments_calls_equal_the_jacobians_product():
    """Three segments, whose right-hand side calls the segments' functions: the columns'
    derivative by forward derivatives through the calls (what the sensitivities compile
    for a chain) against the Jacobian's product of the same expression, at bent, moving
    states, with and without the parameters' seeds, in fewer instructions; and the two
    parts of the split (forward through the calls too) sum to it."""
    model = sc.Model(sc.presets.ifac2020().with_segments(3), quadrature_nodes=2, compile=False)
    rhs = model.casadi_rhs()
    n_x, n_d, m = rhs.size1_in(0), rhs.size1_in(2), 3
    xs, tau, ds = ca.SX.sym("x", n_x), ca.SX.sym("tau", model.n), ca.SX.sym("d", n_d)
    v, scales = ca.SX.sym("v", n_x, m), ca.SX.sym("scale", m)
    f = rhs(xs, tau, ds)
    seeds = parameter_seeds(n_d, (0, n_d // 2, n_d - 1), scales)
    inputs = [xs, ca.vec(v), tau, ds, scales]
    rng = np.random.default_rng(3)
    x = np.zeros(n_x)
    spread = np.tile([1e-3, 2.0, 2.0], 3)
    x[: model.n] = np.tile([0.064, 8.0, -4.0], 3) + rng.normal(0, 1, model.n) * spread
    x[model.n : 2 * model.n] = rng.normal(0, 1, model.n) * np.tile([0.01, 10, 10], 3)
    values = [x, rng.normal(size=n_x * m), rng.normal(0, 1e-3, model.n), model.parameters]
    values.append(rng.uniform(0.5, 2.0, m))
    wholes = []
    for along in ((ds, seeds), (None, None)):
        through = ca.Function("through", inputs, [tangents(f, xs, v, *along, True)])
        product = ca.Function("product", inputs, [tangents(f, xs, v, *along, False)])
        expected = np.array(product(*values))
        got = np.array(through(*values))
        assert np.abs(expected).max() > 0
        assert np.abs(got - expected).max() <= 1e-11 * np.abs(expected).max()
        assert through.n_instructions() < product.n_instructions() / 3
        wholes.append(expected)
    parts = column_parts(f, xs, tau, ds, v, scales, seeds, model.n, True)
    state, columns, parameters = values[0], values[1], values[3]
    arguments = (np.concatenate([state, columns]), values[2], np.append(parameters, values[4]))
    total = sum(np.array(part(*arguments)).ravel() for part in parts)
    whole = wholes[0].ravel(order="F")  # vec: column after column
    assert np.abs(total - whole).max() <= 1e-11 * np.abs(whole).max()


def test_fits_of_one_structure_build_their_sensitivity_functions_once(monkeypatch):
    """The SX functions (whose common-subexpression elimination is most of an evaluator's
    build at one segment) are kept with the model by the state's expression: another
    input hold builds none, an input lag (another state derivative) and the split over
    two threads build theirs; an evaluator from kept functions computes what one from
    a fresh model does."""
    built = []
    original = sensitivity_module.sensitivity_functions

    def counting(*args):
        built.append(args[1:])
        return original(*args)

    monkeypatch.setattr(sensitivity_module, "sensitivity_functions", counting)
    model = sc.Model(sc.presets.ifac2020(), quadrature_nodes=4)  # from the disk cache
    first, theta = bellows_trial(model, "linear")
    assert len(built) == 1
    again, _ = bellows_trial(model, "constant")
    assert len(built) == 1
    bellows_trial(model, "linear", lag=1)
    assert len(built) == 2
    bellows_trial(model, "linear", threads=2)
    assert len(built) == 3
    fresh, _ = bellows_trial(sc.Model(sc.presets.ifac2020(), quadrature_nodes=4), "constant")
    y, jacobian = again(theta)
    y_fresh, jacobian_fresh = fresh(theta)
    np.testing.assert_array_equal(y, y_fresh)
    np.testing.assert_array_equal(jacobian, jacobian_fresh)
    assert np.abs(first(theta)[0] - y).max() > 0  # the holds differ: not one evaluator


def test_two_threads_give_the_one_threads_trajectory_and_jacobian(model):
    """The parts are summed in another order than the whole is computed, so the columns
    (outside the error test) differ by rounding, within what nothing controls."""
    evaluate, theta = bellows_trial(model, "linear")
    y, jacobian = evaluate(theta)
    split, _ = bellows_trial(model, "linear", threads=2)
    y_split, jacobian_split = split(theta)
    assert split.driven.helper == "shared" and len(split.driven.columns) == 2
    assert split.stats["route"] == "sensitivity-driver-split"
    rtol = SENSITIVITY_CVODES["reltol"]
    assert np.abs(y_split - y).max() <= 2 * rtol * np.abs(y).max()
    error = np.abs(jacobian_split - jacobian).max(axis=0) / np.abs(jacobian).max(axis=0)
    assert error.max() <= UNCONTROLLED * rtol, error


HELPER_TAKES_ALL = ("SOFTCURVE_TEST_HELPER_TAKES_ALL",)
"""The define of a build of the driver where the helper thread evaluates every second
part (the driver never claims one; ``parts.c``): the helper's path for certain."""


def test_the_helper_thread_changes_no_bit(model):
    """Whichever thread evaluates the second part, the sum is the same: with and without
    the helper thread, every output and counter is equal, over many evaluations. The
    test's own build of the driver (:data:`HELPER_TAKES_ALL`) runs the helper's path for
    certain; under the product's ``"shared"`` the scheduler decides (on a busy machine the
    helper may never win a claim)."""
    helper_only = driver_library.library(HELPER_TAKES_ALL)
    assert helper_only is not None and helper_only is not driver_library.library()
    evaluate, theta = bellows_trial(model, "linear", threads=2)
    problem, parts = evaluate._route()
    route = evaluate.driven
    d_value = np.array(evaluate.direct(theta)[0]).ravel()
    start = np.concatenate([d_value[-evaluate.n_x :], evaluate.seed.ravel("F")])
    dsc = np.concatenate([d_value, evaluate.scale])
    runs = [
        integrate_sensitivities(
            problem,
            parts,
            start,
            d_value,
            dsc,
            route.times,
            route.table,
            route.linear,
            route.settings,
            helper,
            library,
        )  # fmt: skip
        for helper, library in [
            ("none", None),
            ("shared", helper_only),
            ("shared", None),
            ("shared", None),
        ]
    ]
    alone = runs[0][3]
    assert alone["helper_evaluations"] == 0 and alone["sensitivity_evaluations"] > 100
    helper_path = runs[1][3]
    assert helper_path["helper_evaluations"] == helper_path["sensitivity_evaluations"]
    for out, reached, flag, counts in runs[1:]:
        assert flag == 0 and reached == route.times.size
        np.testing.assert_array_equal(out, runs[0][0])
        assert 0 <= counts.pop("helper_evaluations") <= counts["sensitivity_evaluations"]
        assert counts == {k: v for k, v in alone.items() if k != "helper_evaluations"}


def test_an_unknown_helper_mode_is_refused_by_name(model):
    evaluate, _ = bellows_trial(model, "linear", threads=2)
    problem, parts = evaluate._route()
    with pytest.raises(ValueError, match="helper must be one of .* got True"):
        integrate_sensitivities(problem, parts, *[None] * 7, True)


@pytest.mark.parametrize("threads", [1, 2])
def test_an_evaluator_without_the_driver_integrates_by_casadi(model, threads):
    """The fallback of a process without the driver: CasADi's CVODES on the driver's
    compiled function of the augmented system, or on that system assembled from the
    compiled parts, to the same trajectory."""
    evaluate, theta = bellows_trial(model, "linear", threads=threads)
    y, jacobian = evaluate(theta)
    evaluate._native = False  # as a worker that could not load the libraries
    y_casadi, jacobian_casadi = evaluate(theta)
    assert evaluate.stats["route"] == "sensitivity-casadi"
    _assert_agree(y, jacobian, y_casadi, jacobian_casadi, 1e-6)


@pytest.mark.parametrize("hold", ["linear", "constant"])
def test_the_outputs_alone_are_the_outputs_of_a_call(model, hold):
    """The state integrated without the columns, on the driver's route: the outputs of a
    call to the integration's tolerance, no sensitivity evaluated; on CasADi's route (a
    worker that could not load the libraries) a call's outputs."""
    evaluate, theta = bellows_trial(model, hold, lag=1)
    assert evaluate.outputs_alone
    y, _ = evaluate(theta)
    alone = evaluate.outputs(theta)
    assert evaluate.stats["sensitivity_evaluations"] == 0 and evaluate.stats["steps"] > 0
    np.testing.assert_allclose(alone, y, rtol=1e-6, atol=1e-6 * np.abs(y).max())
    evaluate._native = False
    np.testing.assert_array_equal(evaluate.outputs(theta), evaluate(theta)[0])
    assert evaluate.stats["route"] == "sensitivity-casadi"
