"""The fixed-step :class:`Stepper`: many members advanced by one period per call, for
the learning environments and model-predictive control."""

from softcurve.simulation.stepper._methods import METHODS as METHODS
from softcurve.simulation.stepper._methods import default_substeps as default_substeps
from softcurve.simulation.stepper._scheme import checked_jacobian as checked_jacobian
from softcurve.simulation.stepper._stability import check_explicit_step as check_explicit_step
from softcurve.simulation.stepper._stepper import Stepper as Stepper
from softcurve.simulation.stepper._stepper import StepResult as StepResult

__all__ = [
    "METHODS",
    "default_substeps",
    "check_explicit_step",
    "checked_jacobian",
    "Stepper",
    "StepResult",
]
