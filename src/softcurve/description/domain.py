"""The domain of a state: the robot's configuration domain and its actuator's.

Each rule is written once, next to what it is about: the configuration domain in
each element kind's module (:mod:`softcurve.description.elements`, through
:meth:`Robot.inside <softcurve.description.robot.Robot.inside>`), the
actuator's (every tendon length and chamber volume > 0) in
:mod:`softcurve.description.fibers` through :meth:`Actuator.fibers
<softcurve.description.actuator.Actuator.fibers>`. :func:`state_problem` and
:func:`states_inside` combine them, and :func:`checked_status` is the one place every
analysis result (equilibria, inverse statics, quasi-static sweeps, fits of equilibria,
trajectories) passes through: a result outside the domain is never SUCCESS but
``LEFT_DOMAIN``, its message naming what left, its value and the allowed range.
"""

from __future__ import annotations

import numpy as np

from softcurve.base.status import Status
from softcurve.description.fibers import fiber_problem, fibers_inside


def state_problem(robot, q, actuator=None, *, entry: str = "q") -> str | None:
    """What puts the configuration ``q`` outside the model's domain or the actuator's,
    naming the coordinate or the actuator element, its value and the allowed range;
    None inside.

    Parameters
    ----------
    robot : Robot
        The robot whose domain is checked.
    q : array_like, shape (n,)
        One configuration [m, 1/m, 1/m].
    actuator : Actuator or None
        The actuator whose geometry is checked too.
    entry : str
        How an index into ``q`` is named (see
        :func:`~softcurve.description.robot.domain_problem`).
    """
    problem = robot.domain_problem(q, entry=entry)
    if problem is None and actuator is not None:
        problem = fiber_problem(actuator.fibers(), q)
    return problem


def states_inside(robot, q, actuator=None) -> np.ndarray:
    """Vectorized :func:`state_problem` ``is None``: shape (...).

    Parameters
    ----------
    robot : Robot
        The robot.
    q : array_like, shape (..., n)
        Configurations [m, 1/m, 1/m].
    actuator : Actuator or None
        The actuator whose geometry is checked too.
    """
    inside = robot.inside(q)
    if actuator is not None:
        inside &= fibers_inside(actuator.fibers(), q)
    return inside


def checked_status(robot, q, actuator, status: Status, message: str) -> tuple[Status, str]:
    """``(status, message)`` of a result whose state is ``q``: unchanged inside the
    domain; outside, ``LEFT_DOMAIN`` with the reason first (never SUCCESS).

    Parameters
    ----------
    robot : Robot
        The robot.
    q : array_like, shape (n,)
        The result's configuration [m, 1/m, 1/m].
    actuator : Actuator or None
        The actuator of the result's loads.
    status : Status
        The solver's status.
    message : str
        The solver's message.
    """
    problem = state_problem(robot, q, actuator)
    if problem is None:
        return status, message
    return Status.LEFT_DOMAIN, f"outside the model's domain: {problem} ({message})"
