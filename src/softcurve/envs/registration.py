"""Registration of the tasks with Gymnasium.

Gymnasium 1.x has no plugin discovery (1.4, the version tested, looks up no package entry
points in ``gymnasium.envs.registration``), so the ids are registered when :mod:`softcurve.envs` is
imported: ``import softcurve.envs`` then ``gymnasium.make("softcurve/Reach-v0")``, or
in one string, ``gymnasium.make("softcurve.envs:softcurve/Reach-v0")`` (Gymnasium imports
the module before the ``:``). Each id has a ``vector_entry_point``:
``gymnasium.make_vec("softcurve/Reach-v0", num_envs=N)`` returns the native
:class:`~softcurve.envs.vector.ReachVector`.
"""

from __future__ import annotations

import gymnasium

TASK_IDS = {
    "softcurve/Reach-v0": ("Reach", "ReachVector"),
    "softcurve/Track-v0": ("Track", "TrackVector"),
    "softcurve/Press-v0": ("Press", "PressVector"),
}
"""Gymnasium id -> (single class, vector class)."""


def register_tasks() -> None:
    """Register the ids of :data:`TASK_IDS` with Gymnasium (once; again is a no-op)."""
    for env_id, (single, vector) in TASK_IDS.items():
        if env_id in gymnasium.registry:
            continue
        gymnasium.register(
            id=env_id,
            entry_point=f"softcurve.envs.single:{single}",
            vector_entry_point=f"softcurve.envs.vector:{vector}",
        )
