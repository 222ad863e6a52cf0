"""Tiny hand-made ParallelEnvs for the adapter tests (no SB3/torch import here, so that a
subprocess worker unpickling them stays light)."""

from __future__ import annotations

from typing import Any, ClassVar

import gymnasium
import numpy as np
from pettingzoo import ParallelEnv


class CountEnv(ParallelEnv):  # type: ignore[type-arg]
    """Agents ``a0..a{n-1}``; observation ``[100 * episode + 10 * i + t]`` (uint8 would overflow:
    float32); reward ``i + t``; agent ``early`` terminates at ``t == 2``; everyone truncates
    at ``t == horizon``. Records the seeds it was reset with."""

    metadata: ClassVar[dict[str, Any]] = {"name": "count_v0", "render_modes": ["rgb_array"]}

    def __init__(
        self, n: int = 3, horizon: int = 4, early: str | None = "a2", render_mode: str | None = None
    ) -> None:
        self.possible_agents = [f"a{i}" for i in range(n)]
        self.agents: list[str] = []
        self.horizon = horizon
        self.early = early
        self.render_mode = render_mode
        self.t = 0
        self.episode = -1
        self.seeds: list[int | None] = []
        self.options: list[Any] = []
        self._obs = gymnasium.spaces.Box(0, 1e6, (1,), dtype=np.float32)
        self._act = gymnasium.spaces.Discrete(3)
        self.last_actions: dict[str, int] = {}

    def observation_space(self, agent: str) -> gymnasium.spaces.Space[Any]:
        return self._obs

    def action_space(self, agent: str) -> gymnasium.spaces.Space[Any]:
        return self._act

    def value(self, agent: str) -> float:
        return 100.0 * self.episode + 10 * self.possible_agents.index(agent) + self.t

    def reset(self, seed: int | None = None, options: dict[str, Any] | None = None) -> Any:
        self.seeds.append(seed)
        self.options.append(options)
        self.t = 0
        self.episode += 1
        self.agents = list(self.possible_agents)
        return (
            {a: np.array([self.value(a)], np.float32) for a in self.agents},
            {a: {"reset": self.episode} for a in self.agents},
        )

    def step(self, actions: dict[str, Any]) -> Any:
        assert set(actions) == set(self.agents), (actions, self.agents)
        self.last_actions = {a: int(v) for a, v in actions.items()}
        self.t += 1
        agents = list(self.agents)
        obs = {a: np.array([self.value(a)], np.float32) for a in agents}
        rew = {a: float(self.possible_agents.index(a) + self.t) for a in agents}
        term = {a: a == self.early and self.t == 2 for a in agents}
        trunc = {a: self.t >= self.horizon and not term[a] for a in agents}
        infos = {a: {"t": self.t} for a in agents}
        self.agents = [a for a in agents if not (term[a] or trunc[a])]
        return obs, rew, term, trunc, infos

    def render(self) -> np.ndarray:
        return np.full((2, 3, 3), self.t, dtype=np.uint8)

    def ping(self, x: int) -> tuple[int, int]:
        return (self.episode, x)
