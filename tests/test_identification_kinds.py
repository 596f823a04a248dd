"""Identification on robots of every element kind: the output maps read each kind's
coordinates, a map meant for constant curvature is refused on another robot, and fits
of equilibria (marker positions under loads) and of a free motion (the tip's path)
recover the bending, twist and shear stiffness of a six-strain segment from noisy
data."""

from __future__ import annotations

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
from softcurve.identification.experiments._loading import Experiment
from softcurve.identification.fits._dynamic import fit_equilibria, fit_trajectory
from softcurve.identification.fits._parameters import Free
from softcurve.identification.maps import (
    InputMap,
    OutputMap,
    bending_angle_map,
    curvature_map,
    marker_position_map,
    tip_position_map,
)

from .test_kinds import robots, six_strain_segment

SEG = "segments[0]."


def _evaluate(output, model, q):
    q_s = ca.SX.sym("q", model.n)
    values = {k: ca.SX(v) for k, v in output.parameters.items()}
    y = output.function(q_s, ca.SX.zeros(model.n), values, ca.DM(model.parameters))
    return np.array(ca.Function("y", [q_s], [y])(q)).ravel()


def test_bending_angle_and_curvature_of_each_kind():
    """Of a constant-strain segment, beta = u_y L0 and (kx, ky) = (u_y, -u_x) / v_z: the
    constant-curvature segment's map ``u = sigma (-ky, kx, 0)``, ``v_z = sigma`` read
    back; of the mixed chain's constant-curvature segment (element 2, after a rigid
    link), its own coordinates wherever they are in q."""
    model = sc.Model(robots()["mixed"], compile=False)
    robot = model.robot
    q = robot.rest_configuration()
    q[:3] = [1.5, 2.0, 3.0]  # twisting segment: (twist, bend_y, bend_x) -> sorted
    q[3:] = [0.07, 4.0, -2.5]  # the paper's segment: l, kx, ky
    twisting = robot.segments[0]
    xi = twisting.full_strain(q[:3])
    beta = _evaluate(bending_angle_map(0, degrees=False, model=model), model, q)
    np.testing.assert_allclose(beta, twisting.rest_length * xi[1], rtol=1e-15)
    kx, ky = _evaluate(curvature_map(0, model=model), model, q)
    np.testing.assert_allclose([kx, ky], [xi[1] / xi[5], -xi[0] / xi[5]], rtol=1e-15)
    np.testing.assert_allclose(_evaluate(curvature_map(2, model=model), model, q), [4.0, -2.5])
    beta = _evaluate(bending_angle_map(2, degrees=False, model=model), model, q)
    np.testing.assert_allclose(beta, 0.07 * 4.0, rtol=1e-15)
    # the marker maps go through the pose: the gripper's tip is the robot's
    tip = _evaluate(tip_position_map(model), model, q)
    np.testing.assert_allclose(tip, model.pose(q, 1.0).position, atol=1e-15)
    with pytest.raises(sc.ParameterError, match="segment 1 is a rigid body"):
        curvature_map(1, model=model)
    only_twist = sc.Robot(segments=(six_strain_segment(strains=("twist",),
        bending_stiffness=None, shear_stiffness=None, stretch_stiffness=None,
        damping=None),))  # fmt: skip
    with pytest.raises(sc.ParameterError, match="does not bend about y"):
        bending_angle_map(0, model=sc.Model(only_twist, compile=False))


def test_a_constant_curvature_map_is_refused_on_another_robot():
    """Without model=, a map reads (l, kx, ky) at q[3 i]: a fit on a six-strain robot
    says so, before any work, instead of fitting other coordinates."""
    model = sc.Model(robots()["six strains"], compile=False)
    data = Experiment([0.0, 1.0], {"kx": [0.0, 0.0], "ky": [0.0, 0.0]}, {"f": [0.0, 0.0]})
    forces = InputMap(lambda q, u, values: ca.SX.zeros(model.n), {})
    with pytest.raises(sc.ParameterError, match="build the map with model="):
        fit_equilibria(model, data, output=curvature_map(), input_map=forces, free=[])
    with pytest.raises(sc.ParameterError, match="built for another robot"):
        other = sc.Model(robots()["mixed"], compile=False)
        output = curvature_map(model=other)
        fit_equilibria(model, data, output=output, input_map=forces, free=[])


def _short_thick_robot():
    """A short, thick silicone segment (4 cm, radius 1.5 cm, all six strains: shear a
    third of the bending deflection) carrying a rigid arm 4 cm to the side, so that a
    force at the arm's end bends, shears and twists the segment."""
    r, length, e = 0.015, 0.04, 1e6
    g, area, inertia = e / 3, np.pi * r**2, np.pi * r**4 / 4
    segment = six_strain_segment(
        rest_length=length,
        radius=r,
        mass=1070.0 * area * length,
        bending_stiffness=sc.LinearStiffness(e * inertia),
        torsion_stiffness=sc.LinearStiffness(g * 2 * inertia),
        shear_stiffness=sc.LinearStiffness(0.9 * g * area),
        stretch_stiffness=sc.LinearStiffness(e * area),
    )
    arm = sc.RigidBody(mass=0.01, tip_position=[0.04, 0.0, 0.02], inertia=[2e-6, 4e-6, 4e-6])
    return sc.Robot(segments=(segment, arm))


def _tip_force_map(model) -> InputMap:
    """Forces [N] at the arm's end, fixed in the world frame: ``tau = J(q)^T F``."""
    pose, parameters = model.symbolic["pose"], ca.DM(model.parameters)

    def function(q, u, values):
        return ca.jacobian(pose(q, 1.0, parameters)[1], q).T @ u

    return InputMap(function, {}, units=("N", "N", "N"))


def test_a_fit_of_equilibria_recovers_bending_twist_and_shear_stiffness():
    """Forty equilibria under forces of up to 1 N at the arm's end in random
    directions, the arm's end and the segment's tip seen by a motion-capture system
    with 0.01 mm of noise (seeded): the three stiffnesses come back within 3 % from
    starts 50 % off, each inside its 99 % interval."""
    robot = _short_thick_robot()
    model = sc.Model(robot)
    truth = {SEG + f"{law}.k0": getattr(robot.segments[0], law).k0
             for law in ("bending_stiffness", "torsion_stiffness", "shear_stiffness")}  # fmt: skip
    rng = np.random.default_rng(45)
    count = 40
    forces = rng.normal(size=(count, 3))
    forces *= rng.uniform(0.3, 1.0, size=(count, 1)) / np.linalg.norm(forces, axis=1)[:, None]
    t = np.arange(count, dtype=float)
    arm = tip_position_map(model, names=("ax", "ay", "az"))
    tip = marker_position_map(model, 0, 1.0, names=("sx", "sy", "sz"))
    both = OutputMap(
        lambda q, qd, values, p: ca.vertcat(
            arm.function(q, qd, values, p), tip.function(q, qd, values, p)
        ),
        arm.names + tip.names,
        arm.units + tip.units,
        {**arm.parameters, **tip.parameters},
    )
    names = both.names
    inputs = {f"F{a}": forces[:, k] for k, a in enumerate("xyz")}
    template = Experiment(t, {n: 0 * t for n in names}, inputs, units=dict.fromkeys(names, "m")
                          | dict.fromkeys(inputs, "N"))  # fmt: skip
    loads = _tip_force_map(model)
    clean = fit_equilibria(model, template, output=both, input_map=loads, free=[])
    assert clean.success, clean.message
    measured = clean.predicted + 1e-5 * rng.standard_normal(clean.predicted.shape)
    data = template.with_signals(**{n: measured[:, k] for k, n in enumerate(names)})
    free = [
        Free(name, 0.1 * value, 10 * value, initial=1.5 * value) for name, value in truth.items()
    ]
    report = fit_equilibria(model, data, output=both, input_map=loads, free=free,
                            confidence=0.99)  # fmt: skip
    assert report.success, report.message
    expected = np.array(list(truth.values()))
    np.testing.assert_allclose(report.values, expected, rtol=0.03)
    lo, hi = report.intervals.T
    assert np.all((lo <= expected) & (expected <= hi)), report.table()


@pytest.mark.slow  # compiles its own structures: in the slow study, under the CI budget
def test_a_fit_of_a_free_motion_recovers_bending_twist_and_shear_stiffness():
    """A six-strain segment carrying a gripper, released bent and twisted (0.8 rad and
    1 rad), its gripper's tip tracked for 0.3 s with 0.01 mm of noise (seeded): the
    trajectory fit recovers its three stiffnesses within 1 % from starts 30 % off, each
    inside its 95 % interval."""
    from .test_kinds import six_strain_gripper_robot, twisted

    robot = six_strain_gripper_robot()
    model = sc.Model(robot)
    x0 = np.concatenate([twisted(robot, twist=10.0, bend=8.0), np.zeros(robot.n)])
    t = np.linspace(0.0, 0.3, 151)
    output = tip_position_map(model)
    units = dict.fromkeys(output.names, "m")
    template = Experiment(t, {n: 0 * t for n in output.names}, units=units)
    clean = fit_trajectory(model, template, output=output, x0=x0, free=[])
    assert clean.success, clean.message
    rng = np.random.default_rng(1)
    measured = clean.predicted + 1e-5 * rng.standard_normal(clean.predicted.shape)
    data = template.with_signals(**{n: measured[:, k] for k, n in enumerate(output.names)})
    truth = {SEG + f"{law}.k0": getattr(robot.segments[0], law).k0
             for law in ("bending_stiffness", "torsion_stiffness", "shear_stiffness")}  # fmt: skip
    free = [
        Free(name, 0.1 * value, 10 * value, initial=1.3 * value) for name, value in truth.items()
    ]
    report = fit_trajectory(model, data, output=output, x0=x0, free=free)
    assert report.success, report.message
    expected = np.array(list(truth.values()))
    np.testing.assert_allclose(report.values, expected, rtol=0.01)
    lo, hi = report.intervals.T
    assert np.all((lo <= expected) & (expected <= hi)), report.table()
