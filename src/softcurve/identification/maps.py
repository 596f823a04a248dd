"""Output and input maps for identification: what a sensor measures, what the inputs do.

An :class:`OutputMap` turns the state into measured signals (a tip IMU's bending
angle, curvatures, a tip position), possibly with sensor offsets; an
:class:`InputMap` turns measured inputs into generalized forces (bellow pressures
through a geometric or a constant pressure map, tendon tensions through their routing,
with an unknown mounting angle).
Both may read named *extra* parameters, which the fits of
:mod:`softcurve.identification.dynamic` can estimate. The functions build CasADi
expressions and work with SX or MX arguments.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError
from softcurve.compiled.model import Model
from softcurve.description.pneumatic import PneumaticActuator
from softcurve.description.tendons import TendonActuator


@dataclass(frozen=True)
class OutputMap:
    """Measured signals as a function of the state: ``y = function(q, qd, values, p)``.

    Built by :func:`bending_angle`, :func:`curvatures` and :func:`tip_position`, or by
    hand for another sensor.

    Parameters
    ----------
    function : callable
        ``function(q, qd, values, p) -> y``: CasADi expressions of the coordinates ``q``
        [m, 1/m, 1/m], their rates ``qd``, the dict ``values`` of named extra parameters
        and the robot's parameter vector ``p``; returns the (k,) outputs.
    names : tuple of str
        Labels of the k outputs, in order.
    units : tuple of str
        Unit of each output (e.g. ``"deg"``, ``"1/m"``), in order.
    parameters : dict of str to float
        The named extra parameters ``function`` reads, with nominal values [unit of
        each parameter].
    """

    function: Callable
    names: tuple[str, ...]
    units: tuple[str, ...]
    parameters: dict


@dataclass(frozen=True)
class InputMap:
    """Generalized forces from measured inputs: ``tau = function(q, u, values)``.

    Built by :func:`bellows_input_map`, :func:`tendon_input_map` and
    :func:`constant_input_map`, or by hand.

    Parameters
    ----------
    function : callable
        ``function(q, u, values) -> tau``: CasADi expressions of the coordinates ``q``
        [m, 1/m, 1/m], the measured inputs ``u`` and the dict ``values`` of named extra
        parameters; returns the (n,) generalized forces [N, N m^2, N m^2] per segment.
    parameters : dict of str to float
        The named extra parameters ``function`` reads, with nominal values [unit of
        each parameter].
    """

    function: Callable
    parameters: dict


def bending_angle(segment: int = 0, *, degrees: bool = True, offset: str | None = None):
    """Signed bending angle ``beta = kx * l`` of one segment, for motion in the x-z plane.

    That is what an IMU at the tip of a single segment measures.

    Parameters
    ----------
    segment : int
        Index of the segment, from the base.
    degrees : bool
        Output in degrees (else radians).
    offset : str, optional
        Name of an extra parameter (sensor zero, nominal 0, in the output's unit) added
        to the output.
    """
    factor = 180.0 / np.pi if degrees else 1.0

    def function(q, qd, values, p):
        y = factor * q[3 * segment] * q[3 * segment + 1]
        return y + (values[offset] if offset else 0)

    return OutputMap(
        function, ("beta",), ("deg" if degrees else "rad",), {offset: 0.0} if offset else {}
    )


def curvatures(segment: int = 0, *, offsets: tuple[str, str] | None = None):
    """``(kx, ky)`` of one segment [1/m], plus optional sensor offsets.

    Parameters
    ----------
    segment : int
        Index of the segment, from the base.
    offsets : tuple of str, optional
        Names of two extra parameters (sensor zeros [1/m], nominal 0) added to
        ``kx`` and ``ky``.
    """

    def function(q, qd, values, p):
        y = ca.vertcat(q[3 * segment + 1], q[3 * segment + 2])
        return y + ca.vertcat(*(values[o] for o in offsets)) if offsets else y

    return OutputMap(
        function, ("kx", "ky"), ("1/m", "1/m"), {o: 0.0 for o in offsets} if offsets else {}
    )


def tip_position(model: Model):
    """Tip position in the world frame [m].

    Parameters
    ----------
    model : Model
        The compiled model whose kinematics gives the tip pose.
    """
    pose = model.symbolic["pose"]

    def function(q, qd, values, p):
        return pose(q, 1.0, p)[1]

    return OutputMap(function, ("x", "y", "z"), ("m", "m", "m"), {})


def _azimuths(values, prefix: str, numbering: int):
    if numbering not in (1, -1):
        raise ParameterError(f"numbering must be +1 (counter-clockwise) or -1, got {numbering!r}")
    return [values[f"{prefix}.angle"] + numbering * 2.0 * np.pi * i / 3.0 for i in range(3)]


def bellows_input_map(
    *, area: float, distance: float, numbering: int = 1, prefix: str = "bellows"
) -> InputMap:
    """Three bellows with ``H(q)`` from geometry (:class:`PneumaticActuator`).

    Extra parameters: ``prefix.area`` [m^2], ``prefix.distance`` [m] and
    ``prefix.angle`` [rad], the azimuth of bellow 0 in the sensor's frame (mounting
    angle); bellow ``i`` sits at ``angle + numbering * 2 pi i / 3``. ``numbering = -1``
    is for bellows numbered clockwise. The inputs are the gauge pressures [Pa].

    Parameters
    ----------
    area : float
        Nominal effective cross-section of every bellow [m^2].
    distance : float
        Nominal distance ``rho`` from the backbone to each bellow's center line [m].
    numbering : int
        +1 for bellows numbered counter-clockwise, -1 for clockwise.
    prefix : str
        Prefix of the extra parameters' names.
    """
    actuator = PneumaticActuator.three_bellows(distance=distance, area=area, p_max=1e9)

    def function(q, u, values):
        geometry = []
        for phi in _azimuths(values, prefix, numbering):
            geometry += [phi, values[f"{prefix}.distance"], values[f"{prefix}.area"]]
        return actuator.input_matrix_symbolic(q, ca.vertcat(*geometry)) @ u

    nominal = {f"{prefix}.area": area, f"{prefix}.distance": distance, f"{prefix}.angle": 0.0}
    return InputMap(function, nominal)


def tendon_input_map(
    *,
    distance: float,
    n_segments: int = 1,
    numbering: int = 1,
    friction: float | None = None,
    prefix: str = "tendons",
) -> InputMap:
    """Three tendons per segment with ``H(q)`` from their routing
    (:meth:`TendonActuator.three_per_segment`: set ``j`` is tied to the tip of segment
    ``j``, the inputs are the tensions [N], proximal set first).

    Extra parameters: ``prefix.distance`` ``rho`` [m] of every tendon and
    ``prefix.angle`` [rad], the azimuth of tendon 0 of each set in the sensor's frame
    (mounting angle); tendon ``i`` of a set sits at ``angle + numbering * 2 pi i / 3``.
    With ``friction`` given, also ``prefix.friction``, the capstan coefficient ``mu`` of
    the routing. From statics alone, ``rho`` and the bending stiffness enter (nearly)
    only as their ratio (``docs/validation.md``, "Tendons"): fix one to fit the other.

    Parameters
    ----------
    distance : float
        Nominal distance ``rho`` from the backbone to each tendon [m].
    n_segments : int
        Number of segments (three tendons each).
    numbering : int
        +1 for tendons numbered counter-clockwise, -1 for clockwise.
    friction : float, optional
        Nominal capstan friction coefficient (dimensionless, >= 0); None for a
        frictionless routing without the extra parameter.
    prefix : str
        Prefix of the extra parameters' names.
    """
    mu = 0.0 if friction is None else friction
    actuator = TendonActuator.three_per_segment(
        distance=distance, t_max=1e9, n_segments=n_segments, friction=mu
    )

    def function(q, u, values):
        geometry = []
        rho = values[f"{prefix}.distance"]
        mu = 0.0 if friction is None else values[f"{prefix}.friction"]
        for _ in range(n_segments):
            for phi in _azimuths(values, prefix, numbering):
                geometry += [phi, rho, mu]
        return actuator.input_matrix_symbolic(q, ca.vertcat(*geometry)) @ u

    nominal = {f"{prefix}.distance": distance, f"{prefix}.angle": 0.0}
    if friction is not None:
        nominal[f"{prefix}.friction"] = float(friction)
    return InputMap(function, nominal)


def constant_input_map(
    *, elongation_gain: float, bending_gain: float, numbering: int = 1, prefix: str = "map"
) -> InputMap:
    """The authors' constant map: ``tau_l = a_e sum p_i``,
    ``(tau_kx, tau_ky) = -a_k sum p_i (cos phi_i, sin phi_i)`` (away from each bellow).

    Extra parameters ``prefix.a_e`` [N/Pa], ``prefix.a_k`` [N m^2/Pa] and
    ``prefix.angle`` [rad] (azimuth of bellow 0, as in :func:`bellows_input_map`).

    Parameters
    ----------
    elongation_gain : float
        Nominal ``a_e`` [N/Pa].
    bending_gain : float
        Nominal ``a_k`` [N m^2/Pa].
    numbering : int
        +1 for bellows numbered counter-clockwise, -1 for clockwise.
    prefix : str
        Prefix of the extra parameters' names.
    """

    def function(q, u, values):
        phi = _azimuths(values, prefix, numbering)
        rows = [
            ca.horzcat(*[values[f"{prefix}.a_e"]] * 3),
            ca.horzcat(*[-values[f"{prefix}.a_k"] * ca.cos(a) for a in phi]),
            ca.horzcat(*[-values[f"{prefix}.a_k"] * ca.sin(a) for a in phi]),
        ]
        return ca.vertcat(*rows) @ u

    nominal = {
        f"{prefix}.a_e": elongation_gain,
        f"{prefix}.a_k": bending_gain,
        f"{prefix}.angle": 0.0,
    }
    return InputMap(function, nominal)
