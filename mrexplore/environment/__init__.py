"""The PettingZoo environment: options, observations, the env class and the robot view.

Imports are lazy so that ``mrexplore.environment.view`` (used by policies) does not pull in the
simulator.
"""

from __future__ import annotations

from typing import Any

__all__ = [
    "BatchedExploreEnv",
    "EnvConfig",
    "ExploreVectorEnv",
    "MultiRobotExplorationEnv",
    "RobotView",
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
    if name == "RobotView":
        from mrexplore.types import RobotView

        return RobotView
    raise AttributeError(f"module 'mrexplore.environment' has no attribute {name!r}")
