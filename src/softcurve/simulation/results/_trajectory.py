"""The result of a simulation: :class:`Trajectory` on the output grid."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property
from pathlib import Path

import numpy as np

from softcurve.base.status import Result, Status
from softcurve.compiled import Model
from softcurve.description.actuator import Actuator
from softcurve.figures import animate, plot_states, plot_tip
from softcurve.figures.drawing import model_rows
from softcurve.figures.shapes import result_figure_options
from softcurve.figures.trajectories import animation_options, figure_options
from softcurve.figures.viewer import trajectory_viewer, viewer_options
from softcurve.simulation.results._contact import ContactHistory, contact_along
from softcurve.simulation.results._files import (
    coordinate_columns,
    read_trajectory,
    save_trajectory,
)


@dataclass(frozen=True, eq=False)
class Trajectory(Result):
    """A simulated (or loaded) trajectory on the output grid; immutable.

    Attributes
    ----------
    t : ndarray, shape (T,)
        Output times [s].
    q : ndarray, shape (T, n)
        Coordinates ``(l, kx, ky)`` per segment [m, 1/m, 1/m].
    qd : ndarray, shape (T, n)
        Their rates [m/s, 1/(m s), 1/(m s)].
    lam : ndarray, shape (T, n_creep)
        Creep states, three per segment with creep [unit of the coordinate times that
        of ``Creep.gain``].
    tip_positions : ndarray, shape (T, 3), optional
        Tip positions [m] where known (loaded files, batch members); else :attr:`tip`
        computes them from the model.
    tau : ndarray, shape (T, n), optional
        Generalized input forces [N, N m^2, N m^2] applied from each output time on (zero-order
        hold); with an actuator, the force ``H(q) u`` at each output time.
    inputs : ndarray, shape (T, m), optional
        The actuator's inputs (e.g. chamber pressures [Pa]) when an actuator drove the
        robot (the lagging states with a ``time_constant``); saved as columns ``u1 ...``.
    stats : dict
        ``method``, ``steps``, ``rhs_evaluations``, ``jacobian_evaluations``,
        ``wall_time`` [s] and the tolerances used.
    status : Status
        ``SUCCESS``, ``INTEGRATION_FAILED`` or ``LEFT_DOMAIN`` (a string is parsed).
    message : str
        What happened; on failure, where and what to try.
    model : Model, optional
        The model that was simulated (None for a loaded file).
    actuator : Actuator, optional
        The actuator that drove the robot (None without one, or for a loaded file); the
        viewer draws the tendons of a :class:`~softcurve.TendonActuator`.
    coordinates : tuple of str, optional
        The coordinates' names as a file's columns (``bend_x1 ... stretch1``), where
        they are not the model's: those of a loaded file's metadata (see
        :attr:`coordinate_names`).
    units : tuple of str, optional
        Their units, likewise (see :attr:`coordinate_units`).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    lam: np.ndarray
    tip_positions: np.ndarray | None = field(default=None, repr=False)
    tau: np.ndarray | None = None
    inputs: np.ndarray | None = None
    stats: dict = field(default_factory=dict)
    status: Status = Status.SUCCESS
    message: str = ""
    model: Model | None = field(default=None, repr=False)
    actuator: Actuator | None = field(default=None, repr=False)
    coordinates: tuple[str, ...] | None = field(default=None, repr=False)
    units: tuple[str, ...] | None = field(default=None, repr=False)

    def __post_init__(self):
        object.__setattr__(self, "status", Status.parse(self.status))
        for name in ("coordinates", "units"):
            value = getattr(self, name)
            if value is not None:
                object.__setattr__(self, name, tuple(value))

    @property
    def coordinate_names(self) -> tuple[str, ...]:
        """The name of each coordinate, numbered by its element from 1 (``l1 kx1 ky1``,
        ``bend_x2 ... stretch2``; the columns of a saved file): the model's, else the
        loaded file's, else those of constant-curvature segments (a file that does not
        name them)."""
        if self.model is not None:
            return tuple(coordinate_columns(self.model.robot))
        if self.coordinates is not None:
            return self.coordinates
        return tuple(f"{c}{i + 1}" for i in range(self.n // 3) for c in ("l", "kx", "ky"))

    @property
    def coordinate_units(self) -> tuple[str, ...]:
        """The unit of each coordinate (``"m"``, ``"1/m"``; ``""`` for a strain), from
        the same source as :attr:`coordinate_names`."""
        if self.model is not None:
            return tuple(self.model.robot.coordinate_units())
        if self.units is not None:
            return self.units
        return ("m", "1/m", "1/m") * (self.n // 3)

    @cached_property
    def tip(self) -> np.ndarray:
        """Tip positions (T, 3) [m] in the world frame; computed from the model on first
        access (about 2 us per output time) unless given."""
        if self.tip_positions is not None:
            return self.tip_positions
        if self.t.size == 0:
            return np.empty((0, 3))
        return self._model(None).evaluate_along("pose", self.q, 1.0)[1]

    @property
    def n(self) -> int:
        """Number of coordinates."""
        return self.q.shape[1]

    @property
    def x(self) -> np.ndarray:
        """States ``(q, qd, lam)`` as rows, shape (T, n_state)."""
        return np.hstack([self.q, self.qd, self.lam])

    def _model(self, model) -> Model:
        model = model if model is not None else self.model
        if model is None:
            raise ValueError("this trajectory has no model attached: pass model=Model(robot)")
        model_rows(model, self.q[:1], "the trajectory")
        return model

    def energy(self, model: Model | None = None) -> np.ndarray:
        """Mechanical energy ``T + V`` [J] at every output time, shape (T,).

        Parameters
        ----------
        model : Model, optional
            The model to evaluate with (default the one simulated).
        """
        model = self._model(model)
        terms = model.evaluate_along("dynamics_terms", self.q, self.qd, self.lam)
        mass = terms[0].reshape(-1, self.n, self.n)
        kinetic = 0.5 * np.einsum("ti,tij,tj->t", self.qd, mass, self.qd)
        potential = model.evaluate_along("potential_energy", self.q)  # Vg, Ve (, Vc)
        return kinetic + sum(part[:, 0] for part in potential)

    def contact(self, model: Model | None = None) -> ContactHistory:
        """The force and point of each obstacle on the robot at every output time.

        Parameters
        ----------
        model : Model, optional
            A model with an environment to evaluate with (default the one simulated).

        Returns
        -------
        ContactHistory
            Arrays per obstacle over time; ``.plot()`` draws the forces.
        """
        return contact_along(self._model(model), self.t, self.q, self.qd)

    def save(self, path) -> Path:
        """Write to ``path`` atomically; returns the path.
        :func:`softcurve.load_trajectory` reads it back.

        Parameters
        ----------
        path : str or Path
            Target file, ``.csv`` or ``.npz``.
        """
        return save_trajectory(self, path)

    @result_figure_options
    @figure_options
    def plot(self, ax=None, *, window="auto", inputs=None):
        """The states figure (paper Fig. 4): ``l``, ``kx``, ``ky`` of each segment against
        time, one panel each, and the actuator's inputs below them in an actuated run;
        round-off curvatures of a planar run are drawn as zero.

        Parameters
        ----------
        ax : None or sequence of matplotlib.axes.Axes, shape (3,) or (4,)
            Panels for ``l``, ``kx`` and ``ky`` (and the inputs); None draws a new figure.
        %(window)s
        %(inputs)s
        """
        return plot_states(self, ax, window=window, inputs=inputs)

    @result_figure_options
    @figure_options
    def plot_tip(self, ax=None, *, window="auto"):
        """The 3-D tip trajectory (paper Fig. 5) over the states figure's time window,
        colored by time, on equal axes.

        Parameters
        ----------
        ax : None or matplotlib.axes.Axes, shape (1,)
            A 3-D Axes (``projection="3d"``); None draws a new figure.
        %(window)s
        """
        return plot_tip(self, ax, window=window)

    @animation_options
    def animate(
        self,
        path,
        model: Model | None = None,
        *,
        fps: float = 25,
        speed: float = 1.0,
        points: int = 20,
        dpi: float = 80,
        figsize=(5.0, 5.0),
        window="auto",
        progress: bool = False,
    ) -> Path:
        """Write an animation of the backbone over the motion's time window (the states
        figure's) to ``path``, whole or not at all.

        Parameters
        ----------
        path : str or Path
            ``.gif``, or ``.mp4`` where ffmpeg is on the PATH.
        model : Model, optional
            Gives the backbone shapes (default: the model attached to the trajectory).
        %(fps)s
        %(speed)s
        %(points)s
        %(dpi)s
        %(figsize)s
        %(window)s
        %(progress)s
        """
        return animate(
            self,
            path,
            self._model(model),
            fps=fps,
            speed=speed,
            points=points,
            dpi=dpi,
            figsize=figsize,
            window=window,
            progress=progress,
        )

    @viewer_options
    def to_html(
        self,
        path,
        model: Model | None = None,
        *,
        actuator=None,
        obstacles=(),
        fps: float = 25,
        rings: int = 16,
    ) -> Path:
        """Write the interactive 3-D viewer: one self-contained, offline HTML file showing
        the robot as a tube of its radius, segment by segment, with its base frame, tip
        path and tendons; play/pause, time slider, real-time or slowed playback, orbit
        and zoom (docs/viewer.md; needs the extra ``viewer``: Plotly).

        Parameters
        ----------
        path : str or Path
            The ``.html`` file, written whole or not at all.
        model : Model, optional
            Gives the robot's shape and radii (default: the model attached).
        %(actuator)s
        %(obstacles)s
        %(fps)s
        %(rings)s

        """
        return trajectory_viewer(
            self,
            path,
            self._model(model),
            actuator=self.actuator if actuator is None else actuator,
            obstacles=obstacles,
            fps=fps,
            rings=rings,
        )


def load_trajectory(path) -> Trajectory:
    """Read a trajectory written by :meth:`Trajectory.save`; no model is attached (pass
    one to :meth:`Trajectory.energy` or :meth:`Trajectory.animate`).

    Parameters
    ----------
    path : str or Path
        A ``.csv`` or ``.npz`` file.

    Raises
    ------
    TrajectoryFileError
        A :class:`~softcurve.ParameterError` naming the file, the line (the row of an
        NPZ file) and what is wrong, if the file disagrees with its own metadata: cut
        short, columns that do not match ``n``, a NaN or infinite cell, a time not after
        the one before. A failed run's file, which may end early, loads with its status.
    """
    return Trajectory(**read_trajectory(path))
