"""A trained stable-baselines3 policy as a team policy (one shared policy for every robot).

Loading needs stable-baselines3 (and torch) only: no training dependency beyond SB3.
"""

from __future__ import annotations

import json
import zipfile
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
import yaml
from numpy.typing import NDArray

from mrexplore.errors import ConfigError

ALGOS = ("ppo", "a2c", "dqn", "maskable_ppo", "recurrent_ppo")
#: Algorithms from sb3-contrib (``pip install sb3-contrib``): ``maskable_ppo`` is its
#: ``MaskablePPO``, for the goal-level env's action masks; ``recurrent_ppo`` its
#: ``RecurrentPPO`` (an LSTM policy: memory across decisions; it takes no masks, so a masked
#: choice falls back to the env's row 0, and the mask is one more input).
CONTRIB_ALGOS = ("maskable_ppo", "recurrent_ppo")
#: Env options that shape the observation (and, for the goal level, the actions): a trained
#: policy must run with the ones it saw.
OBSERVATION_OPTIONS = (
    "obs_heading_up",
    "global_view_m",
    "local_view_m",
    "obs_size_px",
    "obs_layout",
    "obs_dtype",
    "action_mode",
    "goal_candidates",
    "goal_max_steps",
    "goal_memory",
    "goal_gain",
    "goal_turns",
)


def read_config(folder: str | Path) -> dict[str, Any]:
    """A policy folder's ``config.yaml`` as a mapping ({} when absent).

    Raises:
        ConfigError: the file is not YAML, not a mapping, or names an unknown ``algo``, or its
            ``env`` is not a mapping.
    """
    cfg_path = Path(folder) / "config.yaml"
    if not cfg_path.is_file():
        return {}
    try:
        cfg = yaml.safe_load(cfg_path.read_text())
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        first = str(exc).splitlines()[0] if str(exc) else type(exc).__name__
        raise ConfigError(f"{cfg_path} is not valid YAML ({first})") from None
    if cfg is None:
        cfg = {}
    if not isinstance(cfg, dict):
        raise ConfigError(f"{cfg_path} must be a mapping of settings, got {type(cfg).__name__}")
    algo = cfg.get("algo", "ppo")
    if algo not in ALGOS:
        raise ConfigError(f"{cfg_path}: unknown algo {algo!r}; choose one of {', '.join(ALGOS)}")
    if not isinstance(cfg.get("env", {}), dict):
        raise ConfigError(f"{cfg_path}: 'env' must be a mapping of env options")
    return cfg


def model_algo(model_path: str | Path) -> str | None:
    """The algorithm a stable-baselines3 ``model.zip`` was saved by, read from its ``data``
    (``ppo``, ``a2c``, ``dqn``; None when the file does not say).

    Raises:
        ConfigError: the file is not a stable-baselines3 model archive (corrupt, truncated).
    """
    try:
        with zipfile.ZipFile(model_path) as z:
            data = json.loads(z.read("data"))
    except (zipfile.BadZipFile, KeyError, ValueError, OSError) as exc:
        raise ConfigError(
            f"{model_path} is not a stable-baselines3 model file ({type(exc).__name__}: {exc})"
        ) from None
    if not isinstance(data, dict):
        raise ConfigError(f"{model_path} is not a stable-baselines3 model file (bad 'data')")
    if "clip_range" in data:
        policy_class = json.dumps(data.get("policy_class", "")).lower()
        if "maskable" in policy_class:
            return "maskable_ppo"
        return "recurrent_ppo" if "lstm" in policy_class else "ppo"
    if "target_update_interval" in data:
        return "dqn"
    if "n_steps" in data:
        return "a2c"
    return None


def observation_options(folder: str | Path) -> dict[str, Any]:
    """The observation options a trained policy was trained with (from its config.yaml)."""
    env = read_config(folder).get("env", {})
    return {k: env[k] for k in OBSERVATION_OPTIONS if k in env}


def algo_class(algo: str) -> Any:
    """The SB3 class for ``algo`` (``ppo``, ``a2c``, ``dqn``; ``maskable_ppo`` and
    ``recurrent_ppo`` from sb3-contrib), with an install hint."""
    if algo in CONTRIB_ALGOS:
        try:
            import sb3_contrib
        except ImportError as exc:  # pragma: no cover - exercised only without the extra
            raise ImportError(f"{algo} needs sb3-contrib: pip install 'mrexplore[train]'") from exc
        return sb3_contrib.MaskablePPO if algo == "maskable_ppo" else sb3_contrib.RecurrentPPO
    try:
        import stable_baselines3 as sb3
    except ImportError as exc:  # pragma: no cover - exercised only without the extra
        raise ImportError(
            "trained policies need stable-baselines3: pip install 'mrexplore[train]'"
        ) from exc
    classes = {"ppo": sb3.PPO, "a2c": sb3.A2C, "dqn": sb3.DQN}
    if algo not in classes:
        raise ConfigError(f"unknown algorithm {algo!r}; choose one of {', '.join(ALGOS)}")
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
        # recurrent models (sb3-contrib's RecurrentPPO): each robot's LSTM state, carried
        # from one decision to the next and cleared by reset(); a robot absent = episode start
        self.recurrent = _is_recurrent(model)
        self._lstm: dict[str, tuple[NDArray[np.float32], NDArray[np.float32]]] = {}

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
        algo = str(read_config(folder).get("algo", "ppo"))
        saved_by = model_algo(model_path)
        if saved_by is not None and saved_by != algo:
            raise ConfigError(
                f"{cfg_path} says algo {algo!r} but {model_path} was saved by {saved_by!r}; "
                "fix the config's 'algo'"
            )
        try:
            model = algo_class(algo).load(str(model_path), device="cpu")
        except (ValueError, KeyError, RuntimeError, EOFError, zipfile.BadZipFile) as exc:
            raise ConfigError(
                f"cannot load {model_path} as a {algo} model ({type(exc).__name__}: "
                f"{str(exc).splitlines()[0] if str(exc) else ''})"
            ) from None
        return cls(model, agents, deterministic)

    def reset(self, rng: np.random.Generator) -> None:
        """Seed the action sampling from ``rng`` (SB3 samples with torch's generator), so the same
        episode seed gives the same run. A recurrent model's memory starts empty again."""
        self._lstm = {}
        if not self.deterministic:
            import torch

            torch.manual_seed(int(rng.integers(2**62)))

    def act_obs(self, observations: Mapping[str, Any]) -> dict[str, int]:
        """Actions for all robots from their observations, in one batch.

        Dict observations (the goal-level env's) are stacked per key; their ``action_mask``
        goes to models that take masks (sb3-contrib's ``MaskablePPO``).
        """
        agents = [a for a in self.agents if a in observations]
        if not agents:
            return {}
        first = observations[agents[0]]
        kwargs: dict[str, Any] = {}
        if isinstance(first, Mapping):
            batch: Any = {k: np.stack([observations[a][k] for a in agents]) for k in first}
            if "action_mask" in batch and _takes_masks(self.model):
                kwargs["action_masks"] = batch["action_mask"].astype(bool)
        else:
            batch = np.stack([observations[a] for a in agents])
        if self.recurrent:
            actions = self._predict_recurrent(agents, batch)
        else:
            actions, _ = self.model.predict(batch, deterministic=self.deterministic, **kwargs)
        return {a: int(x) for a, x in zip(agents, np.asarray(actions).reshape(-1), strict=False)}

    def act(self, views: Mapping[str, Any]) -> dict[str, int]:
        raise TypeError("TrainedTeamPolicy acts on observations: call act_obs(observations)")

    def _predict_recurrent(self, agents: list[str], batch: Any) -> Any:
        """The actions of a recurrent model for ``agents`` (one batch), each robot with its
        own LSTM state: ``(n_layers, 1, hidden)`` hidden and cell arrays per robot, stacked
        along axis 1 for the call and kept for the next one."""
        starts = np.array([a not in self._lstm for a in agents])
        state = None
        if not starts.all():
            shape = self.model.policy.lstm_hidden_state_shape  # (n_layers, 1, hidden)
            zero = np.zeros(shape, dtype=np.float32)
            hs, cs = zip(*(self._lstm.get(a, (zero, zero)) for a in agents), strict=True)
            state = (np.concatenate(hs, axis=1), np.concatenate(cs, axis=1))
        actions, (h, c) = self.model.predict(
            batch, state=state, episode_start=starts, deterministic=self.deterministic
        )
        for k, a in enumerate(agents):
            self._lstm[a] = (h[:, k : k + 1].copy(), c[:, k : k + 1].copy())
        return actions


def _is_recurrent(model: Any) -> bool:
    """Whether ``model`` keeps an LSTM state between calls (sb3-contrib's ``RecurrentPPO``)."""
    return hasattr(getattr(model, "policy", None), "lstm_hidden_state_shape")


def _takes_masks(model: Any) -> bool:
    """Whether ``model.predict`` accepts ``action_masks`` (sb3-contrib's maskable models)."""
    import inspect

    return "action_masks" in inspect.signature(model.predict).parameters


#: Where ``mrexplore train --backend rllib`` leaves the shared policy inside its folder.
RLLIB_MODULE = Path("checkpoint") / "learner_group" / "learner" / "rl_module" / "shared"


def is_rllib_folder(folder: str | Path) -> bool:
    """A folder written by ``mrexplore train --backend rllib`` (its config says so)."""
    return read_config(folder).get("backend") == "rllib"


class RllibTeamPolicy:
    """Every robot acts with the RLlib ``RLModule`` trained by ``train --backend rllib`` (the
    shared policy), on its own observation (channels-last float, as trained). Actions are
    sampled from the policy's logits with a torch Generator seeded by :meth:`reset`, like
    :class:`TrainedTeamPolicy`; ``deterministic`` takes the arg-max."""

    uses_observations = True

    def __init__(self, module: Any, agents: Sequence[str], deterministic: bool = False) -> None:
        import torch

        self.module = module
        self.agents = list(agents)
        self.deterministic = deterministic
        self._gen = torch.Generator().manual_seed(0)

    @classmethod
    def load(
        cls, folder: str | Path, agents: Sequence[str], deterministic: bool = False
    ) -> RllibTeamPolicy:
        """Load ``folder/checkpoint/.../rl_module/shared``.

        Raises:
            FileNotFoundError: no checkpoint in ``folder``.
            ConfigError: RLlib is not installed.
        """
        path = Path(folder) / RLLIB_MODULE
        if not path.is_dir():
            raise FileNotFoundError(f"no RLlib policy checkpoint at {path}")
        try:
            from ray.rllib.core.rl_module.rl_module import RLModule
        except ImportError as exc:
            raise ConfigError(
                f"{folder} holds an RLlib policy: pip install 'mrexplore[rllib]'"
            ) from exc
        return cls(RLModule.from_checkpoint(path.resolve()), agents, deterministic)

    def reset(self, rng: np.random.Generator) -> None:
        """Seed the action sampling from ``rng``: the same episode seed gives the same run."""
        self._gen.manual_seed(int(rng.integers(2**62)))

    def act_obs(self, observations: Mapping[str, NDArray[Any]]) -> dict[str, int]:
        """Actions for all robots from their observations, in one batch."""
        import torch

        agents = [a for a in self.agents if a in observations]
        if not agents:
            return {}
        batch = torch.as_tensor(np.stack([observations[a] for a in agents]))
        with torch.no_grad():
            logits = self.module.forward_inference({"obs": batch})["action_dist_inputs"]
        if self.deterministic:
            actions = logits.argmax(dim=-1)
        else:
            probs = torch.softmax(logits, dim=-1)
            actions = torch.multinomial(probs, 1, generator=self._gen).reshape(-1)
        return {a: int(x) for a, x in zip(agents, actions.tolist(), strict=True)}

    def act(self, views: Mapping[str, Any]) -> dict[str, int]:
        raise TypeError("RllibTeamPolicy acts on observations: call act_obs(observations)")


def load_team_policy(
    folder: str | Path, agents: Sequence[str], deterministic: bool = False
) -> TrainedTeamPolicy | RllibTeamPolicy:
    """The trained policy in ``folder``: an SB3 ``model.zip`` or an RLlib checkpoint."""
    if is_rllib_folder(folder):
        return RllibTeamPolicy.load(folder, agents, deterministic)
    return TrainedTeamPolicy.load(folder, agents, deterministic)
