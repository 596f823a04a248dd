"""Model-based control: computed torque, PD with compensation, and actuator inputs.

Controllers follow the protocol of :func:`softcurve.simulate`: an object with a
``sample_time`` [s] and ``__call__(t, q, qd, lam)``, whose output is held constant
between samples, and an optional ``reset()``. The output is generalized forces
``tau`` (n,), or, for a controller run with ``simulate(..., actuator=...)``, the
actuator's inputs ``u`` (m,) (its commands, when the actuator has a lag), which the
robot receives as ``H(q) u``. :func:`closed_loop_rhs` evaluates a controller at every
right-hand-side call instead: the continuous-time limit, in which computed torque with a
perfect model is exact.

- :class:`ComputedTorque` (feedback linearization): ``tau = ID(q, qd, qdd_r + Kd e' + Kp e,
  lam)`` with ``ID`` the controller model's inverse dynamics (including damping and the
  creep force ``K^T lam``), so a perfect model gives ``e'' + Kd e' + Kp e = 0``.
- :class:`PDGravityElastic`: ``tau = N(q) + Kp (q_r - q) + Kd (qd_r - qd)``.
- :class:`InputAllocator` maps a wanted ``tau`` to bounded actuator inputs by bounded
  least squares (pressures, tensions: never below their lower bound, so never a
  negative tension; a bound that stops the inputs is flagged); :class:`ActuatorDriven` wraps a
  generalized-force controller into one that returns the actuator's inputs (saturated
  and, with the actuator's ``time_constant``, with the lag inverted over one sample).
- :class:`SaturatedInputs` clips the inputs a controller returns to the actuator's
  bounds. ``simulate`` refuses inputs outside them (a controller commanding a negative
  tension stops the run with a ParameterError); a controller whose raw output may leave
  the bounds is run through this wrapper, which records where it clipped.
- References ``q_r(t)`` are in :mod:`softcurve.control.references`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import scipy.optimize

from softcurve.analysis.loads import coordinate_scale
from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError, real_array, real_scalar
from softcurve.control.references import Reference, checked_reference
from softcurve.description.actuator import Actuator
from softcurve.figures import plot_input_bounds
from softcurve.simulation import sample_time as checked_sample_time


# -- controllers ------------------------------------------------------------------------
def _gain(name: str, value, n: int) -> np.ndarray:
    g = np.broadcast_to(np.asarray(value, dtype=np.float64), (n,))
    if not (np.all(np.isfinite(g)) and np.all(g >= 0)):
        raise ParameterError(f"{name} must be finite and >= 0, got {np.asarray(value).tolist()}")
    return g.copy()


class SampledController:
    """Base of the controllers: the sample time and the record of every sample computed.

    Parameters
    ----------
    sample_time : float
        Time between two samples [s], ``>= softcurve.simulation.MIN_TIME`` (about
        1.5e-154 s; ``simulate`` also wants at most ``max_outputs`` samples); the output
        is held in between.
    """

    def __init__(self, sample_time: float):
        self.sample_time = checked_sample_time("sample_time", sample_time)
        self.log: list[dict] = []

    def reset(self) -> None:
        """Forget the record (and any state) before a new run."""
        self.log = []

    def history(self, key: str) -> np.ndarray:
        """One logged quantity over all samples.

        Parameters
        ----------
        key : str
            ``"t"``, ``"tau"``, ``"inputs"``, ... (each controller says what it logs).
        """
        return np.array([entry[key] for entry in self.log])


class ComputedTorque(SampledController):
    """Feedback linearization of a reference trajectory.

    Parameters
    ----------
    model : Model
        The controller's model of the robot (may differ from the simulated one).
    reference : Reference
        ``q_r(t)`` to track.
    kp, kd : float or array_like, shape (n,)
        Gains of the error dynamics ``e'' + kd e' + kp e = 0`` [1/s^2, 1/s].
    sample_time : float
        Time between two samples [s].
    """

    def __init__(self, model, reference: Reference, *, kp, kd, sample_time: float):
        super().__init__(sample_time)
        self.model, self.reference = model, checked_reference(reference, model.robot)
        self.kp, self.kd = _gain("kp", kp, model.n), _gain("kd", kd, model.n)

    def __call__(self, t, q, qd, lam=None) -> np.ndarray:
        r = self.reference(t)
        qdd = r.qdd + self.kd * (r.qd - qd) + self.kp * (r.q - q)
        tau = np.array(self.model.inverse_dynamics(q, qd, qdd, lam))  # own copy for the log
        self.log.append({"t": t, "tau": tau, "error": r.q - q})
        return tau


class PDGravityElastic(SampledController):
    """PD control plus compensation of gravity and elasticity at the current configuration:
    ``tau = N(q) + kp (q_r - q) + kd (qd_r - qd)``.

    Parameters
    ----------
    model : Model
        The controller's model of the robot.
    reference : Reference
        ``q_r(t)``; its rates ``qd_r`` enter the damping term.
    kp, kd : float or array_like, shape (n,)
        Generalized stiffness [N/m, N m^2 per 1/m] and damping [N s/m, N m^2 s per 1/m]
        per coordinate.
    sample_time : float
        Time between two samples [s].
    """

    def __init__(self, model, reference: Reference, *, kp, kd, sample_time: float):
        super().__init__(sample_time)
        self.model, self.reference = model, checked_reference(reference, model.robot)
        self.kp, self.kd = _gain("kp", kp, model.n), _gain("kd", kd, model.n)

    def __call__(self, t, q, qd, lam=None) -> np.ndarray:
        r = self.reference(t)
        tau = self.model.potential_force(q) + self.kp * (r.q - q) + self.kd * (r.qd - qd)
        self.log.append({"t": t, "tau": tau, "error": r.q - q})
        return tau


def closed_loop_rhs(model, controller, *, actuator: Actuator | None = None) -> Callable:
    """``f(t, x) -> xdot`` of the robot under ``controller`` evaluated at every call (no
    hold): the continuous-time closed loop, for SciPy's ``solve_ivp``.

    Parameters
    ----------
    model : Model
        The robot.
    controller : callable
        ``controller(t, q, qd, lam)`` returning ``tau`` (n,), or the actuator's inputs
        (m,) when ``actuator`` is given.
    actuator : Actuator, optional
        The robot then receives ``H(q) u`` (inputs without lag).
    """

    def f(t, x):
        q, qd, lam = model.split_state(x)
        output = controller(t, q, qd, lam)
        tau = output if actuator is None else actuator.input_matrix(q) @ output
        # a fresh array: SciPy keeps the stages it is given
        return np.array(model.state_derivative(x, tau))

    return f


# -- actuator inputs ---------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Allocation(Result):
    """Bounded actuator inputs for a wanted generalized force.

    Attributes
    ----------
    inputs : ndarray, shape (m,)
        The allocated inputs [the actuator's ``input_unit``], within its bounds.
    tau_requested, tau_achieved : ndarray, shape (n,)
        The wanted ``tau`` and the achieved ``H(q) u`` [N, N m^2, N m^2] per segment.
    saturated : ndarray, shape (m,), bool
        True where a bound is active.
    residual : float
        ``|W (H u - tau)|`` [J].
    status : Status
        SUCCESS when ``H u`` meets ``tau`` (to ``tolerance`` of the allocator), else
        INFEASIBLE: the bounds keep the inputs from producing it (the closest is returned).
    message : str
        The residual and the saturated inputs.
    """

    inputs: np.ndarray
    tau_requested: np.ndarray
    tau_achieved: np.ndarray
    saturated: np.ndarray
    residual: float
    status: Status
    message: str

    def plot(self, ax=None, *, actuator):
        """The allocated inputs against the actuator's bounds, those at a bound crossed,
        titled by the residual.

        Parameters
        ----------
        ax : None or matplotlib.axes.Axes, shape (1,)
            Where to draw; None draws a new figure.
        actuator : Actuator
            The actuator allocated for (its bounds, input name and unit).

        Returns
        -------
        matplotlib.figure.Figure
            Write it with :func:`softcurve.figures.save_figure`.
        """
        return plot_input_bounds(
            self.inputs, actuator, ax, saturated=self.saturated, title=self.message
        )


class InputAllocator:
    """``tau -> u``: bounded least squares in energy units.

    Inputs are kept within ``[lower, upper]`` (tensions within ``[t_min, t_max]``,
    ``t_min >= 0``: never negative); a ``tau`` the bounds cannot produce (a tendon would
    have to push) is met as closely as they allow, the inputs at their bounds flagged
    ``saturated``. With more inputs than ``H(q)`` has rank (e.g. four tendons per
    segment) the closest ``H u`` is reached by a set of inputs and BVLS returns one of
    them. For tendons without friction every member of that set has the same total
    tension: for a change ``dT`` in the null space of ``H`` the first segment's bending
    rows (``sum dT_i rho_i (cos phi_i, sin phi_i) = 0``) turn its axial row into
    ``sum dT_i = 0``, so a minimum-total rule (that of
    :func:`~softcurve.analysis.inverse_statics.inverse_statics`) could not choose here.

    Parameters
    ----------
    actuator : Actuator
        The actuator whose inputs are chosen.
    robot : Robot
        Supplies the weights ``W = diag(l0, 1/l0, 1/l0)`` per segment.
    tolerance : float
        An allocation whose residual is below ``tolerance`` times ``|W tau|`` is exact
        (dimensionless).
    """

    def __init__(self, actuator: Actuator, robot, *, tolerance: float = 1e-9):
        actuator.check_robot(robot)
        self.actuator = actuator
        self.weights = coordinate_scale(robot)
        self.tolerance = real_scalar("tolerance", tolerance, positive=True)

    def allocate(self, q, tau) -> Allocation:
        """The inputs within bounds whose ``H(q) u`` is closest to ``tau``.

        Parameters
        ----------
        q : array_like, shape (n,)
            Configuration [m, 1/m, 1/m].
        tau : array_like, shape (n,)
            Wanted generalized forces [N, N m^2].
        """
        h = self.actuator.input_matrix(q)
        tau = real_array("tau", tau, (self.actuator.n,))
        w = self.weights
        lower, upper = self.actuator.lower, self.actuator.upper
        # Column scaling by the input range keeps the problem well conditioned.
        span = upper - lower
        solution = scipy.optimize.lsq_linear(
            (w[:, None] * h) * span[None, :],
            w * (tau - h @ lower),
            bounds=(0.0, 1.0),
            method="bvls",
        )
        u = np.clip(lower + span * solution.x, lower, upper)
        achieved = h @ u
        saturated = (solution.x <= 0.0) | (solution.x >= 1.0)
        residual = float(np.linalg.norm(w * (achieved - tau)))
        exact = residual <= self.tolerance * max(float(np.linalg.norm(w * tau)), 1e-300)
        message = f"residual {residual:.3g} J; {int(saturated.sum())} input(s) at a bound"
        return Allocation(
            inputs=u,
            tau_requested=tau,
            tau_achieved=achieved,
            saturated=saturated,
            residual=residual,
            status=Status.SUCCESS if exact else Status.INFEASIBLE,
            message=message,
        )


class ActuatorDriven(SampledController):
    """A generalized-force controller turned into one that returns actuator inputs.

    At each sample the wrapped controller's ``tau`` is allocated to bounded inputs
    (:class:`InputAllocator`) and the inputs ``u`` (m,) are returned; run it with
    ``simulate(model, q0, qd0, actuator=actuator, controller=driven, ...)``, which
    applies ``H(q) u``. With the actuator's ``time_constant`` the returned values are
    commands, which the inputs follow with the first-order lag; the wrapper tracks the
    inputs by the exact response over each sample (:meth:`Actuator.input_step`).

    With ``compensate_lag`` the command is the one that brings each input to its
    allocated value by the next sample, ``c = (u* - a u) / (1 - a)`` with
    ``a = exp(-sample_time / time_constant)``, saturated to the bounds (the exact inverse
    of the first-order lag over one sample); the inputs then reach their targets one
    sample late instead of with the lag.

    Logged per sample: ``t``, ``tau_wanted``, ``allocated``, ``command``, ``inputs`` (the
    inputs at the sample), ``tau`` (``H(q) u`` with them), ``saturated`` (allocated inputs
    at a bound) and ``command_saturated`` (commands at a bound, after the lag inversion).

    Parameters
    ----------
    controller : callable
        Any controller of the protocol returning ``tau`` (its ``sample_time`` is used).
    actuator : Actuator
        The actuator driving the robot.
    robot : Robot
        The robot (weights of the allocation).
    compensate_lag : bool
        Invert the input lag over one sample (default True; no effect without a lag).
    """

    def __init__(self, controller, actuator: Actuator, robot, *, compensate_lag: bool = True):
        super().__init__(controller.sample_time)
        self.controller = controller
        self.compensate_lag = bool(compensate_lag)
        self.allocator = InputAllocator(actuator, robot)
        self.actuator = actuator
        self.reset()

    def reset(self) -> None:
        """Forget the record, reset the wrapped controller; the inputs start at rest."""
        super().reset()
        if hasattr(self.controller, "reset"):
            self.controller.reset()
        self._inputs = self.actuator.rest_inputs()
        self._command = self._inputs.copy()
        self._time: float | None = None

    def __call__(self, t, q, qd, lam=None) -> np.ndarray:
        if self._time is not None:
            self._inputs = self.actuator.input_step(self._inputs, self._command, t - self._time)
        tau_wanted = np.array(self.controller(t, q, qd, lam), dtype=np.float64)
        allocation = self.allocator.allocate(q, tau_wanted)
        command = allocation.inputs
        lag = self.actuator.time_constant
        if lag is None:
            self._inputs = command
        elif self.compensate_lag:
            a = math.exp(-self.sample_time / lag)
            command = self.actuator.clip((command - a * self._inputs) / (1.0 - a))
        self._command, self._time = command, t
        self.log.append(
            {
                "t": t,
                "tau_wanted": tau_wanted,
                "tau": self.actuator.input_matrix(q) @ self._inputs,
                "allocated": allocation.inputs,
                "command": command,
                "inputs": self._inputs.copy(),
                "saturated": allocation.saturated,
                "command_saturated": at_bound(self.actuator, command),
            }
        )
        return command.copy()


def at_bound(actuator: Actuator, inputs) -> np.ndarray:
    """Which inputs sit on a bound of ``actuator``, shape (m,), bool.

    Parameters
    ----------
    actuator : Actuator
        Gives the bounds ``lower``, ``upper``.
    inputs : array_like, shape (m,)
        Inputs [the actuator's ``input_unit``].
    """
    u = np.asarray(inputs, dtype=np.float64)
    return (u <= actuator.lower) | (u >= actuator.upper)


class SaturatedInputs(SampledController):
    """A controller returning actuator inputs, its output clipped to the actuator's bounds.

    ``simulate(..., actuator=...)`` refuses a controller output outside the bounds (a
    negative tension, a pressure above ``p_max``); wrapped in this, the output is
    saturated instead (:meth:`Actuator.clip`), e.g. a PD law on tensions that would
    command a tendon to push. Logged per sample: ``t``, ``requested`` (the wrapped
    controller's output), ``inputs`` (the clipped inputs returned) and ``saturated``
    (where a bound is active).

    Parameters
    ----------
    controller : callable
        A controller of the protocol returning the actuator's inputs (m,) [its
        ``input_unit``]; its ``sample_time`` is used.
    actuator : Actuator
        Gives the bounds.
    """

    def __init__(self, controller, actuator: Actuator):
        super().__init__(getattr(controller, "sample_time", None))
        self.controller, self.actuator = controller, actuator

    def reset(self) -> None:
        """Forget the record and reset the wrapped controller."""
        super().reset()
        if hasattr(self.controller, "reset"):
            self.controller.reset()

    def __call__(self, t, q, qd, lam=None) -> np.ndarray:
        requested = np.array(self.controller(t, q, qd, lam), dtype=np.float64)
        inputs = self.actuator.clip(requested)
        saturated = at_bound(self.actuator, inputs)
        self.log.append({"t": t, "requested": requested, "inputs": inputs, "saturated": saturated})
        return inputs.copy()
