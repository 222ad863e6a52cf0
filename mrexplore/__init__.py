"""mrexplore: multi-robot exploration on occupancy grids with a verified semantic map merger.

>>> import mrexplore
>>> penv = mrexplore.parallel_env(world="small_office", n_robots=2)
>>> obs, infos = penv.reset(seed=0)
>>> sorted(obs)
['robot_0', 'robot_1']
>>> obs["robot_0"].shape, obs["robot_0"].dtype.name
((8, 64, 64), 'uint8')

``parallel_env(**options)`` builds the PettingZoo ``ParallelEnv``; ``env(**options)`` the AEC
version; the options are the fields of :class:`mrexplore.environment.EnvConfig`. Importing the
package registers the Gymnasium id ``mrexplore/Explore-v0`` (one robot).
"""

from __future__ import annotations

from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # pragma: no cover
    from mrexplore.environment.parallel_env import MultiRobotExplorationEnv

__version__ = "0.1.0"

__all__ = ["__version__", "env", "parallel_env", "raw_env"]


def parallel_env(render_mode: str | None = None, **options: Any) -> MultiRobotExplorationEnv:
    """The multi-robot exploration env as a PettingZoo ``ParallelEnv``.

    Options: see :class:`mrexplore.environment.EnvConfig` (``world``, ``n_robots``, ``task``,
    ``merger``, ``comm_range_m``, ``max_range_m``, ...). An unknown option raises
    ``ConfigError``.
    """
    from mrexplore.environment import MultiRobotExplorationEnv

    return MultiRobotExplorationEnv(render_mode=render_mode, **options)


def env(render_mode: str | None = None, **options: Any) -> Any:
    """The same env as a PettingZoo AEC env (``parallel_to_aec``, order-enforced)."""
    from pettingzoo.utils.conversions import parallel_to_aec

    return parallel_to_aec(parallel_env(render_mode=render_mode, **options))


def raw_env(render_mode: str | None = None, **options: Any) -> Any:
    """The AEC version without PettingZoo's order-enforcing wrapper (PettingZoo convention)."""
    from pettingzoo.utils.conversions import parallel_to_aec_wrapper

    return parallel_to_aec_wrapper(parallel_env(render_mode=render_mode, **options))


def _register_gymnasium() -> None:
    """Register ``mrexplore/Explore-v0`` (single robot) with Gymnasium; idempotent."""
    try:
        import gymnasium
    except ImportError:  # pragma: no cover - gymnasium is a core dependency
        return
    if "mrexplore/Explore-v0" not in gymnasium.registry:
        gymnasium.register(
            id="mrexplore/Explore-v0",
            entry_point="mrexplore.wrappers.single:SingleRobotExploreEnv",
        )


_register_gymnasium()
