"""softcurve/Press-v0: the paper's robot beside a wall (one compiled model with an
obstacle, about 25 s on a fresh cache): Gymnasium's checker, and the force it reads."""

from __future__ import annotations

import warnings

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")

from gymnasium.utils.env_checker import check_env  # noqa: E402

import softcurve as sc  # noqa: E402
import softcurve.envs as envs  # noqa: E402
from softcurve.envs.tasks import PRESS_RANGE  # noqa: E402


def test_press_passes_the_checker_and_feels_the_wall():
    env = gymnasium.make("softcurve/Press-v0", max_episode_steps=30)
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        check_env(env.unwrapped, skip_render_check=True)
    task = env.unwrapped.task
    _, info = env.reset(seed=4)
    low, high = PRESS_RANGE
    assert low * task.largest <= info["target_force"] <= high * task.largest
    assert info["force"] == 0.0  # the robot starts clear of the wall
    for _ in range(30):  # the bellow at azimuth 0 bends the robot toward the wall
        _, reward, terminated, truncated, info = env.step(np.array([1.0, -1.0, -1.0]))
    assert info["failure"] is None and not terminated and truncated
    assert info["force"] > task.largest * low
    assert reward == pytest.approx(
        -min(abs(info["force"] - info["target_force"]) / task.largest, 1)
    )


def test_press_needs_a_wall_for_a_robot_of_its_own():
    with pytest.raises(ValueError, match="wall"):
        envs.Press(robot=sc.presets.ifac2020())
