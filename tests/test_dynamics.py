"""Dynamics: closed-form cases, structural identities, and cross-checks of two algorithms."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest
from scipy.integrate import solve_ivp

import softcurve as sc

from .conftest import assert_close, random_state


def test_straight_segment_inertia(paper_model):
    m, r = 0.0494, 0.0235
    for length in (0.0644, 0.07):
        d = paper_model.mass_matrix([length, 0.0, 0.0])
        bending = m * length**4 / 20 + m * r**2 * length**2 / 12
        assert_close(np.diag(d), [m / 3, bending, bending], rtol=1e-15, what="diag D")
        assert_close(d - np.diag(np.diag(d)), 0.0, atol=1e-20, what="off-diagonal")


def kinetic_energy_from_pose(model, q, qd, nodes=40, h=1e-6):
    """Independent reference: slice energies from finite-difference velocities of the pose."""
    s, w = np.polynomial.legendre.leggauss(nodes)
    s, w = 0.5 * (s + 1), 0.5 * w
    n_seg = model.robot.n_segments
    energy = 0.0
    for i, segment in enumerate(model.robot.segments):
        inertia = segment.radius**2 * np.array([0.25, 0.25, 0.5])
        for sk, wk in zip(s, w, strict=True):
            point = (i + sk) / n_seg
            plus, minus = model.pose(q + h * qd, point), model.pose(q - h * qd, point)
            velocity = (plus.position - minus.position) / (2 * h)
            rotation = model.pose(q, point).rotation
            omega_hat = rotation.T @ (plus.rotation - minus.rotation) / (2 * h)
            omega = np.array([omega_hat[2, 1], omega_hat[0, 2], omega_hat[1, 0]])
            energy += 0.5 * wk * segment.mass * (velocity @ velocity + omega @ (inertia * omega))
    return energy


def test_kinetic_energy_matches_pose_velocities(rng, two_segment_model):
    model = two_segment_model
    for _ in range(4):
        q, qd = random_state(rng, model)
        reference = kinetic_energy_from_pose(model, q, qd)
        assert model.kinetic_energy(q, qd) == pytest.approx(reference, rel=1e-7)


def test_mass_matrix_symmetric_positive_definite(paper_model, rng):
    for curvature in (0.0, 1e-8, 30.0, 90.0):
        q, _ = random_state(rng, paper_model, curvature=curvature)
        d = paper_model.mass_matrix(q)
        assert_close(d, d.T, atol=0, rtol=1e-15, scale=np.abs(d).max(), what="symmetry")
        assert np.linalg.eigvalsh(d).min() > 0


def test_newton_euler_matches_christoffel_symbols_of_d(rng, two_segment_model):
    """Two algorithms: the model's C (from the Newton-Euler pass) against the Christoffel
    symbols of its mass matrix, C_ij = sum_k (dD_ij/dq_k + dD_ik/dq_j - dD_jk/dq_i) qd_k / 2,
    i.e. C = (Ddot + A - A^T) / 2 with A = d(D qd)/dq; and Ddot - 2C is skew-symmetric."""
    model = two_segment_model
    e = model.expressions
    d = e.mass_matrix
    a = ca.jacobian(d @ e.qd, e.q)
    d_dot = ca.jtimes(d, e.q, e.qd)
    reference = ca.Function("c", [e.q, e.qd, e.p], [0.5 * (d_dot + a - a.T), d_dot])
    for _ in range(5):
        q, qd = random_state(rng, model)
        c_ref, d_dot_value = (np.array(v) for v in reference(q, qd, model.parameters))
        c = model.coriolis_matrix(q, qd)
        scale = np.abs(c_ref).max()
        assert_close(c, c_ref, atol=1e-12 * scale, what="C")
        kane = model.coriolis_force(q, qd)
        assert_close(c @ qd, kane, atol=1e-12 * np.abs(kane).max(), what="C qd")
        n = d_dot_value - 2 * c
        assert_close(n + n.T, 0.0, atol=1e-12 * np.abs(n).max(), what="Ddot - 2C skew")


def test_inverse_of_forward_dynamics_is_identity(paper_model, rng):
    for _ in range(10):
        q, qd = random_state(rng, paper_model)
        tau = rng.normal(size=3) * [1.0, 1e-3, 1e-3]
        lam = rng.normal(size=3) * [1e-3, 1e-2, 1e-2]
        qdd = paper_model.forward_dynamics(q, qd, tau, lam)
        back = paper_model.inverse_dynamics(q, qd, qdd, lam)
        assert_close(back, tau, rtol=1e-10, scale=np.abs(tau).max() + 1e-6, what="tau")


def test_forces_are_gradients_of_the_energies(paper_model, rng):
    e = paper_model.expressions
    energy = ca.Function("V", [e.q, e.p], [e.gravity_energy, e.elastic_energy])
    newton_euler = ca.Function("tau", [e.q, e.qd, e.qdd, e.lam, e.p], [e.inverse_dynamics])
    h = 1e-7
    for _ in range(5):
        q, _ = random_state(rng, paper_model, curvature=60.0)
        fd = np.zeros((2, 3))
        for j in range(3):
            step = np.zeros(3)
            step[j] = h * max(abs(q[j]), 1.0)
            plus = np.array([float(v) for v in energy(q + step, paper_model.parameters)])
            minus = np.array([float(v) for v in energy(q - step, paper_model.parameters)])
            fd[:, j] = (plus - minus) / (2 * step[j])
        gravity, elastic = paper_model.gravity_force(q), paper_model.elastic_force(q)
        assert_close(gravity, fd[0], rtol=1e-6, scale=np.abs(gravity).max(), what="gravity")
        assert_close(elastic, fd[1], rtol=1e-6, scale=np.abs(elastic).max(), what="elastic")
        # the equation of motion's own gravity, from its Newton-Euler pass (at rest)
        at_rest = newton_euler(q, np.zeros(3), np.zeros(3), np.zeros(3), paper_model.parameters)
        at_rest = np.array(at_rest).ravel()
        scale = np.abs(gravity).max()
        assert_close(at_rest - elastic, fd[0], rtol=1e-6, scale=scale, what="Newton-Euler G")
        assert_close(at_rest - elastic, gravity, rtol=1e-12, scale=scale, what="G two ways")


def test_elastic_force_matches_the_stiffness_laws(paper_model):
    segment = paper_model.robot.segments[0]
    l0 = segment.rest_length
    for eps in (-0.004, 0.0, 0.003):
        force = paper_model.elastic_force([l0 + eps, 0.0, 0.0])
        assert_close(
            force, [segment.elongation_stiffness.force(eps), 0, 0], rtol=1e-14, atol=1e-300
        )
    length, kx = 0.07, 30.0
    beta = kx * length
    force = paper_model.elastic_force([length, kx, 0.0])
    # V_b(beta) with beta = kx l: dV/dkx = k_b(beta) beta l, dV/dl = k_e(eps) eps + k_b beta kx
    k_b = segment.bending_stiffness.force(beta)
    expected = [segment.elongation_stiffness.force(length - l0) + k_b * kx, k_b * length, 0.0]
    assert_close(force, expected, rtol=1e-14, atol=1e-300, what="bending force")


def test_gravity_energy_of_the_straight_robot(paper_model):
    for length in (0.06, 0.0644):
        energy = paper_model.potential_energy([length, 0.0, 0.0])
        law = paper_model.robot.segments[0].elongation_stiffness
        eps = length - 0.0644
        x = np.linspace(0.0, eps, 20001)
        stored = np.trapezoid(law.force(x), x) if eps else 0.0
        assert energy == pytest.approx(0.0494 * 9.81 * length / 2 + stored, rel=1e-9)


def taylor_reference(function, arguments, index, direction, h):
    """Second-order Taylor value of ``function`` at ``arguments[index] + h direction`` from
    exact derivatives at ``arguments`` (evaluated where the curvature is exactly zero)."""
    symbols = [ca.SX.sym(f"a{i}", ca.DM(a).shape[0]) for i, a in enumerate(arguments)]
    out = function(*symbols)
    first = ca.jtimes(out, symbols[index], ca.DM(direction))
    second = ca.jtimes(first, symbols[index], ca.DM(direction))
    f = ca.Function("taylor", symbols, [out, first, second])
    value, d1, d2 = (np.array(v).ravel() for v in f(*arguments))
    return value + h * d1 + 0.5 * h**2 * d2


@pytest.mark.parametrize("kappa", [0.0, 1e-9, 1e-6])
@pytest.mark.parametrize(
    "name", ["forward_dynamics", "mass_matrix", "coriolis_force", "gravity_force", "elastic_force"]
)
def test_values_near_zero_curvature_agree_with_the_limit(paper_model, name, kappa):
    """Exact at zero curvature: values at kappa in {0, 1e-9, 1e-6} along a direction in the
    (kx, ky) plane equal the second-order Taylor expansion about kappa = 0 built from exact
    derivatives at 0. An epsilon, a NaN or a cancellation near zero would fail this."""
    p = paper_model.parameters
    q0 = np.array([0.0650, 0.0, 0.0])
    qd = np.array([0.02, 30.0, -20.0])
    direction = np.array([0.0, 0.6, 0.8])
    inputs = {
        "forward_dynamics": [q0, qd, np.array([0.1, 1e-4, 0.0]), np.array([1e-3, 1e-3, 0.0]), p],
        "mass_matrix": [q0, p],
        "coriolis_force": [q0, qd, p],
        "gravity_force": [q0, p],
        "elastic_force": [q0, p],
    }[name]
    reference = taylor_reference(paper_model.symbolic[name], inputs, 0, direction, kappa)
    at = [q0 + kappa * direction, *inputs[1:-1]]
    value = np.asarray(getattr(paper_model, name)(*at)).ravel()
    assert np.all(np.isfinite(value))
    assert_close(value, reference, rtol=1e-10, scale=np.abs(reference).max(), what=name)


def test_quadrature_converged():
    """Default nodes integrate to machine precision for bending angles up to pi."""
    robot = sc.presets.ifac2020()
    default = sc.Model(robot, compile=False)
    fine = sc.Model(robot, quadrature_nodes=40, compile=False)
    l0 = 0.0644
    for beta in (0.5, 2.0, np.pi):
        q = np.array([l0, beta / l0 * 0.6, beta / l0 * 0.8])
        qd = np.array([0.1, 50.0, -30.0])
        for name, args in [
            ("mass_matrix", (q,)),
            ("coriolis_force", (q, qd)),
            ("gravity_force", (q,)),
        ]:
            a, b = getattr(default, name)(*args), getattr(fine, name)(*args)
            assert_close(a, b, rtol=2e-14, scale=np.abs(b).max(), what=f"{name} beta={beta}")


def test_energy_is_conserved_without_dissipation(conservative_model):
    model = conservative_model
    x0 = np.array([0.064, 25.0, 0.0, 0.0, 0.0, 1500.0, 1e-3, 1e-2, -1e-2])  # creep inert
    result = solve_ivp(
        model.rhs(),
        (0.0, 1.0),
        x0,
        method="DOP853",
        rtol=1e-12,
        atol=1e-12,
        dense_output=False,
        t_eval=np.linspace(0, 1, 11),
    )
    assert result.success
    energies = [model.energy(x[:3], x[3:6]) for x in result.y.T]
    drift = np.abs(np.array(energies) - energies[0]).max() / abs(energies[0])
    assert drift < 1e-8, f"relative energy drift {drift:.2e}"


def test_compiled_equals_virtual_machine(paper_model, rng):
    vm = sc.Model(paper_model.robot, compile=False)
    for _ in range(3):
        q, qd = random_state(rng, paper_model)
        tau, lam = rng.normal(size=3) * 1e-3, rng.normal(size=3) * 1e-3
        for name, args in [
            ("forward_dynamics", (q, qd, tau, lam)),
            ("mass_matrix", (q,)),
            ("coriolis_matrix", (q, qd)),
            ("potential_energy", (q,)),
            ("jacobian", (q, 0.4)),
        ]:
            a, b = getattr(paper_model, name)(*args), getattr(vm, name)(*args)
            assert_close(a, b, rtol=1e-13, scale=np.abs(b).max(), what=name)


def test_two_segment_robot_moving_as_one_has_the_energy_of_one():
    """Two equal segments with equal curvatures and rates are one segment of twice the
    length and mass: same kinetic and potential energy (elastic energy aside)."""
    single_robot = sc.presets.ifac2020(creep=False)
    seg = single_robot.segments[0]
    half = seg.replace(rest_length=seg.rest_length / 2, mass=seg.mass / 2)
    double = sc.Model(single_robot.replace(segments=(half, half)), compile=False)
    single = sc.Model(single_robot, compile=False)
    q1, qd1 = np.array([0.066, 18.0, -7.0]), np.array([0.05, 40.0, 90.0])
    q2 = np.array([0.033, 18.0, -7.0] * 2)
    qd2 = np.array([0.025, 40.0, 90.0] * 2)
    assert double.kinetic_energy(q2, qd2) == pytest.approx(
        single.kinetic_energy(q1, qd1), rel=1e-13
    )
    e2, e1 = double.expressions, single.expressions
    v2 = float(ca.Function("v", [e2.q, e2.p], [e2.gravity_energy])(q2, double.parameters))
    v1 = float(ca.Function("v", [e1.q, e1.p], [e1.gravity_energy])(q1, single.parameters))
    assert v2 == pytest.approx(v1, rel=1e-13)
