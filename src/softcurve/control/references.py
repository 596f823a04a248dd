"""References for the controllers: ``q_r(t)`` with exact derivatives (CasADi).

:class:`Reference` wraps any CasADi expression of time; :func:`tip_circle` is the
reference of a single segment whose tip runs a horizontal circle, through the
closed-form inverse kinematics :func:`tip_to_coordinates`.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError, real_array, real_scalar


@dataclass(frozen=True)
class ReferenceSample:
    """The reference and its exact time derivatives at one time.

    Attributes
    ----------
    q : ndarray, shape (n,)
        Reference coordinates ``q_r`` [m, 1/m, 1/m] per segment.
    qd : ndarray, shape (n,)
        Their rates ``qd_r`` [m/s, 1/(m s), 1/(m s)] per segment.
    qdd : ndarray, shape (n,)
        Their accelerations ``qdd_r`` [m/s^2, 1/(m s^2), 1/(m s^2)] per segment.
    """

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
    constant_curvature : bool
        Whether the reference is written in the coordinates ``(l, kx, ky)`` of
        constant-curvature segments (:func:`tip_circle`), which a controller then refuses
        on a robot of other elements.
    """

    def __init__(self, expression: Callable, n: int, constant_curvature: bool = False):
        t = ca.SX.sym("t")
        q = ca.vertcat(expression(t))
        if q.shape != (n, 1):
            raise ParameterError(f"the reference expression must have shape ({n},), got {q.shape}")
        qd = ca.jacobian(q, t)
        qdd = ca.jacobian(qd, t)
        self.n = n
        self.constant_curvature = constant_curvature
        self._function = ca.Function("reference", [t], [q, qd, qdd])

    def check_robot(self, robot) -> None:
        """Raise :class:`ParameterError` unless the reference describes ``robot``'s
        coordinates: as many, and, for a reference in ``(l, kx, ky)``, constant-curvature
        segments only.

        Parameters
        ----------
        robot : Robot
            The robot whose coordinates the reference gives.
        """
        if self.n != robot.n:
            raise ParameterError(
                f"reference has {self.n} coordinates, the robot {robot.n}: give one per "
                "coordinate of the robot"
            )
        if self.constant_curvature and not robot.constant_curvature:
            raise ParameterError(
                "reference is written in the coordinates (l, kx, ky) of constant-curvature "
                "segments, the robot has other elements: give it in the robot's coordinates"
            )

    def symbolic(self, t) -> ReferenceSample:
        """The reference and its derivatives at a CasADi time ``t`` (expressions).

        Parameters
        ----------
        t : casadi.SX or casadi.MX
            A scalar time [s].
        """
        q, qd, qdd = self._function(t)
        return ReferenceSample(q, qd, qdd)

    def __call__(self, t: float) -> ReferenceSample:
        q, qd, qdd = (np.array(v, dtype=np.float64).ravel() for v in self._function(float(t)))
        return ReferenceSample(q, qd, qdd)

    @classmethod
    def constant(cls, q) -> Reference:
        """A set point.

        Parameters
        ----------
        q : array_like, shape (n,)
            The constant reference coordinates [m, 1/m, 1/m] per segment.
        """
        q = np.asarray(q, dtype=np.float64)
        return cls(lambda t: ca.DM(q) + 0 * t, q.size)

    @classmethod
    def sinusoid(cls, center, amplitude, frequency: float, phase=0.0) -> Reference:
        """``center + amplitude sin(2 pi frequency t + phase)`` per coordinate.

        Parameters
        ----------
        center : array_like, shape (n,)
            Mean coordinates [m, 1/m, 1/m] per segment.
        amplitude : float or array_like, shape (n,)
            Amplitude per coordinate, in the units of ``center``; a scalar applies to all.
        frequency : float
            Frequency [Hz].
        phase : float or array_like, shape (n,)
            Phase per coordinate [rad]; a scalar applies to all.
        """
        center = np.asarray(center, dtype=np.float64)
        amplitude = np.broadcast_to(np.asarray(amplitude, dtype=np.float64), center.shape)
        phase = np.broadcast_to(np.asarray(phase, dtype=np.float64), center.shape)
        w = 2.0 * math.pi * real_scalar("frequency", frequency, positive=True)
        return cls(
            lambda t: ca.DM(center) + ca.DM(amplitude) * ca.sin(w * t + ca.DM(phase)),
            center.size,
        )


def checked_reference(reference, robot) -> Reference:
    """``reference`` if it is a :class:`Reference` of ``robot``'s coordinates
    (:meth:`Reference.check_robot`), else :class:`ParameterError` saying why.

    Parameters
    ----------
    reference : Reference
        The reference a controller or a plan was given.
    robot : Robot
        The robot it is for.
    """
    if not isinstance(reference, Reference):
        raise ParameterError(f"reference must be a Reference, got {type(reference).__name__}")
    reference.check_robot(robot)
    return reference


def tip_to_coordinates(position):
    """Closed-form inverse kinematics of one constant-curvature segment (CasADi or float).

    The arc from the origin (tangent +z) through ``position = (x, y, z)`` with ``z > 0``:
    ``d = |(x, y)|``, bending angle ``beta = 2 atan2(d, z)``, curvature
    ``kappa = 2 d / (d^2 + z^2)``, length ``l = beta / kappa`` and
    ``(kx, ky) = kappa (x, y) / d``. Requires ``d > 0`` (the tip off the axis).

    Parameters
    ----------
    position : array_like or casadi.SX, shape (3,)
        Tip position in the base frame [m].

    Returns
    -------
    casadi.SX or casadi.DM, shape (3, 1)
        The coordinates ``(l, kx, ky)`` [m, 1/m, 1/m].
    """
    x, y, z = position[0], position[1], position[2]
    d = ca.sqrt(x**2 + y**2)
    beta = 2 * ca.atan2(d, z)
    kappa = 2 * d / (d**2 + z**2)
    return ca.vertcat(beta / kappa, kappa * x / d, kappa * y / d)


def tip_circle(
    center, radius: float, period: float, *, phase: float = 0.0, segments: int = 1
) -> Reference:
    """Reference for a robot whose tip runs a horizontal circle.

    The circle ``center + radius (cos w t, sin w t, 0)`` with ``w = 2 pi / period``,
    in the base frame; it must not pass through the z axis (see
    :func:`tip_to_coordinates`). With several segments the backbone is kept one circular
    arc through the tip, shared equally: each segment has a ``1/segments`` share of the
    arc's length and the arc's curvature ``(kx, ky)`` (the frames of constant-curvature
    segments do not twist, so equal curvatures continue one arc).

    Parameters
    ----------
    center : array_like, shape (3,)
        Center of the circle in the base frame [m]; above the base (z > 0) and farther
        from the z axis than ``radius``.
    radius : float
        Radius of the circle [m].
    period : float
        Time of one revolution [s].
    phase : float
        Angle on the circle at ``t = 0`` [rad].
    segments : int
        Number of segments of the robot (the reference has ``3 segments`` coordinates).
    """
    center = real_array("center", center, (3,))
    radius = real_scalar("radius", radius, positive=True)
    w = 2.0 * math.pi / real_scalar("period", period, positive=True)
    if np.hypot(center[0], center[1]) <= radius or center[2] <= 0:
        raise ParameterError(
            "the tip circle must stay off the z axis (|center_xy| > radius) and above the "
            f"base (center z > 0); got center {center.tolist()}, radius {radius}"
        )

    if isinstance(segments, bool) or not isinstance(segments, int) or segments < 1:
        raise ParameterError(f"segments must be an integer >= 1, got {segments!r}")

    def expression(t):
        point = ca.DM(center) + radius * ca.vertcat(ca.cos(w * t + phase), ca.sin(w * t + phase), 0)
        arc = tip_to_coordinates(point)
        return ca.repmat(ca.vertcat(arc[0] / segments, arc[1], arc[2]), segments, 1)

    return Reference(expression, 3 * segments, constant_curvature=True)
