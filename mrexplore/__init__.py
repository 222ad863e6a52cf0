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
    from mrexplore.environment.batched import BatchedExploreEnv, ExploreVectorEnv
    from mrexplore.environment.goal_actions import GoalActionEnv
    from mrexplore.environment.parallel_env import MultiRobotExplorationEnv

__version__ = "0.1.0"

__all__ = ["__version__", "env", "parallel_env", "raw_env", "vector_env"]


#: Options of the goal level (``mrexplore.environment.goal_actions.GOAL_OPTIONS``, kept here so
#: that the low-level path imports nothing more).
_GOAL_KEYS = frozenset(
    {"action_mode", "goal_candidates", "goal_max_steps", "goal_memory", "goal_gain", "goal_turns"}
)


def parallel_env(
    render_mode: str | None = None, **options: Any
) -> MultiRobotExplorationEnv | GoalActionEnv:
    """The multi-robot exploration env as a PettingZoo ``ParallelEnv``.

    Options: see :class:`mrexplore.environment.EnvConfig` (``world``, ``n_robots``, ``task``,
    ``merger``, ``comm_range_m``, ``max_range_m``, ...). An unknown option raises
    ``ConfigError``. ``action_mode="goal"`` (default ``"low"``) returns the goal-level env
    (:mod:`mrexplore.environment.goal_actions`: one step = one choice among candidate goals),
    with its own options ``goal_candidates`` and ``goal_max_steps``; the rest configure the
    low-level env it drives.
    """
    from mrexplore.environment import MultiRobotExplorationEnv

    if not _GOAL_KEYS & options.keys():  # the low-level env, exactly as before
        return MultiRobotExplorationEnv(render_mode=render_mode, **options)
    from mrexplore.environment.goal_actions import GoalActionEnv, split_options

    _, goal, low_options = split_options(options)
    low = MultiRobotExplorationEnv(render_mode=render_mode, **low_options)
    return low if goal is None else GoalActionEnv(low, goal)


def vector_env(
    num_envs: int = 1, render_mode: str | None = None, **options: Any
) -> ExploreVectorEnv | BatchedExploreEnv:
    """``num_envs`` worlds stepped in one call, for training (:mod:`mrexplore.environment.batched`).

    ``n_robots=1``: a ``gymnasium.vector.VectorEnv`` (:class:`ExploreVectorEnv`, observations
    (N, C, H, W)); a team (the default, 2 robots): a :class:`BatchedExploreEnv` with arrays
    (N, R, ...). Both auto-reset in the same step (``final_obs`` / ``final_info`` in the infos);
    ``reset(seed=s)`` seeds world k with ``s + k``. The options are those of
    :func:`parallel_env` (low-level actions only), and ``num_threads``: the threads that step
    the worlds (default: every usable core; the run is the same at any number), or for a team
    ``num_workers``: worker processes that step blocks of the worlds, each with its own GIL
    (:class:`~mrexplore.environment.processes.ProcessBatchedEnv`; the same run). For
    stable-baselines3:
    ``mrexplore.wrappers.make_vec_env(n_copies=N, batched=True, ...)``.

    Raises:
        ConfigError: ``num_envs`` not an integer >= 1, or a bad env option.
    """
    from mrexplore.environment.batched import (
        BatchedExploreEnv,
        ExploreVectorEnv,
        check_num_envs,
    )
    from mrexplore.errors import ConfigError

    check_num_envs(num_envs)
    if options.get("n_robots", 2) == 1:
        if "num_workers" in options:
            raise ConfigError(
                "vector_env: num_workers is for teams (n_robots >= 2); one robot per world "
                "steps on threads (num_threads)"
            )
        return ExploreVectorEnv(num_envs, render_mode=render_mode, **options)
    if "num_workers" in options:
        from mrexplore.environment.processes import ProcessBatchedEnv

        return ProcessBatchedEnv(num_envs, render_mode=render_mode, **options)
    return BatchedExploreEnv(num_envs, render_mode=render_mode, **options)


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
