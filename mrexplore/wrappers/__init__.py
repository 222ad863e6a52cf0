"""Wrappers: the map merger on any PettingZoo env, the single-robot Gymnasium env, the SB3 adapter.

* :class:`MapMergeWrapper` (:mod:`.merge_wrapper`): runs the merger on any ``ParallelEnv`` that
  implements the map protocol (``local_map(agent)``, ``map_resolution_m``, optional
  ``own_pose_cell(agent)``).
* :class:`SingleRobotExploreEnv` (:mod:`.single`): ``gymnasium.make("mrexplore/Explore-v0")``.
* :class:`ParallelEnvVecEnv`, :func:`make_vec_env` (:mod:`.sb3_vec`): a ``ParallelEnv`` as an SB3
  ``VecEnv``, one slot per robot, one shared policy; :class:`BatchedVecEnv` (``make_vec_env(...,
  batched=True)``) the same over the batched env of :func:`mrexplore.vector_env`. Needs
  stable-baselines3 (``pip install mrexplore[train]``).
* :class:`VecActionMasks` (:mod:`.action_masks`): per-slot ``action_masks`` for sb3-contrib's
  ``MaskablePPO`` from the goal-level env's ``action_mask`` observations.

Imports are lazy so that ``import mrexplore.wrappers`` pulls in neither the simulator nor
stable-baselines3/torch until a name is used.
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "BatchedVecEnv",
    "MapMergeWrapper",
    "ParallelEnvVecEnv",
    "SingleRobotExploreEnv",
    "VecActionMasks",
    "check_map_protocol",
    "make_vec_env",
]

_WHERE = {
    "MapMergeWrapper": "mrexplore.wrappers.merge_wrapper",
    "check_map_protocol": "mrexplore.wrappers.merge_wrapper",
    "SingleRobotExploreEnv": "mrexplore.wrappers.single",
    "ParallelEnvVecEnv": "mrexplore.wrappers.sb3_vec",
    "make_vec_env": "mrexplore.wrappers.sb3_vec",
    "BatchedVecEnv": "mrexplore.wrappers.sb3_vec",
    "VecActionMasks": "mrexplore.wrappers.action_masks",
}


def __getattr__(name: str) -> Any:
    if name in _WHERE:
        import importlib

        module = importlib.import_module(_WHERE[name])
        return getattr(module, name)
    raise AttributeError(f"module 'mrexplore.wrappers' has no attribute {name!r}")


def __dir__() -> list[str]:
    return sorted(__all__)
