"""Everything above the model for a robot of eight segments (issue 32, item 4): simulate,
batches in lanes, the stepper, equilibria, linearization, a tendon through every
segment, contact along the whole body, identification sensitivities and C export.

Each test checks what the capability computes (an energy balance, a residual, a
derivative against finite differences, agreement with another route), not only that it
runs. The robots are the paper's segment eight times, hanging from the base (its upright
stack buckles under its own weight: self-weight 7.5 N/m against a critical
7.8 EI / L^3 = 0.06 N/m), and lying along a floor for the contact; four quadrature nodes
per segment keep the compile short (the algorithms above the model do not depend on the
quadrature).
"""

from __future__ import annotations

import shutil

import numpy as np
import pytest
from scipy.integrate import cumulative_simpson

import softcurve as sc
from softcurve.compiled._export import build_and_run_test, export_c
from softcurve.identification.experiments import Experiment
from softcurve.identification.fits._parameters import Free, FreeParameters
from softcurve.identification.maps import tip_position_map
from softcurve.simulation.sensitivity import trajectory_sensitivities
from softcurve.simulation.stepper import Stepper

from .conftest import assert_close
from .test_codegen import parse

N = 8
"""Segments of the robots."""
NODES = 4
"""Gauss-Legendre nodes per segment."""
REST = 0.0644
"""Rest length of the paper's segment [m]."""
RC = 1e-3
"""Contact radius [m] of the lying robot: a thin body makes the floor's geometry plain."""
LYING = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])
"""Base rotation of the lying robot: its backbone along the world's x, gravity along the
base frame's +x."""
CONTACT_POINTS = 2
"""Contact points per segment (besides its base): few, as the contact's cost grows with them."""


@pytest.fixture(scope="module")
def model() -> sc.Model:
    """Eight paper segments with damping and creep, hanging from the base, compiled."""
    robot = sc.presets.ifac2020().with_segments(N).replace(gravity=[0.0, 0.0, 9.81])
    return sc.Model(robot, quadrature_nodes=NODES)


@pytest.fixture(scope="module")
def lying() -> sc.Model:
    """The eight segments lying straight on a floor (base frame: the plane x = RC) that
    they touch along their whole length, compiled."""
    robot = sc.presets.ifac2020().with_segments(N).replace(base_rotation=LYING)
    law = sc.ContactLaw(1e7, damping=1.0, points_per_segment=CONTACT_POINTS)
    floor = sc.Environment([sc.Plane([RC, 0.0, 0.0], [-1.0, 0.0, 0.0])], law, [RC] * N)
    return sc.Model(robot, environment=floor, quadrature_nodes=NODES)


@pytest.fixture(scope="module")
def tendon() -> sc.TendonActuator:
    """One tendon 1 cm off the backbone, anchored at the tip: through all eight segments."""
    return sc.TendonActuator([sc.Tendon(0.5, 0.01, 5.0, anchor=N - 1)], n_segments=N)


def bent(kx: float = 5.0, ky: float = -2.0) -> np.ndarray:
    """Every segment at its rest length with the same curvatures [1/m]."""
    return np.tile([REST, kx, ky], N)


def creep_storage(model: sc.Model, lam: np.ndarray) -> np.ndarray:
    """``S = lam' P lam / 2`` per row of ``lam`` (T, n_creep) [J], ``P = K G^-1`` per
    segment (docs/model.md, Passivity)."""
    blocks = [s.creep.compliance / s.creep.gain for s in model.robot.segments]
    p = np.zeros((model.n_creep, model.n_creep))
    for i, block in enumerate(blocks):
        p[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = block
    return 0.5 * np.einsum("ti,ij,tj->t", lam, p, lam)


def normalized_error(model, x, reference) -> np.ndarray:
    """Max over time and states of ``|x - reference|`` over each state's largest value
    (plus its nominal scale, the tolerance's), per member."""
    nominal = np.r_[np.full(model.n, 1e-3), np.full(model.n, 1e-1), np.full(model.n_creep, 1e-6)]
    scale = np.abs(reference).max(axis=-2, keepdims=True) + nominal
    return (np.abs(x - reference) / scale).max(axis=(-2, -1))


def test_a_free_swing_loses_what_damping_and_creep_take(model):
    """Released bent, no input: ``E(t) - E(0)`` equals the work of the creep and damping
    forces, and ``E + S`` (S the creep's storage) never grows."""
    run = sc.simulate(model, bent(), np.zeros(model.n), t_final=0.2, dt=2e-4, rtol=1e-10)
    assert run.success, run.message
    terms = model.evaluate_along("dynamics_terms", run.q, run.qd, run.lam)
    damping, creep = terms[4], terms[5]
    power = np.einsum("ti,ti->t", run.qd, creep - damping)
    work = cumulative_simpson(power, x=run.t, initial=0.0)
    energy = run.energy()
    scale = np.trapezoid(np.abs(power), run.t)
    assert abs(energy[-1] - energy[0]) > 0.1 * scale  # the balance is not trivially zero
    assert_close(energy - energy[0], work, rtol=0, atol=1e-5 * scale, what="energy balance")
    total = energy + creep_storage(model, run.lam)
    assert np.max(np.diff(total)) <= 1e-9 * np.abs(total).max()


def test_a_batch_in_lanes_equals_its_members_alone(model):
    """Four members (one group of lanes): each equals its own simulation to the tolerance."""
    q0s = np.stack([bent(5.0, -2.0), bent(-3.0, 4.0), bent(8.0, 0.0), bent(0.0, 0.0)])
    q0s[3, 0::3] = 1.02 * REST
    run = dict(t_final=0.05, dt=1e-3, rtol=1e-10)
    batch = sc.simulate_batch(model, q0s, np.zeros(model.n), **run)
    assert batch.success and batch.stats["route"] == "driver-lanes", batch.stats["route"]
    alone = np.stack([sc.simulate(model, q0, np.zeros(model.n), **run).x for q0 in q0s])
    assert normalized_error(model, batch.x, alone).max() < 1e-7


def test_the_stepper_follows_simulate(model):
    """Five periods of 20 ms from a bent state, no force: the stepper's tip follows
    simulate's (rtol 1e-10) within the bound of its default steps (test_stepper.py:
    1 mm and 2 % of the tip's travel)."""
    period, periods = 0.02, 5
    stepper = Stepper(model, period=period)
    q0 = bent()
    x = stepper.initial_state(q0)[None, :]
    tips = [stepper.tip(x)[0]]
    for _ in range(periods):
        result = stepper.step(x, np.zeros((1, model.n)))
        assert result.ok.all() and result.success, result.message
        x = result.x
        tips.append(result.tip[0])
    reference = sc.simulate(
        model, q0, np.zeros(model.n), t_final=periods * period, dt=period, rtol=1e-10
    )
    assert reference.success, reference.message
    expected = np.array([model.tip_pose(q).position for q in reference.q])
    travel = np.ptp(expected, axis=0).max()
    assert travel > 1e-3  # it moved
    assert np.abs(np.array(tips) - expected).max() < min(1e-3, 0.02 * travel)


def test_an_equilibrium_under_a_tip_load_balances_it(model):
    """Under a sideways tip force and a torque on segment 3: ``dV/dq = J^T F + tau``."""
    force = np.array([0.05, -0.02, 0.0])
    tau = np.zeros(model.n)
    tau[3 * 3 + 1] = 2e-3
    e = sc.equilibrium(model, bent(), tip_force=force, tau=tau)
    assert e.success and e.stability == "stable", e.message
    load = model.jacobian(e.q, 1.0)[:3].T @ force + tau
    residual = model.potential_force(e.q) - load
    scale = np.abs(model.potential_force(e.q)).max()
    assert_close(residual, 0.0, rtol=0, atol=1e-9 * scale, what="static residual")
    assert model.tip_pose(e.q).position[0] > 0.01  # pushed sideways, by centimetres


def test_the_linearization_is_the_derivative_of_the_state_derivative(model, rng):
    """``A`` against central differences of ``x' = f(x)`` at a bent, moving state."""
    q = bent() + rng.normal(size=model.n) * np.tile([1e-3, 3.0, 3.0], N)
    qd = rng.normal(size=model.n) * np.tile([0.01, 5.0, 5.0], N)
    lin = sc.linearize(model, q, qd)
    x = np.concatenate([q, qd, np.zeros(model.n_creep)])
    steps = 1e-6 * (np.abs(x) + 1e-3)
    columns = [
        (model.state_derivative(x + h * e) - model.state_derivative(x - h * e)) / (2 * h)
        for h, e in zip(steps, np.eye(x.size), strict=True)
    ]
    a = np.column_stack(columns)
    rows = np.abs(a).max(axis=1, keepdims=True)  # rows span orders of magnitude
    assert lin.A.shape == (x.size, x.size)
    assert_close(lin.A, a, rtol=1e-5, scale=rows, what="A")


def test_a_tendon_through_eight_segments(model, tendon, rng):
    """``H(q) = -dL/dq`` (virtual work, against central differences), and pulling the
    tendon shortens it at an equilibrium that balances ``H T``."""
    q = bent() + rng.normal(size=model.n) * np.tile([1e-3, 3.0, 3.0], N)
    h = tendon.input_matrix(q)[:, 0]
    assert np.all(h.reshape(N, 3)[:, 0] != 0)  # every segment feels it
    # the length is affine in each coordinate separately: large central steps are exact
    step = np.where(np.arange(model.n) % 3 == 0, 1e-3, 1.0)
    gradient = [
        (tendon.tendon_lengths(q + s * e)[0] - tendon.tendon_lengths(q - s * e)[0]) / (2 * s)
        for s, e in zip(step, np.eye(model.n), strict=True)
    ]
    assert_close(h, -np.array(gradient), rtol=1e-10, scale=np.abs(h).max(), what="H")
    slack = sc.equilibrium(model, bent(0.0, 0.0))
    pulled = sc.equilibrium(model, slack.q, actuator=tendon, inputs=[2.0])
    assert slack.success and pulled.success, pulled.message
    residual = model.potential_force(pulled.q) - tendon.generalized_force(pulled.q, [2.0])
    scale = np.abs(model.potential_force(pulled.q)).max()
    assert_close(residual, 0.0, rtol=0, atol=1e-9 * scale, what="static residual")
    shortening = tendon.tendon_lengths(slack.q)[0] - tendon.tendon_lengths(pulled.q)[0]
    assert shortening > 1e-3  # [m]: the robot bends toward the tendon


def test_contact_along_the_whole_body(lying):
    """Lying on the floor: released straight, the robot settles onto it with no point
    deeper than its energy allows; at rest the contact force is minus the gradient of
    the penalty energy."""
    run = sc.simulate(lying, np.tile([REST, 0.0, 0.0], N), np.zeros(lying.n), t_final=0.1)
    assert run.success, run.message
    energy = run.energy()  # T + V + V_c, zero at the start: straight at rest on the floor
    assert energy[0] == 0.0 and np.all(np.diff(energy) <= 1e-9 * np.abs(energy).max())
    # penetration of the contact points (base frame x = -world z); the energy bounds it:
    # w U(d) <= V_c <= -V_g <= M g d, with U(d) >= k d^(e+1) / (e+1) - O(smoothing) and
    # w the smallest weight of a point (half a spacing, at the ends of a segment)
    points = N * CONTACT_POINTS + 1
    depth = np.array([-lying.backbone(q, points)[:, 2] for q in run.q])
    law, robot = lying.environment.law, lying.robot
    weight = REST / (2 * CONTACT_POINTS)
    bound = ((law.exponent + 1) * robot.mass * 9.81 / (weight * law.stiffness)) ** (
        1 / law.exponent
    )
    assert 0 < depth.max() <= bound + law.smoothing
    assert np.all(depth[-1, 1:] > 0)  # every point but the clamped base is on the floor
    q = run.q[-1]
    contact = lying.contact(q)
    step = np.where(np.arange(lying.n) % 3 == 0, 1e-8, 1e-6)
    gradient = [
        (lying.contact(q + s * e)["energy"] - lying.contact(q - s * e)["energy"]) / (2 * s)
        for s, e in zip(step, np.eye(lying.n), strict=True)
    ]
    scale = np.abs(contact["generalized"]).max()
    assert scale > 0
    assert_close(contact["generalized"], -np.array(gradient), rtol=1e-6, scale=scale)


def test_trajectory_sensitivities_against_two_simulations(model):
    """The tip's sensitivity to the tip segment's bending stiffness, 0.1 s of a free
    swing, against a central difference of two simulations (rtol 1e-10)."""
    name = f"segments[{N - 1}].bending_stiffness.a1"
    t = np.linspace(0.0, 0.1, 11)
    experiment = Experiment(t, {axis: 0.0 * t for axis in "xyz"}, {})
    free = FreeParameters(model, [Free(name)], {}, {}, None)
    x0 = np.zeros(model.n_state)
    x0[: model.n] = bent()
    output = tip_position_map(model)
    evaluate = trajectory_sensitivities(model, free, output, None, x0, experiment, None)
    y, jacobian = evaluate(free.theta0)
    i = model.robot.layout.index(name)
    # the tip is far from linear in a1 (the tanh law): the central difference's O(h^2)
    # error is 3e-4 of the derivative at h = 1e-3 a1, 4e-8 at 1e-5 a1 (measured)
    h = 1e-5 * model.parameters[i]
    parameters = np.tile(model.parameters, (2, 1))
    parameters[:, i] += [h, -h]
    runs = sc.simulate_batch(
        model, bent(), np.zeros(model.n), parameters=parameters, t_final=0.1, dt=0.01,
        rtol=1e-10, lanes=False,
    )  # fmt: skip
    assert runs.success
    tips = np.array([[model.tip_pose(q).position for q in member] for member in runs.q])
    # the evaluator integrates at its own tolerances (SENSITIVITY_CVODES, rtol 1e-8)
    assert_close(y.T, 0.5 * (tips[0] + tips[1]), rtol=0, atol=1e-7 * np.abs(tips).max())
    difference = ((tips[0] - tips[1]) / (2 * h)).ravel()  # (T k,): time-major, as vec(y)
    assert np.abs(difference).max() > 0
    assert_close(jacobian[:, 0], difference, rtol=1e-5, scale=np.abs(difference).max())


@pytest.mark.skipif(
    not (shutil.which("cc") or shutil.which("gcc") or shutil.which("clang")),
    reason="no C compiler (cc, gcc or clang) found",
)
def test_the_exported_c_computes_the_model(model, tendon, tmp_path):
    """The standalone C of the eight segments (and H of the tendon) compiles, its test
    program runs, and its numbers are the model's."""
    exported = export_c(model, tmp_path, actuator=tendon, prefix="robot8")
    assert exported.success
    output = build_and_run_test(exported, optimization="-O0")  # fast to compile
    assert output.strip().endswith("OK")
    c = parse(output)
    s = exported.sample_inputs
    expected = {
        "forward_dynamics": model.forward_dynamics(*s["forward_dynamics"]),
        "inverse_dynamics": model.inverse_dynamics(*s["inverse_dynamics"]),
        "potential_force": model.potential_force(*s["potential_force"]),
        "input_matrix": tendon.input_matrix(*s["input_matrix"]).ravel(order="F"),
    }
    for name, value in expected.items():
        assert_close(c[name], value, rtol=1e-12, scale=np.abs(value).max(), what=name)
