"""A shared Returns section (``parameters_from(..., returns=...)``) is written once, last,
in the docstring's own indentation, and never beside a written one."""

from __future__ import annotations

import inspect

import pytest
from numpydoc.docscrape import NumpyDocString

from softcurve.analysis.equilibrium_results import Equilibrium, EquilibriumTable
from softcurve.analysis.linear import Linearization
from softcurve.base.docs import parameters_from
from softcurve.figures import animate, plot_configuration
from softcurve.figures.viewer import equilibria_viewer, trajectory_viewer
from softcurve.simulation import Trajectory

TABLE = {"x": ("float", "A length [m].")}
RETURNS = ("numpy.ndarray, shape (3,)", "The point [m].")


def _returns(function) -> list[tuple[str, str]]:
    """The (type, description) pairs numpydoc reads from the Returns section."""
    section = NumpyDocString(inspect.getdoc(function))["Returns"]
    return [(entry.type or entry.name, " ".join(entry.desc)) for entry in section]


def test_the_section_is_added_after_the_parameters_in_their_indentation():
    class Holder:
        @parameters_from(TABLE, returns=RETURNS)
        def method(self, x):
            """Summary.

            Parameters
            ----------
            %(x)s
            """

    lines = Holder.method.__doc__.splitlines()
    (parameters,) = (line for line in lines if line.strip() == "Parameters")
    (returns,) = (line for line in lines if line.strip() == "Returns")
    assert lines.index(parameters) < lines.index(returns)
    assert returns.removesuffix("Returns") == parameters.removesuffix("Parameters")
    parsed = NumpyDocString(inspect.getdoc(Holder.method))
    assert [p.name for p in parsed["Parameters"]] == ["x"]
    assert _returns(Holder.method) == [RETURNS]


def test_a_written_returns_section_is_refused():
    with pytest.raises(ValueError, match="Returns"):

        @parameters_from(TABLE, returns=RETURNS)
        def f(x):
            """Summary.

            Returns
            -------
            float
            """


def test_a_class_is_refused():
    with pytest.raises(TypeError):

        @parameters_from(TABLE, returns=RETURNS)
        class C:
            """Summary."""


@pytest.mark.parametrize(
    "function",
    [
        Equilibrium.plot,
        EquilibriumTable.plot,
        Linearization.plot,
        Trajectory.plot,
        plot_configuration,
    ],
)
def test_result_figures_return_the_figure(function):
    (entry,) = _returns(function)
    assert entry[0] == "matplotlib.figure.Figure"
    assert "save_figure" in entry[1]


@pytest.mark.parametrize(
    "function",
    [
        Equilibrium.to_html,
        EquilibriumTable.to_html,
        Trajectory.to_html,
        trajectory_viewer,
        equilibria_viewer,
        Trajectory.animate,
        animate,
    ],
)
def test_viewers_and_animations_return_the_path(function):
    assert _returns(function) == [("pathlib.Path", "``path``.")]
