"""Tendons: tau = -J_L(q)^T T from the tendons' work, routing, bounds, friction, the
closed-form curvature T rho / EI and the energy balance with tendons doing work."""

from __future__ import annotations

import math

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import cumulative_simpson

import softcurve as sc
from softcurve import ParameterError, Tendon, TendonActuator
from softcurve.description.materials import LinearStiffness
from softcurve.description.robot import Robot, Segment

from .conftest import assert_close

REST = 0.2  # [m]


def segment(**changes) -> Segment:
    fields = dict(
        rest_length=REST,
        mass=0.02,
        radius=0.01,
        elongation_stiffness=LinearStiffness(2e3),
        bending_stiffness=LinearStiffness(0.05),
        damping=np.array([1.0, 1e-4, 1e-4]),
    )
    fields.update(changes)
    return Segment(**fields)


def robot(n_segments=2, gravity=(0.0, 0.0, 0.0), **changes) -> Robot:
    return Robot(segments=(segment(**changes),) * n_segments, gravity=np.array(gravity))


def routed(friction=0.0) -> TendonActuator:
    """Four tendons on a three-segment robot: each anchor, odd azimuths and distances."""
    tendons = (
        Tendon(0.3, 0.010, 20.0, anchor=0, friction=friction),
        Tendon(2.0, 0.015, 20.0, anchor=1, friction=friction),
        Tendon(4.0, 0.008, 20.0, anchor=2, friction=friction),
        Tendon(5.5, 0.012, 20.0, t_min=1.0, anchor=2, friction=friction),
    )
    return TendonActuator(tendons, n_segments=3)


def random_q(rng, n_segments, curvature=15.0):
    return np.concatenate(
        [
            [REST * rng.uniform(0.8, 1.2), *rng.uniform(-curvature, curvature, 2)]
            for _ in range(n_segments)
        ]
    )


# -- the map ----------------------------------------------------------------------------
@pytest.mark.parametrize("trial", range(4))
def test_tau_is_minus_the_gradient_of_the_tendon_work(rng, trial):
    """H(q) T = d/dq (-T . L(q)): against central differences and CasADi's derivative."""
    act = routed()
    q = random_q(rng, 3) if trial else np.array([REST, 0.0, 0.0] * 3)  # and exactly straight
    tensions = rng.uniform(act.lower, act.upper)
    tau = act.generalized_force(q, tensions)
    # L is affine in each coordinate separately: large central steps are exact up to rounding
    step = np.where(np.arange(q.size) % 3 == 0, 1e-2, 1.0)
    difference = np.array(
        [
            -(tensions @ (act.tendon_lengths(q + dq) - act.tendon_lengths(q - dq))) / (2 * h)
            for dq, h in ((step[i] * np.eye(q.size)[i], step[i]) for i in range(q.size))
        ]
    )
    scale = np.abs(tau).max()
    assert_close(tau, difference, rtol=1e-12, scale=scale)
    qs, us = ca.SX.sym("q", q.size), ca.SX.sym("T", act.n_inputs)
    gradient = ca.Function("g", [qs, us], [ca.gradient(act.input_work_symbolic(qs, us), qs)])
    assert_close(tau, np.array(gradient(q, tensions)).ravel(), rtol=1e-14, scale=scale)


def test_a_pulled_tendon_shortens_and_bends_toward_itself():
    act = TendonActuator.three_per_segment(distance=0.01, t_max=10.0)
    straight = np.array([REST, 0.0, 0.0])
    for i, tendon in enumerate(act.tendons):
        tensions = np.zeros(3)
        tensions[i] = 2.0
        tau = act.generalized_force(straight, tensions)
        assert tau[0] == -2.0  # exactly, at zero curvature
        direction = tau[1:] / np.linalg.norm(tau[1:])
        assert_close(direction, [math.cos(tendon.azimuth), math.sin(tendon.azimuth)], atol=1e-15)
        assert_close(np.linalg.norm(tau[1:]), 2.0 * REST * 0.01, rtol=1e-15)


def test_a_tendon_through_two_segments_is_two_one_segment_tendons(rng):
    """Routed through segments 0 and 1 it does, per segment, the work of a tendon of one
    segment on a robot of that segment alone."""
    through = TendonActuator([Tendon(1.1, 0.012, 5.0, anchor=1)], n_segments=2)
    alone = TendonActuator([Tendon(1.1, 0.012, 5.0)], n_segments=1)
    for _ in range(3):
        q = random_q(rng, 2)
        assert_close(
            through.tendon_lengths(q),
            alone.tendon_lengths(q[:3]) + alone.tendon_lengths(q[3:]),
            rtol=1e-15,
        )
        h = through.input_matrix(q)[:, 0]
        assert_close(
            h,
            np.concatenate([alone.input_matrix(q[:3])[:, 0], alone.input_matrix(q[3:])[:, 0]]),
            rtol=1e-15,
        )


def test_tendon_length_is_exact_for_an_arc():
    """The offset fiber of a planar arc of radius 1/kappa is the concentric arc of radius
    1/kappa - rho (tendon on the inside of the bend) over the same angle."""
    act = TendonActuator([Tendon(0.7, 0.01, 5.0)])
    kappa, length = 12.0, 0.18
    q = np.array([length, kappa * math.cos(0.7), kappa * math.sin(0.7)])
    assert_close(act.tendon_lengths(q), [(1 / kappa - 0.01) * kappa * length], rtol=1e-15)


def test_the_map_is_smooth_and_exact_at_zero_curvature():
    for act in (routed(), routed(friction=0.3)):
        qs = ca.SX.sym("q", 9)
        h = act.input_matrix_symbolic(qs)
        derivative = ca.Function("dh", [qs], [ca.jacobian(ca.vec(h), qs)])
        straight = np.array([REST, 0.0, 0.0] * 3)
        assert np.all(np.isfinite(np.array(derivative(straight))))
        assert np.all(np.isfinite(act.input_matrix(straight)))
        # with or without friction, a straight robot sees the full tension everywhere
        assert_close(act.input_matrix(straight), routed().input_matrix(straight), rtol=1e-15)


# -- friction -----------------------------------------------------------------------------
def test_capstan_friction_mean_tension_per_segment(rng):
    """Segment j sees T exp(-mu Theta_(j-1)) (1 - exp(-mu beta_j)) / (mu beta_j)."""
    mu = 0.25
    act = TendonActuator(
        [Tendon(0.0, 0.01, 5.0, anchor=2, friction=mu, wrap_smoothing=1e-9)], n_segments=3
    )
    plain = TendonActuator([Tendon(0.0, 0.01, 5.0, anchor=2)], n_segments=3)
    q = random_q(rng, 3)
    eps = act.tendons[0].wrap_smoothing
    beta = np.hypot(q[0::3] * np.hypot(q[1::3], q[2::3]), eps) - eps
    turned = np.concatenate([[0.0], np.cumsum(beta)[:-1]])
    mean = np.exp(-mu * turned) * (1 - np.exp(-mu * beta)) / (mu * beta)
    expected = plain.input_matrix(q)[:, 0] * np.repeat(mean, 3)
    assert_close(act.input_matrix(q)[:, 0], expected, rtol=1e-12)
    assert np.all(np.diff(mean) < 0)  # tension is lost along the routing
    assert not act.conservative and plain.conservative


def test_mean_capstan_factor_is_exact_across_the_series_switch():
    from softcurve.description.tendons import SERIES_LIMIT, _mean_capstan_factor

    x = ca.SX.sym("x")
    f = ca.Function("f", [x], [_mean_capstan_factor(x)])
    for value in (0.0, 1e-8, 0.999 * SERIES_LIMIT, SERIES_LIMIT, 1.001 * SERIES_LIMIT, 0.5, 3.0):
        exact = 1.0 if value == 0 else -math.expm1(-value) / value
        assert_close(float(f(value)), exact, rtol=2e-16)


def test_friction_makes_equilibria_non_conservative():
    model = sc.Model(robot(1), compile=False)
    act = TendonActuator([Tendon(0.0, 0.01, 5.0, friction=0.2)])
    e = sc.equilibrium(model, [REST, 0.0, 0.0], actuator=act, inputs=[2.0])
    assert e.success and e.stability == "stable"
    assert "not conservative" in e.message
    frictionless = sc.equilibrium(
        model, [REST, 0.0, 0.0], actuator=TendonActuator([Tendon(0.0, 0.01, 5.0)]), inputs=[2.0]
    )
    assert 0 < e.q[1] < frictionless.q[1]  # friction takes tension away: less bending


# -- statics: the closed form -------------------------------------------------------------
@pytest.mark.parametrize("azimuth", [0.0, 1.0, 4.0])
def test_one_tendon_bends_a_segment_to_t_rho_over_ei(azimuth):
    """Inextensible backbone, no gravity: kappa = T rho / EI, with EI = k_b l0 for
    softcurve's bending energy 0.5 k_b (kappa l)^2. With a finite axial stiffness k_e the
    exact balance is k_b kappa l = T rho for the bending and, since the bending energy
    depends on l too, k_e (l - l0) + k_b kappa^2 l = -T (1 - rho kappa), i.e.
    k_e (l - l0) = -T."""
    ei, rho, tension = 0.05 * REST, 0.01, 3.0
    act = TendonActuator([Tendon(azimuth, rho, 10.0)])
    for k_e in (2e3, 2e9):
        model = sc.Model(robot(1, elongation_stiffness=LinearStiffness(k_e)), compile=False)
        e = sc.equilibrium(model, [REST, 0.0, 0.0], actuator=act, inputs=[tension])
        assert e.success
        length, kx, ky = e.q
        kappa = math.hypot(kx, ky)
        assert_close(
            [kx, ky], kappa * np.array([math.cos(azimuth), math.sin(azimuth)]), atol=1e-12 * kappa
        )
        assert_close(0.05 * kappa * length, tension * rho, rtol=1e-10)
        assert_close(
            k_e * (length - REST) + 0.05 * kappa**2 * length,
            -tension * (1 - rho * kappa),
            rtol=1e-8,
        )
        assert_close(k_e * (length - REST), -tension, rtol=1e-8)
        if k_e > 1e9:  # nearly inextensible: the closed form to O(T / k_e)
            assert_close(kappa, tension * rho / ei, rtol=1e-8)


# -- inputs ---------------------------------------------------------------------------------
def test_tensions_are_bounded_and_never_negative():
    act = routed()
    assert_close(act.lower, [0.0, 0.0, 0.0, 1.0], rtol=0)
    assert np.all(act.rest_inputs() >= act.lower)
    with pytest.raises(ParameterError, match=r"tensions\[2\] = -0.5 N is outside its bounds"):
        act.check_inputs([1.0, 1.0, -0.5, 2.0])
    assert np.all(act.clip([-3.0, 50.0, 1.0, 0.0]) == [0.0, 20.0, 1.0, 1.0])
    lagged = TendonActuator(act.tendons, n_segments=3, time_constant=0.05)
    u = lagged.clip([20.0, 0.0, 5.0, 1.0])
    for command in ([-10.0, 30.0, 0.0, -1.0], [0.0, 0.0, 0.0, 0.0]):
        for dt in (1e-4, 0.01, 1.0):
            assert np.all(lagged.input_step(u, command, dt) >= lagged.lower)


def test_simulated_tensions_with_lag_stay_within_bounds():
    model = sc.Model(robot(2))
    act = TendonActuator.three_per_segment(
        distance=0.01, t_max=4.0, n_segments=2, time_constant=0.02
    )
    steps = np.array([[4.0, 0, 0, 0, 2.0, 0], [0] * 6, [0, 4.0, 0, 1.0, 0, 0], [0] * 6])
    t = np.linspace(0.0, 0.4, 401)  # one row per output time (dt = 1 ms)
    tensions = steps[np.minimum((t / 0.1).astype(int), 3)]
    run = sc.simulate(
        model, [REST, 0, 0] * 2, np.zeros(6), actuator=act, inputs=tensions, t_final=0.4
    )
    assert run.success, run.message
    assert np.all(run.inputs >= 0.0) and np.all(run.inputs <= 4.0)
    assert run.inputs.max() > 1.0  # the lag did let the tensions rise


@pytest.mark.parametrize("damped", [False, True])
def test_energy_balance_with_tendons_doing_work(damped):
    """E(t) - E(0) = int qd . (H(q) T(t) - R qd) dt with lagging tensions; without damping
    and at constant tension E + T . L(q) is conserved."""
    damping = np.array([1.0, 1e-4, 1e-4]) if damped else np.zeros(3)
    model = sc.Model(robot(2, gravity=(0.0, 0.0, -9.81), damping=damping))
    act = TendonActuator.three_per_segment(
        distance=0.01, t_max=4.0, n_segments=2, time_constant=0.05
    )
    commands = np.array([3.0, 0.0, 0.5, 0.0, 2.0, 0.0])
    run = sc.simulate(
        model,
        [REST, 0, 0] * 2,
        np.zeros(6),
        actuator=act,
        inputs=commands,
        t_final=0.3,
        dt=1e-4,
        rtol=1e-10,
    )
    assert run.success, run.message
    h = np.array([act.input_matrix(q) for q in run.q])
    r = np.diag(np.tile(damping, 2))
    power = np.einsum("ti,tij,tj->t", run.qd, h, run.inputs) - np.einsum(
        "ti,ij,tj->t", run.qd, r, run.qd
    )
    work = cumulative_simpson(power, x=run.t, initial=0.0)
    energy = run.energy()
    scale = np.trapezoid(np.abs(power), run.t)
    assert np.max(np.abs(energy - energy[0] - work)) < 1e-6 * scale
    assert abs(energy[-1] - energy[0]) > 0.1 * scale  # not trivially zero
    if not damped:
        constant = sc.simulate(
            model,
            run.q[-1],
            run.qd[-1],
            actuator=TendonActuator(act.tendons, n_segments=2),
            inputs=run.inputs[-1],
            t_final=0.2,
            dt=1e-3,
            rtol=1e-11,
        )
        lengths = np.array([act.tendon_lengths(q) for q in constant.q])
        total = constant.energy() + lengths @ constant.inputs[-1]
        assert np.max(np.abs(total - total[0])) < 1e-7 * np.ptp(constant.energy())


# -- validation -------------------------------------------------------------------------------
@pytest.mark.parametrize(
    ("fields", "message"),
    [
        (dict(distance=0.0), "distance must be > 0"),
        (dict(distance=float("nan")), "distance must be finite"),
        (dict(azimuth="x"), "azimuth must be a real number"),
        (dict(t_min=-1.0), r"t_min must be >= 0 N \(a tendon cannot push\), got -1.0"),
        (dict(t_max=0.0), "t_max must be > t_min = 0.0 N, got 0.0"),
        (dict(t_min=3.0, t_max=2.0), "t_max must be > t_min = 3.0 N"),
        (dict(anchor=-1), "anchor must be an integer >= 0, got -1"),
        (dict(anchor=True), "anchor must be an integer >= 0, got True"),
        (dict(anchor=1.0), "anchor must be an integer >= 0"),
        (dict(friction=-0.1), "friction must be >= 0, got -0.1"),
        (dict(wrap_smoothing=0.0), "wrap_smoothing must be > 0"),
    ],
)
def test_bad_tendons_name_the_field(fields, message):
    args = dict(azimuth=0.0, distance=0.01, t_max=5.0)
    args.update(fields)
    with pytest.raises(ParameterError, match=message):
        Tendon(**args)


def test_bad_actuators_name_the_field():
    tendon = Tendon(0.0, 0.01, 5.0, anchor=2)
    with pytest.raises(ParameterError, match=r"tendons\[0\].anchor = 2 is beyond .*n_segments = 2"):
        TendonActuator([tendon], n_segments=2)
    with pytest.raises(ParameterError, match="at least one Tendon"):
        TendonActuator([])
    with pytest.raises(ParameterError, match=r"tendons\[1\] must be a Tendon, got dict"):
        TendonActuator([Tendon(0.0, 0.01, 5.0), {"azimuth": 0.0}])
    with pytest.raises(ParameterError, match="n_segments must be an integer >= 1, got 0"):
        TendonActuator([Tendon(0.0, 0.01, 5.0)], n_segments=0)
    with pytest.raises(ParameterError, match="time_constant must be > 0"):
        TendonActuator([Tendon(0.0, 0.01, 5.0)], time_constant=0.0)
    with pytest.raises(ParameterError, match="n = 3 coordinates but the robot has n = 6"):
        sc.simulate(
            sc.Model(robot(2)),
            [REST, 0, 0] * 2,
            np.zeros(6),
            actuator=TendonActuator([Tendon(0.0, 0.01, 5.0)]),
            inputs=[1.0],
        )


# -- linearization with tensions as inputs ------------------------------------------------
@pytest.mark.parametrize("friction", [0.0, 0.3])
def test_linearization_with_tensions_matches_finite_differences(rng, friction):
    """A and B of linearize(wrt="actuator") against central differences of the state
    derivative in the state and in the tensions, with and without capstan friction (K is
    then not symmetric)."""
    model = sc.Model(robot(2, gravity=(0.0, 0.0, -9.81)), compile=False)
    act = TendonActuator.three_per_segment(
        distance=0.01, t_max=10.0, n_segments=2, friction=friction
    )
    tensions = np.array([2.0, 0.5, 0.0, 1.0, 0.0, 0.3])
    q = np.array([0.19, 6.0, -3.0, 0.2, -4.0, 5.0])
    qd = rng.normal(size=6) * [0.01, 5, 5, 0.01, 5, 5]
    lin = sc.linearize(model, q, qd, actuator=act, inputs=tensions, wrt="actuator")
    x = np.concatenate([q, qd])

    def rhs(x, du=0.0):
        tau = act.input_matrix(x[:6]) @ (tensions + du)
        return np.array(model.state_derivative(x, tau))

    steps = 1e-6 * (np.abs(x) + 1e-3)
    a = np.column_stack(
        [
            (rhs(x + h * e) - rhs(x - h * e)) / (2 * h)
            for h, e in zip(steps, np.eye(12), strict=True)
        ]
    )
    # rows span 1e3..1e7 (stiff elongation): each row against its own largest entry; a
    # wrong sign or factor in H(q) or its derivative is an O(1) error in these units
    rows = np.abs(a).max(axis=1, keepdims=True)
    assert_close(lin.A, a, rtol=1e-4, scale=rows)
    b = np.column_stack([(rhs(x, 0.1 * e) - rhs(x, -0.1 * e)) / 0.2 for e in np.eye(6)])
    assert_close(lin.B, b, rtol=1e-6, atol=1e-8 * np.abs(b).max())


def test_capstan_work_against_the_tension_integrated_along_the_routing(rng):
    """Independent of the closed form: integrate dT/dtheta = -mu T along a finely split
    routing (theta the angle turned so far) and take the virtual work of the varying
    tension on each segment's uniformly stretched fiber, sum_j int T dL_j."""
    mu = 0.4
    act = TendonActuator(
        [Tendon(0.9, 0.01, 5.0, anchor=2, friction=mu, wrap_smoothing=1e-12)], n_segments=3
    )
    q = random_q(rng, 3)
    beta = q[0::3] * np.hypot(q[1::3], q[2::3])
    samples = 20001
    tension, h_expected = 1.0, np.zeros(9)
    for j in range(3):
        s = np.linspace(0.0, 1.0, samples)
        theta = s * beta[j]
        # explicit integration of the ODE in theta, second order (Heun), from the segment's
        # entry tension: no exponential anywhere
        t = np.empty(samples)
        t[0] = tension
        dtheta = np.diff(theta)
        for k in range(samples - 1):
            slope = -mu * t[k]
            guess = t[k] + dtheta[k] * slope
            t[k + 1] = t[k] + 0.5 * dtheta[k] * (slope - mu * guess)
        mean = np.trapezoid(t, s)
        phi, rho, (length, kx, ky) = 0.9, 0.01, q[3 * j : 3 * j + 3]
        gradient = [1 - rho * (kx * math.cos(phi) + ky * math.sin(phi)),
                    -length * rho * math.cos(phi), -length * rho * math.sin(phi)]  # fmt: skip
        h_expected[3 * j : 3 * j + 3] = -mean * np.array(gradient)
        tension = t[-1]
    assert_close(act.input_matrix(q)[:, 0], h_expected, rtol=1e-9, scale=np.abs(h_expected).max())
