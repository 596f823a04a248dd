"""Tendons under control: tensions never negative in simulation and allocation, the
tracking example's loop, the redundancy rule of inverse statics, and the figures of
actuated runs."""

from __future__ import annotations

import importlib.util
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

import softcurve as sc
from softcurve import ParameterError, Status, TendonActuator
from softcurve.analysis.inverse_statics import inverse_statics
from softcurve.control.controllers import InputAllocator, SaturatedInputs, at_bound
from softcurve.control.references import tip_circle
from softcurve.figures import plot_backbones, plot_inputs

from .conftest import assert_close

REST = 0.2  # [m]
EXAMPLE = Path(__file__).resolve().parents[1] / "examples" / "tendon_tracking.py"


def two_segments(gravity=(0.0, 0.0, 0.0)) -> sc.Robot:
    """The robot of the brief: two 20 cm Hookean segments (the structure that
    tests/test_tendons.py compiles too, so the compiled library is shared)."""
    segment = sc.Segment(
        rest_length=REST,
        mass=0.02,
        radius=0.01,
        elongation_stiffness=sc.LinearStiffness(2e3),
        bending_stiffness=sc.LinearStiffness(0.05),
        damping=np.array([1.0, 1e-4, 1e-4]),
    )
    return sc.Robot(segments=(segment, segment), gravity=np.array(gravity))


def tendons(t_min=0.0, t_max=20.0, time_constant=None) -> TendonActuator:
    return TendonActuator.three_per_segment(
        distance=0.01, t_max=t_max, t_min=t_min, n_segments=2, time_constant=time_constant
    )


@pytest.fixture(scope="module")
def model() -> sc.Model:
    return sc.Model(two_segments())


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


STRAIGHT = np.array([REST, 0.0, 0.0] * 2)


# -- tensions never negative in simulation -------------------------------------------------
def test_constant_tensions_with_slack_tendons_stay_put(model):
    act = tendons()
    u = np.array([3.0, 0.0, 0.0, 0.0, 2.0, 0.0])  # four slack tendons (tension zero)
    run = sc.simulate(model, STRAIGHT, np.zeros(6), actuator=act, inputs=u, t_final=0.2, dt=1e-2)
    assert run.success, run.message
    assert np.all(run.inputs == u)  # held exactly, slack stays zero, never negative
    assert_close(run.tau[-1], act.input_matrix(run.q[-1]) @ u, rtol=1e-12, scale=3.0)


def test_lagging_tensions_released_to_zero_never_undershoot(model):
    """Commands dropping from t_max to zero: the lagging tensions decay toward zero and
    never cross it (the lag states are integrated by CVODES)."""
    act = tendons(t_max=5.0, time_constant=0.005)
    t = np.linspace(0.0, 0.2, 201)
    grid = np.where((t < 0.05)[:, None], [5.0, 0.0, 5.0, 0.0, 5.0, 0.0], 0.0)
    run = sc.simulate(model, STRAIGHT, np.zeros(6), actuator=act, inputs=grid, t_final=0.2)
    assert run.success, run.message
    assert np.all(run.inputs >= 0.0) and np.all(run.inputs <= 5.0)
    assert run.inputs[50].max() > 4.0 and run.inputs[-1].max() < 1e-6 * 5.0  # rose, released


class PushingController:
    """A PD law on the tensions that commands some tendons to push (negative)."""

    sample_time = 0.01

    def __call__(self, t, q, qd, lam=None):
        return np.array([2.0, -1.0, -1.0, -0.5, 1.5, -3.0]) + 10.0 * (q[0] - REST)


def test_a_controller_commanding_negative_tensions_is_refused_or_clipped(model):
    act = tendons(time_constant=0.02)
    with pytest.raises(
        ParameterError, match=r"\[1\] = -1.0 N is outside its bounds \[0.0, 20.0\] N"
    ):
        sc.simulate(
            model, STRAIGHT, np.zeros(6), actuator=act, controller=PushingController(), t_final=0.1
        )
    clipped = SaturatedInputs(PushingController(), act)
    run = sc.simulate(model, STRAIGHT, np.zeros(6), actuator=act, controller=clipped, t_final=0.3)
    assert run.success, run.message
    assert np.all(run.inputs >= 0.0)
    requested, inputs = clipped.history("requested"), clipped.history("inputs")
    assert np.all(inputs >= 0.0) and np.any(requested < 0.0)
    assert np.array_equal(clipped.history("saturated"), requested <= 0.0)
    assert_close(inputs, np.clip(requested, 0.0, 20.0), rtol=0)
    assert run.inputs[-1, 0] > 1.0 and run.inputs[-1, 1] == 0.0  # pulled, and slack


# -- allocation never negative ---------------------------------------------------------------
def test_allocation_keeps_tensions_within_bounds_and_flags_them(rng):
    robot = two_segments()
    for act in (tendons(), tendons(t_min=0.5, t_max=8.0)):
        allocator = InputAllocator(act, robot)
        for trial in range(60):
            q = np.array([REST * 0.95, *rng.normal(0, 4, 2), REST * 0.97, *rng.normal(0, 4, 2)])
            if trial % 3 == 0:  # feasible: produced by tensions within the bounds
                wanted = rng.uniform(act.lower, act.upper)
                tau = act.input_matrix(q) @ wanted
            else:  # anything, including extension, which tendons cannot produce
                tau = rng.normal(0.0, 1.0, 6) * np.array([5.0, 0.05, 0.05] * 2)
            result = allocator.allocate(q, tau)
            assert np.all(result.inputs >= act.lower) and np.all(result.inputs <= act.upper)
            assert np.array_equal(result.saturated, at_bound(act, result.inputs))
            if trial % 3 == 0:
                assert result.success, result.message
                assert_close(result.inputs, wanted, rtol=1e-7, scale=act.upper)
    # pulling the robot longer needs pushing tendons: all at their lower bound, flagged
    result = InputAllocator(tendons(), robot).allocate(STRAIGHT, [3.0, 0, 0, 1.0, 0, 0])
    assert np.all(result.inputs == 0.0) and result.saturated.all()
    assert result.status is Status.INFEASIBLE


# -- the tracking example -------------------------------------------------------------------
def test_the_tracking_example_loop_follows_the_circle_within_bounds():
    """examples/tendon_tracking.py, 1 s: after the 0.5 s start transient the tip stays
    within 0.3 mm of the reference (measured 0.20 mm), the tensions within their bounds."""
    spec = importlib.util.spec_from_file_location("tendon_tracking", EXAMPLE)
    example = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(example)
    model, act, reference = example.build()
    run, driven, error, path = example.track(model, act, reference, 1.0)
    settled = run.t >= example.TRANSIENT
    assert error[settled].max() < 3e-4
    assert np.all(run.inputs >= act.lower) and np.all(run.inputs <= act.upper)
    commands = driven.history("command")
    assert np.all(commands >= act.lower) and np.all(commands <= act.upper)
    assert_close(path[:, 2], example.CIRCLE["center"][2], rtol=1e-12)  # the circle's height


def test_two_segment_tip_circle_keeps_one_arc():
    reference = tip_circle((0.05, 0.01, 0.15), 0.02, 2.0, segments=2)
    one = tip_circle((0.05, 0.01, 0.15), 0.02, 2.0)
    for t in (0.0, 0.3, 1.1):
        two, single = reference(t), one(t)
        assert_close(two.q[:3], two.q[3:], rtol=0)
        assert_close(two.q[0] + two.q[3], single.q[0], rtol=1e-15)
        assert_close(two.qdd[1:3], single.qdd[1:3], rtol=1e-15)
    with pytest.raises(ParameterError, match="segments must be an integer >= 1"):
        tip_circle((0.05, 0.0, 0.15), 0.02, 2.0, segments=0)


# -- the redundancy rule of inverse statics ---------------------------------------------------
def test_inverse_statics_with_six_tensions_takes_the_least_total(model):
    """Six tensions, a 3-D target: the tip reaches it; the total tension above t_min is
    the least of every solution constructed here that reaches it too."""
    act = tendons(t_min=0.5)
    generator = np.array([3.0, 0.5, 0.5, 0.5, 4.0, 0.5])  # reaches the target by construction
    start = sc.equilibrium(model, STRAIGHT, actuator=act, inputs=generator)
    target = start.tip_position
    best = inverse_statics(model, act, target)
    assert best.success, best.message
    assert best.rule == "minimum_total" and "minimum total tensions" in best.message
    assert best.distance < 1e-9 * REST
    assert np.all(best.inputs >= act.lower) and np.all(best.inputs <= act.upper)
    assert_close(best.total, np.sum(best.inputs - act.lower), rtol=1e-15)
    assert best.saturated.any()  # the least total leaves some tendons at the pretension
    assert_close(model.tip_pose(best.q).position, target, atol=1e-9 * REST)

    first = inverse_statics(model, act, target, redundancy="none")
    assert first.success and first.rule == "none"
    others = {"first stage": first.total, "generator": np.sum(generator - act.lower)}
    # a tension floor raised uniformly, or one tendon held above its least-total value:
    # each still reaches the target, never with less total tension
    raised = inverse_statics(model, tendons(t_min=0.7), target, redundancy="none")
    assert raised.success
    others["uniform + 0.2 N"] = np.sum(raised.inputs - act.lower)
    for i in np.flatnonzero(~best.saturated)[:2]:
        floor = list(act.tendons)
        floor[i] = sc.Tendon(floor[i].azimuth, 0.01, 20.0, best.inputs[i] + 0.3, floor[i].anchor)
        held = inverse_statics(model, TendonActuator(floor, n_segments=2), target)
        assert held.success, held.message
        others[f"tendon {i} + 0.3 N"] = np.sum(held.inputs - act.lower)
    for name, total in others.items():
        assert best.total <= total + 1e-9, f"{name}: {total} < {best.total}"
    assert best.total < min(others["first stage"], others["generator"]) - 0.1  # [N]


def test_redundancy_rule_is_checked(model):
    with pytest.raises(ParameterError, match="redundancy must be one of"):
        inverse_statics(model, tendons(), [0.0, 0.0, 0.35], redundancy="smallest")


# -- figures --------------------------------------------------------------------------------
@pytest.fixture(scope="module")
def tendon_run(model):
    act = tendons(t_max=4.0, time_constant=0.02)
    run = sc.simulate(
        model, STRAIGHT, np.zeros(6), actuator=act, inputs=[4.0, 0, 0, 0, 2.0, 0], t_final=0.1
    )
    assert run.success
    return run, act


def test_inputs_figure_draws_tensions_and_bounds(tendon_run):
    run, act = tendon_run
    figure = plot_inputs(run, act)
    assert isinstance(figure, Figure)
    ax = figure.axes[0]
    assert ax.get_ylabel() == "tensions [N]" and ax.get_xlabel() == "time t [s]"
    assert len(ax.lines) == 6 + 2  # six tensions, bounds 0 and 4 N
    _, given = plt.subplots()
    assert plot_inputs(run, act, given, labels="abcdef") is given.figure
    with pytest.raises(ParameterError, match="labels must name the 6 inputs"):
        plot_inputs(run, act, labels=["a"])
    with pytest.raises(ParameterError, match="no actuator inputs"):
        plot_inputs(sc.simulate(run.model, STRAIGHT, np.zeros(6), t_final=0.01), act)


def test_backbones_figure_draws_shapes_and_the_path(tendon_run):
    run, _ = tendon_run
    path = np.column_stack([np.zeros(5), np.zeros(5), np.linspace(0.3, 0.4, 5)])
    figure = plot_backbones(run, [0.0, 0.05, 0.1], path=path)
    assert isinstance(figure, Figure) and len(figure.axes) == 2
    side, top = figure.axes
    assert len(side.lines) == 1 + 2 * 3  # the path, then a backbone and a tip per time
    assert_close(side.lines[0].get_ydata(), 1e3 * path[:, 2], rtol=0)
    _, axes = plt.subplots(1, 2)
    assert plot_backbones(run, 0.05, axes) is axes[0].figure
    with pytest.raises(ParameterError, match="2 panel"):
        plot_backbones(run, 0.05, axes[0])
