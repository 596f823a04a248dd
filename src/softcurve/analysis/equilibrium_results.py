"""Results of the static analysis: one :class:`Equilibrium`, and the
:class:`EquilibriumTable` of all equilibria found in a region."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from softcurve.analysis.loads import StaticLoad
from softcurve.base.status import Result, Status
from softcurve.figures import plot_configuration, plot_equilibria
from softcurve.figures.shapes import result_figure_options
from softcurve.figures.viewer import equilibria_viewer, viewer_options

STABILITY_KINDS = ("stable", "unstable", "saddle", "degenerate")
"""The classification of an equilibrium (see :mod:`softcurve.analysis.statics`)."""

EIGENVALUE_HEADING = "min eig SKS [J]"
"""The heading of :meth:`EquilibriumTable.table`'s smallest eigenvalue: of ``S K S``,
the Hessian of the potential in the dimensionless coordinates ``q / S``, an energy."""


@dataclass(frozen=True, eq=False)
class Equilibrium(Result):
    """One equilibrium (or one representative of a ring of them).

    Attributes
    ----------
    q : ndarray, shape (n,)
        Configuration; for a ring, the member bending toward +x (first bent segment).
    status : Status
        SUCCESS when the solver met the tolerance at a state inside the model's and the
        actuator's domain; LEFT_DOMAIN outside it (the message names the coordinate or
        the actuator element); else NOT_CONVERGED or EVALUATION_LIMIT.
    message : str
        The scaled residual reached, and notes (ring, non-conservative loads).
    stability : str
        ``"stable"``, ``"unstable"`` (local maximum), ``"saddle"`` or ``"degenerate"``.
    continuum : str or None
        ``"ring"`` for a continuum under rotational symmetry, else None.
    eigenvalues : ndarray, shape (n,) or (n - 1,)
        Of the scaled tangent stiffness ``S K S`` [J] (real parts), ascending; for a
        ring, on the complement of the ring's tangent.
    residual : ndarray, shape (n,)
        ``N(q) - loads`` [N, N m^2].
    potential : float
        Total potential of the conservative loads [J].
    tip_position : ndarray, shape (3,)
        World tip position [m].
    curvature : ndarray, shape (N,)
        Bending curvature ``|kappa|`` [1/m] of each element (0 for a rigid body).
    """

    q: np.ndarray
    status: Status
    message: str
    stability: str
    continuum: str | None
    eigenvalues: np.ndarray
    residual: np.ndarray
    potential: float
    tip_position: np.ndarray
    curvature: np.ndarray

    @property
    def unstable_directions(self) -> int:
        """Number of negative eigenvalues (the Morse index)."""
        return int(np.sum(self.eigenvalues < 0))

    @viewer_options
    def to_html(self, path, model, *, actuator=None, obstacles=(), rings: int = 16):
        """Write the interactive 3-D viewer of this equilibrium: one self-contained,
        offline HTML file (docs/viewer.md; needs the extra ``viewer``: Plotly).

        Parameters
        ----------
        path : str or pathlib.Path
            The ``.html`` file, written whole or not at all.
        model : Model
            The model the equilibrium was found for (its shape and radii).
        %(actuator)s
        %(obstacles)s
        %(rings)s

        """
        return equilibria_viewer(
            [self], path, model, actuator=actuator, obstacles=obstacles, rings=rings
        )

    @result_figure_options
    def plot(self, ax=None, *, model, actuator=None, inputs=None):
        """The backbone at the equilibrium from the side (x-z) and from above (x-y), its
        tip marked, titled by its stability; with the actuator's inputs, a third panel of
        them against their bounds.

        Parameters
        ----------
        ax : None or sequence of matplotlib.axes.Axes, shape (2,) or (3,)
            Panels for the side view, the top view and, with ``inputs``, the inputs;
            None draws a new figure.
        %(model)s
        actuator : Actuator, optional
            The actuator the equilibrium was found with; given with ``inputs``.
        inputs : array_like, shape (m,), optional
            Its inputs there [the actuator's ``input_unit``].

        """
        kind = f"{self.stability} equilibrium" + (" (ring)" if self.continuum else "")
        title = kind if self.success else f"{kind}, {self.status.value}"
        return plot_configuration(model, self.q, ax, actuator=actuator, inputs=inputs, title=title)


@dataclass(frozen=True, eq=False)
class EquilibriumTable(Result):
    """All equilibria found in a region, deduplicated, ordered by potential.

    Attributes
    ----------
    equilibria : tuple of Equilibrium
        The distinct equilibria found inside ``bounds``, lowest potential first.
    status : Status
        SUCCESS when at least one equilibrium was found in the region, else
        NOT_CONVERGED (no start converged inside it).
    message : str
        How many equilibria and rings, from how many converged starts.
    starts, converged_starts, evaluations : int
        Multi-start statistics (residual and tangent evaluations in total).
    bounds : ndarray, shape (n, 2)
        The region searched, one ``(low, high)`` row per coordinate [m, 1/m, 1/m]
        per segment.
    load : StaticLoad
        The constant loads the equilibria balance.
    """

    equilibria: tuple[Equilibrium, ...]
    status: Status
    message: str
    starts: int
    converged_starts: int
    evaluations: int
    bounds: np.ndarray
    load: StaticLoad

    def __len__(self) -> int:
        return len(self.equilibria)

    def __iter__(self):
        return iter(self.equilibria)

    def __getitem__(self, i) -> Equilibrium:
        return self.equilibria[i]

    @property
    def stable(self) -> tuple[Equilibrium, ...]:
        """The stable equilibria, lowest potential first."""
        return tuple(e for e in self.equilibria if e.stability == "stable")

    def table(self) -> str:
        """A plain-text table, one row per equilibrium or ring: the coordinates, the net
        curvatures, the potential ``V`` [J] and the smallest eigenvalue of ``S K S`` [J],
        the potential's Hessian in the dimensionless coordinates ``q / S`` (the Hessian
        in ``q`` itself has mixed units, J per product of two coordinates' units)."""
        robot = self.load.model.robot
        headings, forms = [], []
        for i, s in enumerate(robot.segments):
            for name, unit in zip(s.coordinate_names, s.coordinate_units, strict=True):
                heading = f"{name}({i}) [{unit or '-'}]"
                width = max(10, len(heading))
                headings.append(f"{heading:>{width}}")
                forms.append(f"{width}.6f" if unit == "m" else f"{width}.5f")  # m: to the um
        head = f"{'#':>2}  {'stability':<10} {'set':<6} " + " ".join(headings)
        head += f" {'|kappa| [1/m]':>13} {'V [J]':>12} {EIGENVALUE_HEADING:>15}"
        rows = [head]
        for k, e in enumerate(self.equilibria):
            coords = " ".join(f"{v:{f}}" for v, f in zip(e.q, forms, strict=True))
            kappa = ",".join(f"{c:.5f}" for c in e.curvature)
            rows.append(
                f"{k:>2}  {e.stability:<10} {e.continuum or 'point':<6} {coords} {kappa:>13} "
                f"{e.potential:12.5e} {e.eigenvalues[0]:15.4e}"
            )
        return "\n".join(rows)

    @viewer_options
    def to_html(self, path, *, obstacles=(), rings: int = 16):
        """Write the interactive 3-D viewer of the equilibria, one per slider position
        (docs/viewer.md; needs the extra ``viewer``: Plotly); the tendons of the load's
        actuator are drawn.

        Parameters
        ----------
        path : str or pathlib.Path
            The ``.html`` file, written whole or not at all.
        %(obstacles)s
        %(rings)s

        """
        return equilibria_viewer(
            self.equilibria,
            path,
            self.load.model,
            actuator=self.load.actuator,
            obstacles=obstacles,
            rings=rings,
        )

    @result_figure_options
    def plot(self, ax=None):
        """Backbones of every equilibrium in the x-z plane, styled by stability (rings
        drawn by their representative).

        Parameters
        ----------
        ax : None or matplotlib.axes.Axes, shape (1,)
            Where to draw; None draws a new figure.

        """
        return plot_equilibria(self, ax)
