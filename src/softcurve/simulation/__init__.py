"""Simulation: integrate a model's equation of motion in time.

:func:`simulate` (one robot, error-controlled), :func:`simulate_batch` (many members at
once), the fixed-step :class:`Stepper` of the learning environments and
:func:`trajectory_sensitivities` (the identification's forward sensitivities) all
integrate through the methods of :mod:`softcurve.simulation.solvers`. Subpackages, bottom
to top: ``solvers`` (the problem, the methods, the C driver), ``results`` (trajectories and
their file format), ``stepper``, ``sensitivity``, ``batch``.
"""

from softcurve.simulation._settings import CSV_BYTES_PER_VALUE as CSV_BYTES_PER_VALUE
from softcurve.simulation._settings import JACOBIANS as JACOBIANS
from softcurve.simulation._settings import MAX_STEPS as MAX_STEPS
from softcurve.simulation._settings import METHODS as METHODS
from softcurve.simulation._settings import MIN_TIME as MIN_TIME
from softcurve.simulation._settings import RTOL_MIN as RTOL_MIN
from softcurve.simulation._settings import SettingsError as SettingsError
from softcurve.simulation._settings import SimulationSettings as SimulationSettings
from softcurve.simulation._settings import checked_rtol as checked_rtol
from softcurve.simulation._settings import format_bytes as format_bytes
from softcurve.simulation._settings import sample_time as sample_time
from softcurve.simulation._simulate import simulate as simulate
from softcurve.simulation.batch import simulate_batch as simulate_batch
from softcurve.simulation.results import BatchTrajectory as BatchTrajectory
from softcurve.simulation.results import ContactHistory as ContactHistory
from softcurve.simulation.results import Trajectory as Trajectory
from softcurve.simulation.results import load_trajectory as load_trajectory
from softcurve.simulation.sensitivity import trajectory_sensitivities as trajectory_sensitivities
from softcurve.simulation.solvers import State as State
from softcurve.simulation.stepper import Stepper as Stepper

__all__ = [
    "CSV_BYTES_PER_VALUE",
    "JACOBIANS",
    "MAX_STEPS",
    "METHODS",
    "MIN_TIME",
    "RTOL_MIN",
    "SettingsError",
    "SimulationSettings",
    "checked_rtol",
    "format_bytes",
    "sample_time",
    "simulate",
    "simulate_batch",
    "BatchTrajectory",
    "ContactHistory",
    "Trajectory",
    "load_trajectory",
    "trajectory_sensitivities",
    "State",
    "Stepper",
]
