"""Gymnasium learning environments: soft robots that learn to reach, track and press
(docs/envs.md).

Needs the optional dependency Gymnasium (``pip install "softcurve[envs]"``); ``import
softcurve`` works without it. Importing this package registers ``softcurve/Reach-v0``,
``softcurve/Track-v0`` and ``softcurve/Press-v0`` with Gymnasium, each with a native
vector environment (:mod:`softcurve.envs.registration`).
"""

from __future__ import annotations

try:
    import gymnasium  # noqa: F401
except ModuleNotFoundError as exc:  # pragma: no cover - depends on the installation
    raise ModuleNotFoundError(
        "softcurve.envs needs Gymnasium: pip install 'softcurve[envs]' (gymnasium>=1.1)"
    ) from exc

from softcurve.envs.registration import TASK_IDS, register_tasks
from softcurve.envs.single import Press, Reach, SoftRobotEnv, Track
from softcurve.envs.vector import PressVector, ReachVector, SoftRobotVectorEnv, TrackVector

register_tasks()

__all__ = [
    "TASK_IDS",
    "Press",
    "PressVector",
    "Reach",
    "ReachVector",
    "SoftRobotEnv",
    "SoftRobotVectorEnv",
    "Track",
    "TrackVector",
    "register_tasks",
]
