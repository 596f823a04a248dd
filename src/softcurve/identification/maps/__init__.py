"""Output and input maps for identification: what a sensor measures, what the inputs do.

An :class:`OutputMap` turns the state into measured signals (a tip IMU's bending
angle, curvatures, marker positions in a motion-capture frame, an IMU's tilt), possibly
with sensor offsets; an :class:`InputMap` turns measured inputs into generalized forces
(chamber pressures through a geometric or a constant pressure map, tendon tensions
through their routing, with per-part gains and azimuths and a mounting angle). Both may
read named *extra* parameters, which the fits of
:mod:`softcurve.identification.fits` can estimate. The functions build CasADi
expressions and work with SX or MX arguments.

The two types are defined in the private module ``_types``, the output maps in
``_outputs`` and the input maps in ``_inputs``. ``docs/identify.md`` builds one by hand.
"""

from softcurve.identification.maps._inputs import actuator_input_map as actuator_input_map
from softcurve.identification.maps._inputs import bellows_input_map as bellows_input_map
from softcurve.identification.maps._inputs import constant_input_map as constant_input_map
from softcurve.identification.maps._inputs import tendon_input_map as tendon_input_map
from softcurve.identification.maps._outputs import SensorFrame as SensorFrame
from softcurve.identification.maps._outputs import bending_angle as bending_angle
from softcurve.identification.maps._outputs import bending_angle_map as bending_angle_map
from softcurve.identification.maps._outputs import curvature_map as curvature_map
from softcurve.identification.maps._outputs import curvatures as curvatures
from softcurve.identification.maps._outputs import imu_orientation as imu_orientation
from softcurve.identification.maps._outputs import imu_orientation_map as imu_orientation_map
from softcurve.identification.maps._outputs import marker_position as marker_position
from softcurve.identification.maps._outputs import marker_position_map as marker_position_map
from softcurve.identification.maps._outputs import rotation_from_angles as rotation_from_angles
from softcurve.identification.maps._outputs import tip_position as tip_position
from softcurve.identification.maps._outputs import tip_position_map as tip_position_map
from softcurve.identification.maps._types import InputMap as InputMap
from softcurve.identification.maps._types import OutputMap as OutputMap

# the old names of the output-map builders (bending_angle, curvatures, imu_orientation,
# marker_position, tip_position) are deprecated aliases: not in __all__ (not documented,
# not star-imported)
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
