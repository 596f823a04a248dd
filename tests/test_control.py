"""Computed torque, PD with compensation, input allocation, MPC, references."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.integrate import solve_ivp

import softcurve as sc
from softcurve import ParameterError, PneumaticActuator, TanhStiffness
from softcurve.base.status import Status
from softcurve.control.controllers import (
    ActuatorDriven,
    ComputedTorque,
    InputAllocator,
    PDGravityElastic,
    closed_loop_rhs,
)
from softcurve.control.mpc import ActuatorMPC
from softcurve.control.references import Reference, tip_circle, tip_to_coordinates
from softcurve.simulation._simulate import simulate

from .conftest import assert_close

CIRCLE = dict(center=(0.02, 0.0, 0.065), radius=0.01, period=2.0)
GAINS = dict(kp=(2 * np.pi * 20) ** 2, kd=2 * 0.9 * 2 * np.pi * 20)  # 20 Hz, damping 0.9


def actuator(**changes):
    fields = dict(distance=0.012, area=2e-4, p_max=6e4)
    fields.update(changes)
    return PneumaticActuator.three_bellows(**fields)


def softer(robot, factor=0.9):
    """The robot with both stiffness laws scaled by ``factor`` (a 10 % model error)."""
    s = robot.segments[0]
    e, b = s.elongation_stiffness, s.bending_stiffness
    segment = s.replace(
        elongation_stiffness=TanhStiffness(factor * e.a1, factor * e.a2, e.a3),
        bending_stiffness=TanhStiffness(factor * b.a1, factor * b.a2, b.a3),
    )
    return robot.replace(segments=(segment,))


def reference_tips(model, reference, t):
    """Tip positions of the reference (copies: never keep views of the model's buffers)."""
    return np.array([np.array(model.tip_pose(reference(ti).q).position) for ti in t])


def tracking_error(model, reference, t, q):
    return np.array([q[i] - reference(ti).q for i, ti in enumerate(t)])


def test_inverse_kinematics_of_the_tip_is_exact(paper_model):
    for point in ([0.02, 0.01, 0.065], [-0.03, 0.002, 0.04], [1e-4, -2e-4, 0.07]):
        q = np.array(tip_to_coordinates(np.array(point))).ravel()
        assert_close(paper_model.tip_pose(q).position, point, rtol=0, atol=1e-15)


def test_reference_derivatives_are_exact():
    ref = tip_circle(**CIRCLE)
    t, h = 0.37, 1e-5
    assert_close(ref(t).qd, (ref(t + h).q - ref(t - h).q) / (2 * h), rtol=1e-7, scale=1.0)
    assert_close(ref(t).qdd, (ref(t + h).qd - ref(t - h).qd) / (2 * h), rtol=1e-6, scale=10.0)
    with pytest.raises(ParameterError, match="must stay off the z axis"):
        tip_circle(center=(0.005, 0, 0.06), radius=0.01, period=1.0)


def test_computed_torque_with_a_perfect_model_is_exact(paper_model):
    """Continuous-time closed loop: the error stays at rounding level."""
    ref = tip_circle(**CIRCLE)
    controller = ComputedTorque(paper_model, ref, sample_time=1e-3, **GAINS)
    start = ref(0.0)
    x0 = np.concatenate([start.q, start.qd, np.zeros(3)])
    run = solve_ivp(
        closed_loop_rhs(paper_model, controller), (0.0, 1.0), x0, method="DOP853",
        rtol=1e-10, atol=1e-14, t_eval=np.linspace(0, 1, 51),
    )  # fmt: skip
    assert run.success
    error = tracking_error(paper_model, ref, run.t, run.y[:3].T)
    scale = np.array([start.q[0], 1 / start.q[0], 1 / start.q[0]])  # 1 m of l, 1 rad of bending
    assert np.max(np.abs(error) / scale) < 1e-11, np.abs(error).max(axis=0)


def test_computed_torque_with_ten_percent_stiffness_error_stays_bounded(paper_model):
    ref = tip_circle(**CIRCLE)
    model_error = sc.Model(softer(paper_model.robot))
    controller = ComputedTorque(model_error, ref, sample_time=1e-3, **GAINS)
    start = ref(0.0)
    run = simulate(paper_model, start.q, start.qd, controller=controller, t_final=3.0, dt=1e-2)
    assert run.success, run.message
    error = tracking_error(paper_model, ref, run.t, run.q)
    tip_error = np.linalg.norm(run.tip - reference_tips(paper_model, ref, run.t), axis=1)
    first, last = tip_error[run.t <= 1.5].max(), tip_error[run.t > 1.5].max()
    print(
        f"10 % stiffness error: max tip error {1e3 * first:.3f} mm (first 1.5 s), "
        f"{1e3 * last:.3f} mm (last 1.5 s); max |e_l| {1e3 * np.abs(error[:, 0]).max():.3f} mm"
    )
    # measured 4.3 mm: the 10 % force error (~1 N on l) over the gain kp D_ll (~260 N/m)
    assert last < 6e-3 and last < 1.1 * first  # bounded, no drift
    assert np.abs(error[:, 0]).max() < 6e-3


def test_sampled_computed_torque_tracks_the_tip_circle(paper_model):
    ref = tip_circle(**CIRCLE)
    controller = ComputedTorque(paper_model, ref, sample_time=1e-3, **GAINS)
    start = ref(0.0)
    run = simulate(paper_model, start.q, start.qd, controller=controller, t_final=1.0, dt=1e-2)
    target = reference_tips(paper_model, ref, run.t)
    assert np.linalg.norm(run.tip - target, axis=1).max() < 1e-4  # measured 0.057 mm
    assert len(controller.log) == 1000


def test_pd_with_compensation_regulates_to_the_set_point(paper_model):
    goal = np.array([0.068, 10.0, -5.0])
    controller = PDGravityElastic(
        paper_model, Reference.constant(goal), kp=[500.0, 5e-4, 5e-4], kd=[2.0, 2e-5, 2e-5],
        sample_time=1e-3,
    )  # fmt: skip
    run = simulate(
        paper_model, [0.0644, 0.0, 0.0], np.zeros(3), controller=controller, t_final=2.0, dt=1e-2
    )
    assert run.success
    # steady state N(q) + kp (goal - q) = N(q) + K^T lam, creep decays: q -> goal
    assert_close(run.q[-1], goal, rtol=2e-3)


def test_allocation_is_exact_when_feasible_and_saturates_otherwise(paper_model, rng):
    act = actuator()
    allocator = InputAllocator(act, paper_model.robot)
    q = np.array([0.066, 8.0, -3.0])
    p = rng.uniform(1e4, 5e4, 3)
    result = allocator.allocate(q, act.input_matrix(q) @ p)
    assert_close(result.inputs, p, rtol=1e-9)
    assert not result.saturated.any() and result.success
    # pulling the robot shorter needs negative pressures: all saturate at zero
    result = allocator.allocate(q, [-5.0, 0.0, 0.0])
    assert np.all(result.inputs >= act.lower) and np.all(result.inputs <= act.upper)
    assert result.saturated.all() and result.residual > 0
    assert result.status is Status.INFEASIBLE
    # optimality: no feasible direction decreases the weighted residual
    w = allocator.weights
    h = act.input_matrix(q)
    for _ in range(20):
        trial = act.clip(result.inputs + rng.normal(scale=1e3, size=3))
        assert np.linalg.norm(w * (h @ trial - result.tau_requested)) >= result.residual - 1e-15


def test_actuator_driven_tip_circle_respects_the_bounds(paper_model):
    act = actuator(p_max=3.5e4, time_constant=0.01)  # tight bound: some samples saturate
    ref = tip_circle(**CIRCLE)
    driven = ActuatorDriven(
        ComputedTorque(paper_model, ref, sample_time=2e-3, **GAINS), act, paper_model.robot
    )
    start = ref(0.0)
    run = simulate(
        paper_model, start.q, start.qd, actuator=act, controller=driven, t_final=1.0, dt=1e-2
    )
    assert run.success, run.message
    command, pressures = driven.history("command"), driven.history("inputs")
    assert np.all(command >= 0.0) and np.all(command <= 3.5e4)
    assert np.all(pressures >= 0.0) and np.all(pressures <= 3.5e4)
    assert driven.history("saturated").any()
    # the lag: each pressure is the exact first-order response to the previous command
    dt = np.diff(driven.history("t"))
    expected = command[:-1] + (pressures[:-1] - command[:-1]) * np.exp(-dt / 0.01)[:, None]
    assert_close(pressures[1:], expected, rtol=1e-12, scale=3.5e4)
    # the wrapper returns the commands, as actuator inputs (m,)
    assert driven(1.0, run.q[-1], run.qd[-1], run.lam[-1]).shape == (3,)
    # and the robot received H(q) u of those inputs: the integrated lag equals the
    # wrapper's exact response at every output time that is a sample time
    times = driven.history("t")
    for k in (1, 25, 50, run.t.size - 2):
        i = int(np.argmin(np.abs(times - run.t[k])))
        assert abs(times[i] - run.t[k]) < 1e-12
        assert_close(run.inputs[k], pressures[i], rtol=1e-5, scale=3.5e4)  # rtol of simulate
    tau = act.input_matrix(run.q[-1]) @ run.inputs[-1]
    assert_close(run.tau[-1], tau, rtol=1e-9, scale=np.abs(tau).max())


def test_bad_controller_arguments(paper_model):
    ref = Reference.constant([0.0644, 0.0, 0.0])
    with pytest.raises(ParameterError, match="sample_time must be > 0"):
        ComputedTorque(paper_model, ref, kp=1.0, kd=1.0, sample_time=0.0)
    with pytest.raises(ParameterError, match="kp must be finite and >= 0"):
        PDGravityElastic(paper_model, ref, kp=-1.0, kd=1.0, sample_time=1e-3)
    six = Reference.constant(np.zeros(6))
    with pytest.raises(ParameterError, match="reference has 6 coordinates, the robot 3"):
        ComputedTorque(paper_model, six, kp=1, kd=1, sample_time=1)
    with pytest.raises(ParameterError, match="reference has 6 coordinates, the robot 3"):
        PDGravityElastic(paper_model, six, kp=1, kd=1, sample_time=1)
    with pytest.raises(ParameterError, match="reference has 6 coordinates, the robot 3"):
        ActuatorMPC(paper_model, actuator(), six)
    with pytest.raises(ParameterError, match="reference must be a Reference, got str"):
        ActuatorMPC(paper_model, actuator(), "circle")


def test_a_reference_in_l_kx_ky_is_refused_on_a_robot_of_other_elements():
    """``tip_circle`` gives ``(l, kx, ky)``; a strain segment of the same three strains has
    as many coordinates, but not these (docs/strains.md gives the map)."""
    strains = sc.StrainSegment(
        rest_length=0.064, mass=0.015, radius=0.01, strains=("bend_x", "bend_y", "stretch"),
        bending_stiffness=sc.LinearStiffness(1e-2), stretch_stiffness=sc.LinearStiffness(50.0),
    )  # fmt: skip
    robot = sc.Robot([strains])
    circle = tip_circle(**CIRCLE)
    assert robot.n == circle.n == 3
    with pytest.raises(ParameterError, match=r"\(l, kx, ky\) of constant-curvature segments"):
        circle.check_robot(robot)
    Reference.constant(np.zeros(3)).check_robot(robot)  # in the robot's own coordinates
    circle.check_robot(sc.presets.ifac2020())


def test_mpc_tracks_the_tip_circle_within_pressure_bounds(paper_model):
    ref = tip_circle(**CIRCLE)
    start = ref(0.0)
    act = actuator()
    mpc = ActuatorMPC(paper_model, act, ref, horizon=10, sample_time=0.01)
    run = simulate(
        paper_model, start.q, start.qd, actuator=act, controller=mpc, t_final=1.0, dt=1e-2
    )
    assert run.success, run.message
    error = np.linalg.norm(run.tip - reference_tips(paper_model, ref, run.t), axis=1)
    assert error[run.t > 0.5].max() < 1e-5  # measured 1.7e-6 m
    pressures = mpc.history("inputs")
    assert np.all(pressures >= 0.0) and np.all(pressures <= 6e4)
    # a tight bound saturates: the pressures stay inside and the error grows
    tight_actuator = actuator(p_max=2.5e4)
    tight = ActuatorMPC(paper_model, tight_actuator, ref, horizon=10, sample_time=0.01)
    run = simulate(
        paper_model, start.q, start.qd, actuator=tight_actuator, controller=tight, t_final=0.5,
        dt=1e-2,
    )  # fmt: skip
    pressures = tight.history("inputs")
    assert np.all(pressures >= 0.0) and np.all(pressures <= 2.5e4)
    assert np.any(pressures == 2.5e4)
    with pytest.raises(ParameterError, match="horizon must be an integer >= 1"):
        ActuatorMPC(paper_model, actuator(), ref, horizon=0)
