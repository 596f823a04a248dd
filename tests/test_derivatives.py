"""The exact Jacobian of the state derivative (softcurve.symbolic.derivatives) against
CasADi's own differentiation of the right-hand side, on every element kind, with creep
and contact; and the C driver's Newton matrix built on it."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.simulation import SettingsError, SimulationSettings
from softcurve.simulation.solvers import (
    ActuatorInput,
    actuated_derivative,
    driver_newton_jacobian,
    driver_problem,
    state_scale,
)

from .test_kinds import random_inputs, robots


def _reference(model):
    """``(d rhs / dx, d rhs / d tau)`` by CasADi's forward and reverse modes through the
    model's symbolic right-hand side: an algorithm independent of the chain's tangents."""
    rhs = model.symbolic["rhs"]
    x, tau = ca.SX.sym("x", model.n_state), ca.SX.sym("tau", model.n)
    xdot = rhs(x, tau, model.parameters)
    return ca.Function("reference", [x, tau], [ca.jacobian(xdot, x), ca.jacobian(xdot, tau)])


def _state(rng, model):
    q, qd, tau, lam = random_inputs(rng, model)
    return np.concatenate([q, qd, lam]), tau


def _relative(a, b):
    return np.abs(a - b).max() / np.abs(b).max()


def _check(model, rng, samples=2):
    jacobian, reference = model.casadi_jacobian(), _reference(model)
    for _ in range(samples):
        x, tau = _state(rng, model)
        j_x, mass = (np.array(v) for v in jacobian(x, tau, model.parameters))
        r_x, r_tau = (np.array(v) for v in reference(x, tau))
        assert _relative(j_x, r_x) < 1e-10
        # d qdd / d tau = D^-1, the mass matrix of the dynamics' terms
        terms = model.dynamics_terms(x[: model.n], x[model.n : 2 * model.n], x[2 * model.n :])
        d = terms.mass_matrix
        np.testing.assert_allclose(mass, d, rtol=1e-12, atol=1e-12 * np.abs(d).max())
        n = model.n
        assert _relative(np.linalg.inv(mass), r_tau[n : 2 * n]) < 1e-9


@pytest.mark.parametrize("kind", ["curvature", "six strains", "creep", "mixed"])
def test_the_exact_jacobian_is_casadis_derivative_of_the_right_hand_side(rng, kind):
    _check(sc.Model(robots()[kind], compile=False), rng)


def test_the_exact_jacobian_of_one_segment_and_of_many(rng):
    _check(sc.Model(sc.presets.ifac2020(), compile=False), rng)
    _check(sc.Model(sc.presets.ifac2020().with_segments(5), compile=False), rng, samples=1)


@pytest.mark.parametrize("friction", [0.0, 0.4])
def test_the_exact_jacobian_holds_the_contact_force(rng, friction):
    robot = sc.presets.ifac2020().with_segments(2)
    tip = robot.rest_length
    sphere = sc.Sphere([0.0, 0.0, tip + 0.004], 0.006)
    law = sc.ContactLaw(1e6, damping=0.1, friction=friction)
    model = sc.Model(robot, environment=sc.Environment([sphere], law), compile=False)
    x, tau = _state(rng, model)
    x[: model.n] = robot.rest_configuration()  # the tip inside the sphere: a force acts
    contact = model.dynamics_terms(x[: model.n], x[model.n : 2 * model.n]).contact_force
    assert np.abs(contact).max() > 0
    j_x, _ = model.casadi_jacobian()(x, tau, model.parameters)
    r_x, _ = _reference(model)(x, tau)
    assert _relative(np.array(j_x), np.array(r_x)) < 1e-10


def test_the_compiled_jacobian_is_the_symbolic_one(rng):
    model = sc.Model(sc.presets.ifac2020().with_segments(2))
    x, tau = _state(rng, model)
    compiled = model.rhs_jacobian(x, tau)
    symbolic = np.array(model.casadi_jacobian()(x, tau, model.parameters)[0])
    assert compiled.shape == (model.n_state, model.n_state)
    assert _relative(compiled, symbolic) < 1e-12
    with pytest.raises(ValueError, match=r"x must have shape \(18,\)"):
        model.rhs_jacobian(x[:-1])


def _actuated(time_constant):
    robot = sc.presets.ifac2020().with_segments(2)
    tendons = sc.TendonActuator.three_per_segment(
        distance=0.01, t_max=5.0, time_constant=time_constant, elements=robot
    )
    return robot, tendons


@pytest.mark.parametrize("time_constant", [None, 0.02])
def test_the_driver_on_the_exact_jacobian_follows_the_differences(time_constant):
    """The same trajectory (to the tolerance) and the same work: the Newton matrix changes,
    not the method; the route says which Jacobian it took."""
    robot, tendons = _actuated(time_constant)
    model = sc.Model(robot)
    inputs = np.linspace(0.0, 3.0, tendons.n_inputs)
    runs = {}
    for jacobian in ("differences", "exact"):
        settings = SimulationSettings(t_final=0.3, dt=0.01, rtol=1e-8, jacobian=jacobian)
        runs[jacobian] = sc.simulate(
            model, robot.rest_configuration(), np.zeros(model.n), actuator=tendons,
            inputs=inputs, settings=settings,
        )  # fmt: skip
    exact, differences = runs["exact"], runs["differences"]
    assert exact.success and differences.success
    assert exact.stats["route"] == "driver"
    assert "exact Jacobian" in exact.stats["route_reason"]
    assert "exact" not in differences.stats["route_reason"]
    np.testing.assert_allclose(exact.q, differences.q, rtol=0, atol=1e-5 * np.abs(exact.q).max())
    assert exact.stats["jacobian_evaluations"] > 0
    assert exact.stats["steps"] <= 1.2 * differences.stats["steps"]


@pytest.mark.parametrize("time_constant", [None, "free", 0.02])
def test_the_drivers_newton_jacobian_is_the_differences_one(rng, time_constant):
    """The driver's scaled Jacobian, exact (the model's and, with an actuator, the force's
    differences through D^-1 and the lag rows) against forward differences of the whole
    right-hand side, at a moving state with scales far from one."""
    if time_constant == "free":
        robot, inputs = sc.presets.ifac2020().with_segments(2), None
    else:
        robot, tendons = _actuated(time_constant)
        inputs = ActuatorInput.of(tendons, robot.n)
    model = sc.Model(robot)
    x = np.concatenate(_state(rng, model)[:1])
    if inputs is not None and inputs.n_states:
        x = np.concatenate([x, rng.uniform(0.5, 2.0, inputs.n_states)])
    u = rng.uniform(0.5, 2.0, model.n if inputs is None else inputs.n_inputs)
    nominal = state_scale(model, x[: model.n_state], inputs) * rng.uniform(0.5, 2.0, x.size)
    both = {}
    for exact in (False, True):
        problem = driver_problem(model, inputs, exact=exact)
        assert problem.exact is exact
        both[exact] = driver_newton_jacobian(problem, x, u, model.parameters, nominal)
    scale = np.abs(both[False]).max(axis=1, keepdims=True) + 1.0
    assert np.abs((both[True] - both[False]) / scale).max() < 1e-5


@pytest.mark.parametrize("time_constant", [None, 0.02])
def test_the_drivers_exact_jacobian_is_casadis_derivative(rng, time_constant):
    """With an actuator, the driver's exact Newton Jacobian (the model's, the force's exact
    derivatives through D^-1, the lag rows) equals CasADi's derivative of the actuated
    state derivative, scaled, to round-off: no forward difference is left in it."""
    robot, tendons = _actuated(time_constant)
    inputs = ActuatorInput.of(tendons, robot.n)
    model = sc.Model(robot)
    x = np.concatenate([_state(rng, model)[0], rng.uniform(0.5, 2.0, inputs.n_states)])
    u = rng.uniform(0.5, 2.0, inputs.n_inputs)
    nominal = state_scale(model, x[: model.n_state], inputs) * rng.uniform(0.5, 2.0, x.size)
    got = driver_newton_jacobian(
        driver_problem(model, inputs, exact=True), x, u, model.parameters, nominal
    )
    f = actuated_derivative(model, inputs, model.casadi_rhs())
    symbols = ca.SX.sym("x", x.size)
    along = ca.Function("j", [symbols], [ca.jacobian(f(symbols, u, model.parameters), symbols)])
    expected = np.array(along(x)) * nominal[None, :] / nominal[:, None]
    assert np.abs(got - expected).max() < 1e-11 * np.abs(expected).max()


def test_the_jacobian_setting_is_checked():
    with pytest.raises(SettingsError, match="jacobian.*differences, exact.*'finite'"):
        SimulationSettings(jacobian="finite")


def test_the_command_line_and_the_scenario_file_take_the_jacobian(tmp_path):
    from softcurve.cli import main
    from softcurve.scenarios.config import load_config

    with pytest.raises(SystemExit) as refused:  # argparse's usage error, before any work
        main(["simulate", "--jacobian", "finite"])
    assert refused.value.code == 2
    config = tmp_path / "robot.toml"
    config.write_text('[robot]\npreset = "ifac2020"\n[simulation]\njacobian = "exact"\n')
    assert load_config(config).settings.jacobian == "exact"
    config.write_text('[robot]\npreset = "ifac2020"\n[simulation]\njacobian = "finite"\n')
    with pytest.raises(sc.ParameterError, match="jacobian"):
        load_config(config)


def test_without_a_compiled_jacobian_the_driver_says_it_took_differences(monkeypatch, tmp_path):
    """A compiler that fails for the Jacobian's library (the model's built before): the
    run goes on with forward differences, says so in its route and warns once."""
    robot = sc.presets.ifac2020().with_segments(3)
    monkeypatch.setenv("SOFTCURVE_CACHE_DIR", str(tmp_path))  # nothing of it cached
    model = sc.Model(robot)
    settings = SimulationSettings(t_final=0.01, dt=0.01, jacobian="exact")
    sc.simulate(
        model,
        robot.rest_configuration(),
        np.zeros(model.n),
        settings=settings.replace(jacobian="differences"),
    )  # the driver's library built with the model's
    monkeypatch.setenv("CC", str(tmp_path / "no-such-compiler"))
    with pytest.warns(UserWarning) as warned:
        result = sc.simulate(model, robot.rest_configuration(), np.zeros(model.n),
                             settings=settings)  # fmt: skip
    said = [str(w.message) for w in warned]
    assert any("exact Jacobian with" in m and "takes forward differences" in m for m in said)
    assert any("the exact Jacobian did not compile" in m for m in said)
    assert result.success
    assert "forward-difference Jacobians" in result.stats["route_reason"]
    assert model.compiled_jacobian() is None
