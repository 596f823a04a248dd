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

import importlib

from softcurve._version import __version__ as __version__

_FACES = {
    "softcurve.analysis.equilibrium_results": ("Equilibrium", "EquilibriumTable"),
    "softcurve.analysis.inverse_statics": ("InverseStatics", "inverse_statics"),
    "softcurve.analysis.linear": ("Linearization",),
    "softcurve.analysis.quasistatic": ("InputSweep", "input_sweep"),
    "softcurve.analysis.statics": ("equilibria", "equilibrium", "linearize"),
    "softcurve.base.status": ("Result", "Status"),
    "softcurve.base.validation": ("ParameterError",),
    "softcurve.compiled": (
        "CacheWarning",
        "CompilerWarning",
        "DynamicsTerms",
        "ExportedC",
        "Model",
        "Pose",
        "export_c",
    ),
    "softcurve.control": (
        "ConfigurationTarget",
        "PredictiveController",
        "RolloutGradient",
        "RolloutSymbols",
        "TipTarget",
        "TrajectoryPlan",
        "Transcription",
        "gradient",
        "optimize_trajectory",
    ),
    "softcurve.control.controllers": (
        "ActuatorDriven",
        "Allocation",
        "ComputedTorque",
        "InputAllocator",
        "PDGravityElastic",
        "SampledController",
        "SaturatedInputs",
    ),
    "softcurve.control.mpc": ("ActuatorMPC",),
    "softcurve.control.references": ("Reference", "tip_circle"),
    "softcurve.description": ("presets",),
    "softcurve.description.actuator": ("Actuator",),
    "softcurve.description.bellows": ("Bellows", "ConstantPressureMap", "PneumaticActuator"),
    "softcurve.description.environment": (
        "Capsule",
        "ContactLaw",
        "Environment",
        "Plane",
        "Sphere",
    ),
    "softcurve.description.layout": ("ParameterLayout",),
    "softcurve.description.materials": ("Creep", "LinearStiffness", "TanhStiffness"),
    "softcurve.description.elements": ("STRAINS", "RigidBody", "Segment", "StrainSegment"),
    "softcurve.description.robot": ("Robot",),
    "softcurve.description.sections": (
        "Material",
        "Section",
        "SectionProperties",
        "section_properties",
    ),
    "softcurve.description.tendons": ("Tendon", "TendonActuator"),
    "softcurve.figures": ("save_figure",),
    "softcurve.identification.experiments": (
        "Experiment",
        "ExperimentError",
        "check_units",
        "load_csv",
        "load_mat",
        "load_mat_trials",
    ),
    "softcurve.identification.fits": (
        "FitError",
        "FitReport",
        "FitWarning",
        "Free",
        "InitialState",
        "fit_equilibria",
        "fit_stiffness",
        "fit_trajectory",
        "initial_equilibrium",
        "predict_equilibria",
        "predict_trajectory",
        "tanh_parameters",
    ),
    "softcurve.identification.maps": (
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
        # deprecated names: not in __all__
        "bending_angle",
        "curvatures",
        "imu_orientation",
        "marker_position",
        "tip_position",
    ),
    "softcurve.scenarios.config": ("Scenario", "load_config"),
    "softcurve.scenarios.sweep": ("SweepResult", "run_sweep"),
    "softcurve.scenarios.sweep_config": ("SweepConfig", "load_sweep"),
    "softcurve.simulation": (
        "BatchTrajectory",
        "ContactHistory",
        "SimulationSettings",
        "State",
        "Trajectory",
        "load_trajectory",
        "simulate",
        "simulate_batch",
    ),
    "softcurve.simulation.solvers": ("RouteWarning",),
}
"""The module each name of the facade comes from (a public module or a face), imported
on the first use of one of its names: ``import softcurve`` itself imports nothing heavy
(no CasADi, SciPy or Matplotlib), so that the command line starts at once."""

_LAYERS = (
    "base",
    "description",
    "symbolic",
    "compiled",
    "figures",
    "analysis",
    "simulation",
    "control",
    "identification",
    "scenarios",
)
"""The layers reached as attributes (``softcurve.simulation``), imported on first use."""

_SOURCE = {name: module for module, names in _FACES.items() for name in names}

__all__ = [
    # description
    "Robot",
    "Segment",
    "StrainSegment",
    "RigidBody",
    "STRAINS",
    "LinearStiffness",
    "TanhStiffness",
    "Creep",
    "Material",
    "Section",
    "SectionProperties",
    "section_properties",
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


def __getattr__(name: str) -> object:
    """A facade name, imported from its module on first use (PEP 562)."""
    if name in _SOURCE:
        module = importlib.import_module(_SOURCE[name])
        try:
            value = getattr(module, name)
        except AttributeError:  # a submodule not yet imported (presets)
            value = importlib.import_module(f"{_SOURCE[name]}.{name}")
    elif name in _LAYERS:
        value = importlib.import_module(f"{__name__}.{name}")
    else:
        raise AttributeError(f"module {__name__!r} has no attribute {name!r}")
    globals()[name] = value  # the next use is a plain attribute read
    return value


def __dir__() -> list[str]:
    return sorted(set(globals()) | set(_SOURCE) | set(_LAYERS))
