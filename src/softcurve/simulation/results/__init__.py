"""Results of a simulation: :class:`Trajectory`, :class:`BatchTrajectory`,
:class:`ContactHistory`, and the trajectory file format."""

from softcurve.simulation.results._batch import BatchTrajectory as BatchTrajectory
from softcurve.simulation.results._batch import batch_status as batch_status
from softcurve.simulation.results._batch import stop_at_actuator_domain as stop_at_actuator_domain
from softcurve.simulation.results._contact import ContactHistory as ContactHistory
from softcurve.simulation.results._files import TrajectoryFileError as TrajectoryFileError
from softcurve.simulation.results._files import column_names as column_names
from softcurve.simulation.results._files import coordinate_columns as coordinate_columns
from softcurve.simulation.results._files import save_trajectory as save_trajectory
from softcurve.simulation.results._trajectory import Trajectory as Trajectory
from softcurve.simulation.results._trajectory import load_trajectory as load_trajectory

__all__ = [
    "BatchTrajectory",
    "batch_status",
    "stop_at_actuator_domain",
    "ContactHistory",
    "column_names",
    "coordinate_columns",
    "save_trajectory",
    "TrajectoryFileError",
    "Trajectory",
    "load_trajectory",
]
