"""The native vector environments: N robots stepped in one call of the compiled stepper
(:class:`~softcurve.envs.core.Episodes`), with Gymnasium's same-step autoreset.

Autoreset (``metadata["autoreset_mode"] = AutoresetMode.SAME_STEP``): a member whose
episode ends (terminated or truncated) is reset within the same ``step``; the returned
observation and info are the new episode's, the last ones of the ended episode are in
``info["final_obs"]`` (an object array, None for the other members) and
``info["final_info"]`` (the info arrays), masked by ``info["_final_obs"]`` and
``info["_final_info"]``. Every info key ``k`` comes with its mask ``info["_k"]``.
"""

from __future__ import annotations

from typing import Any

import numpy as np
from gymnasium.vector import AutoresetMode, VectorEnv
from gymnasium.vector.utils import batch_space

from softcurve.envs.core import make_episodes
from softcurve.envs.setup import env_parameters
from softcurve.envs.tasks import PressTask, ReachTask, TrackTask


def _masked(info: dict, size: int, absent: dict | None = None) -> dict:
    """``info`` with a mask ``_k`` for each key ``k`` (Gymnasium's layout): all true (one
    read-only array shared by the keys), except for the keys of ``absent``, whose
    members given there hold no value (mask false)."""
    every = np.ones(size, dtype=bool)
    every.flags.writeable = False
    absent = absent or {}
    out = {}
    for key, value in info.items():
        out[key] = value
        out[f"_{key}"] = every
        if key in absent:
            out[f"_{key}"] = every.copy()
            out[f"_{key}"][absent[key]] = False
    return out


@env_parameters
class SoftRobotVectorEnv(VectorEnv):
    """N soft robots learning a task in one batch (the base of :class:`ReachVector`,
    :class:`TrackVector`, :class:`PressVector`): each member is the single environment of
    the same task (:class:`~softcurve.envs.single.SoftRobotEnv`), with same-step
    autoreset (module docstring).

    Parameters
    ----------
    num_envs : int
        Number of robots N.
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

    metadata: dict[str, Any] = {"render_modes": [], "autoreset_mode": AutoresetMode.SAME_STEP}
    task_class = ReachTask

    def __init__(
        self,
        num_envs: int = 1,
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
            self.task_class, num_envs, tolerance, robot=robot, actuator=actuator,
            scenario=scenario, environment=environment, period=period,
            max_episode_steps=max_episode_steps, substeps=substeps, threads=threads, method=method,
            jacobian=jacobian,
        )  # fmt: skip
        self.num_envs = self.episodes.size
        self.single_observation_space = self.episodes.observation_space
        self.single_action_space = self.episodes.action_space
        self.observation_space = batch_space(self.single_observation_space, self.num_envs)
        self.action_space = batch_space(self.single_action_space, self.num_envs)
        self.render_mode = None

    @classmethod
    def from_scenario(cls, path, num_envs: int = 1, **options):
        """The vector environment of a TOML scenario file (see
        :meth:`softcurve.envs.single.SoftRobotEnv.from_scenario`).

        Parameters
        ----------
        path : str or Path
            The scenario file (docs/configuration.md).
        num_envs : int
            Number of robots.
        **options : dict
            Further keywords of the constructor.
        """
        return cls(num_envs, scenario=path, **options)

    @property
    def task(self):
        """The task's logic (:mod:`softcurve.envs.tasks`)."""
        return self.episodes.task

    def reset(self, *, seed=None, options: dict | None = None):
        """Start an episode in every member: ``(observations, infos)``.

        Parameters
        ----------
        seed : int or sequence of int, optional
            An int seeds member ``i`` with ``seed + i`` (as Gymnasium's synchronous
            vector environment does), a sequence gives each member its own seed.
        options : dict, optional
            Unused.
        """
        size = self.num_envs
        if seed is None:
            seeds = [None] * size
        elif isinstance(seed, int | np.integer):
            seeds = [int(seed) + i for i in range(size)]
            self._np_random_seed = int(seed)
        else:
            seeds = list(seed)
            if len(seeds) != size:
                raise ValueError(f"seed must hold {size} seeds, got {len(seeds)}")
        members = np.arange(size)
        self.episodes.seed(members, seeds)
        observation, info = self.episodes.reset(members)
        return observation, _masked(info, size)

    def controller_actions(self, controllers) -> np.ndarray:
        """The actions of one controller per member at its episode's state and time
        (:meth:`~softcurve.envs.core.Episodes.controller_actions`): controllers as the
        members' policies. A member's episode that ends is reset within the same step
        (``info["_final_obs"]``): reset its controller then.

        Parameters
        ----------
        controllers : sequence of SampledController, length N
            One controller per member, of the environments' actuator and period.

        Returns
        -------
        ndarray, shape (N, m), float32
            The actions, dimensionless, in [-1, 1].
        """
        return self.episodes.controller_actions(controllers)

    def step(self, actions):
        """Hold ``actions`` for one period in every member, then reset the members whose
        episode ended: ``(observations, rewards, terminations, truncations, infos)``.

        Parameters
        ----------
        actions : array_like, shape (N, m)
            Actuator inputs scaled to [-1, 1], dimensionless.
        """
        observation, reward, terminated, truncated, info = self.episodes.step(actions)
        done = np.flatnonzero(terminated | truncated)
        if done.size:
            final_obs = np.full(self.num_envs, None, dtype=object)
            final_obs[done] = list(observation[done])
            mask = np.zeros(self.num_envs, dtype=bool)
            mask[done] = True
            final_info = _masked({k: v.copy() for k, v in info.items()}, self.num_envs)
            for key in list(final_info):
                if key.startswith("_"):
                    final_info[key] = mask.copy()
            new_observation, new_info = self.episodes.reset(done)
            observation[done] = new_observation
            for key, value in new_info.items():
                info[key][done] = value
            # a reset member's info is its reset's, which has no inputs: none acted yet
            info["inputs"][done] = 0.0
            info = _masked(info, self.num_envs, absent={"inputs": done})
            info.update(final_obs=final_obs, _final_obs=mask, final_info=final_info,
                        _final_info=mask.copy())  # fmt: skip
        else:
            info = _masked(info, self.num_envs)
        return observation, reward, terminated, truncated, info


class ReachVector(SoftRobotVectorEnv):
    """The vector environment of ``softcurve/Reach-v0`` (``gymnasium.make_vec``).
    Parameters: those of :class:`SoftRobotVectorEnv`."""

    task_class = ReachTask


class TrackVector(SoftRobotVectorEnv):
    """The vector environment of ``softcurve/Track-v0``. Parameters: those of
    :class:`SoftRobotVectorEnv`."""

    task_class = TrackTask


class PressVector(SoftRobotVectorEnv):
    """The vector environment of ``softcurve/Press-v0``. Parameters: those of
    :class:`SoftRobotVectorEnv`."""

    task_class = PressTask
