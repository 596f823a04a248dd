"""The Cosserat rod reference of tests/cosserat_rod.py against closed forms, and its
piecewise-constant-strain companion against the rod."""

from __future__ import annotations

import numpy as np
import pytest
import scipy.integrate
import scipy.linalg
import scipy.optimize
import scipy.special
from scipy.spatial.transform import Rotation

from tests.cosserat_rod import (
    circle_rod,
    loaded_straight_rod,
    precurved_rod_under_gravity,
    rest_pose,
    se3_exp,
    segment_means,
    solve_pcs,
    solve_rod,
    strain_summary,
    twist_matrix,
)

from .conftest import assert_close

LENGTH = 0.5
EI, GJ, KGA, EA = 2.0, 1.5, 300.0, 800.0
"""A rod whose four stiffnesses differ, in N m^2 and N."""

STIFF = 1e8
"""kGA and EA [N] of the inextensible, unshearable limit: ``STIFF * L^2 / EI`` = 1.25e7,
so the axial and shear strains, ``F / STIFF``, move the tip by 2.4e-7 of ``L`` under the
elastica's load."""


def assert_rotations(solution, what):
    assert solution.orthonormality < 1e-10, f"{what}: rotation drift {solution.orthonormality}"


def test_pure_torsion_twists_by_tl_over_gj():
    torque = 4.0  # twists the rod by 1.33 rad: a large rotation
    sol = solve_rod(LENGTH, EI, GJ, KGA, EA, tip_moment=(0, 0, torque))
    angle = torque * LENGTH / GJ
    assert_close(
        sol.tip_rotation,
        Rotation.from_rotvec([0, 0, angle]).as_matrix(),
        rtol=0,
        atol=1e-11,
        what="tip rotation",
    )
    assert_close(sol.strains[:, 2], np.full(len(sol.s), torque / GJ), rtol=1e-12, what="twist")
    assert_close(sol.positions[:, 2], sol.s, rtol=1e-12, what="axis unmoved")
    assert_close(sol.positions[:, :2], 0, atol=1e-14, what="axis unmoved")
    assert_rotations(sol, "torsion")


@pytest.mark.parametrize("force", [50.0, -50.0])
def test_axial_load_stretches_by_fl_over_ea(force):
    sol = solve_rod(LENGTH, EI, GJ, KGA, EA, tip_force=(0, 0, force))
    assert_close(
        sol.tip_position, [0, 0, LENGTH * (1 + force / EA)], rtol=1e-12, atol=1e-15, what="tip"
    )
    assert_close(sol.strains[:, 5], 1 + force / EA, rtol=1e-12, what="stretch")


@pytest.mark.parametrize(
    ("load", "expected"),
    [
        # tip force P: F L^3 / (3 EI) + F L / kGA
        ("tip", lambda p: p * LENGTH**3 / (3 * EI) + p * LENGTH / KGA),
        # uniform weight w per length: w L^4 / (8 EI) + w L^2 / (2 kGA)
        ("weight", lambda w: w * LENGTH**4 / (8 * EI) + w * LENGTH**2 / (2 * KGA)),
    ],
)
def test_timoshenko_cantilever_in_the_small_load_limit(load, expected):
    """The relative error, the geometric nonlinearity, falls as the load squared."""
    errors = []
    for scale in (1e-2, 1e-3):
        p = scale * EI / LENGTH**2  # rotations of order `scale` rad
        keywords = (
            {"tip_force": (p, 0, 0)}
            if load == "tip"
            else {"mass_per_length": p, "gravity": (1.0, 0, 0)}
        )
        sol = solve_rod(LENGTH, EI, GJ, KGA, EA, **keywords)
        deflection = expected(p)
        errors.append(abs(sol.tip_position[0] - deflection) / deflection)
    assert errors[0] < 1e-4, errors
    assert errors[1] < errors[0] / 50, errors  # O(load^2): a hundredfold for tenfold


def test_precurved_rod_without_load_keeps_its_rest_shape():
    """A helix of rest curvature, twist, shear and stretch, from a turned and moved base."""
    rest = (3.0, -2.0, 5.0, 0.1, -0.05, 1.2)
    base_rotation = Rotation.from_rotvec([0.3, -0.7, 1.1]).as_matrix()
    base_position = (0.1, -0.2, 0.3)
    sol = solve_rod(
        LENGTH,
        EI,
        GJ,
        KGA,
        EA,
        rest_strain=rest,
        base_position=base_position,
        base_rotation=base_rotation,
        points=11,
    )
    for s, p, r in zip(sol.s, sol.positions, sol.rotations, strict=True):
        expected_r, expected_p = rest_pose(rest, s, base_position, base_rotation)
        # DOP853 at rtol 1e-12 over 3 rad of rotation: errors of a few 1e-12
        assert_close(p, expected_p, rtol=0, atol=1e-10 * LENGTH, what=f"position at {s}")
        assert_close(r, expected_r, rtol=0, atol=1e-10, what=f"rotation at {s}")
    assert_close(sol.strains, np.tile(rest, (len(sol.s), 1)), rtol=0, atol=1e-13, what="strains")
    assert_rotations(sol, "helix")


def test_closed_form_exponential_is_scipys():
    """On both sides of the series' switch, at zero angular strain and over several turns."""
    rng = np.random.default_rng(45)
    x = np.concatenate([[0.0], np.geomspace(1e-9, 20.0, 40)])
    for scale in (0.0, 1e-3, 1.0):
        xi = np.concatenate([scale * rng.standard_normal(3), rng.standard_normal(3)])
        expected = np.array([scipy.linalg.expm(s * twist_matrix(xi)) for s in x])
        assert_close(
            se3_exp(xi, x),
            expected,
            rtol=0,
            atol=1e-13 * (1 + x[:, None, None]),
            what=f"exp at |u| ~ {scale}",
        )


def test_pure_tip_moment_bends_into_a_circle_of_curvature_m_over_ei():
    """No force: an arc of 1.5 rad of curvature M / EI whatever kGA and EA."""
    moment = 1.5 * EI / LENGTH
    sol = solve_rod(LENGTH, EI, GJ, KGA, EA, tip_moment=(moment, 0, 0))
    radius = EI / moment
    angle = sol.s / radius
    # bending about x turns the backbone (z) towards -y
    expected = np.stack([0 * angle, -radius * (1 - np.cos(angle)), radius * np.sin(angle)], 1)
    assert_close(sol.positions, expected, rtol=0, atol=1e-10 * LENGTH, what="circle")
    assert_close(
        sol.tip_rotation,
        Rotation.from_rotvec([1.5, 0, 0]).as_matrix(),
        rtol=0,
        atol=1e-11,
        what="tip rotation",
    )


def elastica_tip(alpha: float):
    """Tip of the inextensible cantilever under a perpendicular dead tip load (Bisshopp
    and Drucker 1945), per length: ``(along the clamp's axis, along the load)`` and the
    tip angle [rad]; ``alpha = P L^2 / EI``.

    With ``theta`` the tangent's angle, ``EI theta'' = -P cos(theta)``, and
    ``1 + sin(theta) = 2 k^2 sin^2(phi)``: ``sqrt(alpha) = K(k) - F(phi1, k)``,
    ``sin(phi1) = 1 / (k sqrt 2)``; the deflection ``1 - 2 (E(k) - E(phi1, k)) /
    sqrt(alpha)``, the axial reach ``sqrt(2 sin(theta0) / alpha)``,
    ``sin(theta0) = 2 k^2 - 1``.
    """

    def phi1(k):
        return np.arcsin(1 / (k * np.sqrt(2)))

    def mismatch(k):
        m = k * k
        return scipy.special.ellipk(m) - scipy.special.ellipkinc(phi1(k), m) - np.sqrt(alpha)

    k = scipy.optimize.brentq(mismatch, 1 / np.sqrt(2) + 1e-15, 1 - 1e-15, xtol=1e-15)
    m = k * k
    e = scipy.special.ellipe(m) - scipy.special.ellipeinc(phi1(k), m)
    sin_theta0 = 2 * m - 1
    return np.sqrt(2 * sin_theta0 / alpha), 1 - 2 * e / np.sqrt(alpha), np.arcsin(sin_theta0)


def test_large_deflection_elastica_under_a_tip_force():
    """A tip angle of 0.99 rad: the reference with stiff kGA and EA meets the elastica
    (the position's error is the stretch and shear ``F / STIFF``, 2.4e-7 of ``L``; the
    tip angle does not depend on them)."""
    alpha = 3.0
    force = alpha * EI / LENGTH**2
    sol = solve_rod(LENGTH, EI, GJ, STIFF, STIFF, tip_force=(force, 0, 0))
    reach, deflection, angle = elastica_tip(alpha)
    assert 0.9 < angle < 1.0  # a large deflection
    assert_close(sol.tip_position / LENGTH, [deflection, 0, reach], rtol=0, atol=1e-6, what="tip")
    assert_close(
        sol.tip_rotation,
        Rotation.from_rotvec([0, angle, 0]).as_matrix(),
        rtol=0,
        atol=1e-10,
        what="tip rotation",
    )
    assert_rotations(sol, "elastica")


def test_base_moment_balances_the_loads_on_the_deformed_shape():
    """Global balance about the base: m(0) = M + (p(L) - p(0)) x F + int (p - p(0)) x f."""
    parameters, sol = precurved_rod_under_gravity(points=401)
    weight = parameters["mass_per_length"] * np.array(parameters["gravity"])
    arm = scipy.integrate.simpson(sol.positions, x=sol.s, axis=0)
    expected = np.cross(arm, weight)
    assert_close(
        sol.moments[0], expected, rtol=1e-9, scale=np.linalg.norm(expected), what="base moment"
    )
    assert_close(sol.forces[0], weight * parameters["length"], rtol=1e-14, what="base force")


def test_the_two_cases_strain_every_kind():
    """Every strain departs from rest in both cases (the figures of the report)."""
    for case in (loaded_straight_rod, precurved_rod_under_gravity):
        parameters, sol = case(points=51)
        change = strain_summary(sol, parameters.get("rest_strain", (0, 0, 0, 0, 0, 1)))
        assert np.all(change[:3] > 0.1), (case.__name__, change)  # [1/m]
        assert np.all(change[3:] > 1e-4), (case.__name__, change)  # [-]
        assert np.max(np.abs(sol.residual)) < 1e-12
        assert_rotations(sol, case.__name__)


def test_circle_rod_stiffnesses():
    rod = circle_rod(0.1, radius=0.01, youngs_modulus=1e6, poisson_ratio=0.5, density=1000)
    area, i = np.pi * 1e-4, np.pi * 1e-8 / 4
    assert_close(
        [rod["EI"], rod["GJ"], rod["kGA"], rod["EA"], rod["mass_per_length"]],
        [1e6 * i, 1e6 / 3 * 2 * i, 0.9 * 1e6 / 3 * area, 1e6 * area, 1000 * area],
        rtol=1e-14,
        what="stiffnesses",
    )


@pytest.mark.parametrize(
    "load",
    [
        {"tip_moment": (1.5 * EI / LENGTH, 0, 0)},
        {"tip_moment": (0, 0, 4.0)},
        {"tip_force": (0, 0, -50.0)},
    ],
    ids=["bending", "torsion", "compression"],
)
def test_one_constant_strain_segment_is_exact_under_uniform_strain(load):
    """Loads under which the rod's strain is uniform: one segment is the rod."""
    sol = solve_rod(LENGTH, EI, GJ, KGA, EA, **load)
    xi, rotation, position = solve_pcs(1, length=LENGTH, EI=EI, GJ=GJ, kGA=KGA, EA=EA, **load)
    assert_close(xi[0], sol.strains[0], rtol=0, atol=1e-10 * np.abs(sol.strains[0]).max())
    assert_close(position, sol.tip_position, rtol=0, atol=1e-11 * LENGTH, what="tip")
    assert_close(rotation, sol.tip_rotation, rtol=0, atol=1e-11, what="tip rotation")


@pytest.mark.parametrize("case", [loaded_straight_rod, precurved_rod_under_gravity])
def test_constant_strain_segments_converge_to_the_rod_at_second_order(case):
    """Tip errors of 1 to 16 segments fall fourfold per doubling (measured orders 2.00 to
    2.05; 16 segments: 1.7e-4 L0 in case (a), 4.1e-4 L0 in case (b))."""
    parameters, sol = case(points=161)
    errors = []
    for count in (1, 2, 4, 8, 16):
        _, _, tip = solve_pcs(count, guess=segment_means(sol, count), **parameters)
        errors.append(np.linalg.norm(tip - sol.tip_position) / parameters["length"])
    orders = np.log2(np.array(errors[:-1]) / errors[1:])
    assert np.all(np.abs(orders - 2) < 0.1), (errors, orders)
    # from the rest strains, with load continuation, the same equilibrium
    _, _, tip = solve_pcs(2, **parameters)
    error = np.linalg.norm(tip - sol.tip_position) / parameters["length"]
    assert_close(error, errors[1], rtol=1e-8, what="from rest")
