"""The stepper's explicit method RK4: its coefficients, its default step, the stability
check at construction, and the compiled rows call it runs on (its accuracy against
simulate and its energy: test_stepper.py, beside ROS34PW2's)."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

import softcurve as sc
from softcurve.base.validation import ParameterError
from softcurve.compiled._generated import compile_function
from softcurve.compiled._native import NativeFunction
from softcurve.compiled._source import load_function
from softcurve.simulation.stepper import Stepper
from softcurve.simulation.stepper._lanes import LanesMembers
from softcurve.simulation.stepper._methods import DEFAULT_EXPLICIT_STEP, RK4
from softcurve.simulation.stepper._scheme import observer
from softcurve.simulation.stepper._stability import EXPLICIT_MARGIN, fastest_rate_at_rest

PERIOD = 0.02


def stiff_model() -> sc.Model:
    """The paper's robot a thousand times stiffer in elongation: the same structure, so
    the same compiled library; its axial mode about 30 times faster."""
    robot = sc.presets.ifac2020()
    segment = robot.segments[0]
    law = segment.elongation_stiffness  # TanhStiffness(a1, a2, a3)
    stiffer = dataclasses.replace(law, a1=1000 * law.a1, a2=1000 * law.a2)
    return sc.Model(robot.replace(segments=(segment.replace(elongation_stiffness=stiffer),)))


@pytest.fixture(scope="module")
def actuator():
    """examples/pneumatic.toml: three bellows, 0..60 kPa, 20 ms pressure lag."""
    return sc.PneumaticActuator.three_bellows(
        distance=0.012, area=2e-4, p_max=6e4, time_constant=0.02
    )


def test_rk4_is_of_order_4_and_its_stability_radius_is_tight():
    z = np.array([1e-2, 1e-2j, -2e-2 + 1e-2j])
    taylor = 1 + z + z**2 / 2 + z**3 / 6 + z**4 / 24
    np.testing.assert_allclose(RK4.stability_function(z), taylor, rtol=1e-15)
    # |R - exp| ~ |z|^5 / 120: order 4
    assert abs(RK4.stability_function(1e-2) - np.exp(1e-2)) < 1e-12
    angles = np.linspace(np.pi / 2, 3 * np.pi / 2, 721)
    inside = RK4.stability_radius * np.exp(1j * angles)
    assert np.all(np.abs(RK4.stability_function(inside)) <= 1 + 1e-12)
    beyond = 1.002 * RK4.stability_radius * np.exp(1j * angles)
    assert np.any(np.abs(RK4.stability_function(beyond)) > 1)


def test_rk4_takes_six_steps_per_20_ms_by_default(paper_model, actuator):
    """The default explicit step (its accuracy: test_stepper.py, with ROS34PW2's)."""
    stepper = Stepper(paper_model, actuator, period=PERIOD, method="RK4", compiled=False)
    assert stepper.substeps == round(PERIOD / DEFAULT_EXPLICIT_STEP) == 6
    assert Stepper(paper_model, actuator, period=0.05, method="RK4", compiled=False).substeps == 15


def test_the_step_is_checked_against_the_robots_fastest_mode(paper_model, actuator):
    """At construction: the paper robot's fastest mode at rest (about 280 1/s) allows
    steps up to 2.615 / (2 x 280) s, 4.6 ms: 5 steps per 20 ms pass, 4 do not, and the
    message names substeps, its value and the smallest allowed; the stiff axial modes of
    a robot a thousand times stiffer in elongation (the tendon robot's are at about
    28,000 rad/s) and an environment's contact are refused."""
    rate = fastest_rate_at_rest(paper_model, Stepper(paper_model, actuator, period=PERIOD)._input)
    assert 250 < rate < 320
    Stepper(paper_model, actuator, period=PERIOD, method="RK4", substeps=5, compiled=False)
    with pytest.raises(ParameterError, match=r"substeps=4 .* substeps >= 5, or method='ROS34PW2'"):
        Stepper(paper_model, actuator, period=PERIOD, method="RK4", substeps=4, compiled=False)
    assert PERIOD / 5 <= RK4.stability_radius / (EXPLICIT_MARGIN * rate) < PERIOD / 4
    with pytest.raises(ParameterError, match="beyond its stability"):
        Stepper(stiff_model(), actuator, period=PERIOD, method="RK4", compiled=False)
    ceiling = sc.Plane([0.0, 0.0, 0.062], [0.0, 0.0, -1.0])
    environment = sc.Environment([ceiling], sc.ContactLaw(stiffness=1e7), contact_radius=[1e-3])
    contact_model = sc.Model(sc.presets.ifac2020(), environment=environment, compile=False)
    with pytest.raises(ParameterError, match="environment"):
        Stepper(contact_model, period=PERIOD, method="RK4")


def test_compiled_rk4_equals_the_virtual_machine(paper_model, actuator, rng):
    """The generated lanes (vector C, :mod:`softcurve.simulation.stepper._lanes`) and
    CasADi's virtual machine compute the same RK4 periods."""
    stepper = Stepper(paper_model, actuator, period=PERIOD, method="RK4", threads=2)
    if stepper._members is None:
        pytest.skip("no working C compiler: the stepper runs in CasADi's virtual machine")
    assert isinstance(stepper._members, LanesMembers)
    machine = Stepper(paper_model, actuator, period=PERIOD, method="RK4", compiled=False)
    x = np.tile(stepper.initial_state([0.064, 5.0, -3.0]), (5, 1))
    x[:, 3:6] += rng.normal(0.0, 1.0, (5, 3)) * [0.01, 10.0, 10.0]
    u = rng.uniform(actuator.lower, actuator.upper, (5, 3))
    compiled, virtual = stepper.step(x, u), machine.step(x, u)
    scale = np.abs(x).max(axis=0) + np.r_[0.064, 1, 1, 0.1, 100, 100, 1, 1, 1, 6e4, 6e4, 6e4]
    assert (np.abs(compiled.x - virtual.x) / scale).max() < 1e-12
    np.testing.assert_allclose(compiled.tip, virtual.tip, rtol=0, atol=1e-14)


def test_the_rows_call_equals_one_member_calls(paper_model, rng):
    """A compiled library's rows call (in place, no copies; the scalar periods' threads
    where the lanes cannot be built) equals its one-member call, and refuses arrays of
    the wrong layout. On the observation, a small function."""
    native = compile_function(observer(paper_model, True), load=load_function)
    if not isinstance(native, NativeFunction):
        pytest.skip("no working C compiler")
    x = np.zeros((5, paper_model.n_state))
    x[:, 0] = 0.064
    x[:, 1:3] = rng.uniform(-20, 20, (5, 2))
    out = np.empty((5, 6))
    p = paper_model.parameters
    assert native.call_rows([x, p], out, 0, 5) == []
    for i in range(5):
        np.testing.assert_array_equal(out[i], native(x[i], p)[0])
    with pytest.raises(ValueError, match="C-contiguous"):
        native.call_rows([x[:, :5], p], out, 0, 5)
    with pytest.raises(ValueError, match=r"\(>= 6, 9\)"):  # fewer rows than asked for
        native.call_rows([x, p], out, 0, 6)
    with pytest.raises(ValueError, match="start <= stop"):
        native.call_rows([x, p], out, 3, 2)


def test_rk4_refuses_a_jacobian_interval(paper_model, actuator):
    stepper = Stepper(paper_model, actuator, period=PERIOD, method="RK4", compiled=False)
    assert stepper.jacobian_every is None
    with pytest.raises(ParameterError, match="jacobian_every"):
        Stepper(paper_model, actuator, period=PERIOD, method="RK4", jacobian_every=1)
