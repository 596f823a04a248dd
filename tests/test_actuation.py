"""Pneumatic actuation: H(q) from the virtual work of the chamber pressures, bounds, lag."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest

from softcurve import Bellows, ConstantPressureMap, ParameterError, PneumaticActuator
from softcurve.description.bellows import ATMOSPHERIC_PRESSURE
from softcurve.scenarios.actuation import from_mapping

from .conftest import assert_close


def actuator(**changes) -> PneumaticActuator:
    fields = dict(distance=0.012, area=2e-4, p_max=6e4)
    fields.update(changes)
    return PneumaticActuator.three_bellows(**fields)


def finite_difference_of_volumes(act, q, step=1e-2):
    columns = []
    for i in range(q.size):
        e = np.zeros(q.size)
        e[i] = step * max(abs(q[i]), 1.0)
        columns.append((act.volumes(q + e) - act.volumes(q - e)) / (2 * e[i]))
    return np.array(columns)  # (n, m): row i is dV/dq_i


@pytest.mark.parametrize("trial", range(4))
def test_pressure_matrix_is_the_derivative_of_the_chamber_volumes(rng, trial):
    chambers = (
        Bellows(0.3, 0.01, 1e-4, 5e4, segments=(0,)),
        Bellows(2.0, 0.015, 2e-4, 5e4, segments=(1,)),
        Bellows(4.0, 0.008, 1.5e-4, 5e4, segments=(0, 1)),  # runs through both segments
        Bellows(5.5, 0.012, 1e-4, 5e4, segments=(1,)),
    )
    act = PneumaticActuator(chambers, n_segments=2)
    q = np.concatenate([[0.06 * rng.uniform(0.8, 1.2), *rng.uniform(-30, 30, 2)] for _ in range(2)])
    # V is affine in each coordinate separately, so central differences with a large step
    # are exact up to rounding; each row is compared relative to its own magnitude.
    expected = finite_difference_of_volumes(act, q)
    row_scale = np.abs(expected).max(axis=1, keepdims=True)
    assert_close(act.input_matrix(q), expected, rtol=1e-12, scale=row_scale)


def test_pressure_work_gradient_is_h_times_p(rng):
    for act in (actuator(), ConstantPressureMap.authors_fit(p_max=1e5)):
        q, p = ca.SX.sym("q", 3), ca.SX.sym("p", 3)
        gradient = ca.Function("g", [q, p], [ca.gradient(act.input_work_symbolic(q, p), q)])
        qv, pv = np.array([0.07, 12.0, -4.0]), rng.uniform(0, 5e4, 3)
        assert_close(np.array(gradient(qv, pv)).ravel(), act.input_matrix(qv) @ pv, rtol=1e-13)


def test_a_pressurized_bellow_lengthens_and_bends_away_from_itself():
    act = actuator()
    straight = np.array([0.0644, 0.0, 0.0])
    for i, phi in enumerate(act.parameter_vector()[0::3]):
        p = np.zeros(3)
        p[i] = 1e4
        tau = act.generalized_force(straight, p)
        assert tau[0] > 0
        bend = tau[1:] / np.linalg.norm(tau[1:])  # generalized force on (kx, ky)
        assert_close(bend, [-math.cos(phi), -math.sin(phi)], rtol=0, atol=1e-15)


def test_closed_form_at_zero_curvature():
    act = PneumaticActuator((Bellows(0.0, 0.01, 1e-4, 1e5),))
    h = act.input_matrix([0.05, 0.0, 0.0])
    assert_close(h[:, 0], [1e-4, -1e-4 * 0.05 * 0.01, 0.0], rtol=1e-15)


def test_authors_fit_matches_bellows_rotated_by_a_quarter_turn():
    fit = ConstantPressureMap.authors_fit(p_max=1e5)
    assert_close(fit.input_matrix(np.zeros(3))[0], [2.34e-7] * 3, rtol=1e-15)
    kinematic = actuator(azimuths=np.array([0, 2 * np.pi / 3, 4 * np.pi / 3]) + np.pi / 2)
    h = kinematic.input_matrix([0.0644, 0.0, 0.0])
    direction = h[1:] / np.linalg.norm(h[1:], axis=0)
    fitted = fit.constant[1:] / np.linalg.norm(fit.constant[1:], axis=0)
    assert_close(direction, fitted, rtol=0, atol=1e-15)


def test_multi_segment_actuator_acts_on_its_own_segment():
    act = PneumaticActuator.three_bellows(distance=0.01, area=1e-4, p_max=5e4, n_segments=2)
    h = act.input_matrix(np.array([0.06, 5.0, 1.0, 0.07, -3.0, 2.0]))
    assert act.n_inputs == 6
    assert np.all(h[3:, :3] == 0) and np.all(h[:3, 3:] == 0)


def test_pressure_bounds_are_enforced():
    act = actuator(p_min=1e3)
    assert_close(act.clip([-5.0, 3e4, 7e4]), [1e3, 3e4, 6e4])
    with pytest.raises(ParameterError, match=r"pressures\[2\] = 70000.0 Pa is outside"):
        act.generalized_force([0.06, 0, 0], [2e3, 3e4, 7e4])
    with pytest.raises(ParameterError, match=r"pressures\[0\] .* outside"):
        act.check_inputs([0.0, 2e3, 2e3])
    vacuum = actuator(p_min=-0.8 * ATMOSPHERIC_PRESSURE)
    assert vacuum.lower[0] < 0


def test_first_order_pressure_lag_is_exact():
    act = actuator(time_constant=0.05)
    p0, command = np.array([0.0, 1e4, 5e4]), np.array([3e4, 9e4, 0.0])  # 9e4 saturates
    target = act.clip(command)
    p = act.input_step(p0, command, 0.02)
    assert_close(p, target + (p0 - target) * math.exp(-0.4), rtol=1e-15)
    # two half steps equal one step, and the rate is the derivative at dt = 0
    half = act.input_step(act.input_step(p0, command, 0.01), command, 0.01)
    assert_close(half, p, rtol=1e-14)
    h = 1e-7
    assert_close((act.input_step(p0, command, h) - p0) / h, act.input_rate(p0, command), rtol=1e-5)
    assert_close(actuator().input_step(p0, command, 0.02), target)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        (dict(distance=0.0), "distance must be > 0"),
        (dict(area=-1.0), "area must be > 0"),
        (dict(p_max=0.0), "p_max must be > p_min"),
        (dict(p_min=-2e5), "p_min must be >= -101325"),
        (dict(time_constant=0.0), "time_constant must be > 0"),
        (dict(p_max=float("nan")), "p_max must be finite"),
    ],
)
def test_bad_actuators(changes, message):
    with pytest.raises(ParameterError, match=message):
        actuator(**changes)


def test_bad_segments_and_matrices():
    with pytest.raises(ParameterError, match="beyond n_segments"):
        PneumaticActuator((Bellows(0.0, 0.01, 1e-4, 1e5, segments=(1,)),))
    with pytest.raises(ParameterError, match="must not repeat"):
        Bellows(0.0, 0.01, 1e-4, 1e5, segments=(0, 0))
    with pytest.raises(ParameterError, match="3 N rows"):
        ConstantPressureMap(np.ones((2, 3)), p_max=1e5)
    with pytest.raises(ParameterError, match="acts on n = 3 coordinates but the robot has n = 6"):
        from softcurve.description import presets

        actuator().check_robot(presets.ifac2020().with_segments(2))


def test_from_mapping_builds_and_validates():
    act = from_mapping({"distance": 0.01, "area": 1e-4, "p_max": 3e4}, n_segments=2)
    assert act.n_inputs == 6 and act.n == 6
    explicit = from_mapping(
        {"bellows": [{"azimuth": 0.5, "distance": 0.01, "area": 1e-4, "p_max": 3e4}]}
    )
    assert explicit.n_inputs == 1
    constant = from_mapping({"kind": "constant", "matrix": np.eye(3).tolist(), "p_max": 1.0})
    assert_close(constant.input_matrix(np.zeros(3)), np.eye(3))
    fit = from_mapping({"kind": "authors_fit", "p_max": 1e5, "time_constant": 0.1})
    assert fit.time_constant == 0.1
    cases = [
        ({"distance": 0.01, "area": 1e-4}, r"actuation: missing required key\(s\) \['p_max'\]"),
        ({"distance": 0.01, "area": 1e-4, "p_max": 1, "rho": 2}, r"unknown key\(s\) \['rho'\]"),
        ({"kind": "magic"}, "kind must be one of"),
        ({"distance": 0.01, "area": 0, "p_max": 1}, "actuation: area must be > 0"),
        ({"bellows": [{"azimuth": 0, "distance": 0.01, "area": 1e-4}]}, r"bellows\[0\]"),
        ({"bellows": [{"azimuth": 0, "radius": 1}]}, r"bellows\[0\]: unknown key"),
    ]
    for mapping, message in cases:
        with pytest.raises(ParameterError, match=message):
            from_mapping(mapping)
