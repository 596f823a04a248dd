"""Measured experiments: :class:`Experiment`, loading CSV and MATLAB files, units."""

from softcurve.identification.experiments._errors import (
    ExperimentFileNotFound as ExperimentFileNotFound,
)
from softcurve.identification.experiments._errors import UnitError as UnitError
from softcurve.identification.experiments._experiment import Experiment as Experiment
from softcurve.identification.experiments._loading import ExperimentError as ExperimentError
from softcurve.identification.experiments._loading import load_csv as load_csv
from softcurve.identification.experiments._loading import load_mat as load_mat
from softcurve.identification.experiments._loading import load_mat_trials as load_mat_trials
from softcurve.identification.experiments._units import check_units as check_units

__all__ = [
    "Experiment",
    "ExperimentError",
    "load_csv",
    "load_mat",
    "load_mat_trials",
    "check_units",
    "ExperimentFileNotFound",
    "UnitError",
]
