"""simulate_batch(): each member equals its single simulation; parameters per member;
failures stay with their member; bad input is refused."""

from __future__ import annotations

import numpy as np
import pytest

import softcurve as sc
from softcurve.simulation.batch import simulate_batch
from tests.conftest import assert_close, random_state

T_FINAL, DT = 0.4, 0.01


def state_scale(model, reference):
    """Per-state scale for normalised comparisons: max |x| over time plus the natural scale."""
    natural = sc.simulate.__globals__["nominal_scale"](model, np.zeros(model.n_state))
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
    batch = simulate_batch(paper_model, T_FINAL, q0s, qd0s, lam0s, tau, dt=DT)
    assert batch.q.shape == (4, 41, 3) and batch.tip.shape == (4, 41, 3)
    assert np.all(batch.success), batch.message
    for i in range(4):
        single = sc.simulate(paper_model, T_FINAL, q0s[i], qd0s[i], lam0s[i], tau[i], dt=DT)
        member = batch.member(i)
        assert member.stats["method"] == single.stats["method"]
        scale = state_scale(paper_model, single)
        assert_close(member.x, single.x, rtol=1e-10, scale=scale, what=f"member {i}")
        assert_close(member.tip, single.tip, rtol=1e-10, scale=0.1, what=f"tip {i}")
        assert_close(batch.energy()[i], single.energy(), rtol=1e-10, scale=1.0, what="energy")


def test_parameters_per_member(paper_model, states):
    """Members with other parameter values equal simulations of the robot built from them."""
    q0s, qd0s, _, _ = states
    names = paper_model.robot.parameter_names()
    base = paper_model.robot.parameter_vector()
    parameters = np.repeat(base[None, :], 3, axis=0)
    parameters[1, names.index("segments[0].bending_stiffness.a1")] = 0.5
    parameters[2, names.index("segments[0].mass")] = 0.07
    parameters[2, names.index("gravity[2]")] = 9.81  # hanging
    batch = simulate_batch(paper_model, T_FINAL, q0s[:3], qd0s[:3], parameters=parameters, dt=DT)
    finals = []
    for i in range(3):
        model = sc.Model(paper_model.robot.with_parameter_vector(parameters[i]))
        single = sc.simulate(model, T_FINAL, q0s[i], qd0s[i], dt=DT)
        scale = state_scale(model, single)
        assert_close(batch.member(i).x, single.x, rtol=1e-10, scale=scale, what=f"member {i}")
        assert_close(batch.tip[i], single.tip, rtol=1e-10, scale=0.1, what=f"tip {i}")
        assert_close(batch.energy()[i], single.energy(), rtol=1e-10, scale=1.0, what="energy")
        finals.append(batch.q[i, -1])
    assert not np.allclose(finals[1], finals[0])  # the parameters do act


def test_method_is_chosen_per_member_as_in_simulate(paper_model):
    """A member with very fast creep is stiff: "cvodes" integrates it with BDF, the others
    with Adams, exactly as single simulations choose."""
    names = paper_model.robot.parameter_names()
    parameters = np.repeat(paper_model.robot.parameter_vector()[None, :], 2, axis=0)
    parameters[1, names.index("segments[0].creep.rate[0]")] = 1e5
    q0, qd0 = np.array([0.064, 25.0, 0.0]), np.array([0.0, 0.0, 150.0])
    batch = simulate_batch(paper_model, 0.2, q0, qd0, parameters=parameters, dt=DT)
    assert batch.stats["methods"] == ["cvodes-adams", "cvodes-bdf"]
    for i in range(2):
        model = sc.Model(paper_model.robot.with_parameter_vector(parameters[i]))
        single = sc.simulate(model, 0.2, q0, qd0, dt=DT)
        assert single.stats["method"] == batch.stats["methods"][i]
        assert_close(batch.member(i).x, single.x, rtol=1e-10, scale=state_scale(model, single))


def test_members_switch_to_bdf_as_in_simulate(paper_model):
    """Over several restart intervals the per-member switch to BDF once settled is the
    one simulate() makes: same family, same result."""
    q0s = np.array([[0.064, 5.0, 0.0], [0.064, 25.0, 0.0]])
    qd0s = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1500.0]])
    batch = simulate_batch(paper_model, 3.0, q0s, qd0s, dt=0.01)
    for i in range(2):
        single = sc.simulate(paper_model, 3.0, q0s[i], qd0s[i], dt=0.01)
        assert batch.stats["methods"][i] == single.stats["method"]
        assert batch.message[i] == single.message.split(" in ")[0]
        assert_close(
            batch.member(i).x, single.x, rtol=1e-10, scale=state_scale(paper_model, single)
        )
    assert batch.stats["methods"][0] == "cvodes-adams+bdf"


def test_threads_do_not_change_results(paper_model, states):
    q0s, qd0s, lam0s, tau = states
    one = simulate_batch(paper_model, 0.2, q0s, qd0s, lam0s, tau, dt=DT, threads=1)
    two = simulate_batch(paper_model, 0.2, q0s, qd0s, lam0s, tau, dt=DT, threads=2)
    np.testing.assert_array_equal(one.x, two.x)
    np.testing.assert_array_equal(one.tip, two.tip)


def test_a_failing_member_keeps_its_partial_result_and_spares_the_others(paper_model):
    """With few steps allowed per output, the fast paper transient fails, the robot at
    rest does not; the failure is reported on its member only."""
    q0s = np.array([[0.0644, 0.0, 0.0], [0.064, 25.0, 0.0], [0.0644, 0.0, 0.0]])
    qd0s = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1500.0], [0.0, 0.0, 0.0]])
    batch = simulate_batch(paper_model, 0.3, q0s, qd0s, dt=0.05, max_steps=100)
    assert list(batch.status) == ["success", "failed", "success"]
    assert batch.reached[1] < batch.t.size and "CV_TOO_MUCH_WORK" in batch.message[1]
    assert np.all(np.isnan(batch.q[1, batch.reached[1] :]))
    assert np.all(np.isfinite(batch.q[[0, 2]]))
    member = batch.member(1)
    assert member.status == "failed" and member.t.size == batch.reached[1]
    single = sc.simulate(paper_model, 0.3, q0s[0], qd0s[0], dt=0.05, max_steps=100)
    assert_close(batch.member(0).x, single.x, rtol=1e-10, scale=state_scale(paper_model, single))


def test_worker_processes_give_the_same_results(paper_model):
    """processes=2 splits the members over two spawned workers: every output, status and
    message equals the run in this process, a failing member included."""
    q0s = np.array([[0.0644, 0.0, 0.0], [0.064, 25.0, 0.0], [0.0644, 2.0, 1.0]])
    qd0s = np.array([[0.0, 0.0, 0.0], [0.0, 0.0, 1500.0], [0.0, 0.0, 0.0]])
    parameters = np.repeat(paper_model.parameters[None, :], 3, axis=0)
    parameters[2, paper_model.robot.parameter_names().index("segments[0].mass")] *= 1.2
    settings = dict(dt=0.05, max_steps=100, parameters=parameters)
    here = simulate_batch(paper_model, 0.3, q0s, qd0s, threads=1, **settings)
    split = simulate_batch(paper_model, 0.3, q0s, qd0s, processes=2, **settings)
    assert list(split.status) == ["success", "failed", "success"]
    assert split.message == here.message and split.stats["processes"] == 2
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
    names = two.parameter_names()
    changed[[i for i, n in enumerate(names) if n.startswith("base_rotation")]] = np.eye(3).ravel()
    np.testing.assert_array_equal(two.with_parameter_vector(changed).parameter_vector(), changed)
    bad = vector.copy()
    bad[robot.parameter_names().index("segments[0].bending_stiffness.a1")] = 0.3  # < a2
    with pytest.raises(sc.ParameterError, match="a1"):
        robot.with_parameter_vector(bad)


def test_bad_input_is_refused(paper_model):
    q0, qd0 = np.array([0.064, 25.0, 0.0]), np.zeros(3)
    cases = [
        (dict(q0s=np.ones((2, 3)), qd0s=np.zeros((3, 3))), "rows"),
        (dict(q0s=np.ones((2, 4)), qd0s=qd0), r"shape \(B, 3\)"),
        (dict(q0s=[[0.064, np.nan, 0.0]], qd0s=qd0), r"q0s\[0\] must be finite"),
        (dict(q0s=q0, qd0s=qd0, method="rk45"), "method"),
        (dict(q0s=q0, qd0s=qd0, threads=0), "threads"),
        (dict(q0s=q0, qd0s=qd0, processes=0), "processes"),
        (dict(q0s=q0, qd0s=qd0, parameters=np.zeros(3)), "parameters"),
    ]
    for kwargs, message in cases:
        with pytest.raises(sc.ParameterError, match=message):
            simulate_batch(paper_model, 0.1, **kwargs)
    bad = paper_model.robot.parameter_vector().copy()
    bad[0] = -1.0
    with pytest.raises(sc.ParameterError, match=r"parameters\[1\]: rest_length"):
        simulate_batch(paper_model, 0.1, q0, qd0, parameters=[paper_model.parameters, bad])


def test_plot_writes_a_figure(paper_model, tmp_path):
    import matplotlib.pyplot as plt

    batch = simulate_batch(paper_model, 0.1, [[0.064, 5.0, 0.0], [0.064, -5.0, 0.0]], np.zeros(3))
    figure = batch.plot(tmp_path / "tips.png")
    assert (tmp_path / "tips.png").stat().st_size > 0 and len(figure.axes) == 3
    plt.close(figure)


def test_blocks_of_members_give_the_same_results(paper_model, states, monkeypatch):
    """Large batches run in blocks of members (bounded memory); the blocks are invisible."""
    import softcurve.simulation.batch as batch_module

    q0s, qd0s, lam0s, tau = states
    whole = simulate_batch(paper_model, 0.2, q0s, qd0s, lam0s, tau, dt=DT)
    monkeypatch.setattr(batch_module, "BLOCK_DOUBLES", 21 * 12)  # one member per block
    assert len(batch_module._blocks(4, 21, 12)) == 4
    blocked = simulate_batch(paper_model, 0.2, q0s, qd0s, lam0s, tau, dt=DT)
    np.testing.assert_array_equal(blocked.x, whole.x)
    np.testing.assert_array_equal(blocked.tip, whole.tip)
    np.testing.assert_array_equal(blocked.energy(), whole.energy())
