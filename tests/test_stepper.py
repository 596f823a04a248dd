"""The batched fixed-step stepper: agreement with simulate, batch equals single calls,
bounds, failing members, dissipation, forces without actuator."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.base.status import Status
from softcurve.base.validation import ParameterError
from softcurve.simulation.solvers import ActuatorInput, actuated_derivative, actuated_jacobian
from softcurve.simulation.stepper._stepper import Stepper

PERIOD = 0.02  # the learning environments' control period [s]


@pytest.fixture(scope="module")
def actuator():
    """examples/pneumatic.toml: three bellows, 0..60 kPa, 20 ms pressure lag."""
    return sc.PneumaticActuator.three_bellows(
        distance=0.012, area=2e-4, p_max=6e4, time_constant=0.02
    )


@pytest.fixture(scope="module")
def stepper(paper_model, actuator):
    return Stepper(paper_model, actuator, period=PERIOD)


def commands(rng, actuator, count: int) -> np.ndarray:
    return rng.uniform(actuator.lower, actuator.upper, (count, actuator.n_inputs))


@pytest.mark.parametrize("method", [None, "RK4"])
def test_agrees_with_simulate_on_piecewise_constant_commands(paper_model, actuator, method, rng):
    """Random pressure commands held for one period each, 0.3 s: the stepper's tip
    follows simulate's (rtol 1e-10) within the bound that set the default steps of both
    kinds of method, 1 mm and 2 % of the tip's travel (docs/stepping.md); so do the
    states."""
    # RK4 in CasADi's virtual machine: the compiled code computes the same (test_stepper_explicit)
    stepper = Stepper(paper_model, actuator, period=PERIOD, method=method, compiled=not method)
    periods = 15
    held = commands(rng, actuator, periods)
    q0 = np.array([0.064, 0.0, 0.0])
    reference = sc.simulate(
        paper_model,
        q0,
        np.zeros(3),
        actuator=actuator,
        inputs=np.vstack([held, held[-1:]]),
        t_final=periods * PERIOD,
        dt=PERIOD,
        rtol=1e-10,
    )
    assert reference.success, reference.message
    x = stepper.initial_state(q0)[None, :]
    tips = [stepper.tip(x)[0]]
    for k in range(periods):
        result = stepper.step(x, held[k : k + 1])
        assert result.ok.all() and result.success, result.message
        x = result.x
        tips.append(result.tip[0])
    tips = np.array(tips)
    expected = np.array([paper_model.tip_pose(q).position for q in reference.q])
    travel = np.ptp(expected, axis=0).max()
    assert np.abs(tips - expected).max() < min(1e-3, 0.02 * travel)
    scale = np.abs(reference.q).max(axis=0)
    assert np.all(np.abs(x[0, :3] - reference.q[-1]) < 0.02 * scale)
    np.testing.assert_allclose(x[0, 9:], reference.inputs[-1], rtol=0.02, atol=0.02 * 6e4)


def test_members_equal_separate_calls(stepper, actuator, rng):
    count = 5
    x0 = stepper.initial_state([0.064, 5.0, -3.0], [0.01, 10.0, 0.0])
    x = (
        np.tile(x0, (count, 1))
        + rng.normal(0.0, 1e-3, (count, stepper.n_state))
        * np.r_[0.001, 1, 1, 0.01, 10, 10, 0, 0, 0, 1e3, 1e3, 1e3]
    )
    u = commands(rng, actuator, count)
    together = stepper.step(x, u)
    for i in range(count):
        alone = stepper.step(x[i : i + 1], u[i : i + 1])
        np.testing.assert_allclose(alone.x[0], together.x[i], rtol=1e-13, atol=1e-300)
        np.testing.assert_allclose(alone.tip[0], together.tip[i], rtol=1e-13)
    assert stepper.step(x[:2], u[:2]).x.shape == (2, stepper.n_state)  # N may change


def test_inputs_are_clipped_to_the_bounds(stepper):
    x = np.tile(stepper.initial_state([0.064, 0.0, 0.0]), (2, 1))
    beyond = np.array([[-1e5, 2e5, 3e4], [0.0, 6e4, 3e4]])
    result = stepper.step(x, beyond)
    np.testing.assert_array_equal(result.x[0], result.x[1])
    np.testing.assert_array_equal(stepper.lower, np.zeros(3))
    np.testing.assert_array_equal(stepper.upper, np.full(3, 6e4))


def test_a_failing_member_is_flagged_and_the_others_are_unaffected(stepper, actuator, rng):
    x = np.tile(stepper.initial_state([0.064, 5.0, 0.0]), (4, 1))
    u = commands(rng, actuator, 4)
    clean = stepper.step(x, u)
    bad = x.copy()
    bad[1, 0] = np.nan  # non-finite
    bad[2, 0] = -0.01  # a negative length: outside the domain
    result = stepper.step(bad, u)
    np.testing.assert_array_equal(result.ok, [True, False, False, True])
    assert result.status is Status.PARTIAL and "member 1" in result.message
    assert "not finite" in result.reasons[1] or "finite" in result.reasons[1]
    assert "l must be in the model's domain" in result.reasons[2]
    np.testing.assert_array_equal(result.x[[0, 3]], clean.x[[0, 3]])
    np.testing.assert_array_equal(result.x[1:3], bad[1:3])  # kept
    assert result.reasons[0] is None and result.reasons[3] is None


def test_the_scheme_creates_no_energy_and_is_stable_at_long_steps(conservative_model):
    """Undamped robot whose creep exerts no force: the exact flow conserves the
    mechanical energy. At the 20 ms period the default scheme resolves the motion and
    the energy stays within its truncation error (2e-4 relative, order 3) of the start,
    never growing; ROS2 in single steps of 50 ms, twice the period of the fastest
    oscillation (247 rad/s), loses energy at every step (L-stable: it damps what it
    cannot resolve) and the robot settles. RK4 at its default step never gains energy
    either: ``|R(iy)|**2 = 1 - y**6/72 + y**8/576 < 1`` within its radius, so it damps the
    fast axial oscillation a little (``y = 0.82`` at 3.3 ms: 2.6 % of the energy over 0.5
    s)."""
    q0, qd0 = [0.064, 25.0, 0.0], [0.0, 0.0, 1500.0]
    for period, method, substeps, tolerance in (
        (PERIOD, None, None, 2e-4),
        (0.05, "ROS2", 1, 0.0),
        (PERIOD, "RK4", None, 0.0),
    ):
        stepper = Stepper(
            conservative_model, period=period, substeps=substeps, method=method, compiled=False
        )
        x = stepper.initial_state(q0, qd0)[None, :]
        n = conservative_model.n
        energy = [conservative_model.energy(x[0, :n], x[0, n : 2 * n])]
        for _ in range(25):
            result = stepper.step(x, np.zeros((1, n)))
            assert result.ok[0], result.reasons
            x = result.x
            energy.append(conservative_model.energy(x[0, :n], x[0, n : 2 * n]))
        energy = np.array(energy)
        swing = energy[0] - conservative_model.potential_energy(x[0, :n])
        assert np.all(energy[1:] <= energy[0] * (1 + tolerance)), energy
        if not tolerance:
            assert np.all(np.diff(energy) <= 0), energy
        assert energy[-1] < energy[0] - 1e-3 * abs(swing)


def test_forces_without_actuator(paper_model):
    """Generalized forces as inputs: a constant bending moment bends the robot as
    simulate does."""
    stepper = Stepper(paper_model, period=PERIOD, compiled=False)
    assert stepper.n_inputs == paper_model.n and stepper.n_state == paper_model.n_state
    assert np.all(np.isinf(stepper.lower)) and np.all(np.isinf(stepper.upper))
    tau = np.array([0.0, 1e-3, 0.0])
    x = stepper.initial_state([0.064, 0.0, 0.0])[None, :]
    for _ in range(10):
        x = stepper.step(x, tau[None, :]).x
    reference = sc.simulate(
        paper_model, [0.064, 0.0, 0.0], np.zeros(3), tau=tau, t_final=10 * PERIOD, rtol=1e-10
    )
    scale = np.abs(reference.q).max(axis=0) + np.array([0.064, 1.0, 1.0])
    assert np.all(np.abs(x[0, :3] - reference.q[-1]) < 0.02 * scale)


def test_compiled_equals_the_virtual_machine_and_the_error_falls_as_order_3(
    paper_model, actuator, stepper, rng
):
    """The generated C and CasADi's virtual machine on the model's library compute the
    same scheme (to the round-off of the forward-difference Jacobian, ~1e-8, which a
    W-method damps further); the error against simulate falls each time the steps are
    halved, faster than for a first-order method (ROS34PW2 is of order 3: the 2 s runs
    of docs/stepping.md fall as substeps**-3)."""
    x = np.tile(stepper.initial_state([0.064, 5.0, -3.0]), (3, 1))
    u = commands(rng, actuator, 3)
    machine = Stepper(paper_model, actuator, period=PERIOD, compiled=False)
    scale = np.abs(x).max(axis=0) + np.r_[0.064, 1, 1, 0.1, 100, 100, 1, 1, 1, 6e4, 6e4, 6e4]
    difference = np.abs(machine.step(x, u).x - stepper.step(x, u).x) / scale
    assert difference.max() < 1e-8
    q0, held = [0.064, 0.0, 0.0], commands(rng, actuator, 1)[0]
    reference = sc.simulate(
        paper_model, q0, np.zeros(3), actuator=actuator, inputs=held, t_final=0.1, rtol=1e-11
    )
    errors = []
    for substeps in (4, 8, 16):
        coarse = Stepper(paper_model, actuator, period=PERIOD, substeps=substeps, compiled=False)
        x = coarse.initial_state(q0)[None, :]
        for _ in range(5):
            x = coarse.step(x, held[None, :]).x
        errors.append(np.abs(x[0, :3] - reference.q[-1]).max() / np.abs(reference.q[-1]).max())
    assert errors[0] > 3 * errors[1] > 9 * errors[2], errors


@pytest.mark.parametrize(
    "actuator_of",
    [
        lambda: None,
        lambda: sc.PneumaticActuator.three_bellows(distance=0.012, area=2e-4, p_max=6e4),
        lambda: sc.PneumaticActuator.three_bellows(
            distance=0.012, area=2e-4, p_max=6e4, time_constant=0.02
        ),
        lambda: sc.TendonActuator.three_per_segment(
            distance=0.008, t_max=5.0, n_segments=2, time_constant=0.01
        ),
    ],
    ids=["forces", "bellows", "lagging bellows", "lagging tendons, two segments"],
)
def test_the_actuated_jacobian_is_casadis_derivative_of_the_state_derivative(actuator_of, rng):
    """The exact Jacobian the stepper can take (the chain algorithms' derivatives and the
    actuator's force moving with the coordinates and the lag) equals CasADi's own
    derivative of the actuated state derivative, at a bent, moving, creeping state with
    inputs inside their bounds."""
    actuator = actuator_of()
    segments = 1 if actuator is None else actuator.n_segments
    model = sc.Model(sc.presets.ifac2020().with_segments(segments), compile=False)
    inputs = None if actuator is None else ActuatorInput.of(actuator, model.n)
    f = actuated_derivative(model, inputs, model.symbolic["rhs"])
    exact = actuated_jacobian(model, inputs, model.jacobian_passes())
    n, n_x = model.n, f.size1_in(0)
    x = np.zeros(n_x)
    x[:n] = np.tile([0.064, 10.0, -5.0], segments) + rng.normal(0.0, 1e-3, n)
    x[n : 2 * n] = rng.normal(0.0, 1.0, n)
    x[2 * n : model.n_state] = rng.normal(0.0, 1e-3, model.n_state - 2 * n)
    if actuator is None:
        u = rng.normal(0.0, 1e-3, n)
    else:
        u = rng.uniform(actuator.lower, actuator.upper)
        x[model.n_state :] = rng.uniform(actuator.lower, actuator.upper)[: n_x - model.n_state]
    symbols = ca.MX.sym("x", n_x)
    expected = np.array(
        ca.Function("j", [symbols], [ca.jacobian(f(symbols, u, model.parameters), symbols)])(x)
    )
    got = np.array(exact(x, u, model.parameters))
    assert np.abs(got - expected).max() < 1e-12 * np.abs(expected).max()


SIX_STRAINS = sc.StrainSegment.from_material(
    sc.Material(youngs_modulus=1e6, density=1070.0, poisson_ratio=0.5),
    sc.Section.circle(0.0235),
    rest_length=0.0644,
    damping=[1e-6, 1e-6, 1e-6, 1e-2, 1e-2, 1e-2],
)
"""A segment of all six strains the paper's segment's size, without creep: its state has
no rows after the accelerations' (``x = (q, qd)``)."""


@pytest.mark.parametrize("case", ["lagging bellows, creep", "six strains, forces"])
def test_the_exact_jacobian_over_lanes_is_the_virtual_machines(case, paper_model, actuator, rng):
    """``jacobian="exact"`` over lanes (the passes, the tangents per coordinate, the mass
    matrix's Cholesky factor in C; the route says so) steps the members as CasADi's
    virtual machine on the same Jacobian (mapped tangents, ``LDL^T``) does, to
    round-off: a check of the Jacobian itself, which a W-method's step against
    differences is not (any matrix keeps its order); and both step as the default,
    differences over lanes, does to the differences' round-off."""
    if case.startswith("six"):
        model, actuator = sc.Model(sc.Robot(segments=(SIX_STRAINS,))), None
        q0 = model.robot.rest_configuration() + np.r_[5.0, -3.0, 2.0, 0.01, -0.01, 0.02]
        qd0, u = np.r_[10.0, 5.0, -8.0, 0.1, 0.2, -0.1], rng.normal(0.0, 1e-3, (3, 6))
        scale = np.r_[15.5, 15.5, 15.5, 1, 1, 1, 1e3, 1e3, 1e3, 10, 10, 10]
    else:
        model, q0, qd0 = paper_model, [0.064, 5.0, -3.0], [0.01, 10.0, 0.0]
        u = commands(rng, actuator, 3)
        scale = np.r_[0.064, 1, 1, 0.1, 100, 100, 1, 1, 1, 6e4, 6e4, 6e4]
    exact = Stepper(model, actuator, period=PERIOD, jacobian="exact")
    assert exact.jacobian == "exact" and exact.stats["jacobian"] == "exact"
    assert exact.route.name == "stepper-lanes" and "exact Jacobian" in exact.route.reason
    machine = Stepper(model, actuator, period=PERIOD, compiled=False, jacobian="exact")
    default = Stepper(model, actuator, period=PERIOD)
    assert default.jacobian == "differences" and default.stats["jacobian"] == "differences"
    x = np.tile(exact.initial_state(q0, qd0), (3, 1))
    steps = [stepper.step(x, u) for stepper in (exact, machine, default)]
    assert all(step.success for step in steps), [step.message for step in steps]
    scale = np.abs(x).max(axis=0) + scale
    lanes, virtual, differences = (step.x for step in steps)
    assert (np.abs(lanes - virtual).max(axis=0) / scale).max() < 1e-10  # measured 4e-11
    assert (np.abs(lanes - differences).max(axis=0) / scale).max() < 1e-6  # 1.5e-7


def test_bad_arguments_raise(paper_model, actuator, stepper):
    with pytest.raises(ParameterError, match="period"):
        Stepper(paper_model, actuator, period=0.0)
    with pytest.raises(ParameterError, match="jacobian must be one of"):
        Stepper(paper_model, actuator, period=PERIOD, jacobian="newton")
    with pytest.raises(ParameterError, match="jacobian='exact'"):
        Stepper(paper_model, actuator, period=PERIOD, method="RK4", jacobian="exact")
    with pytest.raises(ParameterError, match="substeps"):
        Stepper(paper_model, actuator, period=PERIOD, substeps=0)
    with pytest.raises(ParameterError, match="x must have shape"):
        stepper.step(np.zeros((2, 3)), np.zeros((2, 3)))
    with pytest.raises(ParameterError, match="inputs must have shape"):
        stepper.step(np.zeros((2, stepper.n_state)), np.zeros((3, 3)))


def test_contact_force_under_a_ceiling():
    """The paper's robot (thin body) stretching into a ceiling 1 mm above its body: the
    stepper's contact force is the obstacle's force on the robot at the new state
    (model.contact) and pushes down. A model without compiled library (compile=False):
    nothing is compiled."""
    robot = sc.presets.ifac2020()
    ceiling = sc.Plane([0.0, 0.0, 0.062], [0.0, 0.0, -1.0])
    law = sc.ContactLaw(stiffness=1e7, smoothing=1e-6, damping=1.0, friction=0.5)
    environment = sc.Environment([ceiling], law, contact_radius=[1e-3])
    model = sc.Model(robot, environment=environment, compile=False)
    stepper = Stepper(model, period=0.01, substeps=4, method="ROS2")
    x = stepper.initial_state([0.06, 0.0, 0.0], [0.2, 0.0, 0.0])[None, :]
    result = stepper.step(x, np.zeros((1, 3)))
    assert result.ok[0], result.reasons
    n = model.n
    q, qd = result.x[0, :n], result.x[0, n : 2 * n]
    expected = model.contact(q, qd)["forces"].sum(axis=0)
    np.testing.assert_allclose(result.contact_force[0], expected, rtol=1e-9, atol=1e-12)
    assert result.contact_force[0, 2] < -0.01  # the ceiling pushes down [N]
    np.testing.assert_allclose(result.tip[0], model.tip_pose(q).position, rtol=1e-12)
