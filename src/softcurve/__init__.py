"""softcurve: dynamics of hyper-elastic soft robots as spatial curves of constant curvature.

The layers follow the paper: parameters (:mod:`softcurve.robot`, :mod:`softcurve.materials`,
:mod:`softcurve.presets`), the symbolic model (:mod:`softcurve.kinematics`,
:mod:`softcurve.dynamics`), the compiled model (:class:`softcurve.Model`) and the analyses
built on it.
"""

from . import presets
from ._validate import ParameterError
from .actuation import Bellows, ConstantPressureMap, PneumaticActuator, PressureMap
from .batch import BatchTrajectory, simulate_batch
from .control import (
    ComputedTorque,
    PDGravityElastic,
    PressureAllocator,
    PressureDriven,
    Reference,
    tip_circle,
)
from .experiments import Experiment, ExperimentError, load_csv, load_mat
from .identify import FitReport, fit_stiffness
from .identify_dynamic import Free, fit_equilibria, fit_trajectory
from .materials import Creep, LinearStiffness, TanhStiffness
from .model import CompilerWarning, DynamicsTerms, Model, Pose
from .robot import Robot, Segment
from .simulate import simulate
from .statics import equilibria, equilibrium, linearize
from .trajectory import State, Trajectory, load_trajectory

__version__ = "0.1.0"

__all__ = [
    "BatchTrajectory",
    "Bellows",
    "ConstantPressureMap",
    "PneumaticActuator",
    "PressureMap",
    "ComputedTorque",
    "PDGravityElastic",
    "PressureAllocator",
    "PressureDriven",
    "Reference",
    "tip_circle",
    "equilibria",
    "equilibrium",
    "linearize",
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
    "simulate_batch",
    "State",
    "Trajectory",
    "load_trajectory",
    "Experiment",
    "ExperimentError",
    "load_csv",
    "load_mat",
    "FitReport",
    "fit_stiffness",
    "Free",
    "fit_equilibria",
    "fit_trajectory",
]
