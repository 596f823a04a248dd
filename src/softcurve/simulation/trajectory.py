"""The result of a simulation: :class:`Trajectory` on the output grid, and the
:class:`State` handed to input callables."""

from __future__ import annotations

from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from softcurve.compiled.model import Model
from softcurve.figures import animate, plot_states, plot_tip
from softcurve.simulation.trajectory_files import read_trajectory, save_trajectory


@dataclass(frozen=True)
class State:
    """The state passed to a ``tau(t, state)`` callable: ``q``, ``qd``, ``lam`` and ``x``."""

    q: np.ndarray
    qd: np.ndarray
    lam: np.ndarray
    x: np.ndarray


@dataclass(eq=False)
class Trajectory:
    """A simulated (or loaded) trajectory on the output grid.

    Attributes
    ----------
    t : ndarray (T,)
        Output times [s].
    q, qd : ndarray (T, n)
        Coordinates ``(l, kx, ky)`` per segment [m, 1/m] and their rates.
    lam : ndarray (T, n_creep)
        Creep states.
    tip : ndarray (T, 3)
        Tip position in the world frame [m]; computed from the model on first access
        (about 2 us per output time), stored in saved files.
    tau : ndarray (T, n) or None
        Input forces applied from each output time on (zero-order hold); with
        ``pressures``, the force ``H(q) p`` at each output time.
    pressures : ndarray (T, m) or None
        The chamber pressures [Pa] when the robot was driven by pressures (the lagging
        states with a ``time_constant``); saved as columns ``p1 ...``.
    stats : dict
        ``method``, ``steps``, ``rhs_evaluations``, ``jacobian_evaluations``,
        ``wall_time`` [s] and the tolerances used.
    status : {"success", "failed"}
    message : str
        What happened; on failure, where and what to try.
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    lam: np.ndarray
    tip_positions: np.ndarray | None = field(default=None, repr=False)
    tau: np.ndarray | None = None
    pressures: np.ndarray | None = None
    stats: dict = field(default_factory=dict)
    status: str = "success"
    message: str = ""
    model: Model | None = field(default=None, repr=False)

    @property
    def tip(self) -> np.ndarray:
        """Tip positions (T, 3) [m] in the world frame."""
        if self.tip_positions is None:
            if self.t.size == 0:
                self.tip_positions = np.empty((0, 3))
            else:
                self.tip_positions = self._model(None).evaluate_along("pose", self.q, 1.0)[1]
        return self.tip_positions

    @property
    def success(self) -> bool:
        return self.status == "success"

    @property
    def n(self) -> int:
        return self.q.shape[1]

    @property
    def x(self) -> np.ndarray:
        """States ``(q, qd, lam)`` as rows, shape (T, n_state)."""
        return np.hstack([self.q, self.qd, self.lam])

    def _model(self, model) -> Model:
        model = model if model is not None else self.model
        if model is None:
            raise ValueError("this trajectory has no model attached: pass model=Model(robot)")
        return model

    def energy(self, model: Model | None = None) -> np.ndarray:
        """Mechanical energy ``T + V`` [J] at every output time, shape (T,)."""
        model = self._model(model)
        terms = model.evaluate_along("dynamics_terms", self.q, self.qd, self.lam)
        mass = terms[0].reshape(-1, self.n, self.n)
        kinetic = 0.5 * np.einsum("ti,tij,tj->t", self.qd, mass, self.qd)
        gravity, elastic = model.evaluate_along("potential_energy", self.q)
        return kinetic + gravity[:, 0] + elastic[:, 0]

    def save(self, path) -> Path:
        """Write to ``path`` (.csv or .npz), atomically; returns the path.
        :func:`softcurve.load_trajectory` reads it back."""
        return save_trajectory(self, path)

    def plot(self, path=None):
        """The states figure (paper Fig. 4): ``l``, ``kx``, ``ky`` against time."""
        return plot_states(self, path)

    def plot_tip(self, path=None):
        """The 3-D tip trajectory (paper Fig. 5)."""
        return plot_tip(self, path)

    def animate(self, path, model: Model | None = None, **options) -> Path:
        """An animation of the backbone, written to ``path`` (.gif, or .mp4 with ffmpeg)."""
        return animate(self, path, self._model(model), **options)


def load_trajectory(path) -> Trajectory:
    """Read a trajectory written by :meth:`Trajectory.save` (.csv or .npz); no model is
    attached (pass one to :meth:`Trajectory.energy` or :meth:`Trajectory.animate`)."""
    return Trajectory(**read_trajectory(path))
