"""Parameter objects: each bad value raises ParameterError naming the field and range."""

from __future__ import annotations

import numpy as np
import pytest

import softcurve as sc
from softcurve import Creep, LinearStiffness, ParameterError, Robot, Segment, TanhStiffness


def segment(**changes) -> Segment:
    fields = dict(
        rest_length=0.064,
        mass=0.05,
        radius=0.02,
        elongation_stiffness=LinearStiffness(500.0),
        bending_stiffness=TanhStiffness(0.4, 0.3, 0.2),
        damping=[0.1, 1e-6, 1e-6],
    )
    fields.update(changes)
    return Segment(**fields)


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("mass", 0.0, "mass must be > 0"),
        ("mass", -1.0, "mass must be > 0"),
        ("mass", float("nan"), "mass must be finite"),
        ("rest_length", 0.0, "rest_length must be > 0"),
        ("rest_length", float("inf"), "rest_length must be finite"),
        ("radius", -0.01, "radius must be > 0"),
        ("radius", "0.01", "radius must be a real number"),
        ("damping", [[1, 0, 0], [0, -1, 0], [0, 0, 1]], "damping must be positive definite"),
        ("damping", [[1, 2, 0], [0, 1, 0], [0, 0, 1]], "damping must be symmetric"),
        ("damping", [1.0, 2.0], "damping must have shape (3, 3)"),
        ("damping", [1.0, float("nan"), 1.0], "damping must be finite"),
        ("elongation_stiffness", 500.0, "elongation_stiffness must be a LinearStiffness"),
        ("creep", "none", "creep must be a Creep or None"),
    ],
)
def test_bad_segment_fields(field, value, message):
    with pytest.raises(ParameterError, match=message.replace("(", r"\(").replace(")", r"\)")):
        segment(**{field: value})


@pytest.mark.parametrize(
    ("args", "message"),
    [
        ((0.0, -1.0, 1.0), "a1 must be > 0"),
        ((1.0, 1.0, 1.0), "a2 must be < a1"),
        ((1.0, 2.0, 1.0), "a2 must be < a1"),
        ((1.0, 0.5, 0.0), "a3 must be nonzero"),
        ((1.0, float("nan"), 1.0), "a2 must be finite"),
    ],
)
def test_tanh_law_must_be_positive_everywhere(args, message):
    with pytest.raises(ParameterError, match=message):
        TanhStiffness(*args)


def test_tanh_law_range_and_evenness():
    law = TanhStiffness(2.23e3, 1.74e3, -4.55e2)
    x = np.linspace(-0.05, 0.05, 101)
    k = law.stiffness(x)
    assert np.all(k > 0)
    assert k.min() == pytest.approx(2.23e3 - 1.74e3)
    np.testing.assert_array_equal(k, law.stiffness(-x))


def test_linear_law_rejects_nonpositive():
    with pytest.raises(ParameterError, match="k0 must be > 0"):
        LinearStiffness(0.0)


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (dict(rate=[1, 0, 1], gain=[0, 0, 0], compliance=[1, 1, 1]), "creep.rate must be > 0"),
        (dict(rate=[1, 1], gain=[0, 0, 0], compliance=[1, 1, 1]), r"creep.rate must have shape"),
        (
            dict(rate=[1, 1, 1], gain=[0, 0, 0], compliance=np.ones((2, 2))),
            "creep.compliance must have shape",
        ),
    ],
)
def test_bad_creep(kwargs, message):
    with pytest.raises(ParameterError, match=message):
        Creep(**kwargs)


def test_robot_validation():
    with pytest.raises(ParameterError, match="at least one Segment"):
        Robot(segments=())
    with pytest.raises(ParameterError, match=r"segments\[1\] must be a Segment"):
        Robot(segments=(segment(), "segment"))
    with pytest.raises(ParameterError, match="gravity must have shape"):
        Robot(segments=(segment(),), gravity=[0, 9.81])
    with pytest.raises(ParameterError, match="base_rotation must be a rotation matrix"):
        Robot(segments=(segment(),), base_rotation=np.diag([1.0, 1.0, -1.0]))


def test_parameters_are_read_only_and_named():
    robot = sc.presets.ifac2020()
    with pytest.raises(ValueError, match="read-only"):
        robot.gravity[2] = 0.0
    names, values = robot.parameter_names(), robot.parameter_vector()
    assert len(names) == len(values) == 49  # 33 of the segment, gravity, base pose, its span
    lookup = dict(zip(names, values, strict=True))
    assert lookup["segments[0].bending_stiffness.a2"] == 0.399
    assert lookup["segments[0].creep.gain[0]"] == 0.522
    assert lookup["segments[0].damping[0,0]"] == 0.12
    assert lookup["gravity[2]"] == -9.81


def test_model_rejects_bad_arguments(paper_model):
    with pytest.raises(ParameterError, match="quadrature_nodes"):
        sc.Model(sc.presets.ifac2020(), quadrature_nodes=0)
    with pytest.raises(ParameterError, match="robot must be a Robot"):
        sc.Model("ifac2020")
    with pytest.raises(ValueError, match=r"q must have shape \(3,\)"):
        paper_model.mass_matrix([0.064, 0.0])
    with pytest.raises(ValueError, match=r"s must be in \[0, 1\]"):
        paper_model.pose([0.064, 0, 0], 1.5)
    with pytest.raises(ValueError, match=r"lam must have shape \(3,\)"):
        paper_model.forward_dynamics([0.064, 0, 0], [0, 0, 0], [0, 0, 0], [0.0])


# -- passivity (issue 11, case 4) ------------------------------------------------------------
PAPER_CREEP = sc.presets.ifac2020().segments[0].creep


def test_paper_creep_is_passive():
    """rate 321/284/284, gain 0.522/0.00182/0.00182, K diag 502.3/0.0153/0.0153."""
    creep = Creep(PAPER_CREEP.rate, PAPER_CREEP.gain, PAPER_CREEP.compliance)
    np.testing.assert_array_equal(creep.compliance.diagonal(), [502.3, 0.0153, 0.0153])
    assert Creep(PAPER_CREEP.rate, PAPER_CREEP.gain, np.zeros(3)).compliance.sum() == 0


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        (  # the case: negative compliance with the paper's gains
            dict(compliance=-PAPER_CREEP.compliance),
            r"active .*P = K G\^-1 has the negative eigenvalue",
        ),
        (  # a negative gain with a positive compliance is the same sign error
            dict(gain=[-0.522, 0.00182, 0.00182]),
            "P = K G\\^-1 has the negative eigenvalue",
        ),
        (
            dict(compliance=[[502.3, 1.0, 0.0], [0.0, 0.0153, 0.0], [0.0, 0.0, 0.0153]]),
            "is not symmetric",
        ),
        (  # P symmetric positive definite, but P R + R P indefinite
            dict(
                rate=[1.0, 100.0, 1.0],
                gain=[1.0, 1.0, 1.0],
                compliance=[[1.0, 0.9, 0.0], [0.9, 1.0, 0.0], [0.0, 0.0, 1.0]],
            ),
            "P R \\+ R P has the negative eigenvalue",
        ),
        (  # a driven creep state pushing a coordinate whose motion never charges it
            dict(
                gain=[0.522, 0.0, 0.00182],
                compliance=[[502.3, 1.0, 0.0], [0.0, 0.0153, 0.0], [0.0, 0.0, 0.0153]],
            ),
            r"creep state 0 \(gain 0.522\) pushes coordinate 1 .* but gain\[1\] = 0",
        ),
    ],
)
def test_active_creep_is_rejected_with_the_rule(kwargs, message):
    arguments = dict(rate=PAPER_CREEP.rate, gain=PAPER_CREEP.gain)
    arguments["compliance"] = PAPER_CREEP.compliance
    with pytest.raises(ParameterError, match=message) as error:
        Creep(**{**arguments, **kwargs})
    assert "Rule: with R = diag(rate), G = diag(gain), K = compliance" in str(error.value)
    assert "P R + R P positive semidefinite" in str(error.value)


def test_undriven_creep_states_are_accepted():
    """A zero gain switches a creep mode off (a load decaying from lam0, zero from the
    default lam0 = 0), with or without its own compliance (the validation example's)."""
    assert Creep([1.0, 2.0, 3.0], [0.5, 0.0, 0.1], [1.0, 0.0, 3.0]).gain[1] == 0
    creep = Creep.from_gamma([300.0, 0.0, 30.0, 2e-3, 30.0, 2e-3], (1.0, 1e-2, 1e-2))
    assert creep.gain[0] == 0


def test_damping_message_states_the_rule():
    with pytest.raises(ParameterError, match="damping must be positive definite") as error:
        segment(damping=[0.1, -1e-6, 1e-6])
    assert "dissipates the power qd^T R qd" in str(error.value)


# -- the model's domain (issue 11, case 3) ---------------------------------------------------
@pytest.mark.parametrize(
    ("q", "message"),
    [
        (
            [-0.003, 0.0, 0.0],
            r"q0: lengths l must be in the model's domain 0 < l <= 10 rest "
            r"lengths \(0.644 m\): l of segment 1 \(q0\[0\]\) = -0.003 m",
        ),  # fmt: skip
        ([0.0, 0.0, 0.0], r"l of segment 1 \(q0\[0\]\) = 0 m"),
        ([0.65, 0.0, 0.0], r"0 < l <= 10 rest lengths \(0.644 m\): l of segment 1"),
        ([0.064, 80.0, 60.0], r"\|kappa\| l must be <= 2 pi rad .* segment 1 bends 6.4 rad"),
        ([0.064, np.nan, 0.0], r"entries must be finite: kx of segment 1 \(q0\[1\]\) = nan"),
        ([0.064, 0.0, np.inf], r"ky of segment 1 \(q0\[2\]\) = inf"),
        ([0.064, 0.0], r"q0 must have shape \(3,\)"),
    ],
)
def test_configurations_outside_the_domain_are_named(q, message):
    robot = sc.presets.ifac2020()
    with pytest.raises(ParameterError, match=message):
        robot.check_configuration(q)


def test_domain_boundary_and_second_segment():
    robot = sc.presets.ifac2020().with_segments(2)
    q = np.array([0.0644, 0.0, 0.0, 0.644, 2 * np.pi / 0.644 * 0.999, 0.0])
    np.testing.assert_array_equal(robot.check_configuration(q, "q"), q)
    q[3] = -1e-9
    with pytest.raises(ParameterError, match=r"q: .* l of segment 2 \(q\[3\]\) = -1e-09 m"):
        robot.check_configuration(q, "q")


@pytest.mark.parametrize(
    "call",
    [
        lambda m, q: m.forward_dynamics(q, np.zeros(3)),
        lambda m, q: m.inverse_dynamics(q, np.zeros(3), np.zeros(3)),
        lambda m, q: m.mass_matrix(q),
        lambda m, q: m.dynamics_terms(q, np.zeros(3)),
        lambda m, q: m.pose(q, 0.5),
        lambda m, q: m.tip_pose(q),
        lambda m, q: m.jacobian(q, 1.0),
        lambda m, q: m.potential_energy(q),
        lambda m, q: m.energy(q, np.zeros(3)),
    ],
)
def test_model_methods_check_the_configuration(paper_model, call):
    with pytest.raises(ParameterError, match=r"q: lengths l .* l of segment 1 \(q\[0\]\) = -0.01"):
        call(paper_model, np.array([-0.01, 0.0, 0.0]))
    call(paper_model, np.array([0.064, 25.0, 0.0]))
