"""Each element kind's domain, written once (``description/elements``: margins that the
Python rule and the compiled model's ``domain`` Function both evaluate): the two agree bit
for bit on random states, on the boundaries and on NaN; the message names the bound that
fails exactly where the rule says outside; the C driver stops at the first output outside
the domain for every kind, with each member's own parameters."""

from __future__ import annotations

import numpy as np
import pytest

import softcurve as sc
from softcurve.description.elements import MAX_BEND, MAX_SHEAR, MAX_STRETCH, MAX_TWIST
from softcurve.simulation.solvers import _driver as native

from .test_kinds import robots, six_strain_segment

ULPS = np.arange(-4, 5) * np.finfo(float).eps
"""Relative offsets that put a value within a few units of the last place of a bound."""


def _curvature_rows(rng, segment, count):
    """Constant-curvature coordinates across the domain's bounds: some at rest, lengths at
    0 and at the longest exactly, bending angles within a few ulps of 2 pi, NaN, inf."""
    l0 = segment.rest_length
    length = l0 * rng.uniform(0.5, 2.0, count)
    angle = rng.uniform(0, 2 * np.pi, count)
    kappa = rng.uniform(0, 1.2, count) * MAX_BEND / length
    near = rng.random(count) < 0.4
    kappa[near] = MAX_BEND / length[near] * (1 + rng.choice(ULPS, near.sum()))
    q = np.column_stack([length, kappa * np.cos(angle), kappa * np.sin(angle)])
    q[rng.random(count) < 0.05, 0] = MAX_STRETCH * l0
    q[rng.random(count) < 0.05, 0] = 12 * l0
    q[rng.random(count) < 0.03, 0] = 0.0
    q[rng.random(count) < 0.03, 0] = -1e-3
    q[rng.random(count) < 0.02, rng.integers(0, 3)] = np.nan
    q[rng.random(count) < 0.02, rng.integers(0, 3)] = np.inf
    return q


def _strain_rows(rng, segment, count):
    """Strains across every bound: stretch at 0, 10 and beyond, bend, twist and shear
    within a few ulps of their bounds, NaN, inf."""
    l0 = segment.rest_length
    xi = np.tile(segment.rest_strain, (count, 1))
    xi[:, 5] = rng.uniform(0.2, 3.0, count)
    direction = rng.uniform(0, 2 * np.pi, count)
    bend = rng.uniform(0, 1.2, count) * MAX_BEND / l0
    twist = rng.uniform(-1.2, 1.2, count) * MAX_TWIST / l0
    shear = rng.uniform(0, 1.2, count) * MAX_SHEAR * xi[:, 5]
    which = rng.integers(0, 4, count)  # the bound each row sits near, if any
    near = rng.random(count) < 0.5
    offset = 1 + rng.choice(ULPS, count)
    bend = np.where(near & (which == 0), MAX_BEND / l0 * offset, bend)
    twist = np.where(near & (which == 1), np.sign(twist) * MAX_TWIST / l0 * offset, twist)
    shear = np.where(near & (which == 2), MAX_SHEAR * xi[:, 5] * offset, shear)
    xi[:, 5] = np.where(near & (which == 3), MAX_STRETCH * offset, xi[:, 5])
    xi[:, 0], xi[:, 1], xi[:, 2] = bend * np.cos(direction), bend * np.sin(direction), twist
    xi[:, 3], xi[:, 4] = shear * np.cos(direction + 1), shear * np.sin(direction + 1)
    xi[rng.random(count) < 0.03, 5] = 0.0
    xi[rng.random(count) < 0.02, rng.integers(0, 6)] = np.nan
    xi[rng.random(count) < 0.02, rng.integers(0, 6)] = -np.inf
    return xi[:, list(segment.indices)]


def boundary_states(rng, robot, count=4000):
    """Configurations (count, n) of ``robot`` whose elements straddle their bounds."""
    columns = []
    for segment in robot.segments:
        if isinstance(segment, sc.Segment):
            columns.append(_curvature_rows(rng, segment, count))
        elif isinstance(segment, sc.StrainSegment):
            columns.append(_strain_rows(rng, segment, count))
    return np.hstack(columns)


@pytest.fixture(scope="module")
def compiled_robots(paper_model):
    """The paper model and the mixed chain (every kind: constant strain, rigid bodies,
    constant curvature), compiled."""
    return {"curvature": paper_model, "mixed": sc.Model(robots()["mixed"])}


@pytest.mark.parametrize("name", ["curvature", "mixed"])
def test_the_compiled_domain_is_the_python_rule_bit_for_bit(rng, compiled_robots, name):
    model = compiled_robots[name]
    assert model.compiled_library is not None
    q = boundary_states(rng, model.robot)
    with np.errstate(invalid="ignore"):
        compiled = model.evaluate_along("domain", q)[0][:, 0]
    inside = model.robot.inside(q)
    assert 0.2 < inside.mean() < 0.8  # both sides sampled
    np.testing.assert_array_equal(compiled == 1.0, inside)
    np.testing.assert_array_equal(np.isin(compiled, (0.0, 1.0)), True)


@pytest.mark.parametrize("name", ["curvature", "six strains", "mixed"])
def test_a_message_is_written_exactly_where_the_rule_says_outside(rng, name):
    robot = robots()[name]
    q = boundary_states(rng, robot, count=1500)
    inside = robot.inside(q)
    worded = np.array([robot.domain_problem(row) is None for row in q])
    np.testing.assert_array_equal(worded, inside)
    for row in q[~inside][:50]:
        with pytest.raises(sc.ParameterError):
            robot.check_configuration(row)
    for row in q[inside][:50]:
        robot.check_configuration(row)


def test_the_symbolic_domain_is_the_python_rule_on_every_kind(rng):
    """The Function every model has (also uncompiled), for the three robots of
    ``test_kinds`` that the other tests do not compile."""
    for name in ("six strains", "creep"):
        model = sc.Model(robots()[name], compile=False)
        q = boundary_states(rng, model.robot, count=500)
        with np.errstate(invalid="ignore"):
            values = model.evaluate_along("domain", q)[0][:, 0]
        np.testing.assert_array_equal(values == 1.0, model.robot.inside(q))


# -- the C driver stops at the first output outside, for a constant-strain robot ---------

needs_driver = pytest.mark.skipif(
    native.driver() is None, reason="the C driver of CVODES cannot be built here"
)


@pytest.fixture(scope="module")
def strain_model():
    return sc.Model(sc.Robot(segments=(six_strain_segment(),)))


def _pushed(model, index, force, t_final=0.5):
    tau = np.zeros(model.n)
    tau[index] = force
    q0 = model.robot.rest_configuration()
    return sc.simulate(model, q0, np.zeros(model.n), t_final=t_final, dt=1e-3, tau=tau)


@needs_driver
@pytest.mark.parametrize(("strain", "force"), [("stretch", 300.0), ("twist", 0.1)])
def test_the_driver_stops_where_a_strain_leaves_its_domain(strain_model, strain, force):
    """Before, the driver checked constant-curvature robots alone: these runs were SUCCESS
    with a stretch of about 10 (a torn segment) or a twist of three turns."""
    index = sc.STRAINS.index(strain)
    run = _pushed(strain_model, index, force)
    assert run.stats["route"] == "driver"
    assert run.status is sc.Status.LEFT_DOMAIN and not run.success
    assert f"{strain} must be" in run.message or f"{strain} angles" in run.message
    # the trajectory keeps the outputs inside, up to the last one before the exit
    assert strain_model.robot.inside(run.q).all() and 0.001 < run.t[-1] < 0.5


@needs_driver
def test_batch_members_each_check_their_own_domain(strain_model):
    """Two members of one structure that differ in their rest length, twisted to the same
    strain: the twist angle L0 |twist| of the longer one passes a full turn, the other's
    stays inside, from each member's own parameter vector."""
    robot = strain_model.robot
    longer = robot.replace(segments=(robot.segments[0].replace(rest_length=0.12),))
    parameters = np.array([robot.parameter_vector(), longer.parameter_vector()])
    gj = robot.segments[0].torsion_stiffness.k0
    target = 55.0  # [1/m]: a 5.5 rad twist of the shorter, 6.6 rad of the longer
    index = sc.STRAINS.index("twist")
    tau = np.zeros((2, strain_model.n))
    tau[:, index] = np.array([0.1, 0.12]) * gj * target
    q0 = np.tile(robot.rest_configuration(), (2, 1))
    q0[:, index] = 50.0
    batch = sc.simulate_batch(
        strain_model, q0, np.zeros((2, strain_model.n)), t_final=0.5, dt=1e-3,
        tau=tau, parameters=parameters,
    )  # fmt: skip
    assert batch.stats["routes"][0].startswith("driver")
    first, second = batch.member(0), batch.member(1)
    assert first.success, first.message
    assert second.status is sc.Status.LEFT_DOMAIN and "twist" in second.message
    assert np.abs(first.q[:, index]).max() * 0.1 < MAX_TWIST
