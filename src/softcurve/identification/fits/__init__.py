"""Fits of a model to experiments: stiffness laws, trajectories, equilibria; their
parameters, weights, initial states and reports."""

from softcurve.identification.fits._dynamic import fit_equilibria as fit_equilibria
from softcurve.identification.fits._dynamic import fit_trajectory as fit_trajectory
from softcurve.identification.fits._dynamic import predict_equilibria as predict_equilibria
from softcurve.identification.fits._dynamic import predict_trajectory as predict_trajectory
from softcurve.identification.fits._initial_equilibrium import InitialState as InitialState
from softcurve.identification.fits._initial_equilibrium import (
    initial_equilibrium as initial_equilibrium,
)
from softcurve.identification.fits._parameters import Free as Free
from softcurve.identification.fits._parameters import tanh_parameters as tanh_parameters
from softcurve.identification.fits._report import FitError as FitError
from softcurve.identification.fits._report import FitReport as FitReport
from softcurve.identification.fits._report import FitWarning as FitWarning
from softcurve.identification.fits._report import check_confidence as check_confidence
from softcurve.identification.fits._stiffness import fit_stiffness as fit_stiffness

__all__ = [
    "fit_equilibria",
    "fit_trajectory",
    "predict_equilibria",
    "predict_trajectory",
    "InitialState",
    "initial_equilibrium",
    "Free",
    "tanh_parameters",
    "FitError",
    "FitReport",
    "FitWarning",
    "check_confidence",
    "fit_stiffness",
]
