"""The quasi-static fit's predictions (``EquilibriumPredictor``): where each evaluation
starts its equilibria, the samples split over threads, the symbolic functions kept with
the model."""

import numpy as np
import pytest

import softcurve as sc
from softcurve.identification.experiments._loading import Experiment
from softcurve.identification.fits import _equilibria as equilibria
from softcurve.identification.fits._equilibria import EquilibriumPredictor
from softcurve.identification.fits._parameters import Free, FreeParameters
from softcurve.identification.maps import bellows_input_map, curvature_map


@pytest.fixture(scope="module")
def setting():
    segment = sc.Segment(
        rest_length=0.064,
        mass=0.017,
        radius=0.013,
        elongation_stiffness=sc.LinearStiffness(1000.0),
        bending_stiffness=sc.TanhStiffness(0.014, 0.006, 4.0),
        damping=[0.5, 4e-7, 4e-7],
    )
    model = sc.Model(sc.Robot(segments=(segment,)), quadrature_nodes=4)
    t = np.linspace(0.0, 6.0, 16)
    phase, amplitude = 4 * np.pi * t / 6.0, 3e3 + 1.4e4 * t / 6.0
    pressures = {f"p{i}": 2e4 + amplitude * np.sin(phase - 2 * np.pi * i / 3) for i in range(3)}
    experiment = Experiment(t, {"kx": 0 * t, "ky": 0 * t}, pressures)
    inputs, output = bellows_input_map(area=2.3e-5, distance=0.01), curvature_map()
    free = [Free("bellows.angle", -np.pi, np.pi), Free("bellows.area", 1e-7, 1e-3)]
    parameters = FreeParameters(model, free, {**inputs.parameters, **output.parameters}, {})
    q0 = np.array([0.064, 0.0, 0.0])
    return model, parameters, output, inputs, q0, experiment


def _predictor(setting):
    model, parameters, output, inputs, q0, experiment = setting
    return EquilibriumPredictor(model, parameters, output, inputs, q0)(experiment)


def test_each_evaluation_starts_from_the_first_order_prediction(setting, monkeypatch):
    """After an evaluation at ``theta``, the next one's equilibria start at the previous
    solutions moved along their tangent ``dq/dtheta``: the start's error is of second
    order in the change of ``theta`` (a quarter for half the change), and far below the
    error of starting at the previous solutions."""
    starts = []
    solve = equilibria.solve_equilibria

    def recording(batch_system, system_of, q0, **options):
        starts.append(np.array(q0))
        return solve(batch_system, system_of, q0, **options)

    monkeypatch.setattr(equilibria, "solve_equilibria", recording)
    theta = np.array([-0.5, 2.3e-5])
    ratios = []
    for change in (0.04, 0.02):
        evaluate = _predictor(setting)
        evaluate(theta)
        evaluate(theta * (1 + change))
        start = starts[-1]
        solution = _solution(setting, theta * (1 + change))
        previous = _solution(setting, theta)
        predicted_error = np.abs(start - solution).max()
        assert predicted_error < 0.05 * np.abs(previous - solution).max()
        ratios.append(predicted_error)
    assert 0.15 < ratios[1] / ratios[0] < 0.35  # order 2: 1/4


def _long(setting, samples=400):
    """The fixture's setting with the record's sweep sampled ``samples`` times."""
    model, parameters, output, inputs, q0, experiment = setting
    t = np.linspace(0.0, 6.0, samples)
    phase, amplitude = 4 * np.pi * t / 6.0, 3e3 + 1.4e4 * t / 6.0
    pressures = {f"p{i}": 2e4 + amplitude * np.sin(phase - 2 * np.pi * i / 3) for i in range(3)}
    record = Experiment(t, {"kx": 0 * t, "ky": 0 * t}, pressures)
    return model, parameters, output, inputs, q0, record


def test_a_long_record_starts_from_equilibria_of_nearby_inputs(setting, monkeypatch):
    """At the first evaluation of a long record, every sample starts from the solution of
    the sample of nearest inputs among about sqrt(T) solved first, with its stiffness for
    chord steps: the starts lie closer to the solutions than the initial guess does (a
    twentieth of the samples solved first, 36 degrees apart along the sweep's two turns),
    the record takes fewer batched evaluations of its stiffness, and the predictions are
    those of starting every sample at the initial guess."""
    theta = np.array([-0.5, 2.3e-5])
    long = _long(setting)
    samples = long[-1].t.size
    runs, solve = {}, equilibria.solve_equilibria
    for warm in (True, False):
        monkeypatch.setattr(equilibria, "WARM_START_MIN", 256 if warm else samples + 1)
        starts, stiffness_calls = [], []

        def recording(batch_system, system_of, q0, *, seen=(starts, stiffness_calls), **options):
            def counted(q):
                seen[1].append(q.shape[1])
                return batch_system(q)

            if q0.shape[1] == samples:
                seen[0].append(np.array(q0))
            return solve(counted, system_of, q0, **options)

        monkeypatch.setattr(equilibria, "solve_equilibria", recording)
        runs[warm] = (_predictor(long)(theta), starts[0], stiffness_calls.count(samples))
    (y_warm, jac_warm), warm_start, warm_calls = runs[True]
    (y_cold, jac_cold), cold_start, cold_calls = runs[False]
    solution = _solution(long, theta)
    warm_error, cold_error = np.abs(warm_start - solution), np.abs(cold_start - solution)
    assert warm_error.max() < 0.5 * cold_error.max()
    assert np.median(warm_error) < 0.2 * np.median(cold_error)
    assert warm_calls < cold_calls
    np.testing.assert_allclose(y_warm, y_cold, rtol=1e-8, atol=1e-8)  # both within tol
    np.testing.assert_allclose(jac_warm, jac_cold, rtol=1e-6, atol=1e-9)


def test_nearest_starts_measure_each_input_in_its_range():
    """The nearest solved sample in inputs scaled by their ranges (unscaled, the second
    input, a thousand times larger, would pick the other sample for the last two);
    without inputs, the first."""
    inputs = np.array([[0.0, 0.0], [1.0, 1000.0], [0.9, 300.0], [0.1, 600.0]])
    np.testing.assert_array_equal(equilibria.nearest_starts(inputs, np.array([0, 1])), [0, 1, 1, 0])
    assert equilibria.nearest_starts(np.zeros((5, 0)), np.array([2])).tolist() == [0] * 5
    # an input that never changes counts for nothing (its range is zero)
    held = np.column_stack([inputs, np.full(4, 7.0)])
    np.testing.assert_array_equal(equilibria.nearest_starts(held, np.array([0, 1])), [0, 1, 1, 0])


def _solution(setting, theta):
    """The equilibria at ``theta`` (n, T), from a fresh predictor."""
    captured = []
    solve = equilibria.solve_equilibria

    def capturing(*args, **options):
        roots = solve(*args, **options)
        captured.append(np.column_stack([root.q for root in roots]))
        return roots

    original, equilibria.solve_equilibria = equilibria.solve_equilibria, capturing
    try:
        _predictor(setting)(theta)
    finally:
        equilibria.solve_equilibria = original
    return captured[-1]


def test_far_and_failed_evaluations_leave_no_trace(setting):
    """Parameters that jump far, or to where some equilibria leave the model's domain:
    such an evaluation raises (the fit rejects the step) instead of returning roots
    outside the domain, and every later evaluation equals a fresh predictor's (a first-
    order start thrown far is not taken)."""
    evaluate = _predictor(setting)
    sequence = ([-0.5, 2.3e-5], [2.5, 6e-4], [-0.5, 2.3e-5], [-2.0, 3e-4], [1.0, 1e-4])
    for theta in map(np.array, sequence):
        if theta[1] == 6e-4:  # 26 times the area: some samples bend beyond the domain
            for predictor in (evaluate, _predictor(setting)):
                with pytest.raises(RuntimeError, match="outside the model's domain"):
                    predictor(theta)
            continue
        (y, jacobian), (y_fresh, jacobian_fresh) = evaluate(theta), _predictor(setting)(theta)
        np.testing.assert_allclose(y, y_fresh, rtol=1e-8, atol=1e-8)
        np.testing.assert_allclose(jacobian, jacobian_fresh, rtol=1e-6, atol=1e-9)


def test_a_map_reading_a_changed_value_gets_new_functions(setting):
    """The functions kept with the model are keyed by the maps' expressions: a map whose
    function reads a value that changed between two fits predicts with the new value."""
    model, parameters, output, inputs, q0, experiment = setting
    gain = {"value": 1.0}

    def scaled(q, u, values):
        return gain["value"] * inputs.function(q, u, values)

    custom = type(inputs)(scaled, inputs.parameters)
    theta = np.array([-0.5, 2.3e-5])
    before = EquilibriumPredictor(model, parameters, output, custom, q0)(experiment)(theta)[0]
    gain["value"] = 2.0
    after = EquilibriumPredictor(model, parameters, output, custom, q0)(experiment)(theta)[0]
    assert np.abs(after).max() > 1.5 * np.abs(before).max()


def test_threads_give_the_serial_predictions(setting, monkeypatch):
    """The samples on two threads give exactly the predictions and Jacobian of one."""
    theta = np.array([-0.45, 2.2e-5])
    results = []
    for threads in (1, 2):
        monkeypatch.setattr(equilibria, "default_threads", lambda threads=threads: threads)
        evaluate = _predictor(setting)
        results.append([evaluate(theta), evaluate(theta * 1.01)])
    for (y_one, jac_one), (y_two, jac_two) in zip(*results, strict=True):
        np.testing.assert_array_equal(y_one, y_two)
        np.testing.assert_array_equal(jac_one, jac_two)


def test_symbolic_functions_are_built_once_per_model_and_maps(setting):
    model, parameters, output, inputs, q0, experiment = setting
    predictor = EquilibriumPredictor(model, parameters, output, inputs, q0)
    keys, n_p = sorted(parameters.extra), parameters.p0.size
    first = predictor._functions(keys, n_p, 3, [n_p, n_p + 1])
    again = EquilibriumPredictor(model, parameters, output, inputs, q0)._functions(
        keys, n_p, 3, [n_p, n_p + 1]
    )
    assert all(a is b for a, b in zip(first, again, strict=True))
    # other active parameters: the same balance, other sensitivities
    other = predictor._functions(keys, n_p, 3, [n_p])
    assert other[0] is first[0] and other[2] is not first[2]


def test_a_record_of_compiled_min_samples_runs_the_compiled_functions(setting, monkeypatch):
    """From COMPILED_MIN samples on, the balance and its sensitivities are compiled (kept
    with the model apart from the SX ones): the predictions and Jacobian of CasADi's
    virtual machine to rounding."""
    model, parameters, output, inputs, q0, experiment = setting
    theta = np.array([-0.45, 2.2e-5])
    predictor = EquilibriumPredictor(model, parameters, output, inputs, q0)
    keys, n_p = sorted(parameters.extra), parameters.p0.size
    machine = predictor._functions(keys, n_p, 3, [n_p, n_p + 1])
    built = predictor._functions(keys, n_p, 3, [n_p, n_p + 1], compiled=True)
    assert all(f.is_a("SXFunction") for f in machine)
    if built[0].is_a("SXFunction"):
        pytest.skip("no C compiler here: the compiled functions are the SX ones")
    results = []
    for smallest in (experiment.t.size + 1, experiment.t.size):
        monkeypatch.setattr(equilibria, "COMPILED_MIN", smallest)
        results.append(_predictor(setting)(theta))
    (y_vm, jac_vm), (y_c, jac_c) = results
    np.testing.assert_allclose(y_c, y_vm, rtol=1e-12, atol=1e-14)
    np.testing.assert_allclose(jac_c, jac_vm, rtol=1e-9, atol=1e-12)
