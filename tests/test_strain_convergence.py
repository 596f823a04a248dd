"""The strain segments' equilibria converge to the Cosserat rod as their number grows.

The constant-curvature segments first: they are the strain segments of the strains
(bend_x, bend_y, stretch), and their equilibria meet :func:`solve_pcs` restricted to
those strains (which checks it and this file's harness on the model of today). Then the
two cases of tests/cosserat_rod.py (a straight rod under a tip force and moment, a
precurved rod sagging out of its plane under its weight) with 1, 2, 4, 8, 16 equal
:class:`softcurve.StrainSegment` of all six strains. Two checks per number of segments:
the equilibrium is the piecewise-constant-strain one (:func:`solve_pcs`, the same
discretization solved independently: their tips differ by less than 1 % of the
discretization error), and the tip error against the rod (:func:`solve_rod`) falls at
second order (measured with :func:`solve_pcs`: 1.7e-4 L0 and 4.1e-4 L0 at 16 segments).
"""

from __future__ import annotations

import numpy as np
import pytest

import softcurve as sc
from softcurve.analysis.loads import rest_configuration
from tests.cosserat_rod import (
    REST_STRAIN,
    STRAINS,
    loaded_straight_rod,
    precurved_rod_under_gravity,
    segment_means,
    solve_pcs,
)

needs_strain_segments = pytest.mark.skipif(
    not hasattr(sc, "StrainSegment"),
    reason="softcurve.StrainSegment does not exist yet: the strain segments to compare "
    "with the Cosserat rod are to come (issue 45)",
)

CURVATURE_STRAINS = ("bend_x", "bend_y", "stretch")
"""The strains of the constant-curvature segment."""

CURVATURE_AGREEMENT = 1e-8
"""Largest distance [L0] and rotation difference between the constant-curvature
segments' tip and :func:`solve_pcs`'s: measured 7e-10 at one segment (the quadrature of
:func:`solve_pcs`, :data:`~tests.cosserat_rod.PCS_POINTS`; 7e-10 too against 257 points),
6e-11 at two, 4e-12 at four."""

SEGMENTS = (1, 2, 4, 8, 16)
SLOW_FROM = 4
"""Robots of this many segments and more (24 coordinates and more) are in the slow study:
the default run checks one and two segments (their models compile from an empty cache
in about 8 s each on two cores); four took 16 s, eight and sixteen minutes."""

CASES = {"straight": loaded_straight_rod, "precurved": precurved_rod_under_gravity}

IMPLEMENTATION_SHARE = 1e-2
"""Largest distance between the strain segments' tip and :func:`solve_pcs`'s, as a share
of the discretization error (:func:`solve_pcs`'s tip against the rod's): both solve the
same equations, so they differ by their solvers' and quadratures' errors only."""

LOAD_STEPS = (1, 4, 16)
"""Equal load steps tried in turn when an equilibrium from the rest configuration fails."""


def strain_robot(parameters: dict, count: int):
    """The rod of ``parameters`` (:func:`loaded_straight_rod`'s keys) as ``count`` equal
    strain segments of all six strains, clamped at the origin along world z."""
    length = parameters["length"] / count
    segment = sc.StrainSegment(
        rest_length=length,
        mass=parameters["mass_per_length"] * length,
        radius=parameters["material"]["radius"],
        strains=STRAINS,
        bending_stiffness=sc.LinearStiffness(parameters["EI"]),
        torsion_stiffness=sc.LinearStiffness(parameters["GJ"]),
        shear_stiffness=sc.LinearStiffness(parameters["kGA"]),
        stretch_stiffness=sc.LinearStiffness(parameters["EA"]),
        rest_strain=parameters.get("rest_strain", REST_STRAIN),
    )
    gravity = parameters.get("gravity", (0.0, 0.0, 0.0))
    return sc.Robot(segments=(segment,) * count, gravity=gravity)


def loaded_equilibrium(model, parameters: dict):
    """The equilibrium under the loads of ``parameters`` (:func:`loaded_straight_rod`'s
    keys) from the rest configuration, the loads
    applied at once, else in :data:`LOAD_STEPS` equal steps."""
    loads = {
        "tip_force": np.asarray(parameters.get("tip_force", (0.0, 0.0, 0.0)), float),
        "tip_moment": np.asarray(parameters.get("tip_moment", (0.0, 0.0, 0.0)), float),
        "gravity": np.asarray(parameters.get("gravity", (0.0, 0.0, 0.0)), float),
    }
    messages = []
    for steps in LOAD_STEPS:
        q = rest_configuration(model.robot)
        for k in range(1, steps + 1):
            result = sc.equilibrium(model, q, **{n: k / steps * v for n, v in loads.items()})
            if not result.success:
                messages.append(f"{steps} steps, step {k}: {result.message}")
                break
            q = result.q
        else:
            return result
    pytest.fail("no equilibrium: " + "; ".join(messages))


def segments_parameter(counts):
    return [
        pytest.param(c, marks=pytest.mark.slow) if c >= SLOW_FROM else pytest.param(c)
        for c in counts
    ]


@pytest.fixture(scope="module")
def references():
    """Per case: its parameters and the rod's solution (on a grid divisible by 16)."""
    return {name: case(points=321) for name, case in CASES.items()}


def angle(a, b) -> float:
    """The angle of the rotation between two frames [rad]."""
    return float(np.arccos(np.clip((np.trace(a.T @ b) - 1) / 2, -1.0, 1.0)))


def tip_errors(parameters, rod, count):
    """The strain segments' tip and :func:`solve_pcs`'s; their distances to each other and
    to the rod's tip, relative to ``L0``, and the angles between their tip frames [rad]."""
    model = sc.Model(strain_robot(parameters, count))
    equilibrium = loaded_equilibrium(model, parameters)
    rotation, position = model.tip_pose(equilibrium.q)
    _, pcs_rotation, pcs_position = solve_pcs(count, guess=segment_means(rod, count), **parameters)
    length = parameters["length"]
    return {
        "model": position,
        "pcs": pcs_position,
        "model error": np.linalg.norm(position - rod.tip_position) / length,
        "pcs error": np.linalg.norm(pcs_position - rod.tip_position) / length,
        "model to pcs": np.linalg.norm(position - pcs_position) / length,
        "pcs angle": angle(pcs_rotation, rod.tip_rotation),
        "model to pcs angle": angle(rotation, pcs_rotation),
    }


@pytest.mark.parametrize("count", segments_parameter((1, 2, 4)))
def test_constant_curvature_segments_meet_the_piecewise_constant_strain_equilibrium(count):
    """Case (a)'s loads and gravity across the force's plane: every load kind."""
    parameters, _ = loaded_straight_rod(points=3)
    parameters = parameters | {"gravity": (0.0, -9.81, 0.0)}
    length = parameters["length"] / count
    segment = sc.Segment(
        rest_length=length,
        mass=parameters["mass_per_length"] * length,
        radius=parameters["material"]["radius"],
        # the strain energy L0 K (xi - xi*)^2 / 2 in the segment's bending angle and length
        elongation_stiffness=sc.LinearStiffness(parameters["EA"] / length),
        bending_stiffness=sc.LinearStiffness(parameters["EI"] / length),
    )
    model = sc.Model(sc.Robot(segments=(segment,) * count, gravity=parameters["gravity"]))
    rotation, position = model.tip_pose(loaded_equilibrium(model, parameters).q)
    _, expected_rotation, expected_position = solve_pcs(
        count, strains=CURVATURE_STRAINS, **parameters
    )
    assert np.linalg.norm(position - expected_position) < CURVATURE_AGREEMENT * parameters["length"]
    assert angle(rotation, expected_rotation) < CURVATURE_AGREEMENT


@needs_strain_segments
@pytest.mark.parametrize("count", segments_parameter(SEGMENTS))
@pytest.mark.parametrize("case", list(CASES))
def test_strain_segments_meet_the_piecewise_constant_strain_equilibrium(references, case, count):
    parameters, rod = references[case]
    errors = tip_errors(parameters, rod, count)
    assert errors["model to pcs"] < IMPLEMENTATION_SHARE * errors["pcs error"], errors
    assert errors["model to pcs angle"] < IMPLEMENTATION_SHARE * errors["pcs angle"], errors


@needs_strain_segments
@pytest.mark.slow
@pytest.mark.parametrize("case", list(CASES))
def test_strain_segments_converge_to_the_rod_at_second_order(references, case):
    """The tip error against the rod, 1 to 16 segments: falling, at order 2 at the end."""
    parameters, rod = references[case]
    errors = np.array([tip_errors(parameters, rod, c)["model error"] for c in SEGMENTS])
    orders = np.log2(errors[:-1] / errors[1:])
    table = ", ".join(
        f"N = {c}: {e:.3e} L0" + (f" (order {o:.2f})" if i else "")
        for i, (c, e, o) in enumerate(zip(SEGMENTS, errors, np.r_[np.nan, orders], strict=True))
    )
    print(f"{case}: {table}")
    assert np.all(np.diff(errors) < 0), table
    assert orders[-1] > 1.8, table
