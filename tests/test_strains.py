"""The constant-strain segment against closed forms and against the constant-curvature
segment it generalizes.

- The pose is the SE(3) exponential of ``L0`` times the strain twist: against
  ``scipy.linalg.expm`` at random strains and at zero strain (smooth there).
- Pure torsion twists by ``T L / GJ`` and an axial load stretches by ``F L / EA``,
  exactly (one segment is exact for uniform strain).
- A cantilever under a small tip force deflects by Timoshenko's ``F L^3 / (3 EI) + F L /
  (k G A)``; piecewise constant strain converges to it at second order in the number of
  segments.
- The strains (bend x, bend y, stretch) are the constant-curvature segment in other
  coordinates: poses, energies, mass matrices, forward dynamics and equilibria agree to
  round-off through the map ``u = sigma (-ky, kx, 0)``, ``v = (0, 0, sigma)``.
- Each strain's domain: a state outside it is refused, naming the strain, the value and
  the bound.
"""

from __future__ import annotations

import numpy as np
import pytest
from scipy.linalg import expm

import softcurve as sc
from softcurve.base.validation import ParameterError

from .conftest import assert_close
from .test_kinds import six_strain_segment


def twist_matrix(xi):
    """``xi^`` (4, 4) of ``xi = (u, v)``."""
    u, v = xi[:3], xi[3:]
    m = np.zeros((4, 4))
    m[:3, :3] = [[0, -u[2], u[1]], [u[2], 0, -u[0]], [-u[1], u[0], 0]]
    m[:3, 3] = v
    return m


def weightless(robot):
    return robot.replace(gravity=np.zeros(3))


@pytest.fixture(scope="module")
def one_segment():
    """One soft segment with all six strains, no gravity (compiled once)."""
    return sc.Model(weightless(sc.Robot(segments=(six_strain_segment(damping=False),))))


def test_the_pose_is_the_se3_exponential(one_segment, rng):
    segment = one_segment.robot.segments[0]
    for scale in (0.0, 1e-9, 1e-4, 1.0, 3.0):
        xi = segment.rest_strain + scale * rng.uniform(-1, 1, 6) * [20, 20, 20, 0.2, 0.2, 0.3]
        g = expm(segment.rest_length * twist_matrix(xi))
        for s in (0.3, 1.0):
            pose = one_segment.pose(xi, s)
            g_s = expm(s * segment.rest_length * twist_matrix(xi))
            assert_close(pose.rotation, g_s[:3, :3], atol=1e-15, what=f"R at {scale}")
            assert_close(pose.position, g_s[:3, 3], atol=1e-16 * 10, what=f"p at {scale}")
        assert_close(one_segment.tip_pose(xi).position, g[:3, 3], atol=1e-16 * 10)


def test_a_precurved_pretwisted_segment_at_rest_is_a_helix():
    rest = np.array([4.0, -3.0, 6.0, 0.01, -0.02, 1.05])
    segment = six_strain_segment(rest_strain=rest, damping=False)
    model = sc.Model(weightless(sc.Robot(segments=(segment,))), compile=False)
    equilibrium = sc.equilibrium(model, segment.rest_configuration())
    assert equilibrium.success
    assert_close(equilibrium.q, rest, atol=1e-12, what="rest strain is the equilibrium")
    g = expm(segment.rest_length * twist_matrix(rest))
    tip = model.tip_pose(equilibrium.q)
    assert_close(tip.rotation, g[:3, :3], atol=1e-15, what="helix R")
    assert_close(tip.position, g[:3, 3], atol=1e-16 * 10, what="helix p")


def _laws(segment):
    return {
        name: getattr(segment, f"{name}_stiffness").k0
        for name in ("bending", "torsion", "shear", "stretch")
    }


def test_pure_torsion_twists_by_tl_over_gj(one_segment):
    segment = one_segment.robot.segments[0]
    gj, length = _laws(segment)["torsion"], segment.rest_length
    for torque in (1e-4, 5e-3, 2e-2):
        e = sc.equilibrium(one_segment, segment.rest_configuration(), tip_moment=[0, 0, torque])
        assert e.success, e.message
        expected = segment.rest_configuration()
        expected[2] = torque / gj
        assert_close(e.q, expected, atol=1e-12, what="strains under torsion")
        angle = np.arctan2(*one_segment.tip_pose(e.q).rotation[[1, 0], 0])
        assert angle == pytest.approx(torque * length / gj, rel=1e-12)


def test_axial_load_stretches_by_fl_over_ea(one_segment):
    segment = one_segment.robot.segments[0]
    ea, length = _laws(segment)["stretch"], segment.rest_length
    for force in (-20.0, 0.5, 40.0):
        e = sc.equilibrium(one_segment, segment.rest_configuration(), tip_force=[0, 0, force])
        assert e.success, e.message
        tip = one_segment.tip_pose(e.q).position
        assert_close(tip, [0, 0, length + force * length / ea], atol=1e-15, what="tip")


def test_timoshenko_cantilever_converges_at_second_order():
    """A tip force 1e-6 of the load that bends the rod by its length: the linear limit."""
    segment = six_strain_segment(damping=False)
    laws = _laws(segment)
    length = segment.rest_length
    force = 1e-6 * laws["bending"] / length**2
    expected = force * length**3 / (3 * laws["bending"]) + force * length / laws["shear"]
    errors = []
    for count in (1, 2, 4):
        pieces = segment.replace(
            rest_length=length / count, mass=segment.mass / count, slice_inertia=None
        )
        model = sc.Model(weightless(sc.Robot(segments=(pieces,) * count)), compile=False)
        e = sc.equilibrium(model, model.robot.rest_configuration(), tip_force=[force, 0, 0])
        assert e.success, e.message
        errors.append(abs(model.tip_pose(e.q).position[0] - expected) / expected)
    orders = np.log2(np.array(errors[:-1]) / np.array(errors[1:]))
    assert errors[0] < 0.3
    assert np.all(orders > 1.9), f"errors {errors}, orders {orders}"


def curvature_map(q, rest_lengths):
    """``(l, kx, ky)`` per segment to the strains ``(bend_x, bend_y, stretch)``, and its
    Jacobian."""
    strains, jacobian = [], np.zeros((q.size, q.size))
    for i, l0 in enumerate(rest_lengths):
        length, kx, ky = q[3 * i : 3 * i + 3]
        sigma = length / l0
        strains += [-sigma * ky, sigma * kx, sigma]
        jacobian[3 * i : 3 * i + 3, 3 * i : 3 * i + 3] = [
            [-ky / l0, 0, -sigma],
            [kx / l0, sigma, 0],
            [1 / l0, 0, 0],
        ]
    return np.array(strains), jacobian


def strain_twin(segment):
    """The constant-strain segment of ``segment``'s energy: its laws on the elongation
    and bending angle become laws on the stretch and curvature, ``k(x) = L0 k_cc(L0 x)``
    (a tanh law's three numbers times ``L0``)."""
    l0 = segment.rest_length

    def law(cc):
        return type(cc)(*(l0 * p for p in cc.parameters()))

    return sc.StrainSegment(
        rest_length=l0,
        mass=segment.mass,
        radius=segment.radius,
        strains=("bend_x", "bend_y", "stretch"),
        bending_stiffness=law(segment.bending_stiffness),
        stretch_stiffness=law(segment.elongation_stiffness),
    )


@pytest.fixture(scope="module")
def twins():
    """The paper's robot hanging from its base (two segments, its tanh laws, no damping
    and creep: a damper on ``(l, kx, ky)`` rates is not one on the strains' rates) and its
    strain twin."""
    paper = sc.presets.ifac2020(damping=False).with_segments(2)
    segments = tuple(s.replace(creep=None) for s in paper.segments)
    paper = paper.replace(segments=segments, gravity=[0.0, 0.0, 9.81])  # hanging: stable
    twin = paper.replace(segments=tuple(strain_twin(s) for s in paper.segments))
    return sc.Model(paper, compile=False), sc.Model(twin, compile=False)


def test_the_restricted_segment_is_todays_constant_curvature(twins, rng):
    paper, twin = twins
    rest = paper.robot.rest_lengths
    for _ in range(4):
        q = np.concatenate([[l0 * rng.uniform(0.8, 1.2), *rng.uniform(-30, 30, 2)] for l0 in rest])
        qd = rng.normal(size=6) * [0.3, 100, 100, 0.3, 100, 100]
        xi, jacobian = curvature_map(q, rest)
        xid = jacobian @ qd
        for s in (0.25, 0.75, 1.0):
            a, b = paper.pose(q, s), twin.pose(xi, s)
            assert_close(a.position, b.position, atol=1e-17, what="position")
            assert_close(a.rotation, b.rotation, atol=1e-15, what="rotation")
        assert_close(twin.potential_energy(xi), paper.potential_energy(q), rtol=1e-13)
        t = paper.kinetic_energy(q, qd)
        assert twin.kinetic_energy(xi, xid) == pytest.approx(t, rel=1e-13)
        d = paper.mass_matrix(q)
        assert_close(jacobian.T @ twin.mass_matrix(xi) @ jacobian, d, rtol=1e-13,
                     scale=np.abs(d).max(), what="D = J^T D_strain J")  # fmt: skip
        # forward dynamics: xidd = J qdd + Jdot qd, Jdot qd by a central difference of J
        qdd = paper.forward_dynamics(q, qd, np.zeros(6), np.zeros(0))
        xidd = twin.forward_dynamics(xi, xid, np.zeros(6), np.zeros(0))
        h = 1e-6
        jdot_qd = (curvature_map(q + h * qd, rest)[1] - curvature_map(q - h * qd, rest)[1]) @ qd
        expected = jacobian @ qdd + jdot_qd / (2 * h)
        assert_close(xidd, expected, rtol=1e-8, scale=np.abs(expected).max(), what="qdd")


def test_the_restricted_segment_has_todays_equilibria(twins):
    paper, twin = twins
    q0 = paper.robot.rest_configuration()
    for load in ([0.05, 0.0, 0.0], [0.02, -0.03, -0.1]):
        a = sc.equilibrium(paper, q0, tip_force=load)
        b = sc.equilibrium(twin, twin.robot.rest_configuration(), tip_force=load)
        assert a.success and b.success
        assert_close(b.q, curvature_map(a.q, paper.robot.rest_lengths)[0], atol=1e-12,
                     what="equilibrium strains")  # fmt: skip
        assert_close(twin.tip_pose(b.q).position, paper.tip_pose(a.q).position, atol=1e-14)
        assert a.stability == b.stability == "stable"


@pytest.mark.parametrize(
    ("strain", "value", "message"),
    [
        ("stretch", 0.0, "stretch must be in the model's domain 0 < stretch <= 10"),
        ("stretch", 10.5, "stretch must be in the model's domain"),
        ("bend_x", 70.0, r"bending angles \|\(bend_x, bend_y\)\| L0 must be <= 2 pi"),
        ("twist", -63.0, r"twist angles \|twist\| L0 must be <= 2 pi"),
        ("shear_y", 1.2, "shear .* must be <= 1 stretch"),
        ("shear_x", np.nan, "entries must be finite: shear_x of segment 1"),
    ],
)
def test_each_strain_has_its_domain(strain, value, message):
    robot = sc.Robot(segments=(six_strain_segment(),))
    q = robot.rest_configuration()
    q[sc.STRAINS.index(strain)] = value
    assert not robot.inside(q)
    with pytest.raises(ParameterError, match=message):
        robot.check_configuration(q)


@pytest.mark.parametrize(
    ("changes", "message"),
    [
        ({"strains": ("bend",)}, "strains must be distinct names among"),
        ({"strains": ()}, "strains must be distinct names among"),
        ({"torsion_stiffness": None}, "torsion_stiffness must be a LinearStiffness"),
        (
            {"strains": ("bend_x", "bend_y")},
            "torsion_stiffness must be None: the segment chooses none of twist",
        ),
        ({"rest_strain": [0, 0, 0, 0, 0, -1]}, "rest_strain .* is outside the domain"),
        ({"slice_inertia": [1e-5, 0.0, 1e-5]}, "slice_inertia must be > 0"),
        ({"damping": [1, 1, 1, 1, 1, -1]}, "damping"),
        ({"creep": sc.Creep([1.0] * 3, [1.0] * 3, [1.0] * 3)}, "creep must have 6 states"),
    ],
)
def test_bad_strain_segments_are_refused(changes, message):
    segment = six_strain_segment()
    with pytest.raises(ParameterError, match=message):
        segment.replace(**changes)
