"""softcurve: dynamics of hyper-elastic soft robots as spatial curves of constant curvature.

This facade gathers the public API; the package is written in layers, each a folder
that imports only the ones below it (docs/architecture.md): :mod:`softcurve.base`
(validation, the result protocol), :mod:`softcurve.description` (robots, materials,
actuators, presets), :mod:`softcurve.symbolic` (kinematics and the equation of motion in
CasADi), :mod:`softcurve.compiled` (:class:`Model`, compiled to C),
:mod:`softcurve.figures`, :mod:`softcurve.analysis` (equilibria, linearization),
:mod:`softcurve.simulation`, :mod:`softcurve.control`, :mod:`softcurve.identification`,
:mod:`softcurve.scenarios` (TOML files, sweeps) and :mod:`softcurve.cli`.

Examples
--------
>>> import numpy as np
>>> import softcurve as sc
>>> model = sc.Model(sc.presets.ifac2020())
>>> q = np.array([0.064, 25.0, 0.0])  # length [m], curvatures kx, ky [1/m]
>>> model.tip_pose(q).position.round(4)  # [m]
array([0.0412, 0.    , 0.04  ])
"""

from softcurve._version import __version__ as __version__
from softcurve.analysis.equilibrium_results import Equilibrium, EquilibriumTable
from softcurve.analysis.inverse_statics import InverseStatics, inverse_statics
from softcurve.analysis.linear import Linearization
from softcurve.analysis.quasistatic import InputSweep, input_sweep
from softcurve.analysis.statics import equilibria, equilibrium, linearize
from softcurve.base.status import Result, Status
from softcurve.base.validation import ParameterError
from softcurve.compiled import (
    CacheWarning,
    CompilerWarning,
    DynamicsTerms,
    ExportedC,
    Model,
    Pose,
    export_c,
)
from softcurve.control.controllers import (
    ActuatorDriven,
    Allocation,
    ComputedTorque,
    InputAllocator,
    PDGravityElastic,
    SampledController,
    SaturatedInputs,
)
from softcurve.control.mpc import ActuatorMPC
from softcurve.control.references import Reference, tip_circle
from softcurve.description import presets
from softcurve.description.actuator import Actuator
from softcurve.description.bellows import Bellows, ConstantPressureMap, PneumaticActuator
from softcurve.description.environment import Capsule, ContactLaw, Environment, Plane, Sphere
from softcurve.description.layout import ParameterLayout
from softcurve.description.materials import Creep, LinearStiffness, TanhStiffness
from softcurve.description.robot import Robot, Segment
from softcurve.description.tendons import Tendon, TendonActuator
from softcurve.figures import save_figure
from softcurve.identification.experiments import (
    Experiment,
    ExperimentError,
    check_units,
    load_csv,
    load_mat,
    load_mat_trials,
)
from softcurve.identification.fits import (
    FitError,
    FitReport,
    FitWarning,
    Free,
    InitialState,
    fit_equilibria,
    fit_stiffness,
    fit_trajectory,
    initial_equilibrium,
    predict_equilibria,
    predict_trajectory,
    tanh_parameters,
)
from softcurve.identification.maps import (
    InputMap,
    OutputMap,
    SensorFrame,
    actuator_input_map,
    bellows_input_map,
    bending_angle_map,
    constant_input_map,
    curvature_map,
    imu_orientation_map,
    marker_position_map,
    tendon_input_map,
    tip_position_map,
)
from softcurve.identification.maps import bending_angle as bending_angle  # deprecated names
from softcurve.identification.maps import curvatures as curvatures
from softcurve.identification.maps import imu_orientation as imu_orientation
from softcurve.identification.maps import marker_position as marker_position
from softcurve.identification.maps import tip_position as tip_position
from softcurve.scenarios.config import Scenario, load_config
from softcurve.scenarios.sweep import SweepResult, run_sweep
from softcurve.scenarios.sweep_config import SweepConfig, load_sweep
from softcurve.simulation import (
    BatchTrajectory,
    ContactHistory,
    SimulationSettings,
    State,
    Trajectory,
    load_trajectory,
    simulate,
    simulate_batch,
)
from softcurve.simulation.solvers import RouteWarning

__all__ = [
    # description
    "Robot",
    "Segment",
    "LinearStiffness",
    "TanhStiffness",
    "Creep",
    "Actuator",
    "Bellows",
    "PneumaticActuator",
    "ConstantPressureMap",
    "Tendon",
    "TendonActuator",
    "Plane",
    "Sphere",
    "Capsule",
    "ContactLaw",
    "Environment",
    "ParameterLayout",
    "presets",
    # the compiled model
    "Model",
    "DynamicsTerms",
    "Pose",
    "CompilerWarning",
    "CacheWarning",
    "export_c",
    "ExportedC",
    # results and errors
    "Status",
    "Result",
    "ParameterError",
    "save_figure",
    # analysis
    "equilibrium",
    "equilibria",
    "Equilibrium",
    "EquilibriumTable",
    "linearize",
    "Linearization",
    "input_sweep",
    "InputSweep",
    "inverse_statics",
    "InverseStatics",
    # simulation
    "simulate",
    "simulate_batch",
    "SimulationSettings",
    "State",
    "Trajectory",
    "ContactHistory",
    "BatchTrajectory",
    "load_trajectory",
    "RouteWarning",
    # control
    "SampledController",
    "ComputedTorque",
    "PDGravityElastic",
    "InputAllocator",
    "Allocation",
    "ActuatorDriven",
    "SaturatedInputs",
    "ActuatorMPC",
    "Reference",
    "tip_circle",
    # identification
    "Experiment",
    "ExperimentError",
    "load_csv",
    "load_mat",
    "fit_stiffness",
    "fit_trajectory",
    "fit_equilibria",
    "predict_trajectory",
    "predict_equilibria",
    "FitError",
    "FitReport",
    "FitWarning",
    "Free",
    "tanh_parameters",
    "OutputMap",
    "InputMap",
    "tip_position_map",
    "bending_angle_map",
    "curvature_map",
    "bellows_input_map",
    "constant_input_map",
    "tendon_input_map",
    "actuator_input_map",
    "marker_position_map",
    "imu_orientation_map",
    "SensorFrame",
    "load_mat_trials",
    "check_units",
    "initial_equilibrium",
    "InitialState",
    # scenarios
    "Scenario",
    "load_config",
    "SweepConfig",
    "load_sweep",
    "run_sweep",
    "SweepResult",
]
