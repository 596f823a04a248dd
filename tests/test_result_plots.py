"""Results draw themselves: every result has ``.plot(ax=None, ...)`` returning a Figure,
or is named in docs/architecture.md's list of results without a figure; each figure draws
what its result holds (a point per eigenvalue, the backbone's tip where the result says,
the inputs against the actuator's bounds), with its units on the axes."""

from __future__ import annotations

import importlib
import inspect
import pkgutil
import re
import types
from pathlib import Path

import matplotlib.pyplot as plt
import numpy as np
import pytest
from matplotlib.figure import Figure

import softcurve as sc
from softcurve.base.status import Result
from softcurve.figures import plot_eigenvalues, plot_member_tips
from softcurve.simulation.stepper import Stepper

ARCHITECTURE = Path(__file__).resolve().parents[1] / "docs" / "architecture.md"
EXEMPTIONS = re.compile(r"Results without a figure:(?P<names>.*?)\.\s", re.DOTALL)
"""The sentence of docs/architecture.md that names the results without ``plot``."""
MM_PER_M = 1e3
KPA_PER_PA = 1e-3
INPUTS = np.array([4e4, 0.0, 1e4])
"""Bellow pressures [Pa] of the equilibrium drawn: they bend the robot out of the x-z plane."""


@pytest.fixture(autouse=True)
def _close_figures():
    yield
    plt.close("all")


@pytest.fixture(scope="module")
def actuator():
    return sc.PneumaticActuator.three_bellows(distance=0.01, area=2e-5, p_max=1e5)


@pytest.fixture(scope="module")
def equilibrium(paper_model, actuator):
    return sc.equilibrium(paper_model, [0.0644, 0.0, 0.0], actuator=actuator, inputs=INPUTS)


@pytest.fixture(scope="module")
def linearization(paper_model, equilibrium):
    return sc.linearize(paper_model, equilibrium.q)


@pytest.fixture(scope="module")
def inverse(paper_model, actuator, equilibrium):
    """The target is the tip of ``equilibrium``: reachable by construction."""
    return sc.inverse_statics(paper_model, actuator, equilibrium.tip_position)


@pytest.fixture(scope="module")
def initial(paper_model, actuator):
    t = np.linspace(0.0, 0.2, 5)
    inputs = {f"p{i}": np.full(t.size, INPUTS[i]) for i in range(actuator.n_inputs)}
    experiment = sc.Experiment(t, {"x": 0 * t}, inputs, dict.fromkeys(inputs, "Pa"))
    return sc.initial_equilibrium(paper_model, experiment, actuator)


@pytest.fixture(scope="module")
def allocation(paper_model, actuator):
    """Pulling the robot shorter needs negative pressures: every input at its lower bound."""
    allocator = sc.InputAllocator(actuator, paper_model.robot)
    return allocator.allocate([0.066, 8.0, -3.0], [-5.0, 0.0, 0.0])


@pytest.fixture(scope="module")
def step(paper_model, actuator):
    stepper = Stepper(paper_model, actuator, period=0.02, compiled=False)
    x = np.stack([stepper.initial_state([0.0644, 0.0, 0.0])] * 2)
    return stepper.step(x, np.stack([INPUTS, 2 * INPUTS]))


def _options(request, name: str) -> dict:
    """The keywords a result's plot needs: what it does not hold."""
    model, actuator = request.getfixturevalue("paper_model"), request.getfixturevalue("actuator")
    return {
        "equilibrium": {"model": model},
        "inverse": {"model": model},
        "initial": {"model": model},
        "allocation": {"actuator": actuator},
    }.get(name, {})


# (result fixture, number of panels)
PLOTS = [
    ("equilibrium", 2),
    ("linearization", 1),
    ("inverse", 2),
    ("initial", 2),
    ("allocation", 1),
    ("step", 2),
]
IDS = [name for name, _ in PLOTS]


def _points(ax, marker: str) -> np.ndarray:
    """The data of every line drawn with ``marker`` and no line, shape (k, 2)."""
    found = [
        np.column_stack([line.get_xdata(), line.get_ydata()])
        for line in ax.lines
        if line.get_marker() == marker and line.get_linestyle() in ("None", "none", "")
    ]
    return np.concatenate(found) if found else np.empty((0, 2))


@pytest.mark.parametrize(("name", "panels"), PLOTS, ids=IDS)
def test_plot_draws_a_new_figure_or_into_given_axes(request, name, panels):
    result, options = request.getfixturevalue(name), _options(request, name)
    figure = result.plot(**options)
    assert isinstance(figure, Figure) and plt.fignum_exists(figure.number)
    assert len(figure.axes) == panels and all(ax.lines for ax in figure.axes)
    assert all("[" in ax.get_xlabel() and "[" in ax.get_ylabel() for ax in figure.axes)
    mine, axes = plt.subplots(1, panels, squeeze=False)
    assert result.plot(list(axes.ravel()), **options) is mine
    _, too_many = plt.subplots(1, panels + 1)
    with pytest.raises(sc.ParameterError, match=rf"{panels} panel\(s\)"):
        result.plot(list(too_many), **options)


def test_equilibrium_draws_its_backbone_to_its_tip(equilibrium, paper_model, actuator):
    side, top = equilibrium.plot(model=paper_model).axes
    tip = MM_PER_M * equilibrium.tip_position
    np.testing.assert_allclose(_points(side, "o"), [[tip[0], tip[2]]], rtol=1e-12)
    np.testing.assert_allclose(_points(top, "o"), [[tip[0], tip[1]]], rtol=1e-12)
    np.testing.assert_allclose(_points(side, "s"), [[0.0, 0.0]], atol=1e-15)  # the base
    assert (side.get_xlabel(), side.get_ylabel()) == ("x [mm]", "z [mm]")
    assert (top.get_xlabel(), top.get_ylabel()) == ("x [mm]", "y [mm]")
    assert equilibrium.plot(model=paper_model).get_suptitle() == "stable equilibrium"


def test_equilibrium_with_its_inputs_draws_them_against_the_bounds(
    equilibrium, paper_model, actuator
):
    figure = equilibrium.plot(model=paper_model, actuator=actuator, inputs=INPUTS)
    inputs = figure.axes[2]
    m = actuator.n_inputs
    np.testing.assert_allclose(_points(inputs, "o")[:, 1], KPA_PER_PA * INPUTS)
    (bounds,) = inputs.collections  # one bar per input, lower to upper bound
    segments = np.array(bounds.get_segments())
    assert segments.shape == (m, 2, 2)
    np.testing.assert_allclose(segments[:, 0, 1], KPA_PER_PA * actuator.lower)
    np.testing.assert_allclose(segments[:, 1, 1], KPA_PER_PA * actuator.upper)
    assert inputs.get_ylabel() == "pressures [kPa]" and not len(_points(inputs, "x"))
    with pytest.raises(sc.ParameterError, match="both actuator= and inputs="):
        equilibrium.plot(model=paper_model, actuator=actuator)


def test_linearization_draws_one_point_per_eigenvalue(linearization):
    ax = linearization.plot().axes[0]
    drawn = _points(ax, "x")
    s = linearization.eigenvalues
    assert drawn.shape == (s.size, 2)
    np.testing.assert_allclose(np.sort(drawn[:, 0]), np.sort(s.real))
    np.testing.assert_allclose(np.sort(drawn[:, 1]), np.sort(s.imag))
    (stable,) = ax.patches  # the shaded half-plane ends on the imaginary axis
    assert stable.get_x() < s.real.min() and stable.get_x() + stable.get_width() == 0.0
    assert ax.get_xlabel() == "real part Re(s) [1/s]"
    assert ax.get_ylabel() == "imaginary part Im(s) [rad/s]"


def test_eigenvalues_outside_the_stable_half_plane_are_red():
    s = np.array([-1.0 + 2.0j, -1.0 - 2.0j, 0.5, 0.0, np.nan])
    ax = plot_eigenvalues(types.SimpleNamespace(eigenvalues=s, message="test")).axes[0]
    lines = [line for line in ax.lines if line.get_marker() == "x"]
    assert [len(line.get_xdata()) for line in lines] == [2, 2]  # NaN: not drawn
    assert lines[1].get_color() == "tab:red"
    np.testing.assert_array_equal(lines[1].get_xdata(), [0.5, 0.0])


def test_inverse_statics_draws_the_target_reached(inverse, paper_model, actuator):
    side, top, inputs = inverse.plot(model=paper_model, actuator=actuator).axes
    target, tip = MM_PER_M * inverse.target, MM_PER_M * inverse.tip
    np.testing.assert_allclose(_points(side, "*"), [[target[0], target[2]]])
    np.testing.assert_allclose(_points(top, "*"), [[target[0], target[1]]])
    np.testing.assert_allclose(_points(side, "o"), [[tip[0], tip[2]]], rtol=1e-12)
    np.testing.assert_allclose(_points(side, "o"), _points(side, "*"), atol=1e-6)  # reached
    np.testing.assert_allclose(_points(inputs, "o")[:, 1], KPA_PER_PA * inverse.inputs)
    assert len(_points(inputs, "x")) == int(inverse.saturated.sum())


def test_initial_state_marks_the_measured_point(initial, paper_model):
    assert not len(_points(initial.plot(model=paper_model).axes[0], "*"))
    measured = np.array([0.01, 0.002, 0.06])
    side, top = initial.plot(model=paper_model, measured=measured).axes
    np.testing.assert_allclose(_points(side, "*"), [[10.0, 60.0]])
    np.testing.assert_allclose(_points(top, "*"), [[10.0, 2.0]])
    assert "t = 0 s" in initial.plot(model=paper_model).get_suptitle()


def test_allocation_crosses_the_inputs_at_a_bound(allocation, actuator):
    ax = allocation.plot(actuator=actuator).axes[0]
    assert allocation.saturated.all() and allocation.status is sc.Status.INFEASIBLE
    np.testing.assert_allclose(_points(ax, "o")[:, 1], KPA_PER_PA * allocation.inputs)
    assert len(_points(ax, "x")) == actuator.n_inputs
    assert ax.get_ylabel() == "pressures [kPa]" and ax.get_xlabel() == "input [index]"
    assert ax.get_title().startswith("residual")


def test_step_draws_every_member_and_crosses_the_failed(step):
    side, top = step.plot().axes
    tip = MM_PER_M * step.tip
    np.testing.assert_allclose(_points(side, "o"), tip[:, [0, 2]])
    np.testing.assert_allclose(_points(top, "o"), tip[:, [0, 1]])
    failed = types.SimpleNamespace(tip=step.tip, ok=np.array([True, False]), message="one")
    side, _ = plot_member_tips(failed).axes
    np.testing.assert_allclose(_points(side, "o"), tip[:1, [0, 2]])
    np.testing.assert_allclose(_points(side, "x"), tip[1:, [0, 2]])


# -- every result draws, or is named in the documented list of those that do not -----------
def documented_exemptions() -> set[str]:
    """The class names in docs/architecture.md's sentence "Results without a figure: ..."."""
    found = EXEMPTIONS.search(ARCHITECTURE.read_text())
    assert found, "docs/architecture.md has no sentence 'Results without a figure: ...'"
    return set(re.findall(r"`(\w+)`", found["names"]))


def result_classes() -> dict[str, type]:
    """Every subclass of ``Result`` defined in the package, by name (every module but the
    command line's entry point imported, private ones too)."""
    for info in pkgutil.walk_packages(sc.__path__, "softcurve."):
        if not info.name.endswith(".__main__"):  # runs the command line
            importlib.import_module(info.name)
    found, pending = {}, [Result]
    while pending:
        for cls in pending.pop().__subclasses__():
            pending.append(cls)
            if cls.__module__.startswith("softcurve."):
                found[cls.__name__] = cls
    return found


def test_every_result_draws_itself_or_says_why_not():
    classes, exempt = result_classes(), documented_exemptions()
    assert {"Trajectory", "Equilibrium", "ExportedC"} <= set(classes)  # the walk reaches them
    drawing = {
        name for name, cls in classes.items() if inspect.isfunction(getattr(cls, "plot", None))
    }
    missing = sorted(set(classes) - drawing - exempt)
    assert not missing, (
        f"results with neither .plot() nor an entry in {ARCHITECTURE.name}: {missing}"
    )
    for name in sorted(drawing):
        ax = list(inspect.signature(classes[name].plot).parameters.values())[1]
        assert (ax.name, ax.default) == ("ax", None), f"{name}.plot's first argument: {ax}"
    stale = sorted(exempt - (set(classes) - drawing))
    assert not stale, f"{ARCHITECTURE.name} exempts results that draw or do not exist: {stale}"
