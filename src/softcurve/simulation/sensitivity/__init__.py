"""Forward sensitivities of a trajectory to parameters, for the identification:
:func:`trajectory_sensitivities`; the method it integrates with: :func:`choose_method`."""

from softcurve.simulation.sensitivity._sensitivity import (
    AUTO_WITHIN as AUTO_WITHIN,
)
from softcurve.simulation.sensitivity._sensitivity import (
    SENSITIVITY_CVODES as SENSITIVITY_CVODES,
)
from softcurve.simulation.sensitivity._sensitivity import (
    SENSITIVITY_METHODS as SENSITIVITY_METHODS,
)
from softcurve.simulation.sensitivity._sensitivity import (
    SensitivityEvaluator as SensitivityEvaluator,
)
from softcurve.simulation.sensitivity._sensitivity import (
    choose_method as choose_method,
)
from softcurve.simulation.sensitivity._sensitivity import (
    hold_inputs as hold_inputs,
)
from softcurve.simulation.sensitivity._sensitivity import (
    trajectory_sensitivities as trajectory_sensitivities,
)

__all__ = [
    "AUTO_WITHIN",
    "SENSITIVITY_CVODES",
    "SENSITIVITY_METHODS",
    "choose_method",
    "hold_inputs",
    "trajectory_sensitivities",
    "SensitivityEvaluator",
]
