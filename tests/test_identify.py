"""Identification recovers known parameters from data made by softcurve itself.

Small, coarse problems (4 quadrature nodes, short horizons) keep these fast; the
validation on real data is in test_validation_data.py.
"""

import casadi as ca
import matplotlib
import numpy as np
import pytest

import softcurve as sc
from softcurve.base.status import Status
from softcurve.identification.experiments._loading import Experiment
from softcurve.identification.fits._dynamic import (
    fit_equilibria,
    fit_trajectory,
    predict_trajectory,
)
from softcurve.identification.fits._parameters import Free, FreeParameters, tanh_parameters
from softcurve.identification.fits._report import covariance, summarize
from softcurve.identification.fits._stiffness import fit_stiffness
from softcurve.identification.maps import bellows_input_map, bending_angle_map, curvature_map

SEG = "segments[0]."


def _robot(bending=None, creep=None):
    segment = sc.Segment(
        rest_length=0.064,
        mass=0.017,
        radius=0.013,
        elongation_stiffness=sc.LinearStiffness(1000.0),
        bending_stiffness=bending or sc.LinearStiffness(0.008),
        damping=[0.5, 4e-7, 4e-7],
        creep=creep,
    )
    return sc.Robot(segments=(segment,))


# -- static fit of a stiffness law -------------------------------------------------


@pytest.mark.parametrize("noise", [0.0, 0.02])
def test_fit_stiffness_recovers_tanh_law_within_confidence(noise):
    true = sc.TanhStiffness(2.23e3, 1.74e3, -4.55e2)  # the paper's elongation law
    x = np.linspace(-4e-3, 8e-3, 80)
    rng = np.random.default_rng(7)
    force = true.force(x) * (1.0 + noise * rng.standard_normal(x.size))
    report = fit_stiffness(x, force, "tanh")
    assert report.success, report.message
    alpha = np.array([true.a1, true.a2, abs(true.a3)])
    if noise == 0.0:
        np.testing.assert_allclose(report.values, alpha, rtol=1e-6)
    else:
        lo, hi = report.intervals.T
        assert np.all((lo <= alpha) & (alpha <= hi)), report.table()
        np.testing.assert_allclose(np.diag(report.correlation), 1.0)
        assert np.all(np.abs(report.correlation) <= 1.0 + 1e-12)
    law = report.extra["law"]
    assert law.a1 > law.a2 and law.a1 > 0


def test_fit_stiffness_linear_law_matches_closed_form():
    rng = np.random.default_rng(3)
    x = np.linspace(-0.5, 0.5, 50)
    force = 0.01 * x + 1e-4 * rng.standard_normal(x.size)
    report = fit_stiffness(x, force, "linear")
    k_ls = (x @ force) / (x @ x)
    np.testing.assert_allclose(report.value("k0"), k_ls, rtol=1e-9)
    s2 = np.sum((force - k_ls * x) ** 2) / (x.size - 1)
    np.testing.assert_allclose(report.standard_errors[0], np.sqrt(s2 / (x @ x)), rtol=1e-9)
    fig = report.plot()
    assert len(fig.axes) == 2
    matplotlib.pyplot.close(fig)


def test_fit_stiffness_rejects_bad_data():
    with pytest.raises(sc.ParameterError, match="finite"):
        fit_stiffness([0.0, np.nan], [0.0, 1.0])
    with pytest.raises(sc.ParameterError, match="positive stiffness"):
        fit_stiffness([1.0, 2.0], [-1.0, -2.0])
    with pytest.raises(sc.ParameterError, match="law must be"):
        fit_stiffness([1.0, 2.0], [1.0, 2.0], law="cubic")


def test_covariance_flags_parameters_that_only_enter_as_a_product():
    # y = a * b * x: only the product is identifiable; both columns are parallel.
    x = np.linspace(0.0, 1.0, 20)
    jac = np.column_stack([2.0 * x, 3.0 * x, x**2])
    cov, identifiable = covariance(jac, np.full(20, 0.01))
    assert identifiable.tolist() == [False, False, True]
    assert np.isinf(cov[0, 0]) and np.isfinite(cov[2, 2])
    # a converged fit with a singular covariance is reported as not identifiable
    *_, status, message = summarize(
        ("a", "b", "c"), np.ones(3), jac, np.full(20, 0.01), Status.SUCCESS, ""
    )
    assert status is Status.NOT_IDENTIFIABLE and "['a', 'b']" in message


# -- trajectory least squares --------------------------------------------------------


@pytest.fixture(scope="module")
def oscillation():
    """A free oscillation of a known robot, 0.3 s sampled at 2 ms."""
    robot = _robot()
    model = sc.Model(robot, quadrature_nodes=4)
    beta0 = np.radians(20.0)
    x0 = np.array([0.064, beta0 / 0.064, 0.0, 0.0, 0.0, 0.0])
    t = np.arange(0.0, 0.3 + 1e-12, 2e-3)
    template = Experiment(t, {"beta": np.zeros_like(t)}, units={"beta": "deg"})
    clean = fit_trajectory(model, template, output=bending_angle_map(), x0=x0, free=[])
    return model, x0, template.with_signals(beta=clean.predicted[:, 0])


def test_trajectory_jacobian_is_exact(oscillation):
    from softcurve.simulation.sensitivity._sensitivity import trajectory_sensitivities

    model, _, data = oscillation
    free = [Free(SEG + "bending_stiffness.k0"), Free(SEG + "damping[1,1]"), Free("lam0")]
    params = FreeParameters(model, free, {"lam0": 0.3}, {}, None)

    def x0(v):  # the initial bend is a free parameter too
        return ca.vertcat(0.064, v["lam0"] / 0.064, 0, 0, 0, 0)

    evaluate = trajectory_sensitivities(model, params, bending_angle_map(), None, x0, data, None)
    theta = np.array([0.008, 4e-7, 0.3])
    _, jac = evaluate(theta)
    for j in range(3):
        h = 1e-4 * theta[j]
        plus, minus = theta.copy(), theta.copy()
        plus[j] += h
        minus[j] -= h
        fd = (evaluate(plus)[0] - evaluate(minus)[0]).ravel() / (2 * h)
        np.testing.assert_allclose(jac[:, j], fd, rtol=1e-4, atol=1e-5 * np.abs(fd).max())


@pytest.mark.parametrize("noise_deg", [0.0, 0.1])
def test_trajectory_fit_recovers_stiffness_and_damping(oscillation, noise_deg):
    model, x0, data = oscillation
    rng = np.random.default_rng(11)
    beta = data.signals["beta"] + noise_deg * rng.standard_normal(data.t.size)
    noisy = data.with_signals(beta=beta)
    free = [
        Free(SEG + "bending_stiffness.k0", 1e-4, 1.0, initial=0.012),
        Free(SEG + "damping[1,1]", 1e-9, 1e-4, initial=1e-6),
    ]
    report = fit_trajectory(model, noisy, output=bending_angle_map(), x0=x0, free=free)
    assert report.success, report.message
    truth = np.array([0.008, 4e-7])
    if noise_deg == 0.0:
        np.testing.assert_allclose(report.values, truth, rtol=1e-5)
    else:
        lo, hi = report.intervals.T
        assert np.all((lo <= truth) & (truth <= hi)), report.table()
        assert report.rms[0] == pytest.approx(noise_deg, rel=0.2)
    assert report.n_evaluations < 40
    fitted = report.extra["robot"]
    assert fitted.segments[0].bending_stiffness.k0 == pytest.approx(report.values[0])
    again = predict_trajectory(model, data, report, output=bending_angle_map(), x0=x0)
    assert again.rms[0] < 2 * noise_deg + 1e-6
    fig = report.plot(title="oscillation")
    assert fig.axes[0].get_ylabel() == "beta [deg]"
    assert fig.axes[1].get_ylabel() == "model - measured [deg]"
    matplotlib.pyplot.close(fig)
    assert report.parameter_units == ("N m/rad", "N m^3 s")  # from the robot's layout
    assert SEG + "damping[1,1] [N m^3 s]" in report.table()


def test_a_fit_starts_from_an_earlier_report(oscillation):
    model, x0, data = oscillation
    free = [
        Free(SEG + "bending_stiffness.k0", 1e-4, 1.0, initial=0.012),
        Free(SEG + "damping[1,1]", 1e-9, 1e-4, initial=1e-6),
    ]
    options = dict(output=bending_angle_map(), x0=x0, free=free)
    short = fit_trajectory(model, data, max_evaluations=3, **options)
    assert short.status is Status.EVALUATION_LIMIT
    # the same list of Free, whose initial values are those of the first start
    resumed = fit_trajectory(model, data, start=short, **options)
    assert resumed.success, resumed.message
    np.testing.assert_allclose(resumed.values, [0.008, 4e-7], rtol=1e-5)
    # it began at the report's estimate: its first evaluation there costs what it did
    first = fit_trajectory(model, data, start=short, max_evaluations=1, **options)
    np.testing.assert_allclose(first.values, short.values, rtol=1e-14)
    np.testing.assert_allclose(first.predicted, short.predicted, rtol=0, atol=1e-12)
    with pytest.raises(sc.ParameterError, match="start must be a FitReport"):
        fit_trajectory(model, data, start=short.values, **options)


def test_a_prediction_estimates_the_initial_state_of_a_trial_in_motion(oscillation):
    model, x0, data = oscillation
    free = [Free(SEG + "bending_stiffness.k0", 1e-4, 1.0, initial=0.012)]
    options = dict(output=bending_angle_map())
    report = fit_trajectory(model, data, x0=x0, free=free, **options)
    assert report.success and report.extra["input_hold"] == "constant"
    moving = data.trim(0.1, rezero=True)  # starts mid-swing: neither at rest nor at x0
    given = predict_trajectory(model, data, report, x0=x0, **options)
    assert given.rms[0] < 1e-5 and np.array_equal(given.extra["x0"][0], x0)
    at_rest = predict_trajectory(model, moving, report, **options)  # the default
    window = predict_trajectory(model, moving, report, x0="window", window=0.03, **options)
    assert at_rest.rms[0] > 1.0  # degrees: the swing missed
    assert window.rms[0] < 1e-3, window.table()
    # the state found is the true one at 0.1 s (a free oscillation: its own truth)
    truth = fit_trajectory(model, data.trim(0.0, 0.1), x0=x0, free=[], **options)
    assert window.predicted[0, 0] == pytest.approx(truth.predicted[-1, 0], abs=1e-4)
    with pytest.raises(sc.ParameterError, match="needs window"):
        predict_trajectory(model, moving, report, x0="window", **options)
    with pytest.warns(sc.FitWarning, match="input_hold='constant'"):
        predict_trajectory(model, data, report, x0=x0, input_hold="linear", **options)


def test_tanh_reparametrization_and_robot_round_trip():
    robot = _robot(bending=sc.TanhStiffness(0.02, 0.012, 3.0))
    values, bind = tanh_parameters(robot, SEG + "bending_stiffness")
    assert values[SEG + "bending_stiffness.k_zero"] == pytest.approx(0.008)
    assert bind[SEG + "bending_stiffness.a2"](values) == pytest.approx(0.012)
    again = robot.with_parameter_vector(robot.parameter_vector())
    np.testing.assert_array_equal(again.parameter_vector(), robot.parameter_vector())
    with pytest.raises(sc.ParameterError, match="not a tanh"):
        tanh_parameters(_robot(), SEG + "bending_stiffness")


def test_free_names_are_checked():
    model = sc.Model(_robot(), quadrature_nodes=4)
    data = Experiment([0.0, 0.1], {"beta": [0.0, 0.0]})
    with pytest.raises(sc.ParameterError, match="neither a robot parameter"):
        fit_trajectory(model, data, output=bending_angle_map(), x0=np.zeros(6), free=["stiffness"])
    with pytest.raises(sc.ParameterError, match="outside their bounds"):
        fit_trajectory(
            model, data, output=bending_angle_map(), x0=np.zeros(6),
            free=[Free(SEG + "damping[1,1]", 1.0, 2.0)],
        )  # fmt: skip


# -- quasi-static fit with a pressure map and sensor offsets --------------------------------


def test_equilibrium_fit_recovers_mounting_angle_area_and_sensor_zero():
    robot = _robot(bending=sc.TanhStiffness(0.014, 0.006, 4.0))
    model = sc.Model(robot, quadrature_nodes=4)
    values, bind = tanh_parameters(robot, SEG + "bending_stiffness")
    truth = {"bellows.angle": -0.5, "bellows.area": 2.3e-5, "offset.kx": 0.36, "offset.ky": 0.1}
    t = np.linspace(0.0, 6.0, 60)
    # A rotating pressure field of growing amplitude: at one constant amplitude every
    # sample bends equally far, and area and stiffness would only enter as a ratio.
    phase, amplitude = 4 * np.pi * t / 6.0, 3e3 + 1.4e4 * t / 6.0
    pressures = {f"p{i}": 2e4 + amplitude * np.sin(phase - 2 * np.pi * i / 3) for i in range(3)}
    template = Experiment(t, {"kx": 0 * t, "ky": 0 * t}, pressures)
    output = curvature_map(offsets=("offset.kx", "offset.ky"))
    inputs = bellows_input_map(area=2.3e-5, distance=0.01)
    clean = fit_equilibria(
        model, template, output=output, input_map=inputs, free=[], extra={**values, **truth},
        bind=bind,
    )  # fmt: skip
    assert clean.success, clean.message
    rng = np.random.default_rng(5)
    measured = clean.predicted + 0.05 * rng.standard_normal(clean.predicted.shape)
    data = template.with_signals(kx=measured[:, 0], ky=measured[:, 1])
    free = [
        Free("bellows.angle", -np.pi, np.pi, initial=0.0, scale=1.0),
        Free("bellows.area", 1e-7, 1e-3, initial=1.5e-5),
        Free("offset.kx", -2.0, 2.0, initial=0.0, scale=0.1),
        Free("offset.ky", -2.0, 2.0, initial=0.0, scale=0.1),
        Free(SEG + "bending_stiffness.k_inf", 1e-4, 1.0, initial=0.02),
    ]
    # five parameters checked at once: 99% intervals keep the family-wise miss rate low
    report = fit_equilibria(
        model, data, output=output, input_map=inputs, free=free, extra=values, bind=bind,
        confidence=0.99,
    )  # fmt: skip
    assert report.success, report.message
    expected = np.array([*truth.values(), 0.014])
    lo, hi = report.intervals.T
    assert np.all((lo <= expected) & (expected <= hi)), report.table()


def test_stiffness_and_chamber_area_from_statics_are_not_separately_determined():
    # Linear bending stiffness against the chambers' area, curvatures only: the
    # equilibria fix their ratio alone. The Jacobian's columns are not exactly parallel
    # (gravity, rounding), so the rank test passes, but the correlation is +1.000: the
    # fit must not say SUCCESS, and must say which pair and what to do.
    model = sc.Model(_robot(), quadrature_nodes=4)
    t = np.linspace(0.0, 6.0, 60)
    phase, amplitude = 4 * np.pi * t / 6.0, 3e3 + 1.4e4 * t / 6.0
    pressures = {f"p{i}": 2e4 + amplitude * np.sin(phase - 2 * np.pi * i / 3) for i in range(3)}
    template = Experiment(t, {"kx": 0 * t, "ky": 0 * t}, pressures)
    output, inputs = curvature_map(), bellows_input_map(area=2.3e-5, distance=0.01)
    clean = fit_equilibria(model, template, output=output, input_map=inputs, free=[])
    noisy = clean.predicted + 0.05 * np.random.default_rng(5).standard_normal((t.size, 2))
    data = template.with_signals(kx=noisy[:, 0], ky=noisy[:, 1])
    free = [
        Free("bellows.area", 1e-7, 1e-3, initial=1.5e-5),
        Free(SEG + "bending_stiffness.k0", 1e-4, 1.0, initial=0.02),
    ]
    report = fit_equilibria(model, data, output=output, input_map=inputs, free=free)
    assert report.identifiable.all()  # the rank test alone would have said SUCCESS
    assert abs(report.correlation[0, 1]) > 0.999
    assert report.status is Status.NOT_IDENTIFIABLE
    assert "bellows.area ~ segments[0].bending_stiffness.k0" in report.message
    assert "fix one of each pair" in report.message
    # one of them fixed, the other is determined
    alone = fit_equilibria(model, data, output=output, input_map=inputs, free=free[:1])
    assert alone.success, alone.message


def test_cli_fit_reports_and_fails_cleanly(tmp_path, capsys):
    from softcurve.cli import main

    law = sc.TanhStiffness(0.02, 0.012, 3.0)
    beta = np.linspace(0.0, 0.8, 40)
    rows = "\n".join(f"{b},{m}" for b, m in zip(beta, law.force(beta), strict=True))
    path = tmp_path / "static.csv"
    path.write_text("beta,moment\n" + rows + "\n")
    figure = tmp_path / "fit.png"
    code = main(
        ["fit", str(path), "--strain", "beta", "--force", "moment", "--figure", str(figure)]
    )
    out = capsys.readouterr().out
    assert code == 0 and "a1" in out and figure.stat().st_size > 5000
    assert "TanhStiffness(a1=0.02" in out
    code = main(["fit", str(path), "--strain", "beta", "--force", "torque"])
    assert code == 2
    assert "no variable or column 'torque'" in capsys.readouterr().err
