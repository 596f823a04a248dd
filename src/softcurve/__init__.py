"""softcurve: dynamics of hyper-elastic soft robots as spatial curves of constant curvature.

The layers follow the paper: parameters (:mod:`softcurve.robot`, :mod:`softcurve.materials`,
:mod:`softcurve.presets`), the symbolic model (:mod:`softcurve.kinematics`,
:mod:`softcurve.dynamics`), the compiled model (:class:`softcurve.Model`) and the analyses
built on it.
"""

from softcurve._version import __version__ as __version__
from softcurve.analysis.statics import equilibria, equilibrium, linearize
from softcurve.base.validation import ParameterError
from softcurve.compiled.build import CompilerWarning
from softcurve.compiled.model import DynamicsTerms, Model, Pose
from softcurve.control.controllers import (
    ComputedTorque,
    PDGravityElastic,
    PressureAllocator,
    PressureDriven,
    Reference,
    tip_circle,
)
from softcurve.description import presets
from softcurve.description.actuators import (
    Actuator,
    Bellows,
    ConstantPressureMap,
    PneumaticActuator,
)
from softcurve.description.materials import Creep, LinearStiffness, TanhStiffness
from softcurve.description.robot import Robot, Segment
from softcurve.identification.dynamic import Free, fit_equilibria, fit_trajectory
from softcurve.identification.experiments import Experiment, ExperimentError, load_csv, load_mat
from softcurve.identification.stiffness import FitReport, fit_stiffness
from softcurve.simulation.batch import BatchTrajectory, simulate_batch
from softcurve.simulation.simulate import simulate
from softcurve.simulation.trajectory import State, Trajectory, load_trajectory

__all__ = [
    "BatchTrajectory",
    "Bellows",
    "ConstantPressureMap",
    "PneumaticActuator",
    "Actuator",
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
