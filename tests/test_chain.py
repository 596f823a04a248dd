"""The algorithms over the chain (softcurve.symbolic.chain) for robots of 1 to 20
segments: one algorithm against another, the structural identities, and a chain of equal
segments moving as one segment."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.symbolic.dynamics import build_dynamics

from .conftest import assert_close, random_state

SEGMENTS = (1, 2, 5, 12, 20)


def _model(n_segments, creep=True):
    return sc.Model(sc.presets.ifac2020(creep=creep).with_segments(n_segments), compile=False)


def _function(e, inputs, outputs):
    return ca.Function("f", [*inputs, e.p], outputs)


def _inputs(rng, model):
    q, qd = random_state(rng, model)
    tau = rng.normal(size=model.n) * np.tile([1.0, 1e-3, 1e-3], model.robot.n_segments)
    lam = rng.normal(size=model.n_creep) * 1e-3
    return q, qd, tau, lam


@pytest.mark.parametrize("n_segments", SEGMENTS)
def test_the_three_algorithms_agree(rng, n_segments):
    """The composite-body mass matrix is the derivative of the Newton-Euler inverse
    dynamics in ``qdd``, symmetric positive definite; the articulated-body forward
    dynamics inverts the Newton-Euler pass and agrees with solving with ``D``."""
    model = _model(n_segments)
    e = model.expressions
    f = _function(
        e,
        [e.q, e.qd, e.qdd, e.tau, e.lam],
        [e.mass_matrix, ca.jacobian(e.inverse_dynamics, e.qdd), e.inverse_dynamics],
    )
    forward = _function(e, [e.q, e.qd, e.tau, e.lam], [e.forward_dynamics])
    for _ in range(2):
        q, qd, tau, lam = _inputs(rng, model)
        qdd = np.array(forward(q, qd, tau, lam, model.parameters)).ravel()
        d, d_rnea, back = (np.array(v) for v in f(q, qd, qdd, tau, lam, model.parameters))
        assert_close(d, d_rnea, atol=1e-14 * np.abs(d).max(), what="D against d(tau)/d(qdd)")
        assert_close(d, d.T, atol=0, what="symmetry")
        assert np.linalg.eigvalsh(d).min() > 0
        bias = np.array(f(q, qd, np.zeros(model.n), tau, lam, model.parameters)[2]).ravel()
        scale = np.abs(bias).max() + np.abs(tau).max()  # of the terms that cancel
        assert_close(back.ravel(), tau, atol=1e-14 * scale, what="inverse(forward)")
        # D's condition number is 1e6 (N = 1) to 1e10 (N = 20): the accelerations differ
        # by as much; in tau both are exact to round-off (LAPACK's, with pivoting, less so:
        # a residual of 1.6e-13 at N = 20 against the recursion's 1e-15)
        solved = np.linalg.solve(d, tau - bias)
        assert_close(d @ (solved - qdd), 0.0, atol=1e-12 * scale, what="ABA vs solve")


@pytest.mark.parametrize("n_segments", (1, 2, 5))
def test_calls_and_inlined_functions_agree(rng, n_segments):
    structure = _model(n_segments).robot.structure()
    called, inlined = (build_dynamics(structure, inline=flag) for flag in (False, True))
    model = _model(n_segments)
    values = []
    for e in (called, inlined):
        outputs = [e.forward_dynamics, e.mass_matrix, e.coriolis_force, e.gravity_force]
        values.append(_function(e, [e.q, e.qd, e.tau, e.lam], outputs))
    for _ in range(2):
        args = (*_inputs(rng, model), model.parameters)
        for a, b in zip(values[0](*args), values[1](*args), strict=True):
            a, b = np.array(a), np.array(b)
            assert_close(a, b, atol=1e-13 * np.abs(b).max(), what="calls against inlined")


@pytest.mark.parametrize("n_segments", SEGMENTS)
def test_power_balance(rng, n_segments):
    """Along the forward dynamics, ``d(T + V_g + V_e)/dt = qd . (tau + K^T lambda - R qd)``:
    the inertial terms neither create nor destroy energy, with
    ``dT/dt = qd . D qdd + qd . Ddot qd / 2``."""
    model = _model(n_segments)
    e = model.expressions
    qdd = e.forward_dynamics
    kinetic_rate = ca.dot(e.qd, e.mass_matrix @ qdd) + 0.5 * ca.dot(
        e.qd, ca.jtimes(e.mass_matrix, e.q, e.qd) @ e.qd
    )
    potential_rate = ca.dot(e.gravity_force + e.elastic_force, e.qd)
    supplied = ca.dot(e.qd, e.tau + e.creep_force - e.damping_force)
    f = _function(e, [e.q, e.qd, e.tau, e.lam], [kinetic_rate + potential_rate, supplied])
    for _ in range(2):
        q, qd, tau, lam = _inputs(rng, model)
        balance, supplied_value = (float(v) for v in f(q, qd, tau, lam, model.parameters))
        scale = abs(float(ca.dot(qd, qd))) ** 0.5 * 1e-3 + abs(supplied_value)
        assert balance == pytest.approx(supplied_value, abs=1e-9 * scale)


@pytest.mark.parametrize("n_segments", (2, 8))
def test_ddot_minus_2c_is_skew(rng, n_segments):
    model = _model(n_segments)
    e = model.expressions
    d_dot = ca.jtimes(e.mass_matrix, e.q, e.qd)
    f = _function(e, [e.q, e.qd], [d_dot - 2 * e.coriolis_matrix, e.coriolis_matrix @ e.qd])
    for _ in range(2):
        q, qd = random_state(rng, model)
        n, c_qd = (np.array(v) for v in f(q, qd, model.parameters))
        assert_close(n + n.T, 0.0, atol=1e-12 * np.abs(n).max(), what="Ddot - 2C skew")
        kane = model.coriolis_force(q, qd)
        assert_close(c_qd.ravel(), kane, atol=1e-12 * np.abs(kane).max(), what="C qd")


@pytest.mark.parametrize("n_segments", (3, 8, 20))
def test_equal_segments_moving_as_one_are_one_segment(n_segments):
    """``N`` equal segments of ``L / N`` with equal curvatures and rates are one segment
    of length ``L``: same tip pose, kinetic and gravitational energy."""
    one_robot = sc.presets.ifac2020(creep=False)
    seg = one_robot.segments[0]
    piece = seg.replace(rest_length=seg.rest_length / n_segments, mass=seg.mass / n_segments)
    chain = sc.Model(one_robot.replace(segments=(piece,) * n_segments), compile=False)
    one = sc.Model(one_robot, compile=False)
    q1, qd1 = np.array([0.066, 18.0, -7.0]), np.array([0.05, 40.0, 90.0])
    scale = np.tile([1.0 / n_segments, 1.0, 1.0], n_segments)
    q, qd = np.tile(q1, n_segments) * scale, np.tile(qd1, n_segments) * scale
    assert chain.kinetic_energy(q, qd) == pytest.approx(one.kinetic_energy(q1, qd1), rel=1e-12)
    tip, tip1 = chain.tip_pose(q), one.tip_pose(q1)
    assert_close(tip.position, tip1.position, atol=1e-15, what="tip position")
    assert_close(tip.rotation, tip1.rotation, atol=1e-13, what="tip rotation")
    e, e1 = chain.expressions, one.expressions
    v = float(ca.Function("v", [e.q, e.p], [e.gravity_energy])(q, chain.parameters))
    v1 = float(ca.Function("v", [e1.q, e1.p], [e1.gravity_energy])(q1, one.parameters))
    assert v == pytest.approx(v1, rel=1e-12)
