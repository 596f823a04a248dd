"""softcurve: dynamics of hyper-elastic soft robots as spatial curves of constant curvature.

The layers follow the paper: parameters (:mod:`softcurve.robot`, :mod:`softcurve.materials`,
:mod:`softcurve.presets`), the symbolic model (:mod:`softcurve.kinematics`,
:mod:`softcurve.dynamics`), the compiled model (:class:`softcurve.Model`) and the analyses
built on it.
"""

from . import presets
from ._validate import ParameterError
from .actuation import Bellows, ConstantPressureMap, PneumaticActuator, PressureMap
from .materials import Creep, LinearStiffness, TanhStiffness
from .model import CompilerWarning, DynamicsTerms, Model, Pose
from .robot import Robot, Segment
from .simulate import State, Trajectory, load_trajectory, simulate

__version__ = "0.1.0"

__all__ = [
    "Bellows",
    "ConstantPressureMap",
    "PneumaticActuator",
    "PressureMap",
    "CompilerWarning",
    "DynamicsTerms",
    "Creep",
    "LinearStiffness",
    "Model",
    "ParameterError",
    "Pose",
    "Robot",
    "Segment",
    "TanhStiffness",
    "presets",
    "simulate",
    "State",
    "Trajectory",
    "load_trajectory",
]
