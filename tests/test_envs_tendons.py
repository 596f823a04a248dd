"""The tendon task: Reach on the two-segment tendon robot of Rao et al. 2021 with its
material damping (``presets.rao2021(damping_time=RAO2021_DAMPING_TIME)``) and its six
tendons at their default bounds (0-8 N), made as a user makes it
(``gymnasium.make_vec``). Its own file: it compiles the stepper of that robot."""

from __future__ import annotations

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

import softcurve as sc  # noqa: E402
import softcurve.envs  # noqa: E402  (registers the ids)

MEMBERS = 3
"""Environments of the vector: a small batch, several episodes drawn at once."""


def test_random_tensions_run_whole_episodes_without_a_failure():
    """Under ``action_space.sample()`` from seed 0, every member runs its episode to its
    time limit (100 periods of 20 ms): no step fails, every member is truncated once, at
    the last period, with ``failure`` None, and the tips stay within the robot's reach.
    The undamped robot under the former 20 N bounds failed 56 % of such steps."""
    damped = sc.presets.rao2021(damping_time=sc.presets.RAO2021_DAMPING_TIME)
    vector = gymnasium.make_vec(
        "softcurve/Reach-v0", num_envs=MEMBERS, robot=damped,
        actuator=sc.presets.rao2021_tendons(),
    )  # fmt: skip
    stepper = vector.episodes.setup.stepper
    assert stepper.method == "ROS34PW2"  # RK4 refuses the stiff axial modes
    length = vector.episodes.setup.max_episode_steps
    assert length == 100
    vector.reset(seed=0)
    vector.action_space.seed(0)
    truncations, failures, tips = [], 0, []
    for _ in range(length):
        _, reward, terminated, truncated, info = vector.step(vector.action_space.sample())
        assert np.all(np.isfinite(reward)) and not terminated.any()
        truncations.append(truncated.copy())
        if "final_info" in info:
            failures += sum(f is not None for f in info["final_info"]["failure"])
            tips.append(info["final_info"]["tip"][info["_final_info"]])
        else:
            tips.append(info["tip"])
    assert failures == 0
    truncations = np.array(truncations)
    assert not truncations[:-1].any() and truncations[-1].all()
    reach = np.linalg.norm(np.concatenate(tips), axis=1)
    assert np.all(reach <= damped.rest_length)


def test_a_robot_whose_calibration_runs_fail_is_named_at_construction():
    """The undamped robot leaves its domain under some tensions held from the start (18 of
    the 70 calibration runs at 8 N): the environment says so when it is made, with the
    count and the first reason, instead of truncating episodes silently."""
    with pytest.warns(UserWarning, match=r"built-in: [1-9]\d* of 70 calibration runs .* failed"):
        gymnasium.make_vec(
            "softcurve/Reach-v0", num_envs=1, robot=sc.presets.rao2021(),
            actuator=sc.presets.rao2021_tendons(),
        )  # fmt: skip
