"""Output maps (state -> measured signals) and input maps (measured inputs ->
generalized forces) of a fit."""

from softcurve.identification.maps._builders import InputMap as InputMap
from softcurve.identification.maps._builders import OutputMap as OutputMap
from softcurve.identification.maps._builders import SensorFrame as SensorFrame
from softcurve.identification.maps._builders import actuator_input_map as actuator_input_map
from softcurve.identification.maps._builders import bellows_input_map as bellows_input_map
from softcurve.identification.maps._builders import bending_angle_map as bending_angle_map
from softcurve.identification.maps._builders import constant_input_map as constant_input_map
from softcurve.identification.maps._builders import curvature_map as curvature_map
from softcurve.identification.maps._builders import imu_orientation_map as imu_orientation_map
from softcurve.identification.maps._builders import marker_position_map as marker_position_map
from softcurve.identification.maps._builders import tendon_input_map as tendon_input_map
from softcurve.identification.maps._builders import tip_position_map as tip_position_map

# the builders' deprecated names: not in __all__ (not documented, not star-imported)
from softcurve.identification.maps._outputs import bending_angle as bending_angle
from softcurve.identification.maps._outputs import curvatures as curvatures
from softcurve.identification.maps._outputs import imu_orientation as imu_orientation
from softcurve.identification.maps._outputs import marker_position as marker_position
from softcurve.identification.maps._outputs import tip_position as tip_position

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
    "tendon_input_map",
    "tip_position_map",
]
