"""Model-based control: computed torque, PD with compensation, and pressure allocation.

Controllers follow the protocol of :func:`softcurve.simulate`: an object with a
``sample_time`` [s] and ``__call__(t, q, qd, lam) -> tau`` (shape (n,)), whose output
is held constant between samples, and an optional ``reset()``. :func:`closed_loop_rhs`
evaluates one at every right-hand-side call instead: the continuous-time limit, in
which computed torque with a perfect model is exact.

- :class:`ComputedTorque` (feedback linearisation): ``tau = ID(q, qd, qdd_r + Kd e' + Kp e,
  lam)`` with ``ID`` the controller model's inverse dynamics (including damping and the
  creep force ``K^T lam``), so a perfect model gives ``e'' + Kd e' + Kp e = 0``.
- :class:`PDGravityElastic`: ``tau = N(q) + Kp (q_r - q) + Kd (qd_r - qd)``.
- :class:`PressureAllocator` maps a wanted ``tau`` to bounded pressures by bounded least
  squares, ``min |W (H(q) p - tau)|`` over ``lower <= p <= upper`` with ``W = diag(S)``
  (energy units, see :mod:`softcurve.statics`); :class:`PressureDriven` wraps a
  controller so that the robot receives ``H(q) p`` from saturated (and, with the
  actuator's ``time_constant``, lagged) pressures.
- :class:`Reference` is ``q_r(t)`` with exact derivatives (CasADi), e.g.
  :func:`tip_circle` for a single segment.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np
import scipy.optimize

from softcurve.analysis.loads import coordinate_scale
from softcurve.base.validation import ParameterError, real_array, real_scalar
from softcurve.description.actuators import Actuator


# -- references -------------------------------------------------------------------------
@dataclass(frozen=True)
class ReferenceSample:
    """``q_r``, ``qd_r``, ``qdd_r`` at one time, each shape (n,)."""

    q: np.ndarray
    qd: np.ndarray
    qdd: np.ndarray


class Reference:
    """A reference trajectory ``q_r(t)`` with exact first and second derivatives.

    Parameters
    ----------
    expression : callable
        ``expression(t) -> q_r`` for a CasADi scalar symbol ``t``; returns an (n,)
        expression built from CasADi operations.
    n : int
        Number of coordinates.
    """

    def __init__(self, expression: Callable, n: int):
        t = ca.SX.sym("t")
        q = ca.vertcat(expression(t))
        if q.shape != (n, 1):
            raise ParameterError(f"the reference expression must have shape ({n},), got {q.shape}")
        qd = ca.jacobian(q, t)
        qdd = ca.jacobian(qd, t)
        self.n = n
        self._function = ca.Function("reference", [t], [q, qd, qdd])

    def __call__(self, t: float) -> ReferenceSample:
        q, qd, qdd = (np.array(v, dtype=np.float64).ravel() for v in self._function(float(t)))
        return ReferenceSample(q, qd, qdd)

    @classmethod
    def constant(cls, q) -> Reference:
        """A set point."""
        q = np.asarray(q, dtype=np.float64)
        return cls(lambda t: ca.DM(q) + 0 * t, q.size)

    @classmethod
    def sinusoid(cls, center, amplitude, frequency: float, phase=0.0) -> Reference:
        """``center + amplitude sin(2 pi frequency t + phase)`` per coordinate."""
        center = np.asarray(center, dtype=np.float64)
        amplitude = np.broadcast_to(np.asarray(amplitude, dtype=np.float64), center.shape)
        phase = np.broadcast_to(np.asarray(phase, dtype=np.float64), center.shape)
        w = 2.0 * math.pi * real_scalar("frequency", frequency, positive=True)
        return cls(
            lambda t: ca.DM(center) + ca.DM(amplitude) * ca.sin(w * t + ca.DM(phase)),
            center.size,
        )


def tip_to_coordinates(position):
    """Closed-form inverse kinematics of one constant-curvature segment (CasADi or float).

    The arc from the origin (tangent +z) through ``position = (x, y, z)`` with ``z > 0``:
    ``d = |(x, y)|``, bending angle ``beta = 2 atan2(d, z)``, curvature
    ``kappa = 2 d / (d^2 + z^2)``, length ``l = beta / kappa`` and
    ``(kx, ky) = kappa (x, y) / d``. Requires ``d > 0`` (the tip off the axis).
    """
    x, y, z = position[0], position[1], position[2]
    d = ca.sqrt(x**2 + y**2)
    beta = 2 * ca.atan2(d, z)
    kappa = 2 * d / (d**2 + z**2)
    return ca.vertcat(beta / kappa, kappa * x / d, kappa * y / d)


def tip_circle(center, radius: float, period: float, *, phase: float = 0.0) -> Reference:
    """Reference for a single segment whose tip runs a horizontal circle.

    The circle ``center + radius (cos w t, sin w t, 0)`` with ``w = 2 pi / period``,
    in the base frame; it must not pass through the z axis (see
    :func:`tip_to_coordinates`).
    """
    center = real_array("center", center, (3,))
    radius = real_scalar("radius", radius, positive=True)
    w = 2.0 * math.pi / real_scalar("period", period, positive=True)
    if np.hypot(center[0], center[1]) <= radius or center[2] <= 0:
        raise ParameterError(
            "the tip circle must stay off the z axis (|center_xy| > radius) and above the "
            f"base (center z > 0); got center {center.tolist()}, radius {radius}"
        )

    def expression(t):
        point = ca.DM(center) + radius * ca.vertcat(ca.cos(w * t + phase), ca.sin(w * t + phase), 0)
        return tip_to_coordinates(point)

    return Reference(expression, 3)


# -- controllers ------------------------------------------------------------------------
def _gain(name: str, value, n: int) -> np.ndarray:
    g = np.broadcast_to(np.asarray(value, dtype=np.float64), (n,))
    if not (np.all(np.isfinite(g)) and np.all(g >= 0)):
        raise ParameterError(f"{name} must be finite and >= 0, got {np.asarray(value).tolist()}")
    return g.copy()


class _Sampled:
    """Sample time and the record of every sample a controller computed."""

    def __init__(self, sample_time: float):
        self.sample_time = real_scalar("sample_time", sample_time, positive=True)
        self.log: list[dict] = []

    def reset(self) -> None:
        self.log = []

    def history(self, key: str) -> np.ndarray:
        """One logged quantity (e.g. ``"t"``, ``"tau"``, ``"pressures"``) over all samples."""
        return np.array([entry[key] for entry in self.log])


class ComputedTorque(_Sampled):
    """Feedback linearisation of a reference trajectory.

    Parameters
    ----------
    model : Model
        The controller's model of the robot (may differ from the simulated one).
    reference : Reference
    kp, kd : float or array_like, shape (n,)
        Gains of the error dynamics ``e'' + kd e' + kp e = 0`` [1/s^2, 1/s].
    sample_time : float
        [s].
    """

    def __init__(self, model, reference: Reference, *, kp, kd, sample_time: float):
        super().__init__(sample_time)
        if reference.n != model.n:
            raise ParameterError(f"reference has n = {reference.n}, model n = {model.n}")
        self.model, self.reference = model, reference
        self.kp, self.kd = _gain("kp", kp, model.n), _gain("kd", kd, model.n)

    def __call__(self, t, q, qd, lam=None) -> np.ndarray:
        r = self.reference(t)
        qdd = r.qdd + self.kd * (r.qd - qd) + self.kp * (r.q - q)
        tau = np.array(self.model.inverse_dynamics(q, qd, qdd, lam))  # own copy for the log
        self.log.append({"t": t, "tau": tau, "error": r.q - q})
        return tau


class PDGravityElastic(_Sampled):
    """PD control plus compensation of gravity and elasticity at the current configuration:
    ``tau = N(q) + kp (q_r - q) + kd (qd_r - qd)``.

    Parameters
    ----------
    model : Model
    reference : Reference
    kp, kd : float or array_like, shape (n,)
        [N/m, N m^2 per 1/m ...]: generalized stiffness and damping per coordinate.
    sample_time : float
    """

    def __init__(self, model, reference: Reference, *, kp, kd, sample_time: float):
        super().__init__(sample_time)
        self.model, self.reference = model, reference
        self.kp, self.kd = _gain("kp", kp, model.n), _gain("kd", kd, model.n)

    def __call__(self, t, q, qd, lam=None) -> np.ndarray:
        r = self.reference(t)
        tau = self.model.potential_force(q) + self.kp * (r.q - q) + self.kd * (r.qd - qd)
        self.log.append({"t": t, "tau": tau, "error": r.q - q})
        return tau


def closed_loop_rhs(model, controller) -> Callable:
    """``f(t, x) -> xdot`` of the robot under ``controller`` evaluated at every call (no
    hold): the continuous-time closed loop, for SciPy's ``solve_ivp``."""

    def f(t, x):
        q, qd, lam = model.split_state(x)
        # a fresh array: SciPy keeps the stages it is given
        return np.array(model.state_derivative(x, controller(t, q, qd, lam)))

    return f


# -- pressures --------------------------------------------------------------------------
def pressure_input(actuator: Actuator, pressures) -> Callable:
    """A ``tau(t, state)`` input for :func:`softcurve.simulate` from bellow pressures.

    ``pressures`` is a constant array (m,) [Pa] or a callable ``pressures(t) -> (m,)``;
    each value is checked against the bounds (:class:`ParameterError` names the entry),
    and the robot receives ``H(q) p`` at the current configuration, held like any
    callable input between output times.
    """
    if callable(pressures):
        schedule = pressures
    else:
        constant = actuator.check_inputs(pressures)

        def schedule(t):
            return constant

    def tau(t, state):
        p = actuator.check_inputs(schedule(t), name=f"pressures at t = {t:g} s")
        return actuator.input_matrix(state.q) @ p

    return tau


@dataclass(frozen=True)
class Allocation:
    """Bounded pressures for a wanted generalized force.

    pressures (m,) [Pa]; tau_requested, tau_achieved (n,); saturated (m,) bool, True where
    a bound is active; residual: ``|W (H p - tau)|`` [J].
    """

    pressures: np.ndarray
    tau_requested: np.ndarray
    tau_achieved: np.ndarray
    saturated: np.ndarray
    residual: float


class PressureAllocator:
    """``tau -> p``: bounded least squares in energy units.

    Parameters
    ----------
    actuator : Actuator
    robot : Robot
        Supplies the weights ``W = diag(l0, 1/l0, 1/l0)`` per segment.
    """

    def __init__(self, actuator: Actuator, robot):
        actuator.check_robot(robot)
        self.actuator = actuator
        self.weights = coordinate_scale(robot)

    def allocate(self, q, tau) -> Allocation:
        """The pressures within bounds whose ``H(q) p`` is closest to ``tau``."""
        h = self.actuator.input_matrix(q)
        tau = real_array("tau", tau, (self.actuator.n,))
        w = self.weights
        lower, upper = self.actuator.lower, self.actuator.upper
        # Column scaling by the pressure range keeps the problem well conditioned.
        span = upper - lower
        solution = scipy.optimize.lsq_linear(
            (w[:, None] * h) * span[None, :],
            w * (tau - h @ lower),
            bounds=(0.0, 1.0),
            method="bvls",
        )
        p = np.clip(lower + span * solution.x, lower, upper)
        achieved = h @ p
        saturated = (solution.x <= 0.0) | (solution.x >= 1.0)
        return Allocation(p, tau, achieved, saturated, float(np.linalg.norm(w * (achieved - tau))))


class PressureDriven(_Sampled):
    """A generalized-force controller driving the robot through bounded pressures.

    At each sample the wrapped controller's ``tau`` is allocated to pressures
    (:class:`PressureAllocator`); with the actuator's ``time_constant`` the pressures
    follow their commands with the exact first-order response over the previous
    sample; the robot receives ``H(q) p`` held until the next sample.

    With ``compensate_lag`` the command is the one that brings each pressure to its
    allocated value by the next sample, ``c = (p* - a p) / (1 - a)`` with
    ``a = exp(-sample_time / time_constant)``, saturated to the bounds (the exact inverse
    of the first-order lag over one sample); the pressures then reach their targets one
    sample late instead of with the lag.

    Parameters
    ----------
    controller
        Any controller of the protocol (its ``sample_time`` is used).
    actuator : Actuator
    robot : Robot
    compensate_lag : bool
        Invert the pressure lag over one sample (default True; no effect without a lag).
    """

    def __init__(self, controller, actuator: Actuator, robot, *, compensate_lag: bool = True):
        super().__init__(controller.sample_time)
        self.controller = controller
        self.compensate_lag = bool(compensate_lag)
        self.allocator = PressureAllocator(actuator, robot)
        self.actuator = actuator
        self.reset()

    def reset(self) -> None:
        super().reset()
        if hasattr(self.controller, "reset"):
            self.controller.reset()
        self._pressures = self.actuator.clip(np.zeros(self.actuator.n_inputs))
        self._command = self._pressures.copy()
        self._time: float | None = None

    def __call__(self, t, q, qd, lam=None) -> np.ndarray:
        if self._time is not None:
            self._pressures = self.actuator.input_step(
                self._pressures, self._command, t - self._time
            )
        tau_wanted = np.array(self.controller(t, q, qd, lam), dtype=np.float64)
        allocation = self.allocator.allocate(q, tau_wanted)
        command = allocation.pressures
        lag = self.actuator.time_constant
        if lag is None:
            self._pressures = command
        elif self.compensate_lag:
            a = math.exp(-self.sample_time / lag)
            command = self.actuator.clip((command - a * self._pressures) / (1.0 - a))
        self._command, self._time = command, t
        tau = self.actuator.input_matrix(q) @ self._pressures
        self.log.append(
            {
                "t": t,
                "tau_wanted": tau_wanted,
                "tau": tau,
                "allocated": allocation.pressures,
                "command": command,
                "pressures": self._pressures.copy(),
                "saturated": allocation.saturated,
            }
        )
        return tau
