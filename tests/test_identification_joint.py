"""Joint fits of several experiments: shared and per-experiment parameters, weights.

Data are made by softcurve itself (the small robot of test_identify.py, 4 quadrature
nodes, 0.3 s free oscillations), so the truth is known exactly.
"""

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.identification.experiments._loading import Experiment
from softcurve.identification.fits import _joint as joint
from softcurve.identification.fits._dynamic import fit_trajectory, predict_trajectory
from softcurve.identification.fits._parameters import Free
from softcurve.identification.fits._weights import weight_matrix
from softcurve.identification.maps import bending_angle_map, curvature_map

SEG = "segments[0]."
LENGTH = 0.064
TRUTH = {"k0": 0.008, "damping": 4e-7}


def _robot():
    segment = sc.Segment(
        rest_length=LENGTH,
        mass=0.017,
        radius=0.013,
        elongation_stiffness=sc.LinearStiffness(1000.0),
        bending_stiffness=sc.LinearStiffness(TRUTH["k0"]),
        damping=[0.5, TRUTH["damping"], TRUTH["damping"]],
    )
    return sc.Robot(segments=(segment,))


def _state(beta_deg):
    return np.array([LENGTH, np.radians(beta_deg) / LENGTH, 0.0, 0.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def recordings():
    """Two free oscillations from different bends, each with its own sensor zero."""
    model = sc.Model(_robot(), quadrature_nodes=4)
    t = np.arange(0.0, 0.3 + 1e-12, 2e-3)
    bends = {"a": 20.0, "b": -12.0}
    offsets = {"a": 0.5, "b": -0.3}
    data = []
    for name, beta in bends.items():
        template = Experiment(t, {"beta": np.zeros_like(t)}, units={"beta": "deg"}, name=name)
        clean = fit_trajectory(
            model, template, output=bending_angle_map(), x0=_state(beta), free=[], processes=1
        )
        data.append(template.with_signals(beta=clean.predicted[:, 0] + offsets[name]))
    return model, data, bends, offsets


def _free():
    return [
        Free(SEG + "bending_stiffness.k0", 1e-4, 1.0, initial=0.011),
        Free(SEG + "damping[1,1]", 1e-9, 1e-4, initial=8e-7),
        Free("offset", -5.0, 5.0, scale=1.0, per_experiment=True),
        Free("x0.q[1]", -20.0, 20.0, per_experiment=True),
    ]


def test_joint_fit_recovers_shared_and_per_experiment_parameters(recordings):
    model, data, bends, offsets = recordings
    output = bending_angle_map(offset="offset")
    # Each experiment starts 10 % off its true bend: the bends are fitted per experiment.
    x0 = {e.name: _state(0.9 * bends[e.name]) for e in data}
    report = fit_trajectory(model, data, output=output, x0=x0, free=_free(), processes=1)
    assert report.success, report.message
    assert report.names == (
        SEG + "bending_stiffness.k0",
        SEG + "damping[1,1]",
        "offset[a]",
        "offset[b]",
        "x0.q[1][a]",
        "x0.q[1][b]",
    )
    truth = [TRUTH["k0"], TRUTH["damping"], offsets["a"], offsets["b"]]
    truth += [np.radians(bends["a"]) / LENGTH, np.radians(bends["b"]) / LENGTH]
    np.testing.assert_allclose(report.values, truth, rtol=1e-5)
    assert report.parts == (("a", data[0].t.size), ("b", data[1].t.size))
    assert report.part("b").measured.shape == (data[1].t.size, 1)
    assert "experiment a: RMS" in report.table()
    assert report.extra["per_experiment"]["b"]["offset"] == pytest.approx(offsets["b"])
    # predicting both recordings (in two worker processes) reproduces the data
    again = predict_trajectory(model, data, report, output=output, x0=x0, processes=2)
    assert np.all(again.rms < 1e-5), again.table()
    # the prediction integrates without sensitivities: CVODES steps differently
    np.testing.assert_allclose(again.predicted, report.predicted, rtol=0, atol=1e-6)


def test_one_experiment_in_a_list_equals_the_single_fit(recordings):
    model, data, bends, _ = recordings
    output = bending_angle_map(offset="offset")
    x0 = _state(bends["a"])
    free = _free()[:3]
    single = fit_trajectory(model, data[0], output=output, x0=x0, free=free)
    listed = fit_trajectory(model, [data[0]], output=output, x0=[x0], free=free)
    assert single.names[2] == "offset" and listed.names[2] == "offset[a]"
    np.testing.assert_array_equal(single.values, listed.values)
    assert single.n_evaluations == listed.n_evaluations


def test_threads_split_each_evaluation_and_change_the_estimate_by_rounding_only(recordings):
    """threads=2 evaluates the sensitivity equations in two parts on two threads."""
    model, data, bends, _ = recordings
    output = bending_angle_map(offset="offset")
    x0, free = _state(0.9 * bends["a"]), _free()[:3]
    fits = [
        fit_trajectory(model, data[0], output=output, x0=x0, free=free, threads=threads)
        for threads in (1, 2)
    ]
    assert all(f.success for f in fits)
    np.testing.assert_allclose(fits[1].values, fits[0].values, rtol=1e-6)
    for bad in (0, 1.5):
        with pytest.raises(sc.ParameterError, match="threads"):
            fit_trajectory(model, data[0], output=output, x0=x0, free=free, threads=bad)


@pytest.mark.parametrize(
    ("experiments", "processes", "threads", "expected"),
    [(1, None, None, (1, 4)), (3, None, None, (3, 1)), (8, None, None, (4, 1)),
     (2, None, None, (2, 2)), (1, 2, None, (2, 2)), (1, None, 1, (1, 1))],
)  # fmt: skip
def test_the_cores_go_to_experiments_first_then_to_threads(
    monkeypatch, experiments, processes, threads, expected
):
    monkeypatch.setattr(joint, "default_threads", lambda: 4)
    assert joint.parallel_layout(experiments, processes, threads) == expected


def test_joint_fit_checks_its_arguments(recordings):
    model, data, bends, _ = recordings
    output = bending_angle_map(offset="offset")
    twice = [data[0], data[0]]
    with pytest.raises(sc.ParameterError, match="names must differ"):
        fit_trajectory(model, twice, output=output, x0=_state(10.0), free=[])
    with pytest.raises(sc.ParameterError, match="per_experiment=True needs an extra"):
        fit_trajectory(
            model, data, output=output, x0=_state(10.0),
            free=[Free(SEG + "damping[1,1]", per_experiment=True)],
        )  # fmt: skip
    with pytest.raises(sc.ParameterError, match="one per experiment"):
        fit_trajectory(model, data, output=output, x0=[_state(10.0)] * 3, free=[])
    with pytest.raises(sc.ParameterError, match="has 3 lam entries|has 0 lam entries"):
        fit_trajectory(model, data, output=output, x0=_state(10.0), free=["x0.lam[5]"])
    # one callable initial state per experiment, in a list
    starts = [lambda v, b=bends[e.name]: _state(b) for e in data]
    both = fit_trajectory(model, data, output=bending_angle_map(), x0=starts, free=[], processes=1)
    assert both.success and [p[0] for p in both.parts] == ["a", "b"]


def test_weights_per_sample_and_time_window():
    t = np.linspace(0.0, 1.0, 11)
    np.testing.assert_array_equal(weight_matrix([2.0, 3.0], t, 2), np.tile([2.0, 3.0], (11, 1)))
    w = weight_matrix([(0.0, 0.25, 0.0)], t, 2)
    assert np.all(w[:3] == 0.0) and np.all(w[3:] == 1.0)
    np.testing.assert_array_equal(weight_matrix(lambda s: 1 + s, t, 1)[:, 0], 1 + t)
    assert weight_matrix(np.arange(11.0) + 1, t, 2).shape == (11, 2)
    with pytest.raises(sc.ParameterError, match="expected shape"):
        weight_matrix(np.ones(5), t, 2)
    with pytest.raises(sc.ParameterError, match=">= 0"):
        weight_matrix([(0.0, 1.0, 0.0)], t, 2)
    rows = [[1.0, 1.0, 0.0]] * 11  # per sample: ignore the third signal, not a window
    np.testing.assert_array_equal(weight_matrix(rows, t, 3), np.array(rows))


def test_a_discounted_settling_period_removes_its_bias(recordings):
    model, data, bends, offsets = recordings
    output = bending_angle_map(offset="offset")
    # a settling artefact: the first 40 ms read 3 deg too high
    recording = data[0]
    beta = recording.signals["beta"] + 3.0 * (recording.t <= 0.04)
    spoiled = recording.with_signals(beta=beta)
    free = _free()[:3]
    x0 = _state(bends["a"])
    plain = fit_trajectory(model, spoiled, output=output, x0=x0, free=free)
    windowed = fit_trajectory(
        model, spoiled, output=output, x0=x0, free=free, weights=[(0.0, 0.04, 0.0)]
    )
    truth = np.array([TRUTH["k0"], TRUTH["damping"], offsets["a"]])
    assert np.max(np.abs(plain.values / truth - 1)) > 1e-2
    np.testing.assert_allclose(windowed.values, truth, rtol=1e-5)


def test_the_input_lag_time_constant_is_recovered(recordings):
    from softcurve.identification.maps import bellows_input_map, curvature_map

    model = recordings[0]
    t = np.arange(0.0, 0.3 + 1e-12, 2e-3)
    # a pressure step on bellow 0 at 50 ms, then one on bellow 1 at 150 ms
    steps = {"p0": 2e4 * (t >= 0.05), "p1": 1.5e4 * (t >= 0.15), "p2": 0.0 * t}
    template = Experiment(t, {"kx": 0 * t, "ky": 0 * t}, steps, name="steps")
    inputs = bellows_input_map(area=2.3e-5, distance=0.01)
    x0 = _state(2.0)  # not exactly straight: the bellows' map is singular there
    truth = 0.03
    clean = fit_trajectory(
        model, template, output=curvature_map(), input_map=inputs, x0=x0, free=[], input_lag=truth
    )
    data = template.with_signals(kx=clean.predicted[:, 0], ky=clean.predicted[:, 1])
    free = [Free("input_lag", 1e-3, 1.0, initial=0.08), Free("bellows.area", 1e-6, 1e-4)]
    report = fit_trajectory(
        model, data, output=curvature_map(), input_map=inputs, x0=x0, free=free, input_lag=0.08
    )
    assert report.success, report.message
    np.testing.assert_allclose(report.values, [truth, 2.3e-5], rtol=1e-5)
    # the lagged inputs start at the first sample unless set: bellow 0 already inflated
    inflated = fit_trajectory(
        model, template, output=curvature_map(), input_map=inputs, x0=x0, free=[],
        input_lag=truth, extra={"x0.u[0][steps]": 2e4},
    )  # fmt: skip
    difference = np.abs(inflated.predicted - clean.predicted)
    assert np.max(difference[t < 0.05]) > 1.0  # [1/m]
    assert np.max(difference[-1]) < 0.2 * np.max(difference[t < 0.05])  # and it dies out


def test_predictions_never_take_another_experiments_own_values(recordings):
    """A value set or fitted for one experiment (its offset, its initial state) stays
    with it: predicting each experiment reproduces the joint evaluation, and an
    experiment the fit did not have gets the nominal value, not a fitted one's."""
    model, (a, b), bends, _ = recordings
    out = bending_angle_map(offset="offset")
    x0 = {"a": _state(bends["a"]), "b": _state(bends["b"])}
    joint = fit_trajectory(model, [a, b], output=out, x0=x0, free=[],
                           extra={"offset[a]": 0.5}, processes=1)  # fmt: skip
    assert "offset" not in joint.extra["values"]
    rows = slice(a.t.size, None)
    alone = predict_trajectory(model, b, joint, output=out, x0=x0["b"], processes=1)
    assert np.max(np.abs(alone.predicted[:, 0] - joint.predicted[rows, 0])) <= 1e-9
    own_offset = [Free("offset", -5, 5, scale=1.0, per_experiment=True)]
    single = fit_trajectory(model, a, output=out, x0=x0["a"], free=own_offset, processes=1,
                            max_evaluations=10)  # fmt: skip
    other = predict_trajectory(model, b, single, output=out, x0=x0["b"], processes=1)
    nominal = predict_trajectory(
        model, b, joint, output=bending_angle_map(), x0=x0["b"], processes=1
    )
    assert np.max(np.abs(other.predicted[:, 0] - nominal.predicted[:, 0])) <= 1e-9


def test_held_inputs_act_when_sampled_as_in_simulate(recordings):
    """The default ("constant") hold is simulate's zero-order hold: an input acts from
    its sample time on, never before; the fit's prediction equals simulate's run."""
    model = recordings[0]
    dt, t_final = 0.01, 0.3
    t = np.arange(0.0, t_final + 1e-12, dt)
    moment = np.where(t >= 0.1, 2e-4, 0.0)  # a step of the bending moment on kx [N m^2]
    tau = np.column_stack([np.zeros_like(t), moment, np.zeros_like(t)])
    run = sc.simulate(model, [LENGTH, 0, 0], [0, 0, 0], tau=tau, t_final=t_final, dt=dt,
                      rtol=1e-10)  # fmt: skip
    passthrough = sc.InputMap(lambda q, u, values: ca.vertcat(0, u[0], 0), {})
    data = Experiment(t, {"kx": run.q[:, 1], "ky": run.q[:, 2]}, {"m": moment}, name="step")
    fit = fit_trajectory(model, data, output=curvature_map(), input_map=passthrough,
                         x0=_state(0.0), free=[], processes=1)  # fmt: skip
    span = np.ptp(run.q[:, 1])
    assert np.max(np.abs(fit.predicted[:, 0] - run.q[:, 1])) <= 1e-5 * span
