"""Input maps: generalized forces from measured inputs, with parameters to identify.

Every builder returns an :class:`~softcurve.identification.maps.InputMap` whose
geometry is made of *named extra parameters* a fit can estimate:

- :func:`bellows_input_map`: pneumatic chambers, ``H(q)`` from geometry
  (:class:`~softcurve.description.bellows.PneumaticActuator`);
- :func:`tendon_input_map`: tendons, ``H(q)`` from their routing
  (:class:`~softcurve.description.tendons.TendonActuator`);
- :func:`constant_input_map`: the authors' constant pressure map;
- :func:`actuator_input_map`: any :class:`~softcurve.Actuator`, its parameter vector
  (the ``theta`` of ``input_matrix_symbolic``) optionally identified.

Chambers and tendons ("parts") each have a gain (dimensionless, nominal 1: a real
chamber's effective area or a tendon's efficiency relative to the nominal one), an
azimuth and the segments they act on; the whole set is rotated by a mounting angle. A
part ``i`` of a map with prefix ``P`` reads ``P[i].gain`` and ``P[i].azimuth`` [rad]
(at ``P.angle + P[i].azimuth``), and ``P.distance`` [m] (or ``P[i].distance`` with one
distance per part). Redundant sets cannot be estimated together: free ``P.angle`` or
one part's azimuth, not both; free the area (bellows) or one part's gain, not both.
"""

from __future__ import annotations

from collections.abc import Sequence

import casadi as ca
import numpy as np

from softcurve.base.validation import ParameterError, real_array, real_scalar, whole_count
from softcurve.description.actuator import Actuator
from softcurve.description.bellows import Bellows, PneumaticActuator
from softcurve.description.tendons import Tendon, TendonActuator
from softcurve.identification.maps._types import InputMap

UNBOUNDED = 1e9
"""Input bound of the actuators built here [Pa or N]: a map does not check bounds."""


def _numbering(numbering) -> int:
    if numbering not in (1, -1):
        raise ParameterError(f"numbering must be +1 (counter-clockwise) or -1, got {numbering!r}")
    return int(numbering)


def _count(kind: str, n_segments, **given) -> int:
    """The number of parts: the length of the sequences given (equal), else 3 per segment."""
    whole_count("n_segments", n_segments)
    lengths = {k: len(v) for k, v in given.items() if v is not None}
    if len(set(lengths.values())) > 1:
        raise ParameterError(f"one entry per {kind} in each of {sorted(lengths)}, got {lengths}")
    count = next(iter(lengths.values()), 3 * int(n_segments))
    if count < 1:
        raise ParameterError(f"at least one {kind} is needed, got {lengths}")
    return count


def _default_groups(kind: str, field: str, count: int, n_segments: int) -> list[int]:
    if count % n_segments:
        raise ParameterError(
            f"{count} {kind}s cannot be shared evenly by {n_segments} segments: give {field}"
        )
    return [i // (count // n_segments) for i in range(count)]


def _azimuths(azimuths, groups: list, numbering: int) -> list[float]:
    """Given azimuths [rad], or each group's parts evenly spaced, counted ``numbering``."""
    if azimuths is not None:
        return [real_scalar(f"azimuths[{i}]", a) for i, a in enumerate(azimuths)]
    members = {g: [i for i, h in enumerate(groups) if h == g] for g in groups}
    return [
        numbering * 2.0 * np.pi * members[g].index(i) / len(members[g])
        for i, g in enumerate(groups)
    ]


def _part_parameters(prefix, count, distance, azimuths, gains) -> tuple[dict, list]:
    """The extra parameters of the parts and, per part, ``values -> (phi, rho, gain)``."""
    nominal = {f"{prefix}.angle": 0.0}
    if np.ndim(distance) == 0:
        nominal[f"{prefix}.distance"] = real_scalar("distance", distance, positive=True)
        rho = [f"{prefix}.distance"] * count
    else:
        values = real_array("distance", distance, (count,))
        if not np.all(values > 0):
            raise ParameterError(f"distance must be > 0 [m] for every part, got {distance!r}")
        rho = [f"{prefix}[{i}].distance" for i in range(count)]
        nominal.update(zip(rho, values.tolist(), strict=True))
    gains = np.ones(count) if gains is None else real_array("gains", gains, (count,))
    for i in range(count):
        nominal[f"{prefix}[{i}].azimuth"] = float(azimuths[i])
        nominal[f"{prefix}[{i}].gain"] = float(gains[i])

    def geometry(values, i):
        phi = values[f"{prefix}.angle"] + values[f"{prefix}[{i}].azimuth"]
        return phi, values[rho[i]], values[f"{prefix}[{i}].gain"]

    return nominal, geometry


def bellows_input_map(
    *,
    area: float,
    distance,
    numbering: int = 1,
    prefix: str = "bellows",
    n_segments: int = 1,
    segments: Sequence | None = None,
    azimuths: Sequence | None = None,
    gains: Sequence | None = None,
) -> InputMap:
    """Pneumatic chambers with ``H(q)`` from geometry (:class:`PneumaticActuator`).

    Chamber ``i`` sits at azimuth ``prefix.angle + prefix[i].azimuth`` [rad] and
    distance ``prefix.distance`` [m] from the backbone, has the effective cross-section
    ``prefix.area * prefix[i].gain`` [m^2] and acts on the segments
    ``segments[i]``; the inputs are the gauge pressures [Pa], one per chamber. The
    defaults are three chambers per segment, evenly spaced, each acting on its own
    segment (numbered counter-clockwise, or clockwise with ``numbering = -1``), all
    gains 1: the map of earlier versions.

    Parameters
    ----------
    area : float
        Nominal effective cross-section of a chamber of gain 1 [m^2].
    distance : float or array_like, shape (m,)
        Nominal distance ``rho`` from the backbone to the chambers' center lines [m]:
        one for all (extra parameter ``prefix.distance``) or one per chamber
        (``prefix[i].distance``).
    numbering : int
        +1 for chambers numbered counter-clockwise, -1 for clockwise (default azimuths).
    prefix : str
        Prefix of the extra parameters' names.
    n_segments : int
        Number of segments of the robot (``tau`` has ``3 n_segments`` entries).
    segments : sequence of int or of tuple of int, optional
        The segments each chamber runs through (default: three chambers per segment).
    azimuths : array_like, shape (m,), optional
        Nominal azimuth of each chamber [rad] (default: evenly spaced per segment).
    gains : array_like, shape (m,), optional
        Nominal gain of each chamber (dimensionless, default 1).
    """
    numbering = _numbering(numbering)
    area = real_scalar("area", area, positive=True)
    count = _count("chamber", n_segments, segments=segments, azimuths=azimuths, gains=gains)
    if segments is None:
        spans = [(j,) for j in _default_groups("chamber", "segments", count, n_segments)]
    else:
        spans = [(s,) if np.ndim(s) == 0 else tuple(s) for s in segments]
    nominal, geometry = _part_parameters(
        prefix, count, distance, _azimuths(azimuths, spans, numbering), gains
    )
    nominal[f"{prefix}.area"] = area
    try:
        parts = tuple(Bellows(0.0, 1.0, 1.0, UNBOUNDED, segments=span) for span in spans)
        actuator = PneumaticActuator(parts, n_segments=n_segments)
    except ParameterError as exc:
        raise ParameterError(f"segments: {exc}") from None

    def function(q, u, values):
        theta = []
        for i in range(count):
            phi, rho, gain = geometry(values, i)
            theta += [phi, rho, values[f"{prefix}.area"] * gain]
        return actuator.input_matrix_symbolic(q, ca.vertcat(*theta)) @ u

    return InputMap(function, nominal, ("Pa",) * count, robot_problem=constant_curvature_only)


def tendon_input_map(
    *,
    distance,
    n_segments: int = 1,
    numbering: int = 1,
    friction: float | None = None,
    prefix: str = "tendons",
    anchors: Sequence | None = None,
    azimuths: Sequence | None = None,
    gains: Sequence | None = None,
) -> InputMap:
    """Tendons with ``H(q)`` from their routing (:class:`TendonActuator`).

    Tendon ``i`` sits at azimuth ``prefix.angle + prefix[i].azimuth`` [rad] and
    distance ``prefix.distance`` [m] from the backbone, is tied to the tip of segment
    ``anchors[i]`` and its tension [N] acts with the gain ``prefix[i].gain``. The
    defaults are three tendons per segment, set ``j`` tied to the tip of segment ``j``
    (proximal set first), evenly spaced, gains 1
    (:meth:`TendonActuator.three_per_segment`). With ``friction`` given, also
    ``prefix.friction``, the capstan coefficient ``mu`` of the routing. From statics
    alone, ``rho`` and the bending stiffness enter (nearly) only as their ratio
    (``docs/validation.md``, "Tendons"): fix one to fit the other.

    Parameters
    ----------
    distance : float or array_like, shape (m,)
        Nominal distance ``rho`` from the backbone to the tendons [m]: one for all
        (``prefix.distance``) or one per tendon (``prefix[i].distance``).
    n_segments : int
        Number of segments of the robot.
    numbering : int
        +1 for tendons numbered counter-clockwise, -1 for clockwise (default azimuths).
    friction : float, optional
        Nominal capstan friction coefficient (dimensionless, >= 0); None for a
        frictionless routing without the extra parameter.
    prefix : str
        Prefix of the extra parameters' names.
    anchors : sequence of int, optional
        The segment at whose tip each tendon is tied (default: three per segment).
    azimuths : array_like, shape (m,), optional
        Nominal azimuth of each tendon [rad] (default: each set evenly spaced).
    gains : array_like, shape (m,), optional
        Nominal gain of each tendon (dimensionless, default 1).
    """
    numbering = _numbering(numbering)
    count = _count("tendon", n_segments, anchors=anchors, azimuths=azimuths, gains=gains)
    if anchors is None:
        anchors = _default_groups("tendon", "anchors", count, n_segments)
    anchors = list(anchors)
    nominal, geometry = _part_parameters(
        prefix, count, distance, _azimuths(azimuths, anchors, numbering), gains
    )
    if friction is not None:
        nominal[f"{prefix}.friction"] = real_scalar("friction", friction)
    try:
        parts = tuple(Tendon(0.0, 1.0, UNBOUNDED, anchor=a) for a in anchors)
        actuator = TendonActuator(parts, n_segments=n_segments)
    except ParameterError as exc:
        raise ParameterError(f"anchors: {exc}") from None

    def function(q, u, values):
        theta, gains = [], []
        mu = 0.0 if friction is None else values[f"{prefix}.friction"]
        for i in range(count):
            phi, rho, gain = geometry(values, i)
            theta += [phi, rho, mu]
            gains.append(gain)
        return actuator.input_matrix_symbolic(q, ca.vertcat(*theta)) @ (ca.vertcat(*gains) * u)

    return InputMap(function, nominal, ("N",) * count, robot_problem=constant_curvature_only)


def constant_input_map(
    *, elongation_gain: float, bending_gain: float, numbering: int = 1, prefix: str = "map"
) -> InputMap:
    """The authors' constant map: ``tau_l = a_e sum p_i``,
    ``(tau_kx, tau_ky) = -a_k sum p_i (cos phi_i, sin phi_i)`` (away from each bellow).

    Extra parameters ``prefix.a_e`` [N/Pa], ``prefix.a_k`` [N m^2/Pa] and
    ``prefix.angle`` [rad] (azimuth of bellow 0; bellow ``i`` at
    ``angle + numbering 2 pi i / 3``).

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
    offsets = _azimuths(None, [0, 0, 0], _numbering(numbering))

    def function(q, u, values):
        phi = [values[f"{prefix}.angle"] + a for a in offsets]
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
    return InputMap(function, nominal, ("Pa",) * 3, robot_problem=constant_curvature_only)


def actuator_input_map(actuator: Actuator, *, prefix: str | None = None) -> InputMap:
    """Any actuator's ``tau = H(q) u``, its parameters optionally identified.

    With a ``prefix``, every entry of ``actuator.parameter_vector()`` is an extra
    parameter named ``prefix + actuator.parameter_names()[k]`` (e.g. with
    ``prefix=""`` a :class:`PneumaticActuator`'s ``"bellows[0].azimuth"``,
    ``"bellows[0].distance"``, ``"bellows[0].area"``, ...), passed in that order as the
    ``theta`` of ``actuator.input_matrix_symbolic(q, theta)``.

    Parameters
    ----------
    actuator : Actuator
        The actuator; its ``input_unit`` is the unit the inputs must be in.
    prefix : str, optional
        Prefix of the extra parameters' names; None for an actuator held fixed.
    """
    if not isinstance(actuator, Actuator):
        kind = type(actuator).__name__
        raise ParameterError(f"actuator must be a softcurve.Actuator, got {kind}")
    units = (actuator.input_unit,) * actuator.n_inputs
    if prefix is None:

        def fixed(q, u, values):
            return actuator.input_matrix_symbolic(q) @ u

        return InputMap(fixed, {}, units, actuator, _actuator_problem(actuator),
                        actuator.fiber_fields)  # fmt: skip
    names = [prefix + name for name in actuator.parameter_names()]
    nominal = dict(zip(names, actuator.parameter_vector().tolist(), strict=True))

    def function(q, u, values):
        return actuator.input_matrix_symbolic(q, ca.vertcat(*(values[k] for k in names))) @ u

    return InputMap(function, nominal, units, None, _actuator_problem(actuator),
                    actuator.fiber_fields)  # fmt: skip


def _actuator_problem(actuator: Actuator):
    """``robot_problem`` of a map through ``actuator``: its own check of the robot."""

    def problem(robot) -> str | None:
        try:
            actuator.check_robot(robot)
        except ParameterError as exc:
            return str(exc)
        return None

    return problem


def constant_curvature_only(robot) -> str | None:
    """``robot_problem`` of the maps written for constant-curvature segments (their
    fibers' lengths in ``(l, kx, ky)``): None on such a robot, why not on another.

    Parameters
    ----------
    robot : Robot
        The robot a fit drives with the map.
    """
    if robot.constant_curvature:
        return None
    return (
        "the map is written for constant-curvature segments (l, kx, ky); for a robot of other "
        "elements use actuator_input_map with an actuator built with elements=robot"
    )
