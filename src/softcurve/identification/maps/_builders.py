"""Output and input maps for identification: what a sensor measures, what the inputs do.

An :class:`OutputMap` turns the state into measured signals (a tip IMU's bending
angle, curvatures, marker positions in a motion-capture frame, an IMU's tilt), possibly
with sensor offsets; an :class:`InputMap` turns measured inputs into generalized forces
(chamber pressures through a geometric or a constant pressure map, tendon tensions
through their routing, with per-part gains and azimuths and a mounting angle). Both may
read named *extra* parameters, which the fits of
:mod:`softcurve.identification.fits` can estimate. The functions build CasADi
expressions and work with SX or MX arguments.

This module gathers them for the face, :mod:`softcurve.identification.maps`; they are
defined in the private modules ``_types`` (the two types), ``_outputs`` and ``_inputs``.
``docs/identify.md`` builds one by hand.
"""

from __future__ import annotations

from softcurve.identification.maps._inputs import (
    actuator_input_map,
    bellows_input_map,
    constant_input_map,
    tendon_input_map,
)
from softcurve.identification.maps._outputs import (
    SensorFrame,
    bending_angle_map,
    curvature_map,
    imu_orientation_map,
    marker_position_map,
    rotation_from_angles,
    tip_position_map,
)
from softcurve.identification.maps._types import InputMap, OutputMap

__all__ = [
    "InputMap",
    "OutputMap",
    "SensorFrame",
    "actuator_input_map",
    "bellows_input_map",
    "bending_angle_map",
    "constant_input_map",
    "curvature_map",
    "imu_orientation_map",
    "marker_position_map",
    "rotation_from_angles",
    "tendon_input_map",
    "tip_position_map",
]
