"""A trained stable-baselines3 policy as a team policy (one shared policy for every robot).

Loading needs stable-baselines3 (and torch) only: no training dependency beyond SB3.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

ALGOS = ("ppo", "a2c", "dqn")
#: Env options that shape the observation: a trained policy must run with the ones it saw.
OBSERVATION_OPTIONS = ("obs_heading_up", "global_view_m", "local_view_m", "obs_size_px")


def observation_options(folder: str | Path) -> dict[str, Any]:
    """The observation options a trained policy was trained with (from its config.yaml)."""
    cfg_path = Path(folder) / "config.yaml"
    if not cfg_path.is_file():
        return {}
    env = yaml.safe_load(cfg_path.read_text()).get("env", {})
    return {k: env[k] for k in OBSERVATION_OPTIONS if k in env}


def algo_class(algo: str) -> Any:
    """The SB3 class for ``algo`` (``ppo``, ``a2c``, ``dqn``), with an install hint."""
    try:
        import stable_baselines3 as sb3
    except ImportError as exc:  # pragma: no cover - exercised only without the extra
        raise ImportError(
            "trained policies need stable-baselines3: pip install 'mrexplore[train]'"
        ) from exc
    classes = {"ppo": sb3.PPO, "a2c": sb3.A2C, "dqn": sb3.DQN}
    if algo not in classes:
        raise ValueError(f"unknown algorithm {algo!r}; choose one of {', '.join(ALGOS)}")
    return classes[algo]


class TrainedTeamPolicy:
    """Every robot acts with the same SB3 model on its own observation (parameter sharing).

    It reads the env's observations (``uses_observations = True``), which hold only what each
    robot knows (see :mod:`mrexplore.environment.observations`). Actions are *sampled* from the
    policy by default: the arg-max action of our PPO policy loops (measured on 20 held-out worlds:
    50 % coverage, stuck after 15 s, against 91 % when sampling, i.e. the policy as trained).
    """

    uses_observations = True

    def __init__(self, model: Any, agents: Sequence[str], deterministic: bool = False) -> None:
        self.model = model
        self.agents = list(agents)
        self.deterministic = deterministic

    @classmethod
    def load(
        cls, folder: str | Path, agents: Sequence[str], deterministic: bool = False
    ) -> TrainedTeamPolicy:
        """Load ``folder/model.zip`` with the algorithm named in ``folder/config.yaml``."""
        folder = Path(folder)
        cfg_path = folder / "config.yaml"
        model_path = folder / "model.zip"
        if not model_path.is_file():
            raise FileNotFoundError(f"no trained model at {model_path}")
        algo = "ppo"
        if cfg_path.is_file():
            algo = str(yaml.safe_load(cfg_path.read_text()).get("algo", "ppo"))
        model = algo_class(algo).load(str(model_path), device="cpu")
        return cls(model, agents, deterministic)

    def reset(self, rng: np.random.Generator) -> None:
        """Seed the action sampling from ``rng`` (SB3 samples with torch's generator), so the same
        episode seed gives the same run."""
        if not self.deterministic:
            import torch

            torch.manual_seed(int(rng.integers(2**62)))

    def act_obs(self, observations: Mapping[str, NDArray[np.uint8]]) -> dict[str, int]:
        """Actions for all robots from their observations, in one batch."""
        agents = [a for a in self.agents if a in observations]
        if not agents:
            return {}
        batch = np.stack([observations[a] for a in agents])
        actions, _ = self.model.predict(batch, deterministic=self.deterministic)
        return {a: int(x) for a, x in zip(agents, np.asarray(actions).reshape(-1), strict=False)}

    def act(self, views: Mapping[str, Any]) -> dict[str, int]:
        raise TypeError("TrainedTeamPolicy acts on observations: call act_obs(observations)")
