"""Old names still work, with a warning that names the new one: the output-map builders
(``sc.tip_position`` is now ``sc.tip_position_map`` ...) and the modules moved by issue 30
(``softcurve.description.pneumatic``, ``softcurve.analysis.equilibrium``)."""

from __future__ import annotations

import importlib
import warnings

import casadi as ca
import numpy as np
import pytest

import softcurve as sc
import softcurve.identification.maps as maps

from .conftest import assert_close
from .test_identification_maps import evaluate_output

RENAMED = {
    "tip_position": ("tip_position_map", lambda model: ((model,), {"axes": "xz"})),
    "marker_position": ("marker_position_map", lambda model: ((model, 0, 0.5), {})),
    "imu_orientation": ("imu_orientation_map", lambda model: ((model,), {"output": "gravity"})),
    "curvatures": ("curvature_map", lambda model: ((1,), {"offsets": ("ox", "oy")})),
    "bending_angle": ("bending_angle_map", lambda model: ((0,), {"offset": "zero"})),
}
"""Old name: (new name, the arguments of a call on a model)."""

Q = np.array([0.066, 21.0, -4.0, 0.063, 9.0, 13.0])  # two segments [m, 1/m, 1/m]


@pytest.mark.parametrize("old", sorted(RENAMED))
def test_an_old_builder_name_warns_and_builds_the_same_map(two_segment_model, old):
    new, arguments = RENAMED[old]
    args, kwargs = arguments(two_segment_model)
    with pytest.warns(DeprecationWarning, match=rf"{old} is deprecated, use {new}\b"):
        before = getattr(sc, old)(*args, **kwargs)
    after = getattr(sc, new)(*args, **kwargs)
    assert (before.names, before.units, before.parameters) == (
        after.names,
        after.units,
        after.parameters,
    )
    values = {name: 0.1 * (i + 1) for i, name in enumerate(after.parameters)}
    assert_close(
        evaluate_output(before, two_segment_model, Q, values),
        evaluate_output(after, two_segment_model, Q, values),
        atol=0.0,
    )
    assert getattr(maps, old) is getattr(sc, old)  # the same alias on the face
    assert old not in sc.__all__ and new in sc.__all__ and new in maps.__all__


@pytest.mark.parametrize(
    ("old", "new", "name"),
    [
        ("softcurve.description.pneumatic", "softcurve.description.bellows", "PneumaticActuator"),
        ("softcurve.analysis.equilibrium", "softcurve.analysis.equilibrium_results", "Equilibrium"),
    ],
)
def test_a_moved_module_warns_and_gives_the_new_modules_names(old, new, name):
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        shim = importlib.import_module(old)  # importing alone does not warn (walkers, doctests)
    with pytest.warns(DeprecationWarning, match=rf"{old} is deprecated, import {name} from {new}$"):
        value = getattr(shim, name)
    assert value is getattr(importlib.import_module(new), name)
    with pytest.warns(DeprecationWarning, match=new):
        exec(f"from {old} import {name}", {})  # the form old code uses
    with pytest.raises(AttributeError):
        shim.no_such_name  # noqa: B018
    assert not hasattr(shim, "__all__")  # dunders are the shim's own, not forwarded


def test_the_tendon_lengths_keep_their_old_method_name():
    """``tendon_lengths_symbolic`` became the actuators' shared ``fiber_lengths_symbolic``;
    the old name warns and gives the same expression."""
    actuator = sc.presets.rao2021_tendons()
    q = ca.SX.sym("q", actuator.n)
    with pytest.warns(DeprecationWarning, match="use fiber_lengths_symbolic"):
        old = actuator.tendon_lengths_symbolic(q)
    new = actuator.fiber_lengths_symbolic(q)
    assert ca.Function("d", [q], [old - new]).expand()(ca.DM.rand(actuator.n)).full().max() == 0


@pytest.mark.parametrize(
    ("face", "name"),
    [
        ("softcurve.simulation.stepper", "StepResult"),
        ("softcurve.simulation.sensitivity", "SensitivityEvaluator"),
        ("softcurve.identification.maps", "rotation_from_angles"),
        ("softcurve.identification.experiments", "UnitError"),
        ("softcurve.identification.experiments", "ExperimentFileNotFound"),
    ],
)
def test_names_users_meet_are_on_a_face(face, name):
    """Types a public function returns or raises, and helpers the old modules listed,
    are importable from the face that documents them."""
    module = importlib.import_module(face)
    assert name in module.__all__ and getattr(module, name).__name__ == name
