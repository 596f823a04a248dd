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
    assert len(names) == len(values) == 45
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
