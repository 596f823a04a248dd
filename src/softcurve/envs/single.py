"""The single Gymnasium environments: :class:`Reach`, :class:`Track`, :class:`Press`,
each a batch of one (:class:`~softcurve.envs.core.Episodes`), without autoreset."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np

from softcurve.envs.core import make_episodes
from softcurve.envs.setup import env_parameters
from softcurve.envs.tasks import PressTask, ReachTask, TrackTask


def _row(info: dict, i: int) -> dict:
    """Member ``i`` of an info dict of arrays, with Python scalars."""
    row = {}
    for key, value in info.items():
        item = value[i]
        row[key] = item.item() if isinstance(item, np.generic) else item
    return row


@env_parameters
class SoftRobotEnv(gymnasium.Env):
    """A soft robot learning a task (the base of :class:`Reach`, :class:`Track`,
    :class:`Press`): actions in [-1, 1] map linearly onto the actuator's bounds (clipped
    there), one action is held for a control period, the observation is the state, the
    tip and the goal (docs/envs.md). No task terminates; an episode is truncated after
    ``max_episode_steps`` periods, or at once when the integrator fails, with the reason
    in ``info["failure"]`` (None otherwise) and reward -1; the observation then shows the
    state from before the failed step.

    Parameters
    ----------
    %(robot)s
    %(actuator)s
    %(scenario)s
    %(environment)s
    %(period)s
    %(max_episode_steps)s
    %(tolerance)s
    %(substeps)s
    %(threads)s
    %(method)s
    %(jacobian)s
    %(render_mode)s
    """

    metadata: dict[str, Any] = {"render_modes": []}
    task_class = ReachTask

    def __init__(
        self,
        robot=None,
        actuator=None,
        *,
        scenario=None,
        environment=None,
        period=None,
        max_episode_steps=None,
        tolerance=None,
        substeps=None,
        threads=None,
        method=None,
        jacobian=None,
        render_mode=None,
    ):
        if render_mode is not None:
            raise ValueError(f"render_mode must be None (no rendering), got {render_mode!r}")
        self.episodes = make_episodes(
            self.task_class, 1, tolerance, robot=robot, actuator=actuator, scenario=scenario,
            environment=environment, period=period, max_episode_steps=max_episode_steps,
            substeps=substeps, threads=threads, method=method, jacobian=jacobian,
        )  # fmt: skip
        self.observation_space = self.episodes.observation_space
        self.action_space = self.episodes.action_space
        self.render_mode = None

    @classmethod
    def from_scenario(cls, path, **options):
        """The environment of a TOML scenario file (robot, ``[actuation]``,
        ``[environment]``, start, and the period and duration where the file sets them).

        Parameters
        ----------
        path : str or Path
            The scenario file (docs/configuration.md).
        **options : dict
            Further keywords of the constructor (period, tolerance, ...).
        """
        return cls(scenario=path, **options)

    @property
    def task(self):
        """The task's logic (:mod:`softcurve.envs.tasks`)."""
        return self.episodes.task

    def reset(self, *, seed: int | None = None, options: dict | None = None):
        """Start an episode: ``(observation, info)``.

        Parameters
        ----------
        seed : int, optional
            Seeds the episode generator (the same seed gives the same episode).
        options : dict, optional
            Unused.
        """
        super().reset(seed=seed)
        self.episodes.rngs[0] = self.np_random
        observation, info = self.episodes.reset([0])
        return observation[0], _row(info, 0)

    def controller_action(self, controller) -> np.ndarray:
        """The action of ``controller`` at the episode's state and time: the inputs it
        computes now, scaled onto the action space (the inverse of the map from actions
        to inputs). A controller plays the environment's policy with
        ``env.step(env.unwrapped.controller_action(controller))`` every period, on the
        task's rewards and success, beside a learned policy; reset the controller with the
        episode (``controller.reset()``).

        Parameters
        ----------
        controller : SampledController
            A controller of the environment's actuator and period whose output is that
            actuator's inputs, as
            :meth:`~softcurve.envs.core.Episodes.controller_actions` takes them.

        Returns
        -------
        ndarray, shape (m,), float32
            The action, dimensionless, in [-1, 1].
        """
        return self.episodes.controller_actions([controller])[0]

    def step(self, action):
        """Hold ``action`` for one period: ``(observation, reward, terminated,
        truncated, info)``.

        Parameters
        ----------
        action : array_like, shape (m,)
            Actuator inputs scaled to [-1, 1], dimensionless.
        """
        observation, reward, terminated, truncated, info = self.episodes.step(action, single=True)
        return (observation[0], float(reward[0]), bool(terminated[0]), bool(truncated[0]),
                _row(info, 0))  # fmt: skip


class Reach(SoftRobotEnv):
    """``softcurve/Reach-v0``: bring the tip to a random reachable target and hold it
    (:class:`~softcurve.envs.tasks.ReachTask`; episodes of 2 s). Parameters: those of
    :class:`SoftRobotEnv`."""

    task_class = ReachTask


class Track(SoftRobotEnv):
    """``softcurve/Track-v0``: follow a target moving around a closed reachable path,
    from a random phase (:class:`~softcurve.envs.tasks.TrackTask`; episodes of 4 s).
    Parameters: those of :class:`SoftRobotEnv`."""

    task_class = TrackTask


class Press(SoftRobotEnv):
    """``softcurve/Press-v0``: press on a wall with a random target normal force
    (:class:`~softcurve.envs.tasks.PressTask`; episodes of 2 s; default: the paper's
    robot beside the wall of ``examples/contact_wall.toml``). Parameters: those of
    :class:`SoftRobotEnv`."""

    task_class = PressTask
