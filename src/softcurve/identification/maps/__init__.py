"""Output maps (state -> measured signals) and input maps (measured inputs ->
generalized forces) of a fit."""

from softcurve.identification.maps._builders import InputMap as InputMap
from softcurve.identification.maps._builders import OutputMap as OutputMap
from softcurve.identification.maps._builders import SensorFrame as SensorFrame
from softcurve.identification.maps._builders import actuator_input_map as actuator_input_map
from softcurve.identification.maps._builders import bellows_input_map as bellows_input_map
from softcurve.identification.maps._builders import bending_angle as bending_angle
from softcurve.identification.maps._builders import constant_input_map as constant_input_map
from softcurve.identification.maps._builders import curvatures as curvatures
from softcurve.identification.maps._builders import imu_orientation as imu_orientation
from softcurve.identification.maps._builders import marker_position as marker_position
from softcurve.identification.maps._builders import tendon_input_map as tendon_input_map
from softcurve.identification.maps._builders import tip_position as tip_position

__all__ = [
    "InputMap",
    "OutputMap",
    "SensorFrame",
    "actuator_input_map",
    "bellows_input_map",
    "bending_angle",
    "constant_input_map",
    "curvatures",
    "imu_orientation",
    "marker_position",
    "tendon_input_map",
    "tip_position",
]
