"""Members of a batch integrated in groups stacked into one CVODES system, on the state
derivative over lanes (``simulate_batch(lanes=True)``, the default): each member within
its tolerance, results independent of how the batch is split, and failures read exactly
as alone."""

import numpy as np
import pytest

import softcurve as sc
from softcurve.base.status import Status
from softcurve.simulation.batch._batch import simulate_batch
from softcurve.simulation.solvers import _along as along_module
from softcurve.simulation.solvers import _driver as native
from softcurve.simulation.solvers._policy import nominal_scale

from .conftest import compiler_refusing

pytestmark = pytest.mark.skipif(
    sc.simulation.solvers.driver() is None, reason="softcurve's C driver is not available"
)


def members(size: int, seed: int = 2020):
    """Released bent robots, as in benchmarks/bench_batch.py: no two alike."""
    rng = np.random.default_rng(seed)
    q0s = np.column_stack([np.full(size, 0.064), rng.uniform(20, 30, size), np.zeros(size)])
    qd0s = np.column_stack([np.zeros(size), np.zeros(size), rng.uniform(1000, 2000, size)])
    return q0s, qd0s


def normalized_error(model, x, reference) -> np.ndarray:
    """Per member: max over time and states of |x - reference| / (max_t |reference| +
    the state's natural scale)."""
    scale = np.abs(reference).max(axis=1, keepdims=True) + nominal_scale(
        model, np.zeros(model.n_state)
    )
    return (np.abs(x - reference) / scale).max(axis=(1, 2))


def test_grouped_members_are_as_accurate_as_alone(paper_model):
    """The group's tolerances are a member's over sqrt(4): its norm bounds every member's
    own, so no member is integrated less accurately than alone (against rtol 1e-10)."""
    q0s, qd0s = members(8)
    run = dict(t_final=2.0, dt=0.01)
    reference = simulate_batch(paper_model, q0s, qd0s, rtol=1e-10, lanes=False, **run)
    alone = simulate_batch(paper_model, q0s, qd0s, lanes=False, **run)
    grouped = simulate_batch(paper_model, q0s, qd0s, **run)
    assert grouped.success and grouped.stats["methods"] == alone.stats["methods"]
    assert not np.array_equal(grouped.x, alone.x)  # the groups ran
    errors = normalized_error(paper_model, grouped.x, reference.x)
    assert errors.max() <= normalized_error(paper_model, alone.x, reference.x).max()
    assert errors.max() < 100 * 1e-6  # the global error of rtol 1e-6


def test_groups_do_not_depend_on_threads_blocks_or_processes(paper_model, monkeypatch):
    """Shares of threads, blocks of members and chunks of processes hold whole groups of
    four: 10 members (two groups and two alone) give the same bits every way."""
    q0s, qd0s = members(10, seed=7)
    run = dict(t_final=0.3, dt=0.01)
    one = simulate_batch(paper_model, q0s, qd0s, threads=1, **run)
    two = simulate_batch(paper_model, q0s, qd0s, threads=2, **run)
    split = simulate_batch(paper_model, q0s, qd0s, processes=2, **run)
    monkeypatch.setattr(along_module, "BLOCK_DOUBLES", 31 * 9)  # one member per block alone
    blocked = simulate_batch(paper_model, q0s, qd0s, threads=2, **run)
    for other in (two, split, blocked):
        np.testing.assert_array_equal(other.x, one.x)
    alone = simulate_batch(paper_model, q0s, qd0s, lanes=False, **run)
    np.testing.assert_array_equal(one.x[8:], alone.x[8:])  # the two left over ran alone
    assert not np.array_equal(one.x[:8], alone.x[:8])


@pytest.mark.parametrize("case", ["left_domain", "integration_failed"])
def test_a_group_with_a_failing_member_is_integrated_alone(paper_model, case):
    """A member that leaves the domain or fails sends its group back member by member:
    every status, message, reached output and state is that of the members alone."""
    q0s, qd0s = members(4)
    run = dict(t_final=0.1, dt=1e-3)
    if case == "left_domain":
        q0s[1], qd0s[1] = [0.064, 0.0, 0.0], [-50.0, 0.0, 0.0]
    else:
        run["max_steps"] = 10  # the fastest transient needs more per output
    grouped = simulate_batch(paper_model, q0s, qd0s, **run)
    alone = simulate_batch(paper_model, q0s, qd0s, lanes=False, **run)
    assert case in list(grouped.member_status)
    assert grouped.member_message == alone.member_message
    np.testing.assert_array_equal(grouped.reached, alone.reached)
    np.testing.assert_array_equal(grouped.x, alone.x)
    assert grouped.status in (Status.PARTIAL, Status.INTEGRATION_FAILED, Status.LEFT_DOMAIN)


def test_actuated_members_with_lag_in_groups(paper_model):
    """The lanes carry the actuator's force and lag: four bellows members agree with their
    integrations alone within the tolerance."""
    bellows = sc.PneumaticActuator.three_bellows(
        distance=0.01, area=2e-5, p_max=1e5, time_constant=0.05
    )
    inputs = np.array([[1e4, 0, 0], [0, 2e4, 0], [3e4, 0, 1e4], [5e4, 5e4, 0]])
    run = dict(actuator=bellows, inputs=inputs, t_final=0.5, dt=0.01)
    q0, qd0 = [0.0644, 0.0, 0.0], np.zeros(3)
    grouped = simulate_batch(paper_model, q0, qd0, **run)
    alone = simulate_batch(paper_model, q0, qd0, lanes=False, **run)
    reference = simulate_batch(paper_model, q0, qd0, lanes=False, rtol=1e-10, **run)
    assert grouped.success and not np.array_equal(grouped.x, alone.x)
    errors = normalized_error(paper_model, grouped.x, reference.x)
    assert errors.max() < 100 * 1e-6
    np.testing.assert_allclose(grouped.inputs, reference.inputs, rtol=0, atol=1e-4 * 1e5)


def test_without_a_compiler_for_the_lanes_the_members_run_alone(monkeypatch, tmp_path):
    """Where the lanes cannot be compiled, a batch integrates every member alone."""
    log = tmp_path / "refused.log"
    wrapper = compiler_refusing(tmp_path, "driver_lanes.c", log)
    if wrapper is None:
        pytest.skip("no C compiler")
    model = sc.Model(sc.presets.ifac2020())  # its own cache, the library from disk
    monkeypatch.setenv("CC", str(wrapper))
    # the cache key holds no compiler: lanes cached by another test would be loaded
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path / "lanes-cache"))
    q0s, qd0s = members(4)
    with pytest.warns(sc.RouteWarning, match="over lanes did not compile"):
        grouped = simulate_batch(model, q0s, qd0s, t_final=0.2, dt=0.01)
    alone = simulate_batch(model, q0s, qd0s, t_final=0.2, dt=0.01, lanes=False)
    np.testing.assert_array_equal(grouped.x, alone.x)
    assert grouped.stats["route"] == alone.stats["route"] == "driver"
    assert log.read_text().count("x") >= 1  # the lanes were asked for and refused


def test_members_of_other_families_are_not_grouped(paper_model):
    """A heavily damped member starts with BDF, the others with Adams: their four are
    not a group, so every member is integrated, and labelled, as alone."""
    layout = paper_model.robot.layout
    parameters = np.tile(paper_model.parameters, (4, 1))
    for i in range(3):
        parameters[1, layout.index(f"segments[0].damping[{i},{i}]")] *= 1e4
    q0s, qd0s = np.tile([0.064, 20.0, 0.0], (4, 1)), np.zeros((4, 3))
    run = dict(parameters=parameters, t_final=0.2, dt=0.01)
    grouped = simulate_batch(paper_model, q0s, qd0s, **run)
    alone = simulate_batch(paper_model, q0s, qd0s, lanes=False, **run)
    assert grouped.stats["methods"][:2] == ["cvodes-adams", "cvodes-bdf"]
    assert grouped.stats["methods"] == alone.stats["methods"]
    np.testing.assert_array_equal(grouped.x, alone.x)


def test_a_failed_group_leaves_its_members_counters_and_outputs_as_alone(paper_model):
    """Called directly: a group that fails (10 steps per output are too few) is
    integrated again alone; its members' counters are those of their runs alone (the
    group's are not added), and rows beyond what a member reaches are the caller's or
    NaN, never the group's."""
    grouped, alone = (native.problem(paper_model, None, lanes) for lanes in (True, False))
    if grouped is None or grouped.width == 1:
        pytest.skip("no lanes")
    q0s, qd0s = members(4)
    x0 = np.column_stack([q0s, qd0s, np.zeros((4, 3))])
    times = np.linspace(0.0, 0.1, 101)
    nominal = np.array([nominal_scale(paper_model, x) for x in x0])
    args = (np.ones(4, np.int32), x0, np.zeros((4, 1, 3)), np.tile(paper_model.parameters, (4, 1)),
            nominal, times, ([100], [True]),
            native.options(1e-6, 1e-6, 10, max_order=5))  # fmt: skip
    outputs = {}
    for name, problem in (("grouped", grouped), ("alone", alone)):
        out = np.full((4, times.size, 9), 7.0)
        result = native.integrate(problem, *args, out=out)
        outputs[name] = result
    (x, reached, flags, counts, _), (x1, reached1, flags1, counts1, _) = outputs.values()
    assert np.all(flags == -1)  # CV_TOO_MUCH_WORK
    np.testing.assert_array_equal(reached, reached1)
    np.testing.assert_array_equal(counts, counts1)
    for b in range(4):
        np.testing.assert_array_equal(x[b, : reached[b]], x1[b, : reached[b]])
        assert np.all((x[b, reached[b] :] == 7.0) | np.isnan(x[b, reached[b] :]))


def test_worker_chunks_keep_the_groups_of_every_actuator(paper_model):
    """Two actuators alternate over 16 members: the workers' chunks hold whole groups of
    each actuator's members, so processes=2 equals the batch in this process."""
    bellows = sc.PneumaticActuator.three_bellows(
        distance=0.01, area=2e-5, p_max=1e5, time_constant=0.05
    )
    inputs = np.random.default_rng(5).uniform(0, 6e4, (16, 3))
    parameters = np.tile(bellows.parameter_vector(), (16, 1))
    parameters[1::2, 2] *= 1.5  # every other member's chambers further out
    run = dict(actuator=bellows, inputs=inputs, actuator_parameters=parameters, t_final=0.1)
    q0, qd0 = [0.0644, 0.0, 0.0], np.zeros(3)
    here = simulate_batch(paper_model, q0, qd0, threads=1, **run)
    split = simulate_batch(paper_model, q0, qd0, processes=2, **run)
    alone = simulate_batch(paper_model, q0, qd0, lanes=False, **run)
    np.testing.assert_array_equal(split.x, here.x)
    np.testing.assert_array_equal(split.inputs, here.inputs)
    assert split.member_message == here.member_message
    assert split.stats["methods"] == here.stats["methods"]
    assert not np.array_equal(here.x, alone.x)  # the groups ran
