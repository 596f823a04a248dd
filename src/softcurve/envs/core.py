"""The episodes of N robots, stepped together: actions to actuator inputs, one call of
the compiled stepper for all members, observations, rewards, truncation and the
failures of single members. The single environment is the case N = 1 of this class;
the vector environment adds the autoreset.

Observation of a member (float32), in this order: the state ``x`` (coordinates, rates,
creep states, lagging inputs) minus its calibration mean over its calibration standard
deviation; the tip minus the workspace's centre over its radius; the task's goal
(:mod:`softcurve.envs.tasks`). Non-finite entries (only possible after a failure) read
0 and every entry is clipped to +-:data:`OBSERVATION_LIMIT`.
"""

from __future__ import annotations

import numpy as np
from gymnasium import spaces
from gymnasium.utils import seeding

from softcurve.base.validation import ParameterError, whole_count
from softcurve.control.controllers import SampledController
from softcurve.envs.setup import build_setup
from softcurve.envs.tasks import FAILURE_REWARD

OBSERVATION_LIMIT = 1e3
"""Bound of every observation entry: a thousand calibration scales, far beyond any
state the robot reaches within its input bounds (the observations are of order one)."""
NOT_FINITE = "the state was not finite before the step"
"""Failure reason of a member whose state held NaN or infinity when it was stepped."""


def make_episodes(task_class, num_envs: int, tolerance=None, **options):
    """The :class:`Episodes` of ``num_envs`` members of ``task_class``.

    Parameters
    ----------
    task_class : type
        A :class:`~softcurve.envs.tasks.Task` subclass.
    num_envs : int
        Number of members.
    tolerance : float, optional
        The task's success tolerance (its unit).
    **options : dict
        The keywords of :func:`~softcurve.envs.setup.build_setup` (robot, actuator,
        scenario, environment, period, max_episode_steps, substeps, threads, method,
        jacobian).
    """
    whole_count("num_envs", num_envs)
    if options.get("environment") is None and options.get("scenario") is None:
        options["environment"] = task_class.default_environment(options.get("robot") is not None)
    setup = build_setup(duration=task_class.duration, **options)
    return Episodes(task_class(setup, tolerance), int(num_envs))


def _check_controller(controller, stepper) -> None:
    """Refuse a controller that is not a :class:`SampledController` of the stepper's
    actuator sampling once a period."""
    if not isinstance(controller, SampledController):
        raise ParameterError(
            f"controller must be a SampledController, got {type(controller).__name__}"
        )
    if not np.isclose(controller.sample_time, stepper.period, rtol=1e-9, atol=0.0):
        raise ParameterError(
            f"controller.sample_time must be the environment's period "
            f"({stepper.period:g} s), got {controller.sample_time:g} s"
        )
    actuator = getattr(controller, "actuator", None)
    if actuator is not None and actuator != stepper.actuator:
        raise ParameterError(
            "the controller's actuator must be the environment's "
            "(env.unwrapped.episodes.setup.stepper.actuator)"
        )


class Episodes:
    """N members' episodes; see the module docstring.

    Parameters
    ----------
    task : Task
        The task (with its setup and calibration).
    size : int
        Number of members N.
    """

    def __init__(self, task, size: int):
        self.task, self.setup, self.size = task, task.setup, size
        stepper = self.setup.stepper
        self.lower, self.upper = np.asarray(stepper.lower), np.asarray(stepper.upper)
        self.x = np.tile(self.setup.x0, (size, 1))
        self.steps = np.zeros(size, dtype=np.int64)
        self.parameters = np.zeros((size, task.n_parameters))
        self.rngs: list[np.random.Generator | None] = [None] * size
        self.tip0 = np.asarray(stepper.tip(self.setup.x0[None, :]))[0]
        self.force0 = np.zeros(3)  # the start state is clear of obstacles (Scenario checks)
        dim = self.setup.x0.size + 3 + task.n_goal
        limit = np.float32(OBSERVATION_LIMIT)
        self.observation_space = spaces.Box(-limit, limit, (dim,), np.float32)
        self.action_space = spaces.Box(-1.0, 1.0, (self.lower.size,), np.float32)

    # -- actions and observations ---------------------------------------------------
    def inputs(self, actions, single: bool = False) -> np.ndarray:
        """Actuator inputs (N, m), in the actuator's unit, of actions in [-1, 1] (clipped
        there first): -1 is the lower bound, 1 the upper. The actions are checked here,
        for the single and the vector environments: real numbers (any integer or float
        dtype), finite, of the action space's shape, else :class:`ParameterError` naming
        the shape, the dtype and the bounds expected and what was given.

        Parameters
        ----------
        actions : array_like, shape (N, m), or (m,) with ``single``
            The actions, dimensionless.
        single : bool
            The action of a single environment (one member), shape (m,).
        """
        m = self.lower.size
        shape, name = ((m,), "action") if single else ((self.size, m), "actions")
        expected = (
            f"{name} must be real numbers of shape {shape} in [-1, 1] (the action_space; "
            "outside it they are clipped)"
        )
        try:
            a = np.asarray(actions)
        except ValueError:  # ragged nested sequences
            raise ParameterError(f"{expected}, got {actions!r}") from None
        if a.dtype.kind not in "iuf":
            raise ParameterError(f"{expected}, got dtype {a.dtype} ({actions!r})")
        if a.shape != shape:
            raise ParameterError(f"{expected}, got shape {a.shape}")
        a = a.astype(np.float64).reshape(self.size, m)
        if not np.isfinite(a).all():
            bad = int(np.argmax(~np.all(np.isfinite(a), axis=1)))
            raise ParameterError(
                f"{expected}, got non-finite ones for member {bad}: {a[bad].tolist()}"
            )
        return self.lower + (np.clip(a, -1.0, 1.0) + 1.0) / 2.0 * (self.upper - self.lower)

    def actions(self, inputs) -> np.ndarray:
        """Actions (N, m) in [-1, 1] of actuator inputs: the inverse of :meth:`inputs`,
        clipped to [-1, 1].

        Parameters
        ----------
        inputs : array_like, shape (N, m)
            Actuator inputs, in the actuator's unit.
        """
        u = np.asarray(inputs, dtype=np.float64)
        return np.clip(2.0 * (u - self.lower) / (self.upper - self.lower) - 1.0, -1.0, 1.0)

    def controller_actions(self, controllers) -> np.ndarray:
        """The actions of one controller per member at its episode's state and time: the
        inputs each computes now, scaled onto the action space (:meth:`actions`).

        Parameters
        ----------
        controllers : sequence of SampledController, length N
            Controllers of the environments' actuator whose output is that actuator's
            inputs, as ``simulate(..., actuator=..., controller=...)`` runs them
            (:class:`~softcurve.control.PredictiveController`,
            :class:`~softcurve.control.mpc.ActuatorMPC`, or
            :class:`~softcurve.control.controllers.ActuatorDriven` around a torque
            controller), sampling once a period; their models of the robot may differ
            from the environments'. Each is given its member's state ``(q, qd, lam)`` of
            the environments' model and time ``steps * period`` [s].

        Returns
        -------
        ndarray, shape (N, m), float32
            The actions, dimensionless, in [-1, 1].
        """
        stepper = self.setup.stepper
        if len(controllers) != self.size:
            raise ParameterError(
                f"controllers must be one per environment ({self.size}), got {len(controllers)}"
            )
        model = stepper.model
        actions = np.empty((self.size, self.lower.size), dtype=np.float32)
        for i, controller in enumerate(controllers):
            _check_controller(controller, stepper)
            # the model's state, without the lagging inputs that follow it
            q, qd, lam = model.split_state(self.x[i][: model.n_state])
            time = float(self.steps[i]) * stepper.period
            inputs = np.asarray(controller(time, q, qd, lam), dtype=np.float64)
            if inputs.shape != self.lower.shape:
                raise ParameterError(
                    f"controller {i} gave inputs of shape {inputs.shape}, the actuator takes "
                    f"{self.lower.shape}: give a controller of the actuator's inputs"
                )
            actions[i] = self.actions(inputs[None, :])[0]
        return actions

    def observe(self, x, tip, goal) -> np.ndarray:
        """Observations (N, dim) of states, tips and goals (module docstring).

        Parameters
        ----------
        x : ndarray, shape (N, n_state)
            States.
        tip : ndarray, shape (N, 3)
            Tip positions [m].
        goal : ndarray, shape (N, n_goal)
            The task's goal features, dimensionless.
        """
        calibration = self.task.calibration
        state = (x - calibration.state_mean) / calibration.state_scale
        where = (tip - calibration.center) / calibration.radius
        observation = np.hstack([state, where, goal])
        if not np.isfinite(observation).all():  # only after a failure
            observation = np.nan_to_num(observation, nan=0.0, posinf=OBSERVATION_LIMIT,
                                        neginf=-OBSERVATION_LIMIT)  # fmt: skip
        np.clip(observation, -OBSERVATION_LIMIT, OBSERVATION_LIMIT, out=observation)
        return observation.astype(np.float32)

    def _outcome(self, members, x, tip, force, ok, reasons) -> tuple:
        """Observations, rewards, success and info of ``members`` at states ``x``."""
        goal, reward, success, extra = self.task.evaluate(
            self.parameters[members], self.steps[members], tip, force
        )
        failure = np.full(len(members), None, dtype=object)
        if not ok.all():
            reward = np.where(ok, np.nan_to_num(reward), FAILURE_REWARD)
            for i in np.flatnonzero(~ok):
                failure[i] = reasons[i]
        info = {
            "tip": tip,
            "time": self.steps[members] * self.setup.period,
            "is_success": success & ok,
            **extra,
            "failure": failure,
        }
        return self.observe(x, tip, goal), reward, info

    # -- seeding, reset, step -------------------------------------------------------
    def seed(self, members, seeds) -> None:
        """Give ``members`` new generators from ``seeds`` (an int each, or None: keep
        the member's generator, or draw a fresh one if it has none).

        Parameters
        ----------
        members : sequence of int
            Member indices.
        seeds : sequence of int or None
            One seed per member.
        """
        for i, seed in zip(members, seeds, strict=True):
            if seed is not None or self.rngs[i] is None:
                self.rngs[i] = seeding.np_random(seed)[0]

    def reset(self, members) -> tuple[np.ndarray, dict]:
        """Start new episodes for ``members`` (indices); returns their observations and
        info (arrays over those members).

        Parameters
        ----------
        members : ndarray of int, shape (k,)
            Member indices.
        """
        members = np.asarray(members, dtype=np.int64)
        self.seed(members, [None] * members.size)
        self.x[members] = self.setup.x0
        self.steps[members] = 0
        for i in members:
            self.parameters[i] = self.task.draw(self.rngs[i])
        k = members.size
        tip, force = np.tile(self.tip0, (k, 1)), np.tile(self.force0, (k, 1))
        observation, _, info = self._outcome(
            members, self.x[members], tip, force, np.ones(k, dtype=bool), [None] * k
        )
        return observation, info

    def step(self, actions, single: bool = False) -> tuple:
        """Advance every member by one control period: ``(observation, reward,
        terminated, truncated, info)`` as arrays over the members (no reset here).

        Parameters
        ----------
        actions : array_like, shape (N, m), or (m,) with ``single``
            The actions in [-1, 1] (clipped), dimensionless.
        single : bool
            The action of a single environment, shape (m,) (:meth:`inputs`).
        """
        inputs = self.inputs(actions, single)
        finite = np.isfinite(self.x).all(axis=1)
        start = self.x if finite.all() else np.where(finite[:, None], self.x, self.setup.x0)
        result = self.setup.stepper.step(start, inputs)
        x, tip, force = result.x, result.tip, result.contact_force
        ok = result.ok & finite & np.isfinite(x).all(axis=1)
        reasons = result.reasons
        if not ok.all():  # the failed members keep their state from before the step
            reasons = list(reasons)
            for i in np.flatnonzero(~ok):
                reasons[i] = (
                    NOT_FINITE
                    if not finite[i]
                    else (reasons[i] or "the stepper returned a state that is not finite")
                )
            x, tip, force = x.copy(), tip.copy(), force.copy()
            x[~ok] = self.x[~ok]
            tip[~ok], force[~ok] = np.nan, 0.0
            kept = np.flatnonzero(~ok & np.isfinite(x).all(axis=1))
            if kept.size:  # the tip of the state kept
                tip[kept] = self.setup.stepper.tip(x[kept])
        self.x = x
        self.steps += 1
        members = np.arange(self.size)
        observation, reward, info = self._outcome(members, x, tip, force, ok, reasons)
        info["inputs"] = inputs
        terminated = np.zeros(self.size, dtype=bool)
        truncated = (self.steps >= self.setup.max_episode_steps) | ~ok
        return observation, reward, terminated, truncated, info
