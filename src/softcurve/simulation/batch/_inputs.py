"""Batches driven by an actuator: per-member inputs and actuator parameters.

:func:`~softcurve.simulation.batch.simulate_batch` takes, besides constant forces
``tau``, an :class:`~softcurve.Actuator` with constant inputs ``u`` per member (pressures,
tensions; commands when the actuator lags) and, optionally, the actuator's parameters
per member (``actuator.parameter_names()``: a tendon's routing distance, azimuth and
friction, a bellow's area, ...). The force ``H(q; theta) u`` is evaluated along each
member's trajectory inside the integrator, exactly as
:func:`~softcurve.simulation.simulate` does for one robot: members with equal
actuator parameters share one actuator and one integrator
(:class:`~softcurve.simulation.solvers.ActuatorInput`), built once per distinct
parameter vector (a few milliseconds each); the robot parameters stay run-time inputs.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.description.actuator import Actuator
from softcurve.simulation.solvers import ActuatorInput, lag_scale


def member_rows(name: str, value, width: int, default=None) -> np.ndarray | None:
    """``value`` as (B, width) or (1, width) float64, finite; None is ``default`` as one
    row, or stays None.

    Parameters
    ----------
    name : str
        The argument's name, for messages.
    value : array_like, shape (B, width) or (width,), or None
        Per-member rows, or one row shared by every member.
    width : int
        Entries per member.
    default : array_like, shape (width,), optional
        The row when ``value`` is None.
    """
    if value is None:
        return None if default is None else np.asarray(default, dtype=np.float64)[None, :]
    try:
        a = np.array(value, dtype=np.float64)
    except (TypeError, ValueError):
        raise ParameterError(f"{name} must be a real array of shape (B, {width})") from None
    if a.ndim == 1:
        a = a[None, :]
    if a.ndim != 2 or a.shape[1] != width or a.shape[0] < 1:
        raise ParameterError(
            f"{name} must have shape (B, {width}) or ({width},), got {np.shape(value)}"
        )
    bad = ~np.all(np.isfinite(a), axis=1)
    if np.any(bad):
        raise ParameterError(
            f"{name}[{int(np.argmax(bad))}] must be finite, got {a[np.argmax(bad)].tolist()}"
        )
    return a


def drive_arrays(model, tau, actuator, inputs, actuator_parameters, actuator_state=None) -> dict:
    """The per-member arrays of what drives a batch's members: ``{"tau": (B, n)}``, or
    with an actuator ``{"inputs": (B, m), "actuator_parameters": (B, k)}`` and, when it
    lags, ``"actuator_state": (B, m)`` (B may be 1: shared); the arguments of
    :func:`~softcurve.simulation.batch.simulate_batch`.

    Parameters
    ----------
    model : Model
        The compiled model.
    tau : array_like, shape (B, n) or (n,), or None
        Constant forces [N, N m^2, N m^2] (default zero), without an actuator.
    actuator : Actuator or None
        The actuator driving every member.
    inputs : array_like, shape (B, m) or (m,), or None
        Its inputs per member, required with ``actuator``.
    actuator_parameters : array_like, shape (B, k) or (k,), or None
        Its parameters per member (default ``actuator.parameter_vector()``).
    actuator_state : array_like, shape (B, m) or (m,), or None
        The lagging inputs at the start per member (default zero clipped into the bounds).
    """
    n = model.n
    if actuator is None:
        if inputs is not None or actuator_parameters is not None or actuator_state is not None:
            raise ParameterError(
                "inputs, actuator_parameters and actuator_state are an actuator's: give "
                "actuator= too (an Actuator)"
            )
        return {"tau": member_rows("tau", tau, n, np.zeros(n))}
    if not isinstance(actuator, Actuator):
        raise ParameterError(
            f"actuator must be a softcurve.Actuator (e.g. TendonActuator), "
            f"got {type(actuator).__name__}"
        )
    if tau is not None or inputs is None:
        raise ParameterError("with an actuator, give inputs= (the actuator's inputs), not tau")
    actuator.check_robot(model.robot)
    theta = actuator.parameter_vector()
    arrays = {
        "inputs": member_rows("inputs", inputs, actuator.n_inputs),
        "actuator_parameters": member_rows(
            "actuator_parameters", actuator_parameters, theta.size, theta
        ),  # fmt: skip
    }
    if actuator.time_constant is not None or actuator_state is not None:
        start = member_rows(
            "actuator_state", actuator_state, actuator.n_inputs, actuator.lag_start()
        )
        shared = start.shape[0] == 1
        for b, row in enumerate(start):
            actuator.lag_start(row, "actuator_state" if shared else f"actuator_state[{b}]")
        arrays["actuator_state"] = start
    return arrays


@dataclass(frozen=True, eq=False)
class Drives:
    """The actuator inputs of a batch's members, grouped by their actuator parameters.

    Built by :meth:`of`; members ``members[g]`` share the actuator ``actuators[g]`` and
    its integrator input ``inputs[g]``.

    Parameters
    ----------
    actuator : Actuator
        The actuator as given (its parameters are the default).
    actuators : tuple of Actuator
        One per group of members with equal parameters.
    inputs : tuple of ActuatorInput
        Their inputs to the integrator, one per group.
    group : ndarray, shape (B,), of int
        The group of each member.
    """

    actuator: Actuator
    actuators: tuple
    inputs: tuple
    group: np.ndarray

    @classmethod
    def of(cls, actuator: Actuator, n: int, inputs, parameters) -> Drives:
        """Check every member's inputs against the bounds and its parameters as an actuator.

        Parameters
        ----------
        actuator : Actuator
            The actuator of every member.
        n : int
            Number of generalized coordinates of the robot.
        inputs : ndarray, shape (B, m)
            Constant inputs (or commands) per member [``actuator.input_unit``].
        parameters : ndarray, shape (B, k)
            Actuator parameters per member (``actuator.parameter_names()``).
        """
        for row in np.unique(inputs, axis=0):
            b = int(np.flatnonzero(np.all(inputs == row, axis=1))[0])
            actuator.check_inputs(row, f"inputs[{b}]")  # inputs[3][0] = 12.0 N is outside...
        distinct, group = np.unique(parameters, axis=0, return_inverse=True)
        actuators = []
        for g, theta in enumerate(distinct):
            try:
                actuators.append(actuator.with_parameter_vector(theta))
            except ParameterError as exc:
                b = int(np.flatnonzero(group.ravel() == g)[0])
                raise ParameterError(f"actuator_parameters[{b}]: {exc}") from None
        drives = tuple(ActuatorInput.of(a, n) for a in actuators)
        return cls(actuator, tuple(actuators), drives, group.ravel().astype(int))

    @property
    def lag(self) -> bool:
        """Whether the inputs lag their commands (extra states after ``(q, qd, lam)``)."""
        return self.actuator.time_constant is not None

    def extended(self, x0: np.ndarray, nominal: np.ndarray, start: np.ndarray):
        """``(x0, nominal)`` (B, n_state [+ m]): with a lag, the inputs start at ``start``,
        on the scale of their largest bound (as in
        :func:`~softcurve.simulation.simulate`).

        Parameters
        ----------
        x0 : ndarray, shape (B, n_state)
            Initial states.
        nominal : ndarray, shape (B, n_state)
            Their scales.
        start : ndarray, shape (B, m)
            The lagging inputs at the start (``drive_arrays``'s ``"actuator_state"``).
        """
        if not self.lag:
            return x0, nominal
        a, size = self.actuator, x0.shape[0]
        scale = np.broadcast_to(lag_scale(a), (size, a.n_inputs))
        return np.hstack([x0, start]), np.hstack([nominal, scale])

    def initial_forces(self, q0: np.ndarray, x0: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """``H(q0) u0`` (B, n) per member: ``u0`` the inputs, or their initial states
        when they lag; the force at which the integrator family is chosen.

        Parameters
        ----------
        q0 : ndarray, shape (B, n)
            Initial coordinates [m, 1/m, 1/m].
        x0 : ndarray, shape (B, n_state + extra)
            Initial states, with the inputs' after ``(q, qd, lam)`` when they lag.
        inputs : ndarray, shape (B, m)
            The members' inputs (commands when they lag).
        """
        start = x0[:, x0.shape[1] - inputs.shape[1] :] if self.lag else inputs
        forces = np.empty_like(q0)
        for g, drive in enumerate(self.inputs):
            members = np.flatnonzero(self.group == g)
            forces[members] = drive.forces(q0[members], start[members])
        return forces

    def forces(self, member: int, q: np.ndarray, inputs: np.ndarray) -> np.ndarray:
        """``H(q_k) u_k`` (T, n) along one member's trajectory.

        Parameters
        ----------
        member : int
            Index of the member.
        q : ndarray, shape (T, n)
            Its coordinates [m, 1/m, 1/m].
        inputs : ndarray, shape (T, m)
            Its actuator inputs at the same times.
        """
        if q.shape[0] == 0:
            return np.empty((0, q.shape[1]))
        return self.inputs[self.group[member]].forces(q, inputs)
