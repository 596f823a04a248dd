"""Contact along soft and rigid bodies: a gripper (a rigid body at the tip) resting on a
plane, a six-strain robot pressed on a sphere, and the start check for a rigid body.

The contact points are spread along every element by the kinematic chain (a rigid
body's on its base-to-tip segment, with its ``radius``), so none of this needs code of
its own; these tests check it against balances written out by hand.

Tolerances: the hanging robot's balance and the tip point's penalty force are the
solver's residual (1e-10 scaled) and round-off: asserted 1e-9 relative; the generalized
balance on the sphere 1e-9 of the largest force.
"""

from __future__ import annotations

import numpy as np
import pytest

import softcurve as sc
from softcurve.base.status import Status
from softcurve.symbolic.gaps import check_start, start_problem

from .test_kinds import six_strain_segment

G = 9.81  # [m/s^2]
GRIPPER_LENGTH = 0.03  # [m]


def hanging_robot():
    """A six-strain segment hanging from its base (gravity along +z) with a 50 g gripper
    3 cm long at its tip."""
    gripper = sc.RigidBody(mass=0.05, tip_position=[0.0, 0.0, GRIPPER_LENGTH])
    segment = six_strain_segment(damping=False)
    return sc.Robot(segments=(segment, gripper), gravity=[0.0, 0.0, G])


def test_a_gripper_resting_on_a_plane():
    """The gripper's tip rests on a plane below it. By symmetry only the stretch moves;
    its balance, written out by hand: ``EA (v_z - 1) = g (m_segment / 2 + m_gripper) -
    F`` with ``F`` the plane's force on the gripper's tip point, which is the law's
    ``w k h(x)^e`` at the point's penetration ``x`` (the gap), ``w = L_gripper / (2 K)``
    the trapezoidal end weight."""
    robot = hanging_robot()
    segment, gripper = robot.segments
    law = sc.ContactLaw(1e8)
    free_tip = segment.rest_length + GRIPPER_LENGTH
    plane = sc.Plane([0.0, 0.0, free_tip + gripper.radius - 2e-4], [0.0, 0.0, -1.0])
    model = sc.Model(robot, environment=sc.Environment([plane], law), compile=False)
    e = sc.equilibrium(model, robot.rest_configuration())
    assert e.status is Status.SUCCESS, e.message
    assert e.stability == "stable"
    np.testing.assert_allclose(e.q[:5], 0.0, atol=1e-12)
    stretch = e.q[5]
    tip = segment.rest_length * stretch + GRIPPER_LENGTH
    assert e.tip_position[2] == pytest.approx(tip, rel=1e-12)
    penetration = gripper.radius - (plane.point[2] - tip)  # the gap's complement [m]
    spacing = GRIPPER_LENGTH / law.points_per_segment
    assert law.smoothing < penetration < spacing - gripper.radius  # the tip point only
    weight = GRIPPER_LENGTH / (2 * law.points_per_segment)
    force = weight * law.stiffness * (penetration - law.smoothing / 2) ** law.exponent
    contact = model.contact(e.q)
    np.testing.assert_allclose(contact["forces"][0], [0.0, 0.0, -force], rtol=1e-9, atol=1e-15)
    assert contact["points"][0] == pytest.approx([0.0, 0.0, tip], abs=1e-12)
    carried = G * (segment.mass / 2 + gripper.mass)
    assert 0.2 * carried < force < carried  # the plane carries a real part of the weight
    elastic = segment.stretch_stiffness.k0 * (stretch - 1)
    assert elastic == pytest.approx(carried - force, rel=1e-9)


def test_a_six_strain_robot_pressed_on_a_sphere():
    """Two six-strain segments pushed sideways by a tip force onto a sphere beside their
    middle: SUCCESS and stable, the sphere pushes back (against the load), the backbone
    lies a contact radius from the sphere less a small penetration, and the generalized
    forces balance."""
    robot = sc.Robot(segments=(six_strain_segment(damping=False), six_strain_segment()))
    radius, contact_radius = 0.02, robot.segments[0].radius
    centre = np.array([0.035, 0.0, 0.1])
    law = sc.ContactLaw(1e8)
    model = sc.Model(
        robot, environment=sc.Environment([sc.Sphere(centre, radius)], law), compile=False
    )
    force = np.array([0.1, 0.03, 0.0])  # [N], world
    q = robot.rest_configuration()
    for fraction in (0.25, 0.5, 0.75, 1.0):  # the load in steps: the contact is stiff
        e = sc.equilibrium(model, q, tip_force=fraction * force)
        q = e.q
    assert e.status is Status.SUCCESS, e.message
    assert e.stability == "stable"
    contact = model.contact(e.q)
    assert contact["forces"][0, 0] < -0.05  # the sphere holds the robot back
    balance = (
        contact["generalized"]
        + model.jacobian(e.q, 1.0)[:3].T @ force
        - model.gravity_force(e.q)
        - model.elastic_force(e.q)
    )
    assert np.max(np.abs(balance)) <= 1e-9 * np.max(np.abs(model.elastic_force(e.q)))
    s = np.linspace(0.0, 1.0, 401)
    gaps = [np.linalg.norm(model.pose(e.q, x).position - centre) - radius for x in s]
    depth = contact_radius - min(gaps)
    assert 0 < depth < 1e-3  # pressed in, by less than a millimetre
    assert e.tip_position[1] > 1e-3  # a 3-D shape: the load's y part slides it along


def test_the_start_check_sees_a_rigid_body_inside_an_obstacle():
    """A gripper whose tip starts deep in a sphere is refused (naming the obstacle and
    the gripper's element); the same robot outside it is accepted (the squeeze-force test
    on a constant-strain segment and a rigid body)."""
    robot = hanging_robot()
    tip = robot.segments[0].rest_length + GRIPPER_LENGTH
    inside = sc.Environment([sc.Sphere([0.0, 0.0, tip], 0.01)], sc.ContactLaw(1e6))
    q = robot.rest_configuration()
    problem = start_problem(inside, robot, q)
    assert problem is not None
    assert "inside obstacle 0 (Sphere)" in problem and "(segment 2)" in problem
    with pytest.raises(sc.ParameterError, match="inside obstacle 0"):
        check_start(inside, robot, q)
    model = sc.Model(robot, environment=inside, compile=False)
    with pytest.raises(sc.ParameterError, match="inside obstacle 0"):
        sc.simulate(model, q, np.zeros(robot.n), settings=sc.SimulationSettings(t_final=0.01))
    beside = sc.Environment([sc.Sphere([0.05, 0.0, tip], 0.01)], sc.ContactLaw(1e6))
    assert start_problem(beside, robot, q) is None
