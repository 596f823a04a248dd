"""Output and input maps against independent computations, a fit of per-chamber gains and
azimuths, the initial equilibrium of an experiment and simulate's initial actuator state."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.spatial.transform import Rotation

import softcurve as sc
from softcurve.identification.maps import (
    SensorFrame,
    actuator_input_map,
    bellows_input_map,
    bending_angle_map,
    curvature_map,
    imu_orientation_map,
    marker_position_map,
    tendon_input_map,
    tip_position_map,
)

from .conftest import assert_close


def evaluate_output(output, model, q, values=None):
    """The map's outputs at ``q`` with its extra parameters at ``values`` (else nominal)."""
    qs = ca.SX.sym("q", model.n)
    numbers = {**output.parameters, **(values or {})}
    symbols = {k: ca.SX.sym(k) for k in numbers}
    y = output.function(qs, ca.SX.zeros(model.n), symbols, ca.DM(model.parameters))
    f = ca.Function("y", [qs, *symbols.values()], [y])
    return np.array(f(q, *numbers.values())).ravel()


def evaluate_input(input_map, q, u, values=None):
    numbers = {**input_map.parameters, **(values or {})}
    qs, us = ca.SX.sym("q", len(q)), ca.SX.sym("u", len(u))
    symbols = {k: ca.SX.sym(k) for k in numbers}
    f = ca.Function("tau", [qs, us, *symbols.values()], [input_map.function(qs, us, symbols)])
    return np.array(f(q, u, *numbers.values())).ravel()


Q2 = np.array([0.066, 12.0, -5.0, 0.063, -4.0, 9.0])  # two bent segments [m, 1/m, 1/m]


# -- output maps ----------------------------------------------------------------------------


@pytest.mark.parametrize(("segment", "s"), [(0, 0.4), (1, 0.0), (1, 0.7), (-1, 1.0)])
def test_marker_position_is_the_pose_at_that_material_point(two_segment_model, segment, s):
    model, offset = two_segment_model, np.array([0.02, -0.01, 0.005])
    point = ((segment % 2) + s) / 2  # the whole robot's material coordinate
    rotation, position = model.pose(Q2, point)
    on_backbone = evaluate_output(marker_position_map(model, segment, s), model, Q2)
    assert_close(on_backbone, position, rtol=1e-12, scale=np.linalg.norm(position))
    fixed = evaluate_output(marker_position_map(model, segment, s, offset=offset), model, Q2)
    named = marker_position_map(model, segment, s, offset="marker")
    assert set(named.parameters) == {"marker.x", "marker.y", "marker.z"}
    values = dict(zip(["marker.x", "marker.y", "marker.z"], offset, strict=True))
    expected = position + rotation @ offset
    for y in (fixed, evaluate_output(named, model, Q2, values)):
        assert_close(y, expected, rtol=1e-12, scale=np.linalg.norm(expected))


def test_tip_position_keeps_its_old_form_and_projects_onto_chosen_axes(two_segment_model):
    model = two_segment_model
    tip = model.tip_pose(Q2).position
    old = tip_position_map(model)
    assert (old.names, old.units, old.parameters) == (("x", "y", "z"), ("m",) * 3, {})
    assert_close(evaluate_output(old, model, Q2), tip, scale=np.linalg.norm(tip))
    projected = tip_position_map(model, axes="zx", names=("height", "reach"))
    assert projected.names == ("height", "reach")
    assert_close(evaluate_output(projected, model, Q2), tip[[2, 0]], scale=np.linalg.norm(tip))


def test_sensor_frame_is_the_identity_at_zero_and_a_rotation_and_shift_otherwise(
    two_segment_model,
):
    model = two_segment_model
    tip = model.tip_pose(Q2).position
    frame = SensorFrame("mocap", scale=1000.0, unit="mm")
    output = tip_position_map(model, frame=frame)
    assert output.units == ("mm",) * 3 and set(output.parameters) == set(frame.names)
    assert_close(evaluate_output(output, model, Q2), 1000.0 * tip, scale=1000 * 0.2)
    angles, origin = np.array([0.1, -0.2, 0.7]), np.array([0.01, -0.02, 0.03])
    values = dict(zip(frame.names, [*angles, *origin], strict=True))
    # independent: scipy's extrinsic x-y-z rotation is Rz(yaw) Ry(pitch) Rx(roll)
    axes = Rotation.from_euler("xyz", angles).as_matrix()
    expected = 1000.0 * axes.T @ (tip - origin)
    assert_close(evaluate_output(output, model, Q2, values), expected, rtol=1e-12, scale=200.0)


def test_imu_reports_gravity_and_tilt_in_its_own_axes(two_segment_model):
    model = two_segment_model
    straight = np.array([0.0644, 0.0, 0.0] * 2)
    assert_close(
        evaluate_output(imu_orientation_map(model), model, straight), [0.0, 0.0], atol=1e-12
    )
    rotation = model.tip_pose(Q2).rotation
    gravity = model.robot.gravity
    up = rotation.T @ (-gravity / np.linalg.norm(gravity))
    reading = evaluate_output(imu_orientation_map(model, output="gravity"), model, Q2)
    assert_close(reading, up, atol=1e-12)
    roll, pitch = np.arctan2(up[1], up[2]), np.arctan2(-up[0], np.hypot(up[1], up[2]))
    tilt = evaluate_output(imu_orientation_map(model, degrees=False), model, Q2)
    assert_close(tilt, [roll, pitch], rtol=1e-12)
    # an IMU mounted turned by yaw about the tangent sees the same vector turned back
    mounted = imu_orientation_map(model, output="gravity", mounting="imu")
    turned = evaluate_output(mounted, model, Q2, {"imu.yaw": np.pi / 2})
    assert_close(turned, [up[1], -up[0], up[2]], atol=1e-12)


def test_coordinate_maps_keep_their_behaviour(two_segment_model):
    model = two_segment_model
    assert_close(evaluate_output(bending_angle_map(1), model, Q2), [np.degrees(Q2[3] * Q2[4])])
    kx = evaluate_output(curvature_map(1, offsets=("a", "b")), model, Q2, {"a": 0.5, "b": -1.0})
    assert_close(kx, [Q2[4] + 0.5, Q2[5] - 1.0])


@pytest.mark.parametrize(
    ("build", "match"),
    [
        (lambda m: marker_position_map(m, 2), "segment must be an index in"),
        (lambda m: marker_position_map(m, 0, 1.5), "s must be in"),
        (lambda m: tip_position_map(m, axes="xw"), "axes must be distinct letters"),
        (lambda m: tip_position_map(m, axes="xx"), "axes must be distinct letters"),
        (lambda m: imu_orientation_map(m, output="quaternion"), "output must be one of"),
        (lambda m: SensorFrame(scale=-1.0), "scale"),
        (lambda m: bellows_input_map(area=1e-4, distance=0.01, numbering=2), "numbering"),
        (
            lambda m: bellows_input_map(area=1e-4, distance=0.01, gains=[1, 1], azimuths=[0, 1, 2]),
            "one entry per chamber",
        ),
        (lambda m: tendon_input_map(distance=0.01, anchors=[0, 3, 0]), "anchors"),
    ],
)
def test_bad_map_arguments_name_the_field(two_segment_model, build, match):
    with pytest.raises(sc.ParameterError, match=match):
        build(two_segment_model)


# -- input maps -----------------------------------------------------------------------------


def test_bellows_map_with_free_gains_azimuths_and_spans_is_the_actuators_matrix(rng):
    azimuths, gains = np.radians([5.0, 116.0, 246.0, 300.0]), np.array([0.84, 0.72, 1.0, 1.1])
    spans, area, rho = [(0,), (0, 1), (1,), (0, 1)], 2e-5, 0.011
    chambers = tuple(
        sc.Bellows(a, rho, area * g, 1e6, segments=s)
        for a, g, s in zip(azimuths, gains, spans, strict=True)
    )
    actuator = sc.PneumaticActuator(chambers, n_segments=2)
    mapped = bellows_input_map(
        area=area, distance=rho, n_segments=2, segments=spans, azimuths=azimuths, gains=gains
    )
    assert mapped.units == ("Pa",) * 4
    for _ in range(3):
        q = Q2 * (1 + 0.3 * rng.standard_normal(6))
        u = rng.uniform(0, 5e4, 4)
        expected = actuator.input_matrix(q) @ u
        assert_close(evaluate_input(mapped, q, u), expected, scale=np.abs(expected).max())
    # the mounting angle turns every chamber
    turned = sc.PneumaticActuator(
        tuple(sc.Bellows(b.azimuth + 0.3, rho, b.area, 1e6, segments=b.segments) for b in chambers),
        n_segments=2,
    )
    expected = turned.input_matrix(Q2) @ np.full(4, 1e4)
    got = evaluate_input(mapped, Q2, np.full(4, 1e4), {"bellows.angle": 0.3})
    assert_close(got, expected, scale=np.abs(expected).max())


def test_default_bellows_map_is_three_identical_chambers_per_segment():
    actuator = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e6, n_segments=2)
    mapped = bellows_input_map(area=2e-5, distance=0.01, n_segments=2)
    u = np.linspace(1e4, 3e4, 6)
    expected = actuator.input_matrix(Q2) @ u
    assert_close(evaluate_input(mapped, Q2, u), expected, scale=np.abs(expected).max())


def test_tendon_map_with_per_tendon_geometry_is_the_actuators_matrix(rng):
    azimuths, gains, rhos, anchors = [0.1, 2.2, 4.0, 1.0], [1.0, 0.9, 1.2, 0.8], [
        0.010, 0.012, 0.009, 0.011], [0, 0, 1, 1]  # fmt: skip
    mapped = tendon_input_map(
        distance=rhos, n_segments=2, anchors=anchors, azimuths=azimuths, gains=gains,
        friction=0.2,
    )  # fmt: skip
    assert "tendons[2].distance" in mapped.parameters
    assert "tendons.distance" not in mapped.parameters
    actuator = sc.TendonActuator(
        tuple(sc.Tendon(a, r, 50.0, anchor=k, friction=0.2)
              for a, r, k in zip(azimuths, rhos, anchors, strict=True)),
        n_segments=2,
    )  # fmt: skip
    u = rng.uniform(0.5, 5.0, 4)
    expected = actuator.input_matrix(Q2) @ (np.array(gains) * u)
    assert_close(evaluate_input(mapped, Q2, u), expected, scale=np.abs(expected).max())


def test_actuator_map_exposes_input_matrix_symbolic_theta_by_name():
    actuator = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e6)
    q, u = Q2[:3], np.array([1e4, 2e4, 3e4])
    fixed = actuator_input_map(actuator)
    assert fixed.parameters == {} and fixed.units == ("Pa",) * 3
    assert_close(evaluate_input(fixed, q, u), actuator.input_matrix(q) @ u)
    named = actuator_input_map(actuator, prefix="")
    assert list(named.parameters) == actuator.parameter_names()
    vector = actuator.parameter_vector()
    vector[0::3] += 0.2  # every azimuth turned by 0.2 rad
    changed = actuator.with_parameter_vector(vector)
    values = dict(zip(actuator.parameter_names(), vector, strict=True))
    expected = changed.input_matrix(q) @ u
    assert_close(evaluate_input(named, q, u, values), expected, scale=np.abs(expected).max())


def test_equilibrium_fit_recovers_per_chamber_gains_and_azimuths(paper_model):
    """The real robot's chambers: 111/119/130 deg apart, gains 0.84 : 0.72 : 1."""
    model = paper_model
    truth = {
        "bellows[0].gain": 0.84,
        "bellows[1].gain": 0.72,
        "bellows[1].azimuth": np.radians(111.0),
        "bellows[2].azimuth": np.radians(230.0),
    }
    inputs = bellows_input_map(area=2e-5, distance=0.01)
    t = np.linspace(0.0, 6.0, 40)
    phase, amplitude = 4 * np.pi * t / 6.0, 1e4 + 3e4 * t / 6.0
    pressures = {f"p{i}": 4e4 + amplitude * np.sin(phase - 2 * np.pi * i / 3) for i in range(3)}
    units = dict.fromkeys(pressures, "Pa")
    template = sc.Experiment(t, {"kx": 0 * t, "ky": 0 * t}, pressures, units)
    clean = sc.fit_equilibria(
        model, template, output=curvature_map(), input_map=inputs, free=[], extra=truth
    )
    assert clean.success, clean.message
    rng = np.random.default_rng(11)
    noisy = clean.predicted + 0.02 * rng.standard_normal(clean.predicted.shape)
    data = template.with_signals(kx=noisy[:, 0], ky=noisy[:, 1])
    free = [
        sc.Free("bellows[0].gain", 0.3, 2.0, initial=1.0),
        sc.Free("bellows[1].gain", 0.3, 2.0, initial=1.0),
        sc.Free("bellows[1].azimuth", 1.0, 3.0, initial=2 * np.pi / 3, scale=1.0),
        sc.Free("bellows[2].azimuth", 3.0, 5.5, initial=4 * np.pi / 3, scale=1.0),
    ]
    report = sc.fit_equilibria(
        model, data, output=curvature_map(), input_map=inputs, free=free, confidence=0.99
    )
    assert report.success, report.message
    lo, hi = report.intervals.T
    expected = np.array([truth[f.name] for f in free])
    assert np.all((lo <= expected) & (expected <= hi)), report.table()
    assert_close(report.values, expected, rtol=0.02)


def test_a_free_scale_is_estimated_with_the_frame(paper_model):
    """A tracker reporting in counts of unknown size: the scale is an extra parameter."""
    model = paper_model
    frame = SensorFrame("tracker", scale=1000.0, unit="", free_scale=True)
    assert frame.names[-1] == "tracker.scale"
    assert frame.parameters()["tracker.scale"] == 1000.0
    output = tip_position_map(model, frame=frame)
    q = np.array([0.066, 12.0, -5.0])
    tip = model.tip_pose(q).position
    values = {"tracker.scale": 2.5, "tracker.x": 0.01}
    expected = 2.5 * (tip - [0.01, 0.0, 0.0])
    assert_close(evaluate_output(output, model, q, values), expected, rtol=1e-14, scale=0.2)
    inputs = bellows_input_map(area=2e-5, distance=0.01)
    t = np.linspace(0.0, 6.0, 20)
    phase = 4 * np.pi * t / 6.0
    pressures = {f"p{i}": 4e4 + 3e4 * np.sin(phase - 2 * np.pi * i / 3) for i in range(3)}
    zeros = {axis: 0 * t for axis in "xyz"}
    template = sc.Experiment(t, zeros, pressures, dict.fromkeys(pressures, "Pa"))
    truth = {"tracker.scale": 1234.5, "tracker.z": 0.004}
    clean = sc.fit_equilibria(
        model, template, output=output, input_map=inputs, free=[], extra=truth
    )
    noisy = clean.predicted + 0.01 * np.random.default_rng(2).standard_normal((t.size, 3))
    data = template.with_signals(**{a: noisy[:, k] for k, a in enumerate("xyz")})
    free = [sc.Free("tracker.scale", 100.0, 1e4), sc.Free("tracker.z", -0.1, 0.1, scale=0.01)]
    report = sc.fit_equilibria(model, data, output=output, input_map=inputs, free=free)
    assert report.success, report.message
    lo, hi = report.intervals.T
    assert np.all((lo <= [1234.5, 0.004]) & ([1234.5, 0.004] <= hi)), report.table()
    with pytest.raises(sc.ParameterError, match="free_scale"):
        SensorFrame("tracker", free_scale=1)


# -- initial states -------------------------------------------------------------------------


def _pressure_experiment(actuator, start):
    t = np.linspace(0.0, 0.2, 21)
    inputs = {f"p{i}": np.full(t.size, start[i] / 1e3) for i in range(actuator.n_inputs)}
    units = dict.fromkeys(inputs, "kPa")
    return sc.Experiment(t, {"x": 0 * t}, inputs, units)


def test_initial_equilibrium_satisfies_the_static_equation(paper_model):
    model = paper_model
    actuator = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)
    start = np.array([3e4, 1e4, 0.0])
    experiment = _pressure_experiment(actuator, start)
    maps = (actuator_input_map(actuator), bellows_input_map(area=2e-5, distance=0.01))
    for how in (actuator, *maps):
        state = sc.initial_equilibrium(model, experiment, how)
        assert state.success, state.message
        assert_close(state.inputs, start, rtol=1e-15)  # kPa converted once, at load
        static = model.gravity_force(state.q) + model.elastic_force(state.q)
        force = actuator.input_matrix(state.q) @ start
        assert_close(static, force, rtol=0.0, atol=1e-9 * np.abs(force).max())
        assert state.x0.shape == (model.n_state,) and not state.x0[model.n :].any()
    assert np.hypot(*state.q[1:]) > 1.0  # the pressures bend it


def test_initial_equilibrium_rejects_inputs_in_the_wrong_unit(paper_model):
    model = paper_model
    t = np.linspace(0.0, 1.0, 3)
    experiment = sc.Experiment(t, {"x": t}, {f"T{i}": t for i in range(3)}, {"T0": "N"})
    with pytest.raises(sc.ExperimentError, match=r"input 'T0' is in 'N' .* expects 'Pa'"):
        sc.initial_equilibrium(model, experiment, bellows_input_map(area=2e-5, distance=0.01))


def test_simulate_starts_a_lagging_actuator_at_the_given_state(paper_model):
    actuator = sc.PneumaticActuator.three_bellows(
        distance=0.01, area=2e-5, p_max=1e5, time_constant=0.05
    )
    start = np.array([3e4, 1e4, 0.0])
    state = sc.initial_equilibrium(paper_model, _pressure_experiment(actuator, start), actuator)
    q0, qd0, lam0 = np.split(state.x0, [3, 6])
    run = sc.simulate(
        paper_model, q0, qd0, lam0, actuator=actuator, inputs=start,
        actuator_state=state.inputs, t_final=0.2, dt=0.01,
    )  # fmt: skip
    assert run.success, run.message
    assert_close(run.inputs[0], start, rtol=0.0, atol=0.0)
    assert_close(run.inputs, np.tile(start, (run.t.size, 1)), atol=1e-6 * start.max())
    # started at the equilibrium of its inputs, the robot stays there
    assert_close(run.q, np.tile(q0, (run.t.size, 1)), atol=1e-6, scale=0.0)
    from_zero = sc.simulate(
        paper_model, q0, qd0, lam0, actuator=actuator, inputs=start, t_final=0.02, dt=0.01
    )
    assert_close(from_zero.inputs[0], np.zeros(3), atol=0.0)


def test_simulate_checks_the_initial_actuator_state(paper_model):
    q0, zero = [0.0644, 0.0, 0.0], np.zeros(3)
    lagging = sc.PneumaticActuator.three_bellows(
        distance=0.01, area=2e-5, p_max=1e5, time_constant=0.05
    )
    with pytest.raises(sc.ParameterError, match=r"actuator_state\[1\] = 200000.0 Pa is outside"):
        sc.simulate(paper_model, q0, zero, actuator=lagging, inputs=zero,
                    actuator_state=[0.0, 2e5, 0.0], t_final=0.01)  # fmt: skip
    with pytest.raises(sc.ParameterError, match="actuator_state must have shape|actuator_state"):
        sc.simulate(paper_model, q0, zero, actuator=lagging, inputs=zero,
                    actuator_state=[0.0, 1.0], t_final=0.01)  # fmt: skip
    instant = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)
    with pytest.raises(sc.ParameterError, match="time_constant"):
        sc.simulate(paper_model, q0, zero, actuator=instant, inputs=zero,
                    actuator_state=zero, t_final=0.01)  # fmt: skip


def test_batch_members_start_from_their_actuator_states_as_simulate(paper_model):
    lagging = sc.PneumaticActuator.three_bellows(
        distance=0.01, area=2e-5, p_max=1e5, time_constant=0.05
    )
    q0, zero = np.array([0.0644, 0.0, 0.0]), np.zeros(3)
    inputs, states = [[1e4, 1e4, 1e4], zero], [[1e4, 2e4, 3e4], [0.0, 0.0, 5e4]]
    batch = sc.simulate_batch(paper_model, q0, zero, actuator=lagging, inputs=inputs,
                              actuator_state=states, t_final=0.05, dt=0.01)  # fmt: skip
    for b in range(2):
        single = sc.simulate(paper_model, q0, zero, actuator=lagging, inputs=inputs[b],
                             actuator_state=states[b], t_final=0.05, dt=0.01)  # fmt: skip
        assert_close(batch.inputs[b], single.inputs, rtol=0.0, atol=0.0, what="inputs")
        assert_close(batch.x[b], single.x, rtol=0.0, atol=0.0, what="states")
    with pytest.raises(sc.ParameterError, match=r"actuator_state\[1\]\[2\] = 200000.0 Pa"):
        sc.simulate_batch(paper_model, q0, zero, actuator=lagging, inputs=zero,
                          actuator_state=[zero, [0.0, 0.0, 2e5]], t_final=0.01)  # fmt: skip
    instant = sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)
    with pytest.raises(sc.ParameterError, match="time_constant"):
        sc.simulate_batch(paper_model, q0, zero, actuator=instant, inputs=zero,
                          actuator_state=zero, t_final=0.01)  # fmt: skip
