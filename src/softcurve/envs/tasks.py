"""The tasks' logic, vectorized over the members of a batch: what each episode draws at
its start, the goal the policy observes, the reward and success. One owner for the
single and the vector environments (the single one is a batch of one).

Every reward is in [-1, 0]: minus the error, normalized by the workspace's diameter
(*Reach*, *Track*) or the force range (*Press*) and capped at 1; 0 is perfect, and a
step that fails gets -1 (:data:`FAILURE_REWARD`). No task terminates: episodes run to
their time limit (truncation), or end early, truncated, when the integrator fails.
"""

from __future__ import annotations

import numpy as np

from softcurve.base.docs import parameters_from
from softcurve.base.validation import ParameterError, real_scalar
from softcurve.description.environment import ContactLaw, Environment, Plane
from softcurve.envs.calibration import calibrate, track_path

FAILURE_REWARD = -1.0
"""Reward of a step whose integration failed: the worst reward of any task."""
DEFAULT_TOLERANCE = 0.05
"""Default success tolerance as a fraction of the workspace's diameter (*Reach*,
*Track*) or of the force range (*Press*): 5 %."""
PRESS_RANGE = (0.1, 0.9)
"""Target forces of *Press*, as fractions of the largest normal force of the
calibration: inside the range the robot reached, away from no contact and from full
pressure."""


def _tolerance(value, default: float, unit: str) -> float:
    if value is None:
        return default
    return real_scalar(f"tolerance [{unit}]", value, positive=True)


_member_parameters = parameters_from(
    {
        "parameters": ("ndarray, shape (N, n_parameters)", "What each member's episode drew."),
        "steps": ("ndarray, shape (N,)", "Control periods since each member's start (a count)."),
    }
)


@_member_parameters
class Task:
    """The base of the tasks: the goal features, reward and success of every member.

    Parameters
    ----------
    setup : Setup
        The robot, actuator, period and start.
    tolerance : float, optional
        Success tolerance in the task's unit (default: :data:`DEFAULT_TOLERANCE` of the
        workspace's diameter or of the force range).
    """

    name = "task"
    duration = 2.0
    """Default episode duration [s]."""
    n_parameters = 0
    """Numbers drawn per episode."""
    n_goal = 0
    """Goal features appended to the observation."""

    def __init__(self, setup, tolerance=None):
        self.setup = setup
        self.calibration = calibrate(setup)
        self.diameter = 2.0 * self.calibration.radius

    @classmethod
    def default_environment(cls, robot_given: bool):
        """The obstacles the task needs when none is given (None: none).

        Parameters
        ----------
        robot_given : bool
            Whether the user gave a robot (then the default robot's obstacles do not fit).
        """
        return None

    def draw(self, rng: np.random.Generator) -> np.ndarray:
        """The numbers one episode draws at its start, shape (n_parameters,).

        Parameters
        ----------
        rng : numpy.random.Generator
            The member's generator.
        """
        return np.zeros(0)

    def evaluate(self, parameters, steps, tip, force) -> tuple:
        """``(goal (N, n_goal), reward (N,), success (N,), info dict of (N, ...))``.

        Parameters
        ----------
        %(parameters)s
        %(steps)s
        tip : ndarray, shape (N, 3)
            Tip positions [m].
        force : ndarray, shape (N, 3)
            Contact force on the robot [N].
        """
        raise NotImplementedError

    def _scaled(self, point) -> np.ndarray:
        return (point - self.calibration.center) / self.calibration.radius


@_member_parameters
class DistanceTask(Task):
    """The base of the tasks that bring the tip to a target (:class:`ReachTask`,
    :class:`TrackTask`): reward ``-min(|tip - target| / D, 1)`` with ``D`` the
    workspace's diameter; success: ``|tip - target| < tolerance``.

    Parameters
    ----------
    setup : Setup
        The robot, actuator, period and start.
    tolerance : float, optional
        Success distance [m] (default 5 % of the workspace's diameter).
    """

    def __init__(self, setup, tolerance=None):
        super().__init__(setup, tolerance)
        self.tolerance = _tolerance(tolerance, DEFAULT_TOLERANCE * self.diameter, "m")

    def aim(self, parameters, steps) -> tuple[np.ndarray, np.ndarray]:
        """``(target (N, 3) [m], goal (N, n_goal))`` of each member.

        Parameters
        ----------
        %(parameters)s
        %(steps)s
        """
        raise NotImplementedError

    def evaluate(self, parameters, steps, tip, force):
        target, goal = self.aim(parameters, steps)
        distance = np.linalg.norm(tip - target, axis=1)
        reward = -np.minimum(distance / self.diameter, 1.0)
        info = {"target": target, "distance": distance}
        return goal, reward, distance < self.tolerance, info


class ReachTask(DistanceTask):
    """Bring the tip to a target drawn from the reachable workspace (a tip of the
    calibration) and hold it there. Goal: the target (scaled like the tip). Reward and
    success and the constructor's parameters: :class:`DistanceTask`.
    """

    name = "Reach"
    duration = 2.0
    n_parameters = 3
    n_goal = 3

    def draw(self, rng):
        tips = self.calibration.tips
        return tips[rng.integers(tips.shape[0])].copy()

    def aim(self, parameters, steps):
        return parameters, self._scaled(parameters)


class TrackTask(DistanceTask):
    """Follow a target moving along a closed reachable path (the tip under a command
    rotating through the actuators, one turn in
    :data:`~softcurve.envs.calibration.TRACK_CYCLE` = 2 s rounded to whole control
    periods, at least 8), starting at a random phase. Goal: the target and its velocity
    over the turn's angular rate (both scaled like the tip). Reward and success as
    *Reach*, against the moving target; the constructor's parameters:
    :class:`DistanceTask`.
    """

    name = "Track"
    duration = 4.0
    n_parameters = 1
    n_goal = 6

    def __init__(self, setup, tolerance=None):
        super().__init__(setup, tolerance)
        self.path = track_path(setup)
        # the rate the path was recorded at: one point per period, a whole number of
        # periods per turn (TRACK_CYCLE rounded), so the target moves as the robot did
        self.rate = 2 * np.pi / (self.path.shape[0] * setup.period)

    def draw(self, rng):
        return np.array([rng.uniform(0.0, 2 * np.pi)])

    def target(self, parameters, steps) -> tuple[np.ndarray, np.ndarray]:
        """Target position [m] and velocity [m/s] of each member, (N, 3) each.

        Parameters
        ----------
        parameters : ndarray, shape (N, 1)
            Start phase [rad] of each member.
        steps : ndarray, shape (N,)
            Control periods since the start (a count).
        """
        count = self.path.shape[0]
        phase = parameters[:, 0] + self.rate * self.setup.period * steps
        where = np.mod(phase * count / (2 * np.pi) - 1.0, count)  # path[j] at 2 pi (j+1)/P
        j = np.floor(where).astype(int) % count
        after = (j + 1) % count
        w = (where - np.floor(where))[:, None]
        position = (1 - w) * self.path[j] + w * self.path[after]
        velocity = (self.path[after] - self.path[j]) * count * self.rate / (2 * np.pi)
        return position, velocity

    def aim(self, parameters, steps):
        target, velocity = self.target(parameters, steps)
        goal = np.hstack([self._scaled(target), velocity / (self.rate * self.calibration.radius)])
        return target, goal


DEFAULT_WALL = Plane(point=[-0.045, 0.0, 0.0], normal=[1.0, 0.0, 0.0])
"""*Press*'s wall for the default robot, as in ``examples/contact_wall.toml``: the
robot's body (slice radius 23.5 mm) touches it after 21.5 mm of sideways tip travel,
which the bellow at azimuth 0 produces at about a third of its pressure range."""
DEFAULT_LAW = ContactLaw(stiffness=1e7, damping=1.0, friction=0.5)
"""*Press*'s contact law for the default robot (``examples/contact_wall.toml``;
docs/contact.md: tenths of a millimetre of penetration for the paper's robot)."""


class PressTask(Task):
    """Press on a wall with a target normal force, drawn uniformly in
    ``PRESS_RANGE`` = [0.1, 0.9] of the largest force the calibration reached. The wall
    is the first :class:`~softcurve.Plane` of the environment, the force the total
    contact force on the robot along its outward normal. Goal: the target force and the
    force now, both over the largest force ``F``. Reward ``-min(|f - f*| / F, 1)``;
    success ``|f - f*| < tolerance``.

    Parameters
    ----------
    setup : Setup
        The robot, actuator, period, start and obstacles.
    tolerance : float, optional
        Success force error [N] (default 5 % of ``F``).
    """

    name = "Press"
    duration = 2.0
    n_parameters = 1
    n_goal = 2

    def __init__(self, setup, tolerance=None):
        environment = setup.stepper.model.environment
        planes = [o for o in getattr(environment, "obstacles", ()) if isinstance(o, Plane)]
        if not planes:
            raise ParameterError(
                f"{setup.source}: Press needs an environment with a wall (a Plane obstacle)"
            )
        super().__init__(setup, tolerance)
        self.normal = planes[0].normal
        self.largest = float(np.max(self.calibration.forces @ self.normal))
        if not self.largest > 0:
            raise ParameterError(
                f"{setup.source}: the robot never touches the wall at {planes[0].point.tolist()} "
                "within its input bounds: move the wall closer"
            )
        self.tolerance = _tolerance(tolerance, DEFAULT_TOLERANCE * self.largest, "N")

    @classmethod
    def default_environment(cls, robot_given: bool):
        if robot_given:
            return None
        return Environment((DEFAULT_WALL,), DEFAULT_LAW)

    def draw(self, rng):
        low, high = PRESS_RANGE
        return np.array([self.largest * rng.uniform(low, high)])

    def evaluate(self, parameters, steps, tip, force):
        target = parameters[:, 0]
        normal_force = force @ self.normal
        error = np.abs(normal_force - target)
        reward = -np.minimum(error / self.largest, 1.0)
        goal = np.stack([target, normal_force], axis=1) / self.largest
        info = {"target_force": target, "force": normal_force, "force_error": error}
        return goal, reward, error < self.tolerance, info


TASKS = {"Reach": ReachTask, "Track": TrackTask, "Press": PressTask}
"""The tasks by name."""
