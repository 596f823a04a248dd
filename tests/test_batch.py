"""simulate_batch(): each member equals its single simulation; parameters per member;
failures stay with their member; bad input is refused."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import softcurve as sc
import softcurve.simulation.solvers._along as along_module
from softcurve.base.status import Status
from softcurve.simulation.batch._batch import simulate_batch
from softcurve.simulation.solvers._policy import nominal_scale
from tests.conftest import assert_close, random_state

T_FINAL, DT = 0.4, 0.01


def state_scale(model, reference):
    """Per-state scale for normalized comparisons: max |x| over time plus the natural scale."""
    natural = nominal_scale(model, np.zeros(model.n_state))
    return np.abs(reference.x).max(axis=0) + natural


@pytest.fixture(scope="module")
def states(paper_model):
    rng = np.random.default_rng(6)
    pairs = [random_state(rng, paper_model) for _ in range(4)]
    q0s, qd0s = (np.array(column) for column in zip(*pairs, strict=True))
    lam0s = rng.uniform(-1e-3, 1e-3, (4, paper_model.n_creep))
    tau = rng.uniform(-0.05, 0.05, (4, paper_model.n)) * [1.0, 1e-3, 1e-3]
    return q0s, qd0s, lam0s, tau


def test_members_equal_single_simulations(paper_model, states):
    q0s, qd0s, lam0s, tau = states
    batch = simulate_batch(
        paper_model, q0s, qd0s, lam0s, tau=tau, t_final=T_FINAL, dt=DT, lanes=False
    )
    assert batch.q.shape == (4, 41, 3) and batch.tip.shape == (4, 41, 3)
    assert batch.success and np.all(batch.member_success), batch.member_message
    for i in range(4):
        single = sc.simulate(
            paper_model, q0s[i], qd0s[i], lam0s[i], tau=tau[i], t_final=T_FINAL, dt=DT
        )
        member = batch.member(i)
        assert member.stats["method"] == single.stats["method"]
        scale = state_scale(paper_model, single)
        assert_close(member.x, single.x, rtol=1e-10, scale=scale, what=f"member {i}")
        assert_close(member.tip, single.tip, rtol=1e-10, scale=0.1, what=f"tip {i}")
        assert_close(batch.energy()[i], single.energy(), rtol=1e-10, scale=1.0, what="energy")


def test_parameters_per_member(paper_model, states):
    """Members with other parameter values equal simulations of the robot built from them."""
    q0s, qd0s, _, _ = states
    layout = paper_model.robot.layout
    base = paper_model.robot.parameter_vector()
    parameters = np.repeat(base[None, :], 3, axis=0)
    parameters[1, layout.index("segments[0].bending_stiffness.a1")] = 0.5
    parameters[2, layout.index("segments[0].mass")] = 0.07
    parameters[2, layout.index("gravity[2]")] = 9.81  # hanging
    batch = simulate_batch(
        paper_model, q0s[:3], qd0s[:3], t_final=T_FINAL, parameters=parameters, dt=DT
    )
    finals = []
    for i in range(3):
        model = sc.Model(paper_model.robot.with_parameter_vector(parameters[i]))
        single = sc.simulate(model, q0s[i], qd0s[i], t_final=T_FINAL, dt=DT)
        scale = state_scale(model, single)
        assert_close(batch.member(i).x, single.x, rtol=1e-10, scale=scale, what=f"member {i}")
        assert_close(batch.tip[i], single.tip, rtol=1e-10, scale=0.1, what=f"tip {i}")
        assert_close(batch.energy()[i], single.energy(), rtol=1e-10, scale=1.0, what="energy")
        finals.append(batch.q[i, -1])
    assert not np.allclose(finals[1], finals[0])  # the parameters do act


def test_method_is_chosen_per_member_as_in_simulate(paper_model):
    """A member with very fast creep is stiff: "cvodes" integrates it with BDF, the others
    with Adams, exactly as single simulations choose."""
    parameters = np.repeat(paper_model.robot.parameter_vector()[None, :], 2, axis=0)
    parameters[1, paper_model.robot.layout.index("segments[0].creep.rate[0]")] = 1e5
    q0, qd0 = np.array([0.064, 25.0, 0.0]), np.array([0.0, 0.0, 150.0])
    batch = simulate_batch(paper_model, q0, qd0, t_final=0.2, parameters=parameters, dt=DT)
    assert batch.stats["methods"] == ["cvodes-adams", "cvodes-bdf"]
    for i in range(2):
        model = sc.Model(paper_model.robot.with_parameter_vector(parameters[i]))
        single = sc.simulate(model, q0, qd0, t_final=0.2, dt=DT)
        assert single.stats["method"] == batch.stats["methods"][i]
        assert_close(batch.member(i).x, single.x, rtol=1e-10, scale=state_scale(model, single))


def test_members_switch_to_bdf_as_in_simulate(paper_model):
    """Over several restart intervals the per-member switch to BDF once settled is the
    one simulate() makes: same family, same result."""
    q0s = np.array([[0.064, 5.0, 0.0], [0.064, 25.0, 0.0]])
    qd0s = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1500.0]])
    batch = simulate_batch(paper_model, q0s, qd0s, t_final=3.0, dt=0.01)
    for i in range(2):
        single = sc.simulate(paper_model, q0s[i], qd0s[i], t_final=3.0, dt=0.01)
        assert batch.stats["methods"][i] == single.stats["method"]
        assert batch.member_message[i] == single.message.split(" in ")[0]
        assert_close(
            batch.member(i).x, single.x, rtol=1e-10, scale=state_scale(paper_model, single)
        )
    assert batch.stats["methods"][0] == "cvodes-adams+bdf"


def test_threads_do_not_change_results(paper_model, states):
    q0s, qd0s, lam0s, tau = states
    one = simulate_batch(paper_model, q0s, qd0s, lam0s, tau=tau, t_final=0.2, dt=DT, threads=1)
    two = simulate_batch(paper_model, q0s, qd0s, lam0s, tau=tau, t_final=0.2, dt=DT, threads=2)
    np.testing.assert_array_equal(one.x, two.x)
    np.testing.assert_array_equal(one.tip, two.tip)


def test_a_failing_member_keeps_its_partial_result_and_spares_the_others(paper_model):
    """With few steps allowed per output, the fast paper transient fails, the robot at
    rest does not; the failure is reported on its member only."""
    q0s = np.array([[0.0644, 0.0, 0.0], [0.064, 25.0, 0.0], [0.0644, 0.0, 0.0]])
    qd0s = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1500.0], [0.0, 0.0, 0.0]])
    batch = simulate_batch(paper_model, q0s, qd0s, t_final=0.3, dt=0.05, max_steps=100)
    assert list(batch.member_status) == ["success", "integration_failed", "success"]
    assert batch.status is Status.PARTIAL and "1 of 3 members failed" in batch.message
    assert list(batch.member_success) == [True, False, True] and not batch.success
    assert batch.reached[1] < batch.t.size and "CV_TOO_MUCH_WORK" in batch.member_message[1]
    assert np.all(np.isnan(batch.q[1, batch.reached[1] :]))
    assert np.all(np.isfinite(batch.q[[0, 2]]))
    member = batch.member(1)
    assert member.status is Status.INTEGRATION_FAILED and member.t.size == batch.reached[1]
    every = simulate_batch(paper_model, q0s[1], qd0s[1], t_final=0.3, dt=0.05, max_steps=100)
    assert every.status is Status.INTEGRATION_FAILED and "1 of 1 members" in every.message
    with pytest.raises(dataclasses.FrozenInstanceError):
        every.status = Status.SUCCESS
    single = sc.simulate(paper_model, q0s[0], qd0s[0], t_final=0.3, dt=0.05, max_steps=100)
    assert_close(batch.member(0).x, single.x, rtol=1e-10, scale=state_scale(paper_model, single))


def test_worker_processes_give_the_same_results(paper_model):
    """processes=2 splits the members over two spawned workers: every output, status and
    message equals the run in this process, a failing member included."""
    q0s = np.array([[0.0644, 0.0, 0.0], [0.064, 25.0, 0.0], [0.0644, 2.0, 1.0]])
    qd0s = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1500.0], [0.0, 0.0, 0.0]])
    parameters = np.repeat(paper_model.parameters[None, :], 3, axis=0)
    parameters[2, paper_model.robot.layout.index("segments[0].mass")] *= 1.2
    settings = dict(dt=0.05, max_steps=100, parameters=parameters)
    here = simulate_batch(paper_model, q0s, qd0s, t_final=0.3, threads=1, **settings)
    split = simulate_batch(paper_model, q0s, qd0s, t_final=0.3, processes=2, **settings)
    assert list(split.member_status) == ["success", "integration_failed", "success"]
    assert split.member_message == here.member_message and split.stats["processes"] == 2
    assert (split.status, split.message) == (here.status, here.message)
    np.testing.assert_array_equal(split.reached, here.reached)
    np.testing.assert_array_equal(split.x, here.x)
    np.testing.assert_array_equal(split.tip, here.tip)
    assert split.stats["methods"] == here.stats["methods"]


def test_with_parameter_vector_round_trip_and_validation():
    robot = sc.presets.ifac2020()
    vector = robot.parameter_vector()
    np.testing.assert_array_equal(robot.with_parameter_vector(vector).parameter_vector(), vector)
    two = robot.with_segments(2)
    changed = two.parameter_vector() * np.linspace(1.0, 1.1, two.parameter_vector().size)
    changed[two.layout.slice("base_rotation")] = np.eye(3).ravel()
    np.testing.assert_array_equal(two.with_parameter_vector(changed).parameter_vector(), changed)
    bad = vector.copy()
    bad[robot.layout.index("segments[0].bending_stiffness.a1")] = 0.3  # < a2
    with pytest.raises(sc.ParameterError, match="a1"):
        robot.with_parameter_vector(bad)


def test_bad_input_is_refused(paper_model):
    q0, qd0 = np.array([0.064, 25.0, 0.0]), np.zeros(3)
    cases = [
        (dict(q0=np.ones((2, 3)), qd0=np.zeros((3, 3))), "rows"),
        (dict(q0=np.ones((2, 4)), qd0=qd0), r"shape \(B, 3\)"),
        (dict(q0=[[0.064, np.nan, 0.0]], qd0=qd0), r"q0\[0\] must be finite"),
        (dict(q0=q0, qd0=qd0, method="rk45"), "method"),
        (dict(q0=q0, qd0=qd0, threads=0), "threads"),
        (dict(q0=q0, qd0=qd0, processes=0), "processes"),
        (dict(q0=q0, qd0=qd0, parameters=np.zeros(3)), "parameters"),
        (dict(q0=q0, qd0=qd0, dt=1.0), "dt must be <= t_final"),
        (dict(q0=q0, qd0=qd0, atol=np.ones(4)), "atol must have 9 entries"),
    ]
    for kwargs, message in cases:
        with pytest.raises(sc.ParameterError, match=message):
            simulate_batch(paper_model, t_final=0.1, **kwargs)
    bad = paper_model.robot.parameter_vector().copy()
    bad[0] = -1.0
    with pytest.raises(sc.ParameterError, match=r"parameters\[1\]: rest_length"):
        simulate_batch(paper_model, q0, qd0, t_final=0.1, parameters=[paper_model.parameters, bad])


def test_blocks_of_members_give_the_same_results(paper_model, states, monkeypatch):
    """Large batches run in blocks of members (bounded memory); the blocks are invisible."""
    q0s, qd0s, lam0s, tau = states
    whole = simulate_batch(paper_model, q0s, qd0s, lam0s, tau=tau, t_final=0.2, dt=DT)
    monkeypatch.setattr(along_module, "BLOCK_DOUBLES", 21 * 12)  # one member per block
    assert len(along_module.blocks(4, 21, 12)) == 4
    blocked = simulate_batch(paper_model, q0s, qd0s, lam0s, tau=tau, t_final=0.2, dt=DT)
    np.testing.assert_array_equal(blocked.x, whole.x)
    np.testing.assert_array_equal(blocked.tip, whole.tip)
    np.testing.assert_array_equal(blocked.energy(), whole.energy())


def test_a_member_leaving_the_domain_stops_alone(paper_model):
    """Issue 11, case 3 in a batch: the member whose length crosses zero stops with
    LEFT_DOMAIN at its first output outside the domain; the others are untouched."""
    q0s = np.array([[0.0644, 0.0, 0.0], [0.064, 0.0, 0.0], [0.064, 25.0, 0.0]])
    qd0s = np.array([[0.0, 0.0, 0.0], [-50.0, 0.0, 0.0], [0.0, 0.0, 1500.0]])
    for processes in (1, 2):
        batch = simulate_batch(paper_model, q0s, qd0s, t_final=0.1, dt=1e-4, processes=processes)
        assert list(batch.member_status) == ["success", "left_domain", "success"]
        assert batch.status is Status.PARTIAL
        message = batch.member_message[1]
        assert "the state left the model's domain at t = " in message
        assert "l of segment 1 (q[0]) = -" in message and "too soft" in message
        reached = batch.reached[1]
        assert 10 <= reached < batch.t.size and np.all(batch.q[1, :reached, 0] > 0)
        assert np.all(np.isnan(batch.q[1, reached:]))
        member = batch.member(1)
        assert member.status is Status.LEFT_DOMAIN and member.t.size == reached
        single = sc.simulate(paper_model, q0s[1], qd0s[1], t_final=0.1, dt=1e-4)
        assert single.status is Status.LEFT_DOMAIN and single.t.size == reached


def test_q0_outside_the_domain_is_refused_per_member(paper_model):
    q0s = np.array([[0.064, 0.0, 0.0], [0.064, 200.0, 0.0]])
    with pytest.raises(sc.ParameterError, match=r"q0\[1\] \(member 1\): bending angles"):
        simulate_batch(paper_model, q0s, np.zeros(3), t_final=0.1)
    # the limit follows each member's own rest length
    parameters = np.repeat(paper_model.parameters[None, :], 2, axis=0)
    parameters[1, paper_model.robot.layout.index("segments[0].rest_length")] = 0.01
    q0s = np.array([[0.2, 0.0, 0.0], [0.2, 0.0, 0.0]])
    with pytest.raises(sc.ParameterError, match=r"q0\[1\] \(member 1\): lengths l .*0.1 m"):
        simulate_batch(paper_model, q0s, np.zeros(3), parameters=parameters, t_final=0.1)
