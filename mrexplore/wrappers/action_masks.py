"""Action masks for sb3-contrib's ``MaskablePPO`` from a ``VecEnv`` whose Dict observations
carry them (the goal-level env's ``action_mask``; PettingZoo's convention).

``MaskablePPO`` asks the ``VecEnv`` for ``env_method("action_masks")`` (one mask per slot). Our
SB3 adapter calls a method once per *env copy* (all robots of a copy share it), so this wrapper
answers instead, from the masks of the last observation it passed on: slot ``i`` gets
``obs["action_mask"][i]`` as booleans.

>>> import mrexplore
>>> from mrexplore.wrappers.sb3_vec import make_vec_env
>>> venv = VecActionMasks(make_vec_env(n_copies=1, seed=0, world="small_office",
...                                    action_mode="goal", max_cycles=20))
>>> obs = venv.reset()
>>> masks = venv.env_method("action_masks")
>>> len(masks), masks[0].dtype.name, bool(masks[0].any())
(2, 'bool', True)
>>> venv.close()
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray
from stable_baselines3.common.vec_env import VecEnv, VecEnvWrapper
from stable_baselines3.common.vec_env.base_vec_env import VecEnvIndices, VecEnvObs, VecEnvStepReturn

from mrexplore.errors import ConfigError

__all__ = ["MASK_KEY", "VecActionMasks"]

#: The observation key that holds the masks.
MASK_KEY = "action_mask"
_METHOD = "action_masks"


class VecActionMasks(VecEnvWrapper):
    """Serve ``action_masks`` per slot from the observations' ``action_mask`` (see the module).

    Raises:
        ConfigError: the observation space is not a Dict with an ``action_mask`` key.
    """

    def __init__(self, venv: VecEnv) -> None:
        spaces = getattr(venv.observation_space, "spaces", None)
        if not isinstance(spaces, dict) or MASK_KEY not in spaces:
            raise ConfigError(
                f"VecActionMasks needs Dict observations with an '{MASK_KEY}' key, got "
                f"{venv.observation_space}"
            )
        super().__init__(venv)
        self._masks: NDArray[np.bool_] | None = None

    def _keep(self, obs: VecEnvObs) -> None:
        assert isinstance(obs, dict)
        self._masks = np.asarray(obs[MASK_KEY]).astype(bool)

    def reset(self) -> VecEnvObs:
        obs = self.venv.reset()
        self._keep(obs)
        return obs

    def step_wait(self) -> VecEnvStepReturn:
        obs, rewards, dones, infos = self.venv.step_wait()
        self._keep(obs)
        return obs, rewards, dones, infos

    def action_masks(self) -> NDArray[np.bool_]:
        """``(num_envs, K)`` bool: the valid actions of every slot now."""
        if self._masks is None:
            raise RuntimeError("action_masks() before reset()")
        return self._masks.copy()

    def has_attr(self, attr_name: str) -> bool:
        return attr_name == _METHOD or bool(self.venv.has_attr(attr_name))

    def get_attr(self, attr_name: str, indices: VecEnvIndices = None) -> list[Any]:
        if attr_name == _METHOD:
            return [self.action_masks for _ in self._indices(indices)]
        return list(self.venv.get_attr(attr_name, indices))

    def env_method(
        self,
        method_name: str,
        *method_args: Any,
        indices: VecEnvIndices = None,
        **method_kwargs: Any,
    ) -> list[Any]:
        if method_name == _METHOD:
            masks = self.action_masks()
            return [masks[i] for i in self._indices(indices)]
        return list(
            self.venv.env_method(method_name, *method_args, indices=indices, **method_kwargs)
        )

    def _indices(self, indices: VecEnvIndices) -> Sequence[int]:
        if indices is None:
            return range(self.num_envs)
        if isinstance(indices, (int, np.integer)):
            return [int(indices)]
        return [int(i) for i in indices]
