"""Forward sensitivities of a trajectory to parameters, for the identification:
:func:`trajectory_sensitivities`."""

from softcurve.simulation.sensitivity._sensitivity import (
    SENSITIVITY_CVODES as SENSITIVITY_CVODES,
)
from softcurve.simulation.sensitivity._sensitivity import (
    SensitivityEvaluator as SensitivityEvaluator,
)
from softcurve.simulation.sensitivity._sensitivity import (
    trajectory_sensitivities as trajectory_sensitivities,
)

__all__ = [
    "SENSITIVITY_CVODES",
    "trajectory_sensitivities",
    "SensitivityEvaluator",
]
