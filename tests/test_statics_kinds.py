"""The statics on robots of every kind: the multi-start search of equilibria samples each
element's own box, classifies what it finds and refuses roots outside a strain's domain;
linearize gives the modes of a six-strain robot."""

from __future__ import annotations

import numpy as np
import pytest

import softcurve as sc
from softcurve.analysis.statics import default_bounds, planar_pairs, rotate_about_axis

from .conftest import assert_close
from .test_kinds import robots, six_strain_segment

TIP_FORCE = [0.05, 0.02, -0.1]
"""[N]: bends, stretches and shears the six-strain segment, well inside its domain."""


@pytest.fixture(scope="module")
def strain_model():
    return sc.Model(sc.Robot(segments=(six_strain_segment(),)))


def test_each_element_has_its_own_search_box():
    robot = robots()["mixed"]
    bounds = default_bounds(robot)
    assert bounds.shape == (robot.n, 2) and np.all(bounds[:, 1] > bounds[:, 0])
    for segment, offset, size in zip(robot.segments, robot.offsets, robot.sizes, strict=True):
        box = bounds[offset : offset + size]
        np.testing.assert_array_equal(box, segment.search_bounds())
        rest = segment.rest_configuration()
        assert np.all((box[:, 0] <= rest) & (rest <= box[:, 1]))
        assert segment.inside(box.mean(axis=1))


def test_equilibria_of_a_six_strain_robot_under_gravity_and_a_tip_load(strain_model):
    """Before, the search built a box of three rows per element and stopped with a shape
    error."""
    table = sc.equilibria(strain_model, starts=6, tip_force=TIP_FORCE)
    assert table.status is sc.Status.SUCCESS and len(table) == 1
    e = table[0]
    assert e.success and e.stability == "stable" and e.continuum is None
    assert np.all(e.eigenvalues > 0)
    residual = sc.equilibrium(strain_model, e.q, tip_force=TIP_FORCE)
    np.testing.assert_allclose(residual.q, e.q, rtol=0, atol=1e-9)
    twist_free = abs(e.q[sc.STRAINS.index("twist")]) < 1e-9  # no moment about the axis
    bent = np.hypot(*e.q[:2]) > 0.1  # [1/m]
    sheared = np.hypot(*e.q[3:5]) > 1e-4
    assert twist_free and bent and sheared and e.q[5] < 1.0  # compressed by the loads

    lin = sc.linearize(strain_model, e.q, tip_force=TIP_FORCE)
    assert lin.success and lin.asymptotically_stable
    assert lin.frequencies.size == strain_model.n and np.all(lin.frequencies > 0)


@pytest.mark.parametrize(("force", "strain"), [(5000.0, "stretch"), (-500.0, "stretch")])
def test_a_root_outside_a_strains_domain_is_never_success(strain_model, force, strain):
    e = sc.equilibrium(strain_model, strain_model.robot.rest_configuration(),
                       tip_force=[0.0, 0.0, force])  # fmt: skip
    assert e.status is sc.Status.LEFT_DOMAIN and not e.success
    assert strain in e.message
    table = sc.equilibria(strain_model, starts=4, tip_force=[0.0, 0.0, force])
    assert not table.success and len(table) == 0


def test_a_buckled_six_strain_robot_has_a_stable_ring_and_a_saddle(strain_model):
    """Under a compressive tip load beyond Euler's (about 2 N here) the straight column
    is a saddle and the bent ones form a ring about the axis: the strain segment turns
    with the robot by its bending and shear pairs."""
    load = {"tip_force": [0.0, 0.0, -4.0]}
    table = sc.equilibria(strain_model, starts=12, **load)
    assert [(e.stability, e.continuum) for e in table] == [("stable", "ring"), ("saddle", None)]
    ring = table[0]
    bend_x, bend_y = ring.q[:2]
    assert bend_x == 0.0 and bend_y > 0 and ring.q[3] > 0 and ring.q[4] == 0.0  # toward +x
    assert ring.eigenvalues.size == strain_model.n - 1  # the ring's direction left out
    u, v = ring.q[:3], ring.q[3:]  # the backbone's curvature, |p' x p''| / |p'|^3
    curvature = np.linalg.norm(np.cross(v, np.cross(u, v))) / np.linalg.norm(v) ** 3
    assert_close(ring.curvature, [curvature], rtol=1e-14)
    for angle in (0.7, 2.5):  # every turned member is the same ring
        member = rotate_about_axis(ring.q, angle, strain_model.robot)
        assert_close(np.hypot(*member[:2]), bend_y, rtol=1e-14)
        again = sc.equilibrium(strain_model, member, **load)
        assert again.continuum == "ring"
        assert_close(again.q, ring.q, atol=1e-9, scale=np.abs(ring.q) + 1e-3)


def test_every_kind_turns_about_the_axis_or_says_it_cannot():
    robot = robots()["mixed"]
    pairs = planar_pairs(robot)
    names = robot.coordinate_names()
    turned = [(names[int(i)], names[int(j)]) for i, j, *_ in pairs]
    assert turned == [
        ("segments[0].bend_x", "segments[0].bend_y"),
        ("segments[2].kx", "segments[2].ky"),
    ]
    half = six_strain_segment(
        strains=("bend_x", "twist", "stretch"), shear_stiffness=None, damping=False
    )
    lopsided = sc.Robot(segments=(half,))
    assert planar_pairs(lopsided) is None
    with pytest.raises(sc.ParameterError, match="cannot be turned about its axis"):
        rotate_about_axis(lopsided.rest_configuration(), 1.0, lopsided)
