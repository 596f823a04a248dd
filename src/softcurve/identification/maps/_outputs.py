"""Output maps: what a sensor measures, as CasADi expressions of the state.

Every builder returns an :class:`~softcurve.identification.maps.OutputMap`;
sensor offsets, marker offsets and the pose of a sensor's frame are *named extra
parameters* that a fit can estimate (their names are given here, their nominal values
are zero unless the fit's ``extra`` says otherwise).

- :func:`bending_angle_map` and :func:`curvature_map`: read from the coordinates (of a
  constant-curvature segment, or the strains of a constant-strain one).
- :func:`marker_position_map` (a marker at any material point, optionally off the
  backbone) and :func:`tip_position_map`: from the robot's kinematics,
  ``model.symbolic["pose"]``, seen from a :class:`SensorFrame` (a motion-capture
  system's frame, rotated and shifted from the world frame, in its own length unit),
  projected onto some of its axes.
- :func:`imu_orientation_map`: the gravity direction an accelerometer fixed to the robot
  reports, or the tilt angles an IMU computes from it.
"""

from __future__ import annotations

from dataclasses import dataclass

import casadi as ca
import numpy as np

from softcurve.base.deprecation import renamed
from softcurve.base.validation import ParameterError, real_array, real_scalar
from softcurve.compiled import Model
from softcurve.description.elements import STRAINS, RigidBody, Segment, StrainSegment
from softcurve.identification.maps._types import OutputMap

AXES = "xyz"
"""The axes a position can be projected onto."""


def _segment_index(model, segment) -> int:
    """The index of element ``segment`` (negative from the tip) in ``model``'s robot, or
    ParameterError."""
    count = model.robot.n_segments
    whole = isinstance(segment, int | np.integer) and not isinstance(segment, bool)
    if not whole or not -count <= segment < count:
        raise ParameterError(
            f"segment must be an index in [{-count}, {count - 1}] (negative from the tip), "
            f"got {segment!r}"
        )
    return int(segment) % count


def _element(model, segment: int, what: str):
    """``(index, element)`` of ``segment`` (negative from the tip) in ``model``'s robot,
    or ParameterError naming ``what`` needs."""
    index = _segment_index(model, segment)
    element = model.robot.segments[index]
    if element.kind == RigidBody.kind:
        raise ParameterError(f"segment {segment} is a rigid body: it has no {what}")
    return index, element


def _strain(model, index: int, q, p):
    """The full strain ``xi`` (6,) of the constant-strain element ``index`` (CasADi): its
    coordinates where it chooses them, its rest strain from ``p`` elsewhere; and its
    ``L0`` from ``p``."""
    robot, element = model.robot, model.robot.segments[index]
    start, prefix = robot.offsets[index], f"segments[{index}]"
    entries = [p[robot.layout.index(f"{prefix}.rest_strain[{k}]")] for k in range(6)]
    for i, name in enumerate(element.strains):
        entries[STRAINS.index(name)] = q[start + i]
    return ca.vertcat(*entries), p[robot.layout.index(f"{prefix}.rest_length")]


def _curvature_start(segment: int) -> int:
    """Where a map built without a model reads segment ``segment``'s ``(l, kx, ky)``:
    every element before it a constant-curvature segment (the fits check it,
    :func:`_built_for`)."""
    return 3 * segment


def _built_for(model, segment):
    """The check of the robot a map is used with: the structure of ``model``'s robot, or
    (no model) constant-curvature coordinates ``(l, kx, ky)`` at ``q[3 segment]``."""
    if model is not None:
        structure = model.robot.structure()

        def problem(robot):
            if robot.structure() != structure:
                return "the output map was built for another robot: build it with the fit's model"
            return None

        return problem

    def problem(robot):
        index = segment % max(robot.n_segments, 1)
        if segment < robot.n_segments and (
            robot.segments[index].kind == Segment.kind
            and robot.offsets[index] == _curvature_start(index)
        ):
            return None
        return (
            f"the output map reads (l, kx, ky) of segment {segment} at "
            f"q[{_curvature_start(segment)}]; "
            "this robot's elements are not all constant-curvature segments there: build "
            "the map with model="
        )

    return problem


def bending_angle_map(
    segment: int = 0, *, degrees: bool = True, offset: str | None = None, model=None
):
    """Signed bending angle of one segment in the x-z plane: ``beta = kx * l`` of a
    constant-curvature segment, ``u_y L0`` (its bending about y over its reference
    length) of a constant-strain one.

    That is what an IMU at the tip of a single segment measures.

    Parameters
    ----------
    segment : int
        Index of the segment (an element of the robot's chain), from the base.
    degrees : bool
        Output in degrees (else radians).
    offset : str, optional
        Name of an extra parameter (sensor zero, nominal 0, in the output's unit) added
        to the output.
    model : Model, optional
        The model the map is for: needed for a robot other than constant-curvature
        segments alone (it gives each element's kind and where its coordinates are).
        Without it, the map reads ``(l, kx, ky)`` at ``q[3 segment]`` and a fit refuses
        a robot where they are not.
    """
    factor = 180.0 / np.pi if degrees else 1.0
    start, strain = _curvature_start(segment), None
    if model is not None:
        index, element = _element(model, segment, "bending angle")
        start = model.robot.offsets[index]
        if element.kind == StrainSegment.kind:
            if "bend_y" not in element.strains:
                raise ParameterError(
                    f"segment {segment} does not bend about y (its strains: "
                    f"{', '.join(element.strains)}): no bending angle in the x-z plane"
                )
            strain = index

    def function(q, qd, values, p):
        if strain is None:
            y = factor * q[start] * q[start + 1]
        else:
            xi, rest_length = _strain(model, strain, q, p)
            y = factor * rest_length * xi[1]
        return y + (values[offset] if offset else 0)

    return OutputMap(
        function,
        ("beta",),
        ("deg" if degrees else "rad",),
        {offset: 0.0} if offset else {},
        robot_problem=_built_for(model, segment),
    )


def curvature_map(segment: int = 0, *, offsets: tuple[str, str] | None = None, model=None):
    """``(kx, ky)`` of one segment [1/m], plus optional sensor offsets: the coordinates of
    a constant-curvature segment; of a constant-strain one, its backbone's curvature in
    the same axes, ``(u_y, -u_x) / v_z`` (bending over stretch).

    Parameters
    ----------
    segment : int
        Index of the segment (an element of the robot's chain), from the base.
    offsets : tuple of str, optional
        Names of two extra parameters (sensor zeros [1/m], nominal 0) added to
        ``kx`` and ``ky``.
    model : Model, optional
        The model the map is for (as :func:`bending_angle_map`'s).
    """
    start, strain = _curvature_start(segment), None
    if model is not None:
        index, element = _element(model, segment, "curvature")
        start = model.robot.offsets[index]
        if element.kind == StrainSegment.kind:
            if not {"bend_x", "bend_y"} & set(element.strains):
                raise ParameterError(
                    f"segment {segment} does not bend (its strains: "
                    f"{', '.join(element.strains)}): its curvature is its rest curvature"
                )
            strain = index

    def function(q, qd, values, p):
        if strain is None:
            y = ca.vertcat(q[start + 1], q[start + 2])
        else:
            xi = _strain(model, strain, q, p)[0]
            y = ca.vertcat(xi[1], -xi[0]) / xi[5]
        return y + ca.vertcat(*(values[o] for o in offsets)) if offsets else y

    return OutputMap(
        function,
        ("kx", "ky"),
        ("1/m", "1/m"),
        {o: 0.0 for o in offsets} if offsets else {},
        robot_problem=_built_for(model, segment),
    )


def rotation_from_angles(roll, pitch, yaw):
    """``Rz(yaw) Ry(pitch) Rx(roll)`` (3, 3) (CasADi): a rotation by three angles about
    fixed axes x, then y, then z; smooth everywhere, the identity at zero.

    Parameters
    ----------
    roll, pitch, yaw : float or casadi.SX or casadi.MX
        The angles [rad].
    """
    c, s = ca.cos, ca.sin
    rx = ca.vertcat(ca.horzcat(1, 0, 0), ca.horzcat(0, c(roll), -s(roll)),
                    ca.horzcat(0, s(roll), c(roll)))  # fmt: skip
    ry = ca.vertcat(ca.horzcat(c(pitch), 0, s(pitch)), ca.horzcat(0, 1, 0),
                    ca.horzcat(-s(pitch), 0, c(pitch)))  # fmt: skip
    rz = ca.vertcat(ca.horzcat(c(yaw), -s(yaw), 0), ca.horzcat(s(yaw), c(yaw), 0),
                    ca.horzcat(0, 0, 1))  # fmt: skip
    return rz @ ry @ rx


def _angle_names(prefix: str) -> tuple[str, str, str]:
    return f"{prefix}.roll", f"{prefix}.pitch", f"{prefix}.yaw"


@dataclass(frozen=True)
class SensorFrame:
    """The frame a position sensor reports in, posed in the world frame by six named
    extra parameters (nominal zero: the world frame itself).

    The frame's axes are the world axes rotated by :func:`rotation_from_angles` of
    ``prefix.roll``, ``prefix.pitch``, ``prefix.yaw`` [rad]; its origin is at
    ``(prefix.x, prefix.y, prefix.z)`` [m] in the world. A world point ``r`` [m] is
    reported as ``scale * R^T (r - origin)`` [``unit``].

    Parameters
    ----------
    prefix : str
        Prefix of the extra parameters' names.
    scale : float
        Sensor units per metre (e.g. 1000 for a system reporting millimetres) [unit/m],
        > 0; with ``free_scale``, the nominal value of ``prefix.scale``.
    unit : str
        The unit of the reported positions (e.g. ``"mm"``).
    free_scale : bool
        The scale as a seventh extra parameter ``prefix.scale`` [unit/m], to estimate
        with ``Free("prefix.scale", ...)``: data in a unit of unknown size (a camera's
        pixels, a tracker's uncalibrated counts). Estimated with the robot's length, a
        scale is determined only where the data fix the robot's size some other way
        (its rest length known, or gravity's sag).
    """

    prefix: str = "sensor"
    scale: float = 1.0
    unit: str = "m"
    free_scale: bool = False

    def __post_init__(self):
        object.__setattr__(self, "scale", real_scalar("scale", self.scale, positive=True))
        if not isinstance(self.free_scale, bool):
            raise ParameterError(f"free_scale must be True or False, got {self.free_scale!r}")
        if not isinstance(self.prefix, str) or not self.prefix:
            raise ParameterError(f"prefix must be a non-empty str, got {self.prefix!r}")

    @property
    def names(self) -> tuple[str, ...]:
        """The six extra parameters: three angles [rad], then the origin [m]."""
        pose = (*_angle_names(self.prefix), *(f"{self.prefix}.{a}" for a in AXES))
        return (*pose, f"{self.prefix}.scale") if self.free_scale else pose

    def parameters(self) -> dict:
        """The extra parameters with their nominal values (zero; ``scale`` for the
        scale)."""
        values = dict.fromkeys(self.names, 0.0)
        if self.free_scale:
            values[f"{self.prefix}.scale"] = self.scale
        return values

    def rotation(self, values):
        """``R`` (3, 3): the frame's axes (columns) in world coordinates (CasADi).

        Parameters
        ----------
        values : dict of str to casadi.SX or casadi.MX
            The extra parameters, by name [rad].
        """
        return rotation_from_angles(*(values[k] for k in _angle_names(self.prefix)))

    def to_sensor(self, position, values):
        """A world point seen from this frame: ``scale * R^T (r - origin)`` (3,).

        Parameters
        ----------
        position : casadi.SX or casadi.MX, shape (3,)
            World position ``r`` [m].
        values : dict of str to casadi.SX or casadi.MX
            The extra parameters, by name [rad and m].
        """
        origin = ca.vertcat(*(values[f"{self.prefix}.{a}"] for a in AXES))
        scale = values[f"{self.prefix}.scale"] if self.free_scale else self.scale
        return scale * (self.rotation(values).T @ (position - origin))


def _axes(axes: str) -> list[int]:
    if not isinstance(axes, str) or not axes or set(axes) - set(AXES) or len(set(axes)) < len(axes):
        raise ParameterError(
            f"axes must be distinct letters of 'xyz' in the order wanted (e.g. 'xz'), got {axes!r}"
        )
    return [AXES.index(a) for a in axes]


def _material_point(model: Model, segment: int, s: float) -> float:
    """The whole robot's material coordinate of point ``s`` of ``segment``."""
    i = _segment_index(model, segment)
    s = real_scalar("s", s)
    if not 0.0 <= s <= 1.0:
        raise ParameterError(f"s must be in [0, 1] (segment base to tip), got {s!r}")
    bounds = model.robot.span_bounds
    return float(bounds[i] + s * (bounds[i + 1] - bounds[i]))


def _offset(offset):
    """``(values -> (3,) expression, extra parameters)`` of a marker offset."""
    if offset is None:
        return (lambda values: ca.DM.zeros(3)), {}
    if isinstance(offset, str):
        names = [f"{offset}.{a}" for a in AXES]
        return (lambda values: ca.vertcat(*(values[k] for k in names))), dict.fromkeys(names, 0.0)
    fixed = ca.DM(real_array("offset", offset, (3,)))
    return (lambda values: fixed), {}


def _names(names, default: tuple[str, ...]) -> tuple[str, ...]:
    if names is None:
        return default
    names = tuple(str(n) for n in names)
    if len(names) != len(default):
        raise ParameterError(f"names must give {len(default)} labels, got {names!r}")
    return names


def marker_position_map(
    model: Model,
    segment: int = -1,
    s: float = 1.0,
    *,
    offset=None,
    frame: SensorFrame | None = None,
    axes: str = "xyz",
    names=None,
) -> OutputMap:
    """Position of a marker at a material point, in the world or a sensor's frame.

    The marker sits at point ``s`` of ``segment`` (``s = 0`` its base, 1 its tip),
    shifted by ``offset`` in the local material frame there (x, y across the
    cross-section, z along the backbone's tangent; e.g. a marker glued on the surface
    at radius r is ``(r, 0, 0)``).

    Parameters
    ----------
    model : Model
        The model whose kinematics (``model.symbolic["pose"]``) gives the pose.
    segment : int
        Index of the segment, from the base; negative counts from the tip (-1: last).
    s : float
        Material coordinate along the segment, in [0, 1], dimensionless.
    offset : None, str or array_like, shape (3,)
        The marker's offset from the backbone [m] in the local material frame: None
        for none, three numbers, or a prefix naming three extra parameters
        ``offset.x``, ``offset.y``, ``offset.z`` [m] (nominal 0) to identify it.
    frame : SensorFrame, optional
        The frame the positions are reported in (default: the world frame, in m).
    axes : str
        The axes of ``frame`` reported, in order (``"xz"`` projects onto the x-z
        plane).
    names : sequence of str, optional
        Labels of the outputs (default: the axes' letters).
    """
    point = _material_point(model, segment, s)
    pick, marker = _axes(axes), _offset(offset)
    pose = model.symbolic["pose"]
    parameters = {**marker[1], **(frame.parameters() if frame else {})}

    def function(q, qd, values, p):
        rotation, position = pose(q, point, p)
        world = position + rotation @ marker[0](values)
        seen = frame.to_sensor(world, values) if frame else world
        return ca.vertcat(*(seen[i] for i in pick))

    unit = frame.unit if frame else "m"
    return OutputMap(function, _names(names, tuple(axes)), (unit,) * len(pick), parameters)


def tip_position_map(
    model: Model, *, offset=None, frame: SensorFrame | None = None, axes: str = "xyz", names=None
) -> OutputMap:
    """Tip position, in the world frame [m] by default: :func:`marker_position_map` at the
    last segment's tip.

    Parameters
    ----------
    model : Model
        The model whose kinematics gives the tip pose.
    offset : None, str or array_like, shape (3,)
        The marker's offset from the tip [m] in the tip's material frame (see
        :func:`marker_position_map`).
    frame : SensorFrame, optional
        The frame the positions are reported in (default: the world frame, in m).
    axes : str
        The axes reported, in order.
    names : sequence of str, optional
        Labels of the outputs (default: the axes' letters).
    """
    return marker_position_map(model, -1, 1.0, offset=offset, frame=frame, axes=axes, names=names)


IMU_OUTPUTS = {
    "gravity": (("ax", "ay", "az"), "g"),
    "tilt": (("roll", "pitch"), None),
}
"""What :func:`imu_orientation_map` reports: names and unit (None: the angle unit)."""


def imu_orientation_map(
    model: Model,
    segment: int = -1,
    s: float = 1.0,
    *,
    output: str = "tilt",
    mounting: str | None = None,
    degrees: bool = True,
    names=None,
) -> OutputMap:
    """What an IMU fixed to the robot reports about its orientation, at rest.

    An accelerometer at rest measures the specific force, ``-g`` in its own axes; in
    units of ``|g|`` that is ``a = R_imu^T (-g / |g|)``, the "up" direction in the IMU's
    axes (``output="gravity"``). From it an IMU computes its tilt
    (``output="tilt"``): ``roll = atan2(a_y, a_z)`` and
    ``pitch = atan2(-a_x, sqrt(a_y^2 + a_z^2))``, zero when its z axis points up. The
    IMU's axes are the local material frame at point ``s`` of ``segment`` (x, y across
    the cross-section, z along the tangent), rotated by the mounting angles. The
    gravity vector is the robot's (``gravity[0..2]`` of its parameter vector), which
    must not be zero. Dynamic accelerations are not included: use it for slow motion.

    Parameters
    ----------
    model : Model
        The model whose kinematics gives the IMU's orientation.
    segment : int
        Index of the segment, from the base; negative counts from the tip.
    s : float
        Material coordinate along the segment, in [0, 1], dimensionless.
    output : str
        ``"gravity"`` (three components [g]) or ``"tilt"`` (roll and pitch).
    mounting : str, optional
        Prefix of three extra parameters ``mounting.roll``, ``.pitch``, ``.yaw`` [rad]
        (nominal 0) rotating the IMU's axes from the material frame
        (:func:`rotation_from_angles`); None for an IMU aligned with it.
    degrees : bool
        Tilt angles in degrees (else radians).
    names : sequence of str, optional
        Labels of the outputs (default ``("ax", "ay", "az")`` or ``("roll", "pitch")``).
    """
    if output not in IMU_OUTPUTS:
        raise ParameterError(f"output must be one of {sorted(IMU_OUTPUTS)}, got {output!r}")
    point = _material_point(model, segment, s)
    pose = model.symbolic["pose"]
    gravity_index = [model.robot.layout.index(f"gravity[{i}]") for i in range(3)]
    angles = _angle_names(mounting) if mounting else ()
    factor = 180.0 / np.pi if degrees else 1.0

    def function(q, qd, values, p):
        rotation = pose(q, point, p)[0]
        if angles:
            rotation = rotation @ rotation_from_angles(*(values[k] for k in angles))
        gravity = ca.vertcat(*(p[i] for i in gravity_index))
        a = rotation.T @ (-gravity / ca.norm_2(gravity))
        if output == "gravity":
            return a
        roll = ca.atan2(a[1], a[2])
        pitch = ca.atan2(-a[0], ca.sqrt(a[1] ** 2 + a[2] ** 2))
        return factor * ca.vertcat(roll, pitch)

    labels, unit = IMU_OUTPUTS[output]
    unit = unit or ("deg" if degrees else "rad")
    return OutputMap(
        function, _names(names, labels), (unit,) * len(labels), dict.fromkeys(angles, 0.0)
    )


# the builders' old names, which read as if they returned values rather than maps
tip_position = renamed(tip_position_map, "tip_position")
curvatures = renamed(curvature_map, "curvatures")
bending_angle = renamed(bending_angle_map, "bending_angle")
marker_position = renamed(marker_position_map, "marker_position")
imu_orientation = renamed(imu_orientation_map, "imu_orientation")
