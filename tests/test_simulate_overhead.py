"""The per-call work around simulate()'s integration: what is skipped or done once must
give the values the full work gives."""

from __future__ import annotations

import numpy as np
import pytest

import softcurve as sc
from softcurve.simulation._settings import SimulationSettings, settings_with
from softcurve.simulation.solvers import _driver as native
from softcurve.simulation.solvers import _grid as stepping
from softcurve.simulation.solvers import _policy as engine

Q0, QD0 = np.array([0.064, 25.0, 0.0]), np.array([0.0, 0.0, 1500.0])


def _column_changes(inputs: np.ndarray) -> np.ndarray:
    """The rule of ``input_changes`` written plainly, column by column."""
    changed = np.zeros(max(inputs.shape[0] - 2, 0), dtype=bool)
    for column in inputs.T:
        changed |= column[1:-1] != column[:-2]
    return np.flatnonzero(changed) + 1


@pytest.mark.parametrize("width", [1, 3, 7])
def test_input_changes_match_the_column_by_column_rule(rng, width):
    for rows in (2, 3, 4, 50, 1001):
        inputs = rng.integers(0, 3, size=(rows, width)).astype(np.float64)
        inputs[rng.random(rows) < 0.5] = 0.0  # runs of equal rows
        inputs[rng.random((rows, width)) < 0.2] *= -1.0  # -0.0 equals 0.0
        np.testing.assert_array_equal(stepping.input_changes(inputs), _column_changes(inputs))
        strided = np.repeat(inputs, 2, axis=1)[:, ::2]  # not C-contiguous
        np.testing.assert_array_equal(stepping.input_changes(strided), _column_changes(inputs))


@pytest.fixture
def counted_changes(monkeypatch):
    calls = []
    original = stepping.input_changes

    def counting(inputs):
        calls.append(inputs.shape)
        return original(inputs)

    monkeypatch.setattr(stepping, "input_changes", counting)
    return calls


def test_constant_inputs_are_not_searched_for_changes(paper_model, counted_changes):
    if native.problem(paper_model) is None:
        pytest.skip("without the C driver the engine splits the inputs itself")
    bellows = sc.PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4)
    short = dict(t_final=0.05, dt=0.01)
    free = sc.simulate(paper_model, Q0, QD0, **short)
    held = sc.simulate(paper_model, Q0, QD0, tau=[0.1, 0.0, 0.0], **short)
    sc.simulate(paper_model, Q0, QD0, inputs=[2e4, 0.0, 5e3], actuator=bellows, **short)
    assert counted_changes == []
    grid_tau = np.tile([0.1, 0.0, 0.0], (6, 1))
    on_grid = sc.simulate(paper_model, Q0, QD0, tau=grid_tau, **short)
    assert counted_changes == [(6, 3)]
    assert np.array_equal(on_grid.x, held.x) and not np.array_equal(free.x, held.x)


def test_plain_numbers_skip_numpys_checks_and_are_refused_alike():
    """The fast path for Python floats and ints refuses what the full checks refuse."""
    assert settings_with(None, {"t_final": 0.75, "dt": 0.05}, "simulate") == settings_with(
        None, {"t_final": np.float64(0.75), "dt": np.float64(0.05)}, "simulate"
    )
    for bad in (True, -1.0, float("nan"), 0):
        with pytest.raises(sc.ParameterError, match="t_final"):
            settings_with(None, {"t_final": bad}, "simulate")


@pytest.mark.parametrize(
    ("t_final", "dt"), [(10.0, 1e-3), (0.0105, 1e-3), (3.0, 0.01), (1.0, 1 / 3)]
)
def test_output_times_are_integer_multiples_of_dt(t_final, dt):
    grid = SimulationSettings(t_final=t_final, dt=dt).output_times()
    expected = np.arange(grid.size) * dt
    expected[-1] = t_final
    assert grid.tobytes() == expected.tobytes()


def test_the_nominal_floor_is_computed_once_per_model(paper_model, monkeypatch):
    x0 = np.r_[Q0, QD0, np.zeros(paper_model.n_creep)]
    holder = type("RobotView", (), {"robot": paper_model.robot})()
    reference = engine.nominal_scale(holder, x0)  # no cache: the floor computed afresh
    calls = []
    monkeypatch.setattr(engine, "_state_floor", lambda robot: calls.append(robot))
    for _ in range(3):
        assert engine.nominal_scale(paper_model, x0).tobytes() == reference.tobytes()
    assert calls == []


def test_the_family_of_one_ratio_is_the_elementwise_rule():
    ratios = np.array([0.5, 10.0, np.nextafter(10.0, 11.0), 1e3])
    families = engine.multistep_family(ratios)
    for ratio, family in zip(ratios.tolist(), families.tolist(), strict=True):
        assert engine.multistep_family(ratio) == family
        assert engine.multistep_family(ratio, contact=True) == "bdf"


def test_a_finished_run_owns_its_times_and_a_stopped_one_a_copy(paper_model):
    first = sc.simulate(paper_model, Q0, QD0, t_final=0.02, dt=0.01)
    second = sc.simulate(paper_model, Q0, QD0, t_final=0.02, dt=0.01)
    assert not np.shares_memory(first.t, second.t)
    stopped = sc.simulate(paper_model, Q0, QD0, t_final=1.0, max_steps=3)
    assert not stopped.success and stopped.t.base is None
    assert stopped.t.size == stopped.q.shape[0] < 1001
