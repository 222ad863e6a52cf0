"""``mrexplore/Explore-v0``: the single-robot case as a plain ``gymnasium.Env``.

>>> import gymnasium, mrexplore
>>> env = gymnasium.make("mrexplore/Explore-v0", world="small_office", max_cycles=5)
>>> obs, info = env.reset(seed=0)
>>> obs.shape, obs.dtype.name, env.action_space
((8, 64, 64), 'uint8', Discrete(4))
>>> env.close()

One robot (``robot_0``) of the multi-robot env (:func:`mrexplore.parallel_env`) with
``n_robots=1``: the same world, start pose (for a seed), sensing, observation, reward and
termination as the team env, so single- and multi-robot task times compare directly. Options
are those of ``EnvConfig`` except ``n_robots`` (always 1). ``step`` returns ``(obs, reward,
terminated, truncated, info)`` with ``info`` the robot's info dict (``coverage``,
``task_time_s``, ...).
"""

from __future__ import annotations

from typing import Any, SupportsFloat, cast

import gymnasium
import numpy as np
from numpy.typing import NDArray

import mrexplore
from mrexplore.errors import ConfigError

_AGENT = "robot_0"


class SingleRobotExploreEnv(gymnasium.Env[NDArray[np.uint8], Any]):
    """One robot exploring alone; see the module docstring.

    Args:
        render_mode: ``None``, ``"rgb_array"`` or ``"human"`` (passed to the multi-robot env).
        **options: :class:`mrexplore.environment.EnvConfig` fields other than ``n_robots``.

    Raises:
        ConfigError: ``n_robots`` other than 1, or a bad option.
    """

    # A class attribute, as Gymnasium reads it before building the env; the same modes and fps
    # as the multi-robot env (tests/wrappers/test_single.py checks they agree).
    metadata: dict[str, Any] = {"render_modes": ["human", "rgb_array"], "render_fps": 8}  # noqa: RUF012

    def __init__(self, render_mode: str | None = None, **options: Any) -> None:
        n = options.pop("n_robots", 1)
        if n != 1:
            raise ConfigError(
                f"SingleRobotExploreEnv has exactly one robot, got n_robots={n!r}; use "
                "mrexplore.parallel_env(n_robots=...) for teams"
            )
        self.penv: Any = mrexplore.parallel_env(render_mode=render_mode, n_robots=1, **options)
        self.render_mode = render_mode
        self.observation_space = cast(
            gymnasium.spaces.Space[NDArray[np.uint8]], self.penv.observation_space(_AGENT)
        )
        self.action_space = self.penv.action_space(_AGENT)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[NDArray[np.uint8], dict[str, Any]]:
        """Start an episode; ``seed`` re-seeds the env (None continues its random stream)."""
        # Seeds self.np_random (Gymnasium's contract); the simulation draws from its own
        # Generator, seeded with the same seed, so the env stays deterministic per seed.
        super().reset(seed=seed)
        obs, infos = self.penv.reset(seed=seed, options=options)
        return obs[_AGENT], infos[_AGENT]

    def step(
        self, action: Any
    ) -> tuple[NDArray[np.uint8], SupportsFloat, bool, bool, dict[str, Any]]:
        """One step; ``action`` in ``Discrete(4)`` (see :class:`mrexplore.robot.Action`)."""
        obs, rewards, terms, truncs, infos = self.penv.step({_AGENT: action})
        return (
            obs[_AGENT],
            float(rewards[_AGENT]),
            bool(terms[_AGENT]),
            bool(truncs[_AGENT]),
            infos[_AGENT],
        )

    def render(self) -> Any:
        """The frame of the multi-robot env (``"rgb_array"``: HxWx3 uint8), or None."""
        # Typed Any: gymnasium 1.2's stubs want its RenderFrame type var here, 1.4's an array.
        return self.penv.render()

    def close(self) -> None:
        """Release the render window, if any."""
        self.penv.close()

    def robot_view(self) -> Any:
        """The robot's ``RobotView`` (map, pose, goal: what it knows), for scripted policies."""
        return self.penv.robot_view(_AGENT)
