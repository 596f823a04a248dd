"""The result of :func:`~softcurve.simulation.batch.simulate_batch`: :class:`BatchTrajectory`."""

from __future__ import annotations

from dataclasses import dataclass, field
from functools import cached_property

import numpy as np

from softcurve.base.status import Result, Status
from softcurve.compiled import Model
from softcurve.description.actuator import Actuator
from softcurve.figures import plot_batch_tips
from softcurve.figures.trajectories import figure_options
from softcurve.simulation.results._trajectory import Trajectory
from softcurve.simulation.solvers import (
    ActuatorInput,
    actuator_exit,
    energy_along,
    failure_message,
    failure_status,
    tip_along,
)


def batch_status(member_status: np.ndarray) -> tuple[Status, str]:
    """The status of a whole batch from its members': ``SUCCESS`` when every member
    succeeded, ``INTEGRATION_FAILED`` when none did, else ``PARTIAL``; and its message.

    Parameters
    ----------
    member_status : ndarray, shape (B,)
        Status of each member.
    """
    failed = np.flatnonzero(member_status != Status.SUCCESS)
    size = member_status.size
    if failed.size == 0:
        return Status.SUCCESS, f"all {size} members reached t_final"
    listed = ", ".join(map(str, failed[:10])) + (", ..." if failed.size > 10 else "")
    status = Status.INTEGRATION_FAILED if failed.size == size else Status.PARTIAL
    return status, (
        f"{failed.size} of {size} members failed (members {listed}): see member_status "
        "and member_message"
    )


def stop_at_actuator_domain(t, x, inputs, outcome, methods, actuator, parameters) -> None:
    """Stop every member at its first output outside the actuator's domain (a tendon
    length or chamber volume <= 0; :func:`~softcurve.simulation.solvers.actuator_exit`),
    in place, before the result is assembled: its later outputs become NaN, its status
    ``LEFT_DOMAIN`` and its message names the actuator element and the time.

    Parameters
    ----------
    t : ndarray, shape (T,)
        Output times [s].
    x : ndarray, shape (B, T, n_state)
        The members' states (NaN after a failure).
    inputs : ndarray, shape (B, T, m) or None
        The members' actuator inputs.
    outcome : tuple
        ``(member_status, messages, reached)`` of the members, changed in place.
    methods : sequence of str
        Each member's integrator family, for the message.
    actuator : Actuator or None
        The actuator (None: nothing to check).
    parameters : ndarray, shape (B, k) or None
        Each member's actuator parameter vector.
    """
    if actuator is None:
        return
    member_status, messages, reached = outcome
    n = actuator.n
    for b in range(x.shape[0]):
        own = actuator if parameters is None else actuator.with_parameter_vector(parameters[b])
        left = actuator_exit(own, t[: reached[b]], x[b, : reached[b], :n])
        if left is None:
            continue
        k, reason = left
        reached[b], member_status[b] = k, failure_status(reason)
        messages[b] = failure_message(reason, t, k, methods[b]) if k else reason
        x[b, k:] = np.nan
        if inputs is not None:
            inputs[b, k:] = np.nan


@dataclass(frozen=True, eq=False)
class BatchTrajectory(Result):
    """``B`` trajectories on one output grid; immutable.

    Attributes
    ----------
    t : ndarray, shape (T,)
        Output times [s], shared by all members.
    q : ndarray, shape (B, T, n)
        Coordinates per member [m, 1/m, 1/m].
    qd : ndarray, shape (B, T, n)
        Rates per member [m/s, 1/(m s), 1/(m s)].
    lam : ndarray, shape (B, T, n_creep)
        Creep states, three per segment with creep [unit of the coordinate times that
        of ``Creep.gain``].
    tau : ndarray, shape (B, n), or None
        The constant input force of each member [N, N m^2, N m^2]; None when an actuator
        drove the members (its force ``H(q) u`` changes along each trajectory).
    parameters : ndarray, shape (B, n_p)
        The parameter vector of each member (``model.robot.layout.names``).
    member_status : ndarray, shape (B,), of Status
        ``SUCCESS``, ``INTEGRATION_FAILED`` or ``LEFT_DOMAIN`` per member.
    member_message : tuple of str, length B
        What happened to each member.
    reached : ndarray, shape (B,), of int
        Number of valid output times per member; after a failure the remaining entries
        of ``q``, ``qd``, ``lam`` and ``tip`` are NaN (never otherwise).
    status : Status
        ``SUCCESS``, ``PARTIAL`` (some members failed) or ``INTEGRATION_FAILED`` (all did).
    message : str
        Which members failed.
    stats : dict
        ``methods`` (per member), ``wall_time`` [s] of the integration, ``threads``,
        ``size``, ``simulated_time`` [s] (summed over members) and the tolerances.
    model : Model, optional
        The model simulated (its robot gives the structure).
    actuator : Actuator, optional
        The actuator that drove the members (with its default parameters), or None.
    inputs : ndarray, shape (B, T, m), optional
        With an actuator: its inputs of each member at every output time [its
        ``input_unit``] (the states of lagging inputs, or the constant inputs); NaN after
        a member's failure.
    actuator_parameters : ndarray, shape (B, k), optional
        With an actuator: each member's actuator parameters
        (``actuator.parameter_names()``).
    """

    t: np.ndarray
    q: np.ndarray
    qd: np.ndarray
    lam: np.ndarray
    tau: np.ndarray | None
    parameters: np.ndarray
    member_status: np.ndarray
    member_message: tuple
    reached: np.ndarray
    status: Status = Status.SUCCESS
    message: str = ""
    stats: dict = field(default_factory=dict)
    model: Model | None = field(default=None, repr=False)
    actuator: Actuator | None = field(default=None, repr=False)
    inputs: np.ndarray | None = None
    actuator_parameters: np.ndarray | None = None

    def __post_init__(self):
        member_status = np.array([Status.parse(s) for s in self.member_status], dtype=object)
        object.__setattr__(self, "member_status", member_status)
        object.__setattr__(self, "member_message", tuple(self.member_message))
        object.__setattr__(self, "status", Status.parse(self.status))

    @cached_property
    def tip(self) -> np.ndarray:
        """Tip positions (B, T, 3) [m] in the world frame, computed on first access; NaN
        where the state is."""
        q = self.q
        tip = tip_along(self.model, np.nan_to_num(q), self.parameters, self.stats["threads"])
        tip[np.isnan(q[..., 0])] = np.nan
        return tip

    @property
    def size(self) -> int:
        """Number of members ``B``."""
        return self.q.shape[0]

    def __len__(self) -> int:
        return self.size

    @property
    def member_success(self) -> np.ndarray:
        """(B,) bool: which members reached ``t_final``."""
        return np.array([s is Status.SUCCESS for s in self.member_status], dtype=bool)

    @property
    def x(self) -> np.ndarray:
        """States ``(q, qd, lam)``, shape (B, T, n_state)."""
        return np.concatenate([self.q, self.qd, self.lam], axis=2)

    def member_model(self, i: int) -> Model:
        """The compiled model with member ``i``'s parameters (shares the compiled library).

        Parameters
        ----------
        i : int
            Member index.
        """
        if np.array_equal(self.parameters[i], self.model.parameters):
            return self.model
        return Model(
            self.model.robot.with_parameter_vector(self.parameters[i]),
            environment=self.model.environment,
            quadrature_nodes=self.model.quadrature_nodes,
            compile=self.model.compiled_library is not None,
        )

    def member_actuator(self, i: int) -> Actuator | None:
        """The actuator of member ``i``, with its actuator parameters; None without one.

        Parameters
        ----------
        i : int
            Member index.
        """
        if self.actuator is None:
            return None
        return self.actuator.with_parameter_vector(self.actuator_parameters[i])

    def member(self, i: int) -> Trajectory:
        """Member ``i`` as the :class:`~softcurve.Trajectory` of a single simulation.

        Parameters
        ----------
        i : int
            Member index (negative counts from the end).
        """
        i = int(i)
        if not -self.size <= i < self.size:
            raise IndexError(f"member index {i} out of range for a batch of {self.size}")
        i %= self.size
        k = int(self.reached[i])
        stats = {key: v for key, v in self.stats.items() if key not in ("methods", "routes")}
        stats["method"], stats["route"] = self.stats["methods"][i], self.stats["routes"][i]
        inputs = None
        if self.actuator is None:
            tau = np.repeat(self.tau[i][None, :], k, axis=0)
        else:  # H(q) u along the trajectory, as simulate() reports it
            inputs = self.inputs[i, :k].copy()
            force = ActuatorInput.of(self.member_actuator(i), self.model.n)
            tau = force.forces(self.q[i, :k], inputs) if k else np.empty((0, self.model.n))
        return Trajectory(
            t=self.t[:k].copy(),
            q=self.q[i, :k].copy(),
            qd=self.qd[i, :k].copy(),
            lam=self.lam[i, :k].copy(),
            tip_positions=self.tip[i, :k].copy(),
            tau=tau,
            inputs=inputs,
            stats=stats,
            status=self.member_status[i],
            message=self.member_message[i],
            model=self.member_model(i),
            actuator=self.member_actuator(i),
        )

    @figure_options
    def plot(self, ax=None, *, members: int = 50):
        """The tip position of the first ``members`` members against time, one panel per
        world axis.

        Parameters
        ----------
        %(ax)s
        %(members)s

        Returns
        -------
        matplotlib.figure.Figure
            Write it with :func:`softcurve.figures.save_figure`.
        """
        return plot_batch_tips(self, ax, members=members)

    def energy(self) -> np.ndarray:
        """Mechanical energy ``T + V`` [J] of every member at every output time, (B, T);
        NaN after a member's failure."""
        return energy_along(self.model, self.q, self.qd, self.parameters, self.stats["threads"])
