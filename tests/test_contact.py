"""Contact with the environment (issue 13): validation, smoothness and the physics checks.

(a) frictionless static contact converges to the exact constrained equilibrium as the
stiffness grows, at the rate of the penalty law; (b) elastic contact conserves the
total energy, penalty energy included, and damping or friction never add energy;
(c) friction holds a tip below ``mu N`` and lets it slide above; (d) an impact
penetrates no deeper than the law allows and rebounds; (e) far from every obstacle
the model equals the free model exactly. The models run in CasADi's virtual machine
(no compile), so the file stays fast.
"""

from __future__ import annotations

import re

import casadi as ca
import numpy as np
import pytest
from scipy.optimize import minimize

import softcurve as sc
from softcurve.symbolic.contact import penalty_energy, ramp

RC = 1e-3
"""Contact radius [m] of the test robots: a thin body makes the geometry plain."""
SCALE = np.array([0.0644, 1 / 0.0644, 1 / 0.0644])


def _robot(damping: bool = True) -> sc.Robot:
    """The paper's robot whose creep exerts no force (its energy is T + V)."""
    robot = sc.presets.ifac2020(damping=damping)
    seg = robot.segments[0]
    creep = sc.Creep(seg.creep.rate, seg.creep.gain, np.zeros(3))
    return robot.replace(segments=(seg.replace(creep=creep),))


def _model(robot, obstacles, **law) -> sc.Model:
    law = {"stiffness": 1e7, "smoothing": 1e-6, **law}
    env = sc.Environment(obstacles, sc.ContactLaw(**law), contact_radius=[RC])
    return sc.Model(robot, environment=env, compile=False)


# -- the description -----------------------------------------------------------------
@pytest.mark.parametrize(
    ("build", "words"),
    [
        (lambda: sc.Plane([0, 0, 0], [0, 0, 0]), "Plane.normal must be a nonzero"),
        (lambda: sc.Sphere([0, 0, 0], -0.1), "Sphere.radius must be > 0, got -0.1"),
        (lambda: sc.Capsule([0, 0, 0], [0, 0, 0], 0.1), "Capsule.b must differ"),
        (lambda: sc.Capsule([0, 0], [0, 0, 1], 0.1), "Capsule.a must have shape (3,)"),
        (lambda: sc.ContactLaw(0.0), "ContactLaw.stiffness must be > 0"),
        (lambda: sc.ContactLaw(1e6, exponent=0.5), "ContactLaw.exponent must be in [1, 3]"),
        (lambda: sc.ContactLaw(1e6, friction=-1), "ContactLaw.friction must be >= 0"),
        (lambda: sc.ContactLaw(1e6, points_per_segment=0), "points_per_segment must be an"),
        (lambda: sc.Environment([], sc.ContactLaw(1e6)), "at least one obstacle"),
        (lambda: sc.Environment(["wall"], sc.ContactLaw(1e6)), "obstacles[0] must be a Plane"),
        (
            lambda: sc.Environment([sc.Sphere([0, 0, 1], 1)], sc.ContactLaw(1e6), [-1.0]),
            "contact_radius[0] must be > 0",
        ),
    ],
)
def test_invalid_descriptions_are_refused_by_name(build, words):
    with pytest.raises(sc.ParameterError, match=re.escape(words)):
        build()


def test_contact_radius_per_segment_checked_against_robot():
    env = sc.Environment([sc.Sphere([0, 0, 1], 0.1)], sc.ContactLaw(1e6), [0.01, 0.01])
    with pytest.raises(sc.ParameterError, match="one entry per segment"):
        sc.Model(sc.presets.ifac2020(), environment=env, compile=False)


def test_plane_normal_is_normalized():
    plane = sc.Plane([0, 0, 1], [0, 0, -3])
    np.testing.assert_array_equal(plane.normal, [0, 0, -1])
    with pytest.raises(ValueError):
        plane.normal[0] = 1.0  # read-only


# -- the law -------------------------------------------------------------------------
def test_penalty_energy_integrates_the_elastic_force():
    """``dU/dx = k h(x)^e`` everywhere, including the rounded corner and beyond."""
    law = sc.ContactLaw(3e6, exponent=1.5, smoothing=1e-4)
    x = ca.SX.sym("x")
    u = ca.Function("u", [x], [penalty_energy(x, law), ca.gradient(penalty_energy(x, law), x)])
    force = ca.Function("f", [x], [law.stiffness * ramp(x, law.smoothing) ** law.exponent])
    for value in (-1e-3, 0.0, 3e-5, 1e-4, 2.5e-4, 1e-2):
        energy, derivative = (float(v) for v in u(value))
        expected = float(force(value))
        assert abs(derivative - expected) <= 1e-12 * max(abs(expected), 1e-30)
        assert energy >= 0.0 and (energy == 0.0) == (value <= 0.0)


def test_the_powered_ramp_is_the_ramps_power_with_finite_second_derivatives():
    """``ramp(x, w, e) = ramp(x, w)^e``, written so that ``d2/dx2`` is finite at the onset
    (``x = 0``) and at the corner (``x = w``), where ``h^1.5`` gives NaN."""
    x, width = ca.SX.sym("x"), 1e-4
    for exponent in (1.0, 1.5, 2.0, 3.0):
        powered = ramp(x, width, exponent)
        both = ca.Function("r", [x], [powered, ramp(x, width) ** exponent,
                                      ca.hessian(powered, x)[0]])  # fmt: skip
        for value in (-1e-3, 0.0, 3e-5, width, 2.5e-4, 1e-2):
            mine, reference, curvature = (float(v) for v in both(value))
            assert mine == pytest.approx(reference, rel=1e-13, abs=1e-300)
            assert np.isfinite(curvature)
    naive = ca.Function("n", [x], [ca.hessian(ramp(x, width) ** 1.5, x)[0]])
    assert np.isnan(float(naive(0.0)))  # why the power is written piecewise


def test_no_nan_at_zero_curvature_and_at_the_contact_boundary():
    """Every derivative the analyses take is finite at a straight robot touching a wall."""
    model = _model(_robot(), [sc.Plane([0, 0, 0.0644 + RC], [0, 0, -1])], damping=0.5, friction=0.3)
    e = model.expressions
    x = ca.vertcat(e.q, e.qd)
    rhs = ca.vertcat(e.qd, e.forward_dynamics)
    f = ca.Function("a", [x, e.tau, e.lam, e.p], [ca.jacobian(rhs, x)])
    for q in ([0.0644, 0.0, 0.0], [0.0644, 1e-9, 0.0], [0.0650, 0.0, 0.0]):
        a = np.array(f(np.r_[q, 0.0, 0.0, 0.0], np.zeros(3), np.zeros(3), model.parameters))
        assert np.all(np.isfinite(a)), q


# -- (e) far from every obstacle ---------------------------------------------------------
def test_far_from_obstacles_equals_the_free_model_exactly(rng):
    robot = _robot()
    free = sc.Model(robot, compile=False)
    far = [
        sc.Plane([0, 0, -1.0], [0, 0, 1]),
        sc.Sphere([1.0, 0, 0], 0.2),
        sc.Capsule([0, 1.0, 0], [0, 1.0, 1.0], 0.1),
    ]
    model = _model(robot, far, damping=0.7, friction=0.4)
    for _ in range(5):
        q = np.array([0.0644, 0.0, 0.0]) + rng.normal(size=3) * [3e-3, 15.0, 15.0]
        qd = rng.normal(size=3) * [0.1, 100.0, 100.0]
        tau = rng.normal(size=3) * [0.1, 1e-3, 1e-3]
        np.testing.assert_array_equal(
            model.forward_dynamics(q, qd, tau), free.forward_dynamics(q, qd, tau)
        )
        np.testing.assert_array_equal(
            model.inverse_dynamics(q, qd, tau), free.inverse_dynamics(q, qd, tau)
        )
        assert model.potential_energy(q) == free.potential_energy(q)
        np.testing.assert_array_equal(model.potential_force(q), free.potential_force(q))
        assert np.all(model.contact(q, qd)["forces"] == 0.0)


def test_free_model_keeps_its_cache_key():
    """Without environment the compiled library depends on the robot's structure alone,
    exactly as before environments existed."""
    robot = sc.presets.ifac2020()
    free = sc.Model(robot, compile=False)
    assert free._cache_structure() == robot.structure()
    model = _model(robot, [sc.Sphere([0, 0, 1], 0.1)])
    assert model._cache_structure() != robot.structure()


# -- (a) static contact against the constrained optimum -----------------------------
def test_static_contact_converges_to_the_constrained_equilibrium():
    """A tip force pushes the robot against a wall. The exact answer minimizes the
    potential subject to the tip's gap >= 0 (SLSQP). With the penalty, only the tip
    point penetrates, by ``delta = (F_c / (k w))^(1/e)`` (``w`` its weight, ``F_c``
    the contact force): the error in ``q`` is proportional to ``delta`` and so falls as
    ``k^(-1/e)``."""
    robot = sc.presets.ifac2020()
    free = sc.Model(robot, compile=False)
    force = np.array([0.3, 0.0, 0.0])
    start = sc.equilibrium(free, [0.0644, 0.0, 0.0], tip_force=force)
    wall = 0.6 * free.tip_pose(start.q).position[0] + RC

    def work(z):
        q = z * SCALE
        return free.potential_energy(q) - force @ free.tip_pose(q).position

    def gap(z):
        return (wall - RC - free.tip_pose(z * SCALE).position[0]) / 0.0644

    exact = minimize(
        work,
        start.q / SCALE,
        constraints=[{"type": "ineq", "fun": gap}],
        method="SLSQP",
        options={"ftol": 1e-15, "maxiter": 500},
    )
    assert exact.success
    q_exact = exact.x * SCALE
    exponent, stiffnesses = 1.5, (1e6, 1e7, 1e8)
    errors, depths, forces = [], [], []
    for k in stiffnesses:
        model = _model(robot, [sc.Plane([wall, 0, 0], [-1, 0, 0])], stiffness=k, smoothing=1e-8)
        e = sc.equilibrium(model, q_exact, tip_force=force)
        assert e.success, e.message
        errors.append(np.linalg.norm((e.q - q_exact) / SCALE))
        depths.append(free.tip_pose(e.q).position[0] + RC - wall)
        forces.append(-model.contact(e.q)["forces"][0, 0])
    errors, depths, forces = map(np.array, (errors, depths, forces))
    weight = 0.0644 / (2 * 8)  # the tip point's share of the rest length
    predicted = (forces / (np.array(stiffnesses) * weight)) ** (1 / exponent)
    np.testing.assert_allclose(depths, predicted, rtol=1e-3)  # the law, at the tip point
    ratio = errors / depths
    assert np.ptp(ratio) <= 0.02 * ratio.mean()  # error proportional to the penetration
    slopes = np.diff(np.log(errors)) / np.diff(np.log(stiffnesses))
    assert np.all(np.abs(slopes + 1 / exponent) < 0.07), slopes


# -- (b) and (d): energy, impact -------------------------------------------------------------
def test_elastic_contact_conserves_energy_including_the_penalty():
    """A straight robot swung against a wall, no damping anywhere: ``T + V + V_c`` is
    constant to the integrator's tolerance through impact and rebound."""
    model = _model(_robot(damping=False), [sc.Plane([0.01, 0, 0], [-1, 0, 0])])
    q0, qd0 = np.array([0.0644, 0.0, 0.0]), np.array([0.0, 300.0, 0.0])
    run = sc.simulate(model, q0, qd0, t_final=0.05, dt=1e-4, rtol=1e-10, atol=1e-12)
    assert run.success, run.message
    energy = run.energy()
    penalty = np.array([model.contact(q)["energy"] for q in run.q[::5]])
    assert penalty.max() > 0.02 * energy[0]  # the contact was real
    assert np.max(np.abs(energy - energy[0])) <= 1e-8 * energy[0]


def test_impact_is_bounded_rebounds_and_never_gains_energy():
    """A bent robot released toward a wall with Hunt-Crossley damping and friction: the
    energy never rises, the penetration stays below the law's bound (all the initial
    energy above the free equilibrium stored in the tip point's penalty), and the
    robot leaves the wall again."""
    robot = _robot(damping=False)
    law = {"damping": 2.0, "friction": 0.3, "slip_velocity": 1e-3}
    model = _model(robot, [sc.Plane([0.01, 0, 0], [-1, 0, 0])], **law)
    q0, qd0 = np.array([0.0644, -20.0, 0.0]), np.zeros(3)
    run = sc.simulate(model, q0, qd0, t_final=0.06, dt=2e-4, rtol=1e-9, atol=1e-11)
    assert run.success, run.message
    energy = run.energy()
    assert np.all(np.diff(energy) <= 1e-9 * energy[0])
    tip = np.array([model.tip_pose(q).position[0] for q in run.q])
    depth = tip + RC - 0.01
    assert depth.max() > 0  # it hit
    rest = sc.equilibrium(sc.Model(robot, compile=False), [0.0644, 0.0, 0.0])
    available = energy[0] - model.potential_energy(rest.q)
    m = model.environment.law
    weight = 0.0644 / (2 * m.points_per_segment)
    # U(x) >= k (x - w/2)^(e+1) / (e+1) for x >= w: invert for the bound
    bound = (available / weight * (m.exponent + 1) / m.stiffness) ** (1 / (m.exponent + 1))
    assert depth.max() <= bound + m.smoothing
    hit = int(np.argmax(depth))
    assert np.min(depth[hit:]) < -1e-3  # rebounded: a millimetre clear of the wall


# -- (c) friction --------------------------------------------------------------------
@pytest.fixture(scope="module")
def pressed():
    """The robot standing under a ceiling that compresses it: normal force ``N`` [N]."""
    law = {"damping": 1.0, "friction": 0.5, "slip_velocity": 1e-4}
    model = _model(_robot(), [sc.Plane([0, 0, 0.062], [0, 0, -1])], **law)
    rest = sc.equilibrium(model, [0.0612, 0.0, 0.0])
    assert rest.success
    normal = -model.contact(rest.q)["forces"][0, 2]
    assert normal > 0.5
    return model, rest.q, normal


@pytest.mark.parametrize(("fraction", "holds"), [(0.5, True), (1.5, False)])
def test_friction_holds_below_mu_n_and_slides_above(pressed, fraction, holds):
    model, q, normal = pressed
    mu = model.environment.law.friction
    load = np.array([fraction * mu * normal, 0.0, 0.0])  # tangential, on the tip
    tau = model.jacobian(q, 1.0)[:3].T @ load
    run = sc.simulate(model, q, np.zeros(3), tau=tau, t_final=0.2, dt=1e-3)
    assert run.success, run.message
    slip = abs(model.tip_pose(run.q[-1]).position[0])
    if holds:  # creeps at most at v_s F / sqrt(mu^2 N^2 - F^2): microns
        creep = model.environment.law.slip_velocity * fraction / np.sqrt(1 - fraction**2)
        assert slip < 1.5 * creep * 0.2
    else:
        assert slip > 5e-3
