"""Kinematics: closed-form arcs, the straight segment, Jacobians against finite differences."""

from __future__ import annotations

import numpy as np
import pytest

import softcurve as sc

from .conftest import assert_close, random_state


def circle_tip(length, kx, ky, s=1.0):
    """Tip of a constant-curvature arc written without cancellation:
    (1 - cos b)/k = 2 sin(b/2)^2 / k, sin(b)/k."""
    kappa = np.hypot(kx, ky)
    if kappa == 0:
        return np.array([0.0, 0.0, s * length])
    beta = s * length * kappa
    radial = 2 * np.sin(beta / 2) ** 2 / kappa
    return np.array([radial * kx / kappa, radial * ky / kappa, np.sin(beta) / kappa])


@pytest.mark.parametrize(
    "q",
    [
        (0.064, 25.0, 0.0),
        (0.07, 0.0, -40.0),
        (0.05, 30.0, 40.0),
        (0.064, 1e-6, 0.0),
        (0.064, 1e-9, -1e-9),
        (0.064, 0.0, 0.0),
        (0.064, 48.0, 10.0),  # beyond half a turn
    ],
)
def test_tip_is_on_the_circle(paper_model, q):
    for s in (0.3, 1.0):
        position = paper_model.pose(q, s).position
        assert_close(
            position,
            circle_tip(*q, s=s),
            rtol=1e-14,
            atol=0.0,
            scale=np.linalg.norm(position),
            what=f"tip at s={s}, q={q}",
        )


def test_orientation_is_the_tangent_and_orthonormal(paper_model, rng):
    for _ in range(10):
        q, _ = random_state(rng, paper_model, curvature=60.0)
        rotation, position = paper_model.pose(q, 1.0)
        assert_close(rotation.T @ rotation, np.eye(3), atol=1e-15, what="orthonormal")
        assert np.linalg.det(rotation) == pytest.approx(1.0, abs=1e-14)
        h = 1e-6
        tangent = paper_model.pose(q, 1.0).position - paper_model.pose(q, 1.0 - h).position
        assert_close(tangent / np.linalg.norm(tangent), rotation[:, 2], atol=1e-5, what="e_z")


def test_straight_segment_is_exact(paper_model):
    q = np.array([0.0644, 0.0, 0.0])
    for s in (0.0, 0.25, 1.0):
        rotation, position = paper_model.pose(q, s)
        np.testing.assert_array_equal(rotation, np.eye(3))
        np.testing.assert_array_equal(position, [0.0, 0.0, s * 0.0644])
    jacobian = paper_model.jacobian(q, 1.0)
    expected = np.zeros((6, 3))
    expected[2, 0] = 1.0  # dz/dl
    expected[0, 1] = expected[1, 2] = 0.0644**2 / 2  # lateral tip motion per unit curvature
    expected[4, 1], expected[3, 2] = 0.0644, -0.0644  # rotation about +y for kx, -x for ky
    assert_close(jacobian, expected, atol=1e-18, what="straight Jacobian")


def test_jacobian_is_the_time_derivative_of_the_pose(rng, two_segment_model):
    model = two_segment_model
    h = 1e-6
    for _ in range(5):
        q, qd = random_state(rng, model)
        for s in (0.2, 0.5, 0.77, 1.0):
            twist = model.jacobian(q, s) @ qd
            plus, minus = model.pose(q + h * qd, s), model.pose(q - h * qd, s)
            velocity = (plus.position - minus.position) / (2 * h)
            rotation_rate = (plus.rotation - minus.rotation) / (2 * h)
            omega_hat = rotation_rate @ model.pose(q, s).rotation.T
            omega = np.array([omega_hat[2, 1], omega_hat[0, 2], omega_hat[1, 0]])
            scale = np.linalg.norm(twist)
            assert_close(twist[:3], velocity, rtol=1e-7, scale=scale, what="linear")
            assert_close(twist[3:], omega, rtol=1e-7, scale=scale, what="angular")


def test_body_twist_is_the_twist_in_the_local_frame(paper_model, rng):
    q, qd = random_state(rng, paper_model)
    rotation, _ = paper_model.pose(q, 0.6)
    world = paper_model.jacobian(q, 0.6) @ qd
    body = paper_model.body_twist(q, qd, 0.6)
    assert_close(rotation @ body[:3], world[:3], rtol=1e-14, scale=np.linalg.norm(world))
    assert_close(rotation @ body[3:], world[3:], rtol=1e-14, scale=np.linalg.norm(world))


def test_two_equal_segments_make_one_of_double_length(two_segment_model, paper_model):
    model, single = two_segment_model, paper_model
    for kx, ky in [(20.0, -5.0), (0.0, 0.0), (1e-8, 0.0)]:
        tip2 = model.tip_pose([0.06, kx, ky, 0.06, kx, ky])
        tip1 = single.tip_pose([0.12, kx, ky])
        assert_close(tip2.position, tip1.position, rtol=1e-14, scale=0.12, what="position")
        assert_close(tip2.rotation, tip1.rotation, atol=1e-14, what="rotation")
        middle = model.pose([0.06, kx, ky, 0.06, kx, ky], 0.5)
        assert_close(middle.position, single.pose([0.12, kx, ky], 0.5).position, atol=1e-16)


def test_backbone_runs_from_base_to_tip(paper_model):
    q = np.array([0.064, 25.0, 0.0])
    points = paper_model.backbone(q, 21)
    assert points.shape == (21, 3)
    np.testing.assert_array_equal(points[0], 0.0)
    assert_close(points[-1], paper_model.tip_pose(q).position, rtol=1e-15)
    arc = np.sum(np.linalg.norm(np.diff(paper_model.backbone(q, 400), axis=0), axis=1))
    assert arc == pytest.approx(0.064, rel=1e-5)  # chord sum converges to the arc length


def test_base_rotation_turns_the_whole_robot(paper_model):
    upside_down = np.diag([1.0, -1.0, -1.0])
    robot = sc.presets.ifac2020().replace(base_rotation=upside_down)
    hanging, upright = sc.Model(robot), paper_model  # same structure: same compiled library
    q = [0.064, 12.0, 3.0]
    assert_close(
        hanging.tip_pose(q).position, upside_down @ upright.tip_pose(q).position, atol=1e-16
    )
