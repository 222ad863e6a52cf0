"""The PettingZoo environment: options, observations, the env class and the batched env.

Imports are lazy so that importing one part (``mrexplore.environment.config``, ``.infos``) does
not pull in the simulator, the merger and the batched env. What one robot knows at one step is
:class:`mrexplore.types.RobotView` (policies read it without importing the env).
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "BatchedExploreEnv",
    "EnvConfig",
    "ExploreVectorEnv",
    "MultiRobotExplorationEnv",
]


def __getattr__(name: str) -> Any:
    if name == "EnvConfig":
        from mrexplore.environment.config import EnvConfig

        return EnvConfig
    if name == "MultiRobotExplorationEnv":
        from mrexplore.environment.parallel_env import MultiRobotExplorationEnv

        return MultiRobotExplorationEnv
    if name in ("BatchedExploreEnv", "ExploreVectorEnv"):
        from mrexplore.environment import batched

        return getattr(batched, name)
    raise AttributeError(f"module 'mrexplore.environment' has no attribute {name!r}")
