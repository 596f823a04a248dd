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
from .test_kinds import check_power_balance, check_three_algorithms

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
    check_three_algorithms(_model(n_segments), rng, 2, inverse_tolerance=1e-14, inputs=_inputs)


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
    check_power_balance(_model(n_segments), rng, 2, inputs=_inputs)


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
