"""Whether an explicit method's step is stable on a robot: the robot's fastest mode
(the largest ``|lambda|`` of the Jacobian of the stepper's state derivative), at rest or
at any state, against the method's stability radius, with the margin measured for the
modes' growth away from rest. Used by :class:`~softcurve.simulation.stepper.Stepper` at
construction and by the learning environments to pick their method; docs/stepping.md
says what the check does not see.
"""

from __future__ import annotations

import math

import casadi as ca
import numpy as np

from softcurve.analysis.loads import rest_configuration
from softcurve.base.validation import ParameterError
from softcurve.simulation.solvers import ActuatorInput, linear_rates
from softcurve.simulation.stepper._scheme import (
    difference_jacobian,
    rest_scale,
    scheme_parameters,
    state_derivative,
)

EXPLICIT_MARGIN = 2.0
"""Factor between the fastest mode of a robot at rest and the fastest it reaches in use,
allowed for when an explicit method's step is checked (:func:`check_explicit_step`):
under random pressure commands held 20 ms each over 2 s (docs/stepping.md), the paper's
robot with the bellows reached 476 and 483 1/s (two seeds) against 283 1/s at rest, 1.7
times."""


@scheme_parameters
def fastest_rate(model, inputs: ActuatorInput | None, x, u) -> float:
    """The largest ``|lambda|`` [1/s] of the Jacobian of the state derivative at state
    ``x`` and inputs ``u`` (the stepper's own forward differences,
    ``softcurve.simulation.stepper._scheme.difference_jacobian``, on the compiled
    right-hand side).

    Parameters
    ----------
    %(model)s
    %(inputs)s
    x : array_like, shape (n_state [+ m],)
        The state (the stepper's layout).
    u : array_like, shape (m,)
        The inputs (commands with a lag).
    """
    f, scale = state_derivative(model, inputs, symbolic=False), rest_scale(model, inputs)
    x, u = (ca.DM(np.asarray(v, dtype=np.float64)) for v in (x, u))
    jacobian = np.array(difference_jacobian(f, scale, x, u, ca.DM(model.parameters))[0])
    return float(linear_rates(np.linalg.eigvals(jacobian))[1])


@scheme_parameters
def fastest_rate_at_rest(model, inputs: ActuatorInput | None) -> float:
    """:func:`fastest_rate` [1/s] at the robot's rest: straight at rest length, no
    motion, no creep, the inputs and lag states at zero clipped to their bounds.

    Parameters
    ----------
    %(model)s
    %(inputs)s
    """
    n_u = model.n if inputs is None else inputs.lower.size
    u = np.zeros(n_u) if inputs is None else np.clip(np.zeros(n_u), inputs.lower, inputs.upper)
    n_lag = 0 if inputs is None else inputs.n_states
    x = np.zeros(model.n_state + n_lag)
    x[: model.n] = rest_configuration(model.robot)
    x[model.n_state :] = u[:n_lag]
    return fastest_rate(model, inputs, x, u)


@scheme_parameters
def check_explicit_step(model, inputs: ActuatorInput | None, period, substeps, method) -> None:
    """Raise :class:`~softcurve.base.validation.ParameterError` where an explicit
    ``method`` cannot take ``period / substeps`` steps on this robot: with an environment
    (a penalty contact is stiff), or where the robot's fastest mode at rest
    (:func:`fastest_rate_at_rest`) times :data:`EXPLICIT_MARGIN` leaves its stability
    radius.

    Parameters
    ----------
    %(model)s
    %(inputs)s
    period : float
        Control period [s].
    substeps : int
        Steps per period.
    method : ExplicitTableau
        The method.
    """
    if model.environment is not None:
        raise ParameterError(
            f"method={method.name!r} is explicit and the model has an environment, whose "
            "penalty contact is far stiffer than the robot: use method='ROS34PW2'"
        )
    rate = fastest_rate_at_rest(model, inputs)
    longest = method.stability_radius / (EXPLICIT_MARGIN * rate)
    if period / substeps > longest:
        needed = math.ceil(period / longest)
        raise ParameterError(
            f"substeps={substeps} gives {method.name} steps of {period / substeps * 1e3:.3g} "
            f"ms, beyond its stability on this robot: its fastest mode at rest is "
            f"{rate:.4g} 1/s, so steps must be <= {longest * 1e3:.3g} ms (stability "
            f"radius {method.stability_radius} over {EXPLICIT_MARGIN:g} times that rate): "
            f"substeps >= {needed}, or method='ROS34PW2'"
        )
