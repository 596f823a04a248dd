"""Tendons and bellows along every element kind: the offset fiber of a constant-strain
segment (a helix when it twists, leaning when it shears), straight through a rigid body,
against the constant-curvature closed form and an independent integral along the model's
pose; the input map as the gradient of the fibers' lengths; equilibria and a simulation of a
tendon-driven six-strain robot; the fiber's domain.

Tolerances: the reduction to constant curvature is the same number computed two ways
(1e-15 relative); the integral along the pose uses central differences of step 1e-5 in
``s`` on a curve of curvature up to 40 1/m (truncation ~1e-10 relative, round-off
~1e-11), asserted 1e-8; the closed-form gradient against CasADi's derivative of the
length (1e-12) and against central differences (1e-7, step 1e-6 on strains of order 1);
equilibria to the solver's tolerance (1e-9 on strains of order 1 to 50).
"""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.base.status import Status
from softcurve.description.domain import checked_status, state_problem
from softcurve.description.fibers import (
    offset_fiber_gradient,
    offset_fiber_length,
    offset_fiber_turn,
)
from softcurve.scenarios.actuation import from_mapping

from .test_kinds import six_strain_segment

RHO = 0.008  # [m], inside the 1 cm radius of six_strain_segment


def link():
    """A rigid link 2 cm long, tilted and offset, wide enough for the tendons."""
    c, s = np.cos(0.3), np.sin(0.3)
    return sc.RigidBody(
        mass=0.01,
        tip_position=[0.002, -0.001, 0.02],
        tip_rotation=[[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]],
        inertia=[1e-6, 1e-6, 5e-7],
        radius=0.012,
    )


def mixed_robot():
    """A six-strain segment, a rigid link, another six-strain segment (gravity on)."""
    return sc.Robot(segments=(six_strain_segment(damping=False), link(), six_strain_segment()))


def twisted_state(robot, rng):
    """Strains with bending, twist, shear and stretch all well away from zero."""
    q = robot.rest_configuration()
    return q + rng.uniform(-1, 1, q.size) * np.tile([20.0, 20.0, 15.0, 0.1, 0.1, 0.1], 2)


def test_the_fiber_of_a_strain_segment_is_the_constant_curvature_formula(rng):
    """The strains (bend x, bend y, stretch) at ``u = sigma (-ky, kx, 0)``, ``v = (0, 0,
    sigma)``: ``L0 |v + u x r|`` equals ``l (1 - rho k_phi)``, its gradient maps by the
    chain rule, and the wrap angle is the bending angle."""
    l0 = 0.1
    full = six_strain_segment()
    segment = sc.StrainSegment(
        rest_length=l0,
        mass=0.03,
        radius=0.01,
        strains=("bend_x", "bend_y", "stretch"),
        bending_stiffness=full.bending_stiffness,
        stretch_stiffness=full.stretch_stiffness,
    )
    for _ in range(20):
        length, kx, ky = l0 * rng.uniform(0.5, 1.5), *rng.uniform(-30, 30, 2)
        phi, rho = rng.uniform(-np.pi, np.pi), rng.uniform(0.0, 0.01)
        sigma = length / l0
        strains = ca.DM([-sigma * ky, sigma * kx, sigma])
        cc = ca.DM([length, kx, ky])
        ours = float(offset_fiber_length(strains, 0, phi, rho, element=segment, offset=0))
        closed = float(offset_fiber_length(cc, 0, phi, rho))
        assert ours == pytest.approx(closed, rel=1e-15, abs=1e-18)
        assert closed == pytest.approx(length * (1 - rho * (kx * np.cos(phi) + ky * np.sin(phi))))
        turn = float(offset_fiber_turn(strains, 0, phi, rho, element=segment, offset=0))
        assert turn == pytest.approx(length**2 * (kx**2 + ky**2), rel=1e-13)
        # chain rule: dL/d(l, kx, ky) = dL/d(ux, uy, vz) d(ux, uy, vz)/d(l, kx, ky)
        g = np.array(ca.DM(ca.vertcat(*offset_fiber_gradient(strains, 0, phi, rho, segment, 0))))
        g = g.ravel()
        mapped = [
            (g[0] * -ky + g[1] * kx + g[2]) / l0,
            g[1] * sigma,
            -g[0] * sigma,
        ]
        expected = np.array(ca.DM(ca.vertcat(*offset_fiber_gradient(cc, 0, phi, rho)))).ravel()
        np.testing.assert_allclose(mapped, expected, rtol=1e-13, atol=1e-16)


def _integral_along_pose(model, q, element, count, r, h=1e-5, nodes=8):
    """``int |d/dX (p + R r)| dX`` over element ``element`` of ``count``, by Gauss-Legendre
    nodes in ``s`` and central differences of the model's world pose."""
    x, w = np.polynomial.legendre.leggauss(nodes)
    a, b = element / count, (element + 1) / count
    total = 0.0
    for xi, wi in zip(x, w, strict=True):
        s = a + (b - a) * (xi + 1) / 2
        plus, minus = model.pose(q, s + h), model.pose(q, s - h)
        rate = (plus.position + plus.rotation @ r - minus.position - minus.rotation @ r) / (2 * h)
        total += wi * (b - a) / 2 * np.linalg.norm(rate)
    return total


def test_fiber_lengths_match_an_integral_along_the_twisted_sheared_pose(rng):
    robot = mixed_robot()
    model = sc.Model(robot, compile=False)
    tendons = [sc.Tendon(phi, RHO, 10.0, anchor=2) for phi in (0.4, 2.5, -1.9)]
    actuator = sc.TendonActuator(tendons, elements=robot)
    for _ in range(3):
        q = twisted_state(robot, rng)
        pieces = actuator.segment_lengths_symbolic(ca.DM(q))
        for tendon, lengths in zip(tendons, pieces, strict=True):
            r = RHO * np.array([np.cos(tendon.azimuth), np.sin(tendon.azimuth), 0.0])
            for j in (0, 2):  # the soft segments
                expected = _integral_along_pose(model, q, j, 3, r)
                assert float(lengths[j]) == pytest.approx(expected, rel=1e-8)
            # through the rigid link: straight from hole to hole
            base, tip = model.pose(q, 1 / 3), model.pose(q, 2 / 3)
            chord = tip.position + tip.rotation @ r - base.position - base.rotation @ r
            assert float(lengths[1]) == pytest.approx(np.linalg.norm(chord), rel=1e-12)
        total = actuator.tendon_lengths(q)
        np.testing.assert_allclose(total, [float(sum(p)) for p in pieces], rtol=1e-15)


@pytest.mark.parametrize("kind", ["tendons", "bellows"])
def test_the_input_map_is_the_gradient_of_the_work(rng, kind):
    """``H = -dL/dq`` per unit tension, ``A dL/dq`` per unit pressure, against CasADi's
    derivative of the fibers' lengths and central differences of the numeric lengths;
    the input work's gradient is ``H u``."""
    robot = mixed_robot()
    if kind == "tendons":
        actuator = sc.TendonActuator.three_per_segment(distance=RHO, t_max=5.0, elements=robot)
        sign, lengths = -1.0, actuator.tendon_lengths
    else:
        actuator = sc.PneumaticActuator.three_bellows(
            distance=RHO, area=2e-5, p_max=1e5, elements=robot
        )
        sign = 2e-5

        def lengths(q):
            return actuator.volumes(q) / 2e-5

    assert actuator.n == robot.n == 12
    q_sym = ca.SX.sym("q", robot.n)
    autodiff = ca.Function(
        "J", [q_sym], [ca.jacobian(actuator.fiber_lengths_symbolic(q_sym), q_sym)]
    )
    u = rng.uniform(0, 1, actuator.n_inputs) * actuator.upper
    work = ca.Function("W", [q_sym], [ca.gradient(actuator.input_work_symbolic(q_sym, u), q_sym)])
    for _ in range(3):
        q = twisted_state(robot, rng)
        h = actuator.input_matrix(q)
        np.testing.assert_allclose(h, sign * np.array(autodiff(q)).T, rtol=1e-12, atol=1e-16)
        step = 1e-6
        differences = np.array(
            [(lengths(q + step * e) - lengths(q - step * e)) / (2 * step) for e in np.eye(robot.n)]
        )
        np.testing.assert_allclose(h, sign * differences, rtol=1e-7, atol=1e-10 * abs(sign))
        np.testing.assert_allclose(np.array(work(q)).ravel(), h @ u, rtol=1e-12, atol=1e-16)
        assert np.all(h[6:12, : actuator.n_inputs // 2] == 0)  # proximal: no distal force


def test_one_tendon_bends_a_six_strain_segment_by_t_rho_over_ei():
    """A tendon at +y pulled with T: bend_x = -T rho / EI, stretch 1 - T / EA, no twist
    and no shear (the fiber stays straight along the section normal)."""
    segment = six_strain_segment(damping=False)
    robot = sc.Robot(segments=(segment,), gravity=[0.0, 0.0, 0.0])
    actuator = sc.TendonActuator([sc.Tendon(np.pi / 2, RHO, 20.0)], elements=robot)
    e = sc.equilibrium(
        sc.Model(robot, compile=False), robot.rest_configuration(), actuator=actuator, inputs=[5.0]
    )
    assert e.status is Status.SUCCESS and e.stability == "stable"
    bending, stretch = segment.bending_stiffness.k0, segment.stretch_stiffness.k0
    expected = [-5.0 * RHO / bending, 0, 0, 0, 0, 1 - 5.0 / stretch]
    np.testing.assert_allclose(e.q, expected, rtol=1e-12, atol=1e-12)
    assert e.tip_position[1] > 0  # toward the tendon


def test_equilibria_of_a_tendon_driven_six_strain_robot_with_a_rigid_link():
    """Tendons through a rigid link between two six-strain segments under gravity and an
    out-of-plane tip load: SUCCESS and stable; the stationarity checked against the
    model's own forces; the distal tendon twists the robot under the side load."""
    robot = mixed_robot()
    model = sc.Model(robot, compile=False)
    actuator = sc.TendonActuator.three_per_segment(distance=RHO, t_max=20.0, elements=robot)
    assert [t.anchor for t in actuator.tendons] == [0, 0, 0, 2, 2, 2]
    tensions, force = np.array([3.0, 0, 0, 0, 1.0, 0]), np.array([0.0, 0.3, 0.0])
    e = sc.equilibrium(
        model, robot.rest_configuration(), actuator=actuator, inputs=tensions, tip_force=force
    )
    assert e.status is Status.SUCCESS, e.message
    assert e.stability == "stable"
    jacobian = model.jacobian(e.q, 1.0)[:3]
    balance = (
        actuator.input_matrix(e.q) @ tensions
        + jacobian.T @ force
        - model.gravity_force(e.q)
        - model.elastic_force(e.q)
    )
    scale = np.abs(model.elastic_force(e.q)) + np.abs(actuator.input_matrix(e.q) @ tensions)
    assert np.all(np.abs(balance) <= 1e-9 * scale.max())
    assert abs(e.q[2]) > 0.5 and abs(e.q[8]) > 0.01  # twist [1/m] in both segments
    no_load = sc.equilibrium(model, e.q, actuator=actuator, inputs=tensions)
    assert no_load.success and no_load.stability == "stable"


def test_a_folded_fiber_leaves_the_domain():
    """A tendon pulled until the fiber folds through its section (``L0 (v + u x r)_z <=
    0``, for constant curvature: tendon length <= 0) is outside the domain: never SUCCESS
    but LEFT_DOMAIN, naming the tendon and the segment."""
    segment = six_strain_segment(damping=False, rest_length=0.02, mass=0.007)
    robot = sc.Robot(segments=(segment,), gravity=[0.0, 0.0, 0.0])
    actuator = sc.TendonActuator([sc.Tendon(np.pi / 2, RHO, 500.0)], elements=robot)
    inside = np.array([-100.0, 0, 0, 0, 0, 0.9])  # rho |u_x| = 0.8 < 0.9: inside
    folded = np.array([-120.0, 0, 0, 0, 0, 0.9])  # 0.96 > 0.9: folded
    assert actuator.in_domain(np.stack([inside, folded])).tolist() == [True, False]
    assert robot.inside(folded)  # the robot alone: in its domain (bends 2.4 rad)
    assert state_problem(robot, inside, actuator) is None
    status, message = checked_status(robot, folded, actuator, Status.SUCCESS, "converged")
    assert status is Status.LEFT_DOMAIN
    assert "tendons[0] in segment 1" in message and "allowed > 0" in message
    assert actuator.tendon_lengths(folded)[0] > 0  # a length, yet folded: the domain's rule


def test_bellows_on_a_six_strain_segment_and_not_in_a_rigid_body():
    """A pressure p in a chamber of area A at -y: bend_x = -p A rho / EI (away from it),
    stretch 1 + p A / EA; chambers lie in soft segments only."""
    segment = six_strain_segment(damping=False)
    robot = sc.Robot(segments=(segment,), gravity=[0.0, 0.0, 0.0])
    area, p = 2e-5, 5e4
    actuator = sc.PneumaticActuator([sc.Bellows(-np.pi / 2, RHO, area, 1e5)], elements=robot)
    e = sc.equilibrium(
        sc.Model(robot, compile=False), robot.rest_configuration(), actuator=actuator, inputs=[p]
    )
    assert e.status is Status.SUCCESS and e.stability == "stable"
    force = p * area
    bending, stretch = segment.bending_stiffness.k0, segment.stretch_stiffness.k0
    np.testing.assert_allclose(
        e.q, [-force * RHO / bending, 0, 0, 0, 0, 1 + force / stretch], rtol=1e-12, atol=1e-12
    )
    assert actuator.volumes(e.q)[0] == pytest.approx(
        area
        * 0.1
        * (1 + force / stretch)
        * (1 + RHO * force * RHO / bending / (1 + force / stretch))
    )
    with pytest.raises(sc.ParameterError, match=r"bellows\[0\].*RigidBody.*soft segment"):
        sc.PneumaticActuator(
            [sc.Bellows(0.0, RHO, area, 1e5, segments=(1,))], elements=mixed_robot()
        )
    three = sc.PneumaticActuator.three_bellows(
        distance=RHO, area=area, p_max=1e5, elements=mixed_robot()
    )
    assert sorted({b.segments for b in three.bellows}) == [(0,), (2,)]


def test_an_actuator_must_know_the_robot_it_drives():
    """Built without elements it drives constant-curvature segments only; built with
    elements, those of the robot."""
    robot = mixed_robot()
    plain = sc.TendonActuator([sc.Tendon(0.0, RHO, 5.0)], n_segments=4)  # n = 12 too
    with pytest.raises(sc.ParameterError, match="elements=robot"):
        plain.check_robot(robot)
    other = sc.Robot(segments=(six_strain_segment(rest_length=0.12), link(), six_strain_segment()))
    moved = sc.TendonActuator([sc.Tendon(0.0, RHO, 5.0)], elements=other)
    with pytest.raises(sc.ParameterError, match=r"elements\[0\]\.rest_length"):
        moved.check_robot(robot)
    with pytest.raises(sc.ParameterError, match="n_segments = 2 differs"):
        sc.TendonActuator([sc.Tendon(0.0, RHO, 5.0)], n_segments=2, elements=robot)
    narrow = sc.Robot(segments=(six_strain_segment(), link().replace(radius=0.005)))
    with pytest.raises(sc.ParameterError, match=r"segment 2 has radius 0.005 m \(RigidBody"):
        sc.TendonActuator([sc.Tendon(0.0, RHO, 5.0, anchor=1)], elements=narrow).check_robot(narrow)
    sc.TendonActuator([sc.Tendon(0.0, RHO, 5.0, anchor=1)], elements=robot).check_robot(robot)


def test_friction_turns_with_the_helix_of_a_twisted_segment():
    """Pure twist winds the fiber into a helix of radius rho and curvature ``rho uz^2 /
    (1 + (rho uz)^2)`` over the arc length ``L0 sqrt(1 + (rho uz)^2)``: the capstan law
    sees the turn ``L0 rho uz^2 / sqrt(1 + (rho uz)^2)``; a rigid link turns it not at
    all, so the tension leaving the link is the tension entering it."""
    robot = mixed_robot()
    mu, twist = 0.3, 30.0  # [-], [1/m]
    tendon = sc.Tendon(0.7, RHO, 10.0, anchor=2, friction=mu)
    actuator = sc.TendonActuator([tendon], elements=robot)
    q = robot.rest_configuration()
    q[2] = twist
    factors = [float(f) for f in actuator.tension_factors_symbolic(ca.DM(q))[0]]
    turn = 0.1 * RHO * twist**2 / np.sqrt(1 + (RHO * twist) ** 2)
    smoothed = np.sqrt(turn**2 + tendon.wrap_smoothing**2) - tendon.wrap_smoothing
    assert factors[0] == pytest.approx(-np.expm1(-mu * smoothed) / (mu * smoothed), rel=1e-12)
    assert factors[1] == pytest.approx(np.exp(-mu * smoothed), rel=1e-12)  # the link: mean 1
    assert factors[2] == pytest.approx(np.exp(-mu * smoothed), rel=1e-12)  # straight segment


def test_scenario_tables_run_along_the_robots_elements():
    """``[actuation]`` read against a robot of other elements: three tendons or bellows
    per soft segment, or an explicit list whose anchors count the rigid link."""
    robot = mixed_robot()
    tendons = from_mapping({"kind": "tendons", "distance": RHO, "t_max": 5.0}, robot=robot)
    assert tendons.n == 12 and [t.anchor for t in tendons.tendons] == [0, 0, 0, 2, 2, 2]
    tendons.check_robot(robot)
    listed = from_mapping(
        {"tendons": [{"azimuth": 0.0, "distance": RHO, "t_max": 5.0, "anchor": 1}]}, robot=robot
    )
    assert listed.elements == robot.segments
    bellows = from_mapping({"distance": RHO, "area": 2e-5, "p_max": 1e5}, robot=robot)
    assert bellows.n_inputs == 6 and bellows.elements == robot.segments
    with pytest.raises(sc.ParameterError, match=r"actuation: bellows\[0\].*RigidBody"):
        from_mapping(
            {"bellows": [{"azimuth": 0.0, "distance": RHO, "area": 2e-5, "p_max": 1e5,
                          "segments": [1]}]},
            robot=robot,
        )  # fmt: skip


def test_a_tendon_driven_six_strain_robot_simulates():
    """Constant tensions on the robot with a rigid link (CasADi's CVODES): it runs, the
    pulled tendons shorten, and every output lies in the fibers' domain (checked at the
    outputs)."""
    robot = mixed_robot()
    actuator = sc.TendonActuator.three_per_segment(distance=RHO, t_max=5.0, elements=robot)
    run = sc.simulate(
        sc.Model(robot, compile=False),
        robot.rest_configuration(),
        np.zeros(robot.n),
        actuator=actuator,
        inputs=[1.0, 0, 0, 0, 0.5, 0],
        settings=sc.SimulationSettings(t_final=0.05),
    )
    assert run.status is Status.SUCCESS, run.message
    start, end = actuator.tendon_lengths(run.q[0]), actuator.tendon_lengths(run.q[-1])
    assert end[0] < start[0] and end[4] < start[4]
    assert np.all(actuator.in_domain(run.q))
