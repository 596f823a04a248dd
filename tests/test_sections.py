"""A rod's material and cross-section (``softcurve.description.sections``): the closed
forms of circles and tubes, Cowper's shear coefficients, the shear modulus from Poisson's
ratio, the stiffness in the strain order, the map to the paper's constant-curvature
stiffness, and every bad input refused with its field, value and range."""

from __future__ import annotations

import dataclasses
import math
import re

import numpy as np
import pytest

import softcurve as sc
from softcurve.base.validation import ParameterError
from softcurve.description.sections import (
    CONSISTENCY_TOLERANCE,
    INCOMPRESSIBLE,
    Material,
    Section,
    SectionProperties,
    section_properties,
)

SILICONE = Material(youngs_modulus=1e6, density=1070.0, poisson_ratio=0.5)


# -- materials -------------------------------------------------------------------------------
def test_the_shear_modulus_follows_from_poissons_ratio():
    for nu in (-0.5, 0.0, 0.3, 0.5):
        material = Material(youngs_modulus=2e6, density=1000.0, poisson_ratio=nu)
        assert material.shear_modulus == 2e6 / (2 * (1 + nu))
        assert material.poisson_ratio == nu
    assert SILICONE.shear_modulus == pytest.approx(1e6 / 3, rel=1e-15)


def test_poissons_ratio_follows_from_the_shear_modulus():
    material = Material(youngs_modulus=54e9, density=6450.0, shear_modulus=20e9)
    assert material.poisson_ratio == pytest.approx(0.35, rel=1e-15)
    assert material.shear_modulus == 20e9
    # G = E / 3 is incompressible: nu is 0.5, never a rounding above it
    for e in (1e6, 7.0, 54e9, 0.1):
        assert Material(youngs_modulus=e, density=1.0, shear_modulus=e / 3).poisson_ratio <= 0.5


def test_a_material_is_its_own_repr_and_takes_both_moduli_when_they_agree():
    copy = eval(repr(SILICONE), {"Material": Material})  # both moduli, which agree
    assert copy == SILICONE
    given_g = Material(youngs_modulus=3e6, density=1100.0, shear_modulus=1.1e6)
    assert eval(repr(given_g), {"Material": Material}) == given_g


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"youngs_modulus": 0.0}, r"youngs_modulus \[Pa\] must be > 0, got 0.0"),
        ({"youngs_modulus": -1e6}, r"youngs_modulus \[Pa\] must be > 0, got -1000000.0"),
        ({"youngs_modulus": math.inf}, r"youngs_modulus \[Pa\] must be finite, got inf"),
        ({"youngs_modulus": "1e6"}, r"youngs_modulus \[Pa\] must be a real number, got '1e6'"),
        ({"density": 0}, r"density \[kg/m\^3\] must be > 0, got 0.0"),
        ({"density": math.nan}, r"density \[kg/m\^3\] must be finite, got nan"),
        ({"poisson_ratio": 0.6}, r"poisson_ratio \[-\] must be in \(-1, 0.5\].*got 0.6"),
        ({"poisson_ratio": -1.0}, r"poisson_ratio \[-\] must be in \(-1, 0.5\].*got -1.0"),
        ({"poisson_ratio": None, "shear_modulus": -1.0}, r"shear_modulus \[Pa\] must be > 0"),
        (
            {"poisson_ratio": None, "shear_modulus": 0.3e6},
            r"shear_modulus \[Pa\] must be >= youngs_modulus / 3 = 333333.33.*got 300000.0",
        ),
        (
            {"poisson_ratio": None},
            r"needs shear_modulus \[Pa\] or poisson_ratio \[-\], got neither",
        ),
        (
            {"shear_modulus": 0.4e6},
            r"shear_modulus \[Pa\] = 400000.0 and poisson_ratio \[-\] = 0.5 disagree: "
            r"E / \(2 \(1 \+ nu\)\) = 333333.33.*give one of them",
        ),
    ],
)
def test_a_bad_material_is_refused_naming_the_field_value_and_range(fields, message):
    arguments = {"youngs_modulus": 1e6, "density": 1070.0, "poisson_ratio": 0.5} | fields
    with pytest.raises(ParameterError, match=message):
        Material(**arguments)


def test_moduli_that_agree_to_round_off_are_accepted():
    g = 1e6 / 3 * (1 + CONSISTENCY_TOLERANCE / 10)
    assert Material(youngs_modulus=1e6, density=1.0, shear_modulus=g, poisson_ratio=0.5)
    with pytest.raises(ParameterError, match="disagree"):
        Material(youngs_modulus=1e6, density=1.0, shear_modulus=g * 1.001, poisson_ratio=0.5)


def test_replacing_one_modulus_needs_the_other_left_out():
    """A material holds both moduli; changing E alone leaves them disagreeing, and the
    message says to give one."""
    with pytest.raises(ParameterError, match="give one of them"):
        dataclasses.replace(SILICONE, youngs_modulus=2e6)
    stiffer = dataclasses.replace(SILICONE, youngs_modulus=2e6, shear_modulus=None)
    assert stiffer.shear_modulus == pytest.approx(2e6 / 3, rel=1e-15)


# -- sections --------------------------------------------------------------------------------
def test_a_circle_has_the_closed_forms():
    r = 0.01
    circle = Section.circle(r)
    assert circle.area == pytest.approx(math.pi * r**2, rel=1e-15)
    assert circle.second_moment == pytest.approx(math.pi * r**4 / 4, rel=1e-15)
    assert circle.polar_moment == pytest.approx(math.pi * r**4 / 2, rel=1e-15)
    assert circle.radius == r


def test_a_tube_has_the_closed_forms_and_without_a_hole_is_the_circle():
    a, b = 0.012, 0.008
    tube = Section.tube(a, b, poisson_ratio=0.3)
    assert tube.area == pytest.approx(math.pi * (a**2 - b**2), rel=1e-14)
    assert tube.second_moment == pytest.approx(math.pi * (a**4 - b**4) / 4, rel=1e-14)
    assert tube.polar_moment == pytest.approx(math.pi * (a**4 - b**4) / 2, rel=1e-14)
    assert tube.radius == a  # the outer radius, for contact and drawing
    for nu in (0.0, 0.3, 0.5):
        assert Section.tube(a, 0.0, poisson_ratio=nu) == Section.circle(a, poisson_ratio=nu)


def test_cowpers_shear_coefficients():
    """Cowper (1966), Table 1: a circle 6 (1 + nu) / (7 + 6 nu), a hollow circle
    6 (1 + nu) (1 + m^2)^2 / ((7 + 6 nu) (1 + m^2)^2 + (20 + 12 nu) m^2), m = b / a;
    the numbers written out from those formulas."""
    assert Section.circle(0.01, poisson_ratio=0.3).shear_coefficient == pytest.approx(
        7.8 / 8.8, rel=1e-15
    )  # 0.88636...
    assert Section.circle(0.01, poisson_ratio=0.5).shear_coefficient == pytest.approx(
        0.9, rel=1e-15
    )
    assert Section.circle(0.01).shear_coefficient == pytest.approx(0.9, rel=1e-15)
    assert INCOMPRESSIBLE == 0.5
    # m = 1/2: (1 + m^2)^2 = 25/16; nu = 0.3: 7.8 * 25/16 / (8.8 * 25/16 + 23.6 / 4)
    tube = Section.tube(0.02, 0.01, poisson_ratio=0.3)
    assert tube.shear_coefficient == pytest.approx(12.1875 / (13.75 + 5.9), rel=1e-15)
    # nu = 0.5: 9 * 25/16 / (10 * 25/16 + 26 / 4)
    tube = Section.tube(0.02, 0.01, poisson_ratio=0.5)
    assert tube.shear_coefficient == pytest.approx(14.0625 / (15.625 + 6.5), rel=1e-15)
    # a thin tube tends to 2 (1 + nu) / (4 + 3 nu): 0.5306 at nu = 0.3
    thin = Section.tube(1.0, 1.0 - 1e-9, poisson_ratio=0.3)
    assert thin.shear_coefficient == pytest.approx(2.6 / 4.9, rel=1e-8)


def test_a_general_section_keeps_its_constants_and_has_no_radius():
    side = 0.02  # a square: A = a^2, I = a^4 / 12, J = 0.1406 a^4 (Saint-Venant)
    square = Section(area=side**2, second_moment=side**4 / 12, polar_moment=0.1406 * side**4,
                     shear_coefficient=5 / 6)  # fmt: skip
    assert square.radius is None and square.shear_coefficient == 5 / 6
    properties = section_properties(SILICONE, square)
    # rotary inertia about z is the polar moment 2 I, not the torsion constant
    assert properties.slice_inertia == pytest.approx([side**2 / 12, side**2 / 12, side**2 / 6])
    assert properties.torsion == pytest.approx(SILICONE.shear_modulus * 0.1406 * side**4)


GOOD = {"area": 1e-4, "second_moment": 1e-9, "polar_moment": 2e-9, "shear_coefficient": 0.9}


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"area": 0.0}, r"area \[m\^2\] must be > 0, got 0.0"),
        ({"second_moment": -1e-9}, r"second_moment \[m\^4\] must be > 0, got -1e-09"),
        ({"polar_moment": math.inf}, r"polar_moment \[m\^4\] must be finite, got inf"),
        ({"shear_coefficient": 0.0}, r"shear_coefficient \[-\] must be > 0, got 0.0"),
        ({"shear_coefficient": 1.2}, r"shear_coefficient \[-\] must be in \(0, 1\], got 1.2"),
        (
            {"polar_moment": 3e-9},
            r"polar_moment \[m\^4\] must be <= 2 second_moment = 2e-09 .*got 3e-09",
        ),
        (
            {"area": 1e-3},  # ten times the area of GOOD: less I than a disk of that area
            r"second_moment \[m\^4\] must be >= area\^2 / \(4 pi\) = 7.957.*e-08 .*got 1e-09",
        ),
        ({"radius": 0.0}, r"radius \[m\] must be > 0, got 0.0"),
        ({"radius": "1 cm"}, r"radius \[m\] must be a real number, got '1 cm'"),
    ],
)
def test_a_bad_section_is_refused_naming_the_field_value_and_range(fields, message):
    with pytest.raises(ParameterError, match=message):
        Section(**(GOOD | fields))


@pytest.mark.parametrize(
    ("build", "message"),
    [
        (lambda: Section.circle(0.0), r"radius \[m\] must be > 0, got 0.0"),
        (lambda: Section.circle(-0.01), r"radius \[m\] must be > 0, got -0.01"),
        (
            lambda: Section.circle(0.01, poisson_ratio=0.7),
            r"poisson_ratio \[-\] must be in \(-1, 0.5\].*got 0.7",
        ),
        (lambda: Section.tube(0.0, 0.0), r"outer_radius \[m\] must be > 0, got 0.0"),
        (
            lambda: Section.tube(0.01, 0.01),
            r"inner_radius \[m\] must be in \[0, outer_radius\) = \[0, 0.01\), got 0.01",
        ),
        (
            lambda: Section.tube(0.01, -0.001),
            r"inner_radius \[m\] must be in \[0, outer_radius\) = \[0, 0.01\), got -0.001",
        ),
        (lambda: Section.tube(0.01, math.nan), r"inner_radius \[m\] must be finite, got nan"),
        (
            lambda: Section.tube(0.01, 0.005, poisson_ratio=-1.5),
            r"poisson_ratio \[-\] must be in \(-1, 0.5\].*got -1.5",
        ),
    ],
)
def test_a_bad_circle_or_tube_is_refused_naming_the_field_value_and_range(build, message):
    with pytest.raises(ParameterError, match=message):
        build()


def test_circles_and_tubes_pass_their_own_inequalities_at_every_size():
    """``J = 2 I`` and ``I = A^2 / (4 pi)`` hold with equality for a circle: round-off
    must not refuse it at any radius."""
    rng = np.random.default_rng(7)
    for r in 10.0 ** rng.uniform(-6, 2, size=200):
        Section.circle(float(r))
        Section.tube(float(r), float(r) * rng.uniform(0, 0.999))


# -- the properties per length ---------------------------------------------------------------
def test_the_properties_of_a_silicone_rod():
    """The worked example of docs/strains.md: r = 10 mm, E = 1 MPa, nu = 0.5,
    rho = 1070 kg/m^3."""
    rod = section_properties(SILICONE, Section.circle(0.01))
    area, second = math.pi * 1e-4, math.pi * 1e-8 / 4
    g = 1e6 / 3
    expected = [1e6 * second, 1e6 * second, g * 2 * second, 0.9 * g * area, 0.9 * g * area,
                1e6 * area]  # fmt: skip
    assert rod.stiffness == pytest.approx(expected, rel=1e-14)
    assert (rod.bending, rod.torsion, rod.shear, rod.stretch) == pytest.approx(
        (7.853981633974483e-3, 5.235987755982988e-3, 94.24777960769379, 314.1592653589793),
        rel=1e-14,
    )
    assert rod.mass_per_length == pytest.approx(1070 * area, rel=1e-15)
    assert rod.slice_inertia == pytest.approx(np.array([0.25, 0.25, 0.5]) * 1e-4, rel=1e-14)
    assert not rod.stiffness.flags.writeable and not rod.slice_inertia.flags.writeable


def test_the_slice_inertia_of_a_circle_is_the_segments_default_disk():
    """The default slice of a segment of radius r: r^2 (1/4, 1/4, 1/2) per unit mass."""
    for r in (0.001, 0.0235, 0.3):
        rod = section_properties(SILICONE, Section.circle(r))
        assert rod.slice_inertia == pytest.approx(r**2 * np.array([0.25, 0.25, 0.5]), rel=1e-14)


def test_the_constant_curvature_map_gives_the_tendon_robots_stiffness():
    """k_b = E I / L0 and k_e = E A / L0: the numbers of the preset rao2021 (a nitinol
    rod, E = 54 GPa, r = 0.7 mm, L0 = 0.2 m), which the preset takes from this map."""
    rod = section_properties(sc.presets.RAO2021_MATERIAL, sc.presets.RAO2021_SECTION)
    segment = sc.presets.rao2021().segments[0]
    assert rod.bending_angle_stiffness(0.2) == segment.bending_stiffness.k0
    assert rod.elongation_stiffness(0.2) == segment.elongation_stiffness.k0
    # ... and they are the closed forms, written out
    assert segment.bending_stiffness.k0 == pytest.approx(
        54e9 * math.pi * 0.7e-3**4 / 4 / 0.2, rel=1e-14
    )  # 0.050915 N m/rad
    assert segment.elongation_stiffness.k0 == pytest.approx(
        54e9 * math.pi * 0.7e-3**2 / 0.2, rel=1e-14
    )  # 4.16e5 N/m
    assert sc.presets.RAO2021_MATERIAL.shear_modulus == pytest.approx(54e9 / 2.6, rel=1e-15)
    assert rod.mass_per_length == pytest.approx(sc.presets.RAO2021_BACKBONE_DENSITY, rel=1e-14)


def test_the_constant_curvature_map_is_the_rods_energy():
    """``1/2 k_b beta^2 = 1/2 E I |u|^2 L0`` with ``|u| = beta / L0``, and
    ``1/2 k_e (l - L0)^2 = 1/2 E A (l / L0 - 1)^2 L0``."""
    rod = section_properties(SILICONE, Section.circle(0.02))
    rest, beta, length = 0.15, 1.3, 0.17
    assert 0.5 * rod.bending_angle_stiffness(rest) * beta**2 == pytest.approx(
        0.5 * rod.bending * (beta / rest) ** 2 * rest, rel=1e-14
    )
    assert 0.5 * rod.elongation_stiffness(rest) * (length - rest) ** 2 == pytest.approx(
        0.5 * rod.stretch * (length / rest - 1) ** 2 * rest, rel=1e-14
    )
    with pytest.raises(ParameterError, match=r"rest_length \[m\] must be > 0, got 0.0"):
        rod.bending_angle_stiffness(0.0)
    with pytest.raises(ParameterError, match=r"rest_length \[m\] must be > 0, got -1.0"):
        rod.elongation_stiffness(-1.0)


@pytest.mark.parametrize(
    ("fields", "message"),
    [
        ({"mass_per_length": 0.0}, r"mass_per_length \[kg/m\] must be > 0, got 0.0"),
        ({"slice_inertia": [1.0, 1.0]}, r"slice_inertia must have shape \(3,\), got \(2,\)"),
        ({"stiffness": [1, 1, 1, 1, 1, 0]}, r"stiffness must be > 0 in every entry"),
        ({"stiffness": [1, 1, 1, 1, 1, math.nan]}, r"stiffness must be finite"),
    ],
)
def test_bad_properties_are_refused(fields, message):
    good = {"mass_per_length": 1.0, "slice_inertia": [1, 1, 2], "stiffness": [1.0] * 6}
    with pytest.raises(ParameterError, match=message):
        SectionProperties(**(good | fields))


def test_the_facade_gives_the_names():
    assert sc.Material is Material and sc.Section is Section
    assert sc.SectionProperties is SectionProperties
    assert sc.section_properties is section_properties
    for name in ("Material", "Section", "SectionProperties", "section_properties"):
        assert name in sc.__all__


def test_values_are_immutable():
    with pytest.raises(dataclasses.FrozenInstanceError):
        SILICONE.youngs_modulus = 2e6  # type: ignore[misc]
    with pytest.raises(dataclasses.FrozenInstanceError):
        Section.circle(0.01).area = 1.0  # type: ignore[misc]
    assert re.search(r"poisson_ratio=0.5", repr(SILICONE))
