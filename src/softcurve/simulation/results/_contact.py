"""The contact along a trajectory: :class:`ContactHistory`, what
:meth:`softcurve.Trajectory.contact` returns (docs/contact.md)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError
from softcurve.figures.obstacles import plot_contact_forces


def _label(index: int, obstacle) -> str:
    return f"{index}: {type(obstacle).__name__.lower()}"


@dataclass(frozen=True, eq=False)
class ContactHistory(Result):
    """The contact of a robot with its obstacles at every output time; immutable (its
    arrays are read-only).

    Attributes
    ----------
    t : ndarray, shape (T,)
        Output times [s].
    forces : ndarray, shape (T, n_obstacles, 3)
        Total force [N] each obstacle exerts on the robot, base frame (zero out of
        contact).
    points : ndarray, shape (T, n_obstacles, 3)
        Its point of application [m], base frame: the force-weighted mean of the
        contact points; NaN out of contact.
    generalized : ndarray, shape (T, n)
        Generalized contact force ``sum J^T F`` [N, N m^2, N m^2 per segment].
    energy : ndarray, shape (T,)
        Penalty energy ``V_c`` [J].
    labels : tuple of str
        One name per obstacle, ``"<index>: <kind>"``.
    status : Status
        SUCCESS (the history of a failed trajectory covers the times it reached).
    message : str
        What was computed.
    """

    t: np.ndarray
    forces: np.ndarray
    points: np.ndarray
    generalized: np.ndarray
    energy: np.ndarray
    labels: tuple
    status: Status = Status.SUCCESS
    message: str = ""

    def __post_init__(self):
        for name in ("t", "forces", "points", "generalized", "energy"):
            array = np.array(getattr(self, name), dtype=np.float64)
            array.setflags(write=False)
            object.__setattr__(self, name, array)

    @property
    def magnitude(self) -> np.ndarray:
        """``|F|`` [N] of each obstacle's force, shape (T, n_obstacles)."""
        return np.linalg.norm(self.forces, axis=2)

    @property
    def in_contact(self) -> np.ndarray:
        """Whether each obstacle touches the robot, shape (T, n_obstacles), bool."""
        return np.any(self.forces != 0.0, axis=2)

    def plot(self, ax=None):
        """The forces of the obstacles against time: magnitudes, then components.

        Parameters
        ----------
        ax : None or sequence of matplotlib.axes.Axes, shape (2,)
            Panels for the magnitudes and the components; None draws a new figure.

        Returns
        -------
        matplotlib.figure.Figure
            Write it with :func:`softcurve.save_figure`.
        """
        return plot_contact_forces(self, ax)


def contact_along(model, t, q, qd) -> ContactHistory:
    """The :class:`ContactHistory` of ``model`` at the states ``q``, ``qd`` (one compiled
    map over the times, in CasADi's virtual machine).

    Parameters
    ----------
    model : Model
        A model with an environment.
    t : ndarray, shape (T,)
        Times [s].
    q : ndarray, shape (T, n)
        Coordinates [m, 1/m, 1/m].
    qd : ndarray, shape (T, n)
        Rates [m/s, 1/(m s), 1/(m s)].
    """
    environment = model.environment
    if environment is None:
        raise ParameterError(
            "the model has no environment: simulate with Model(robot, environment=...) "
            "or pass such a model to contact(model=...)"
        )
    count = len(environment.obstacles)
    labels = tuple(_label(i, o) for i, o in enumerate(environment.obstacles))
    if len(t) == 0:
        empty = np.empty((0, count, 3))
        return ContactHistory(t, empty, empty, np.empty((0, model.n)), np.empty(0), labels)
    generalized, energy, forces, points = model.evaluate_along("contact", q, qd)
    forces = forces.reshape(-1, 3, count).transpose(0, 2, 1)  # (3, count) rows per time
    points = points.reshape(-1, 3, count).transpose(0, 2, 1).copy()
    points[~np.any(forces != 0.0, axis=2)] = np.nan
    return ContactHistory(
        t=t,
        forces=forces,
        points=points,
        generalized=generalized,
        energy=energy[:, 0],
        labels=labels,
        message=f"contact with {count} obstacle(s) at {len(t)} times",
    )
