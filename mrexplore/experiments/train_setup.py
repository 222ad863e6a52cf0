"""What both trainers (SB3 in :mod:`~mrexplore.experiments.train`, RLlib in
:mod:`~mrexplore.experiments.train_rllib`) decide alike: the training worlds and the size of
the final evaluation, and the steps a stable-baselines3 run really takes.
"""

from __future__ import annotations

from typing import Any

from mrexplore.errors import ConfigError

__all__ = ["final_eval_seed_count", "rollout_steps", "rounded_timesteps", "training_world"]


def training_world(world: str | None, default: str) -> str:
    """The world spec a run trains on: ``world`` as every command reads it, else ``default``.

    A name is the shipped world (the same map every episode), as in ``task-time``, ``demo``
    and ``evaluate``; a fresh world per episode is spelled ``random:<generator>``. The spec is
    checked here (an unknown name fails before any work), and a name that is also a
    generator's gets a one-line notice saying which of the two it means.

    Raises:
        ConfigError: ``world`` names no shipped world, map file, generator or family.
    """
    if world is None:
        return default
    import numpy as np

    from mrexplore.errors import MrexploreError
    from mrexplore.world import GENERATORS, load_world

    try:
        load_world(world, rng=np.random.default_rng(0))
    except MrexploreError as exc:
        raise ConfigError(f"train --world: {exc}") from exc
    if world in GENERATORS:
        print(
            f"train: --world {world} is the shipped world {world}, the same map every "
            f"episode; a fresh {world} per episode is --world random:{world}"
        )
    return world


def final_eval_seed_count(timesteps: int) -> int:
    """Held-out seeds of the final evaluation, scaled to the run: 2 for a smoke test, one per
    15,000 steps, at most 20 (a 2,000-step run used to spend 9 of its 10 minutes on 20 seeds)."""
    return max(2, min(20, int(timesteps) // 15_000))


def rollout_steps(model: Any) -> tuple[int, str]:
    """The env steps a stable-baselines3 model collects between two looks at its budget, and
    what makes them up (for messages): ``n_steps x slots`` for on-policy algorithms (PPO, A2C,
    and sb3-contrib's), ``train_freq x slots`` for off-policy ones counting steps (DQN), the
    slots alone otherwise. ``learn`` stops only at the end of such a chunk."""
    from stable_baselines3.common.off_policy_algorithm import OffPolicyAlgorithm
    from stable_baselines3.common.on_policy_algorithm import OnPolicyAlgorithm
    from stable_baselines3.common.type_aliases import TrainFreq, TrainFrequencyUnit

    slots = int(model.n_envs)
    if isinstance(model, OnPolicyAlgorithm):
        n = int(model.n_steps)
        return n * slots, f"n_steps {n} x {slots} env slots"
    freq = model.train_freq if isinstance(model, OffPolicyAlgorithm) else None
    if isinstance(freq, TrainFreq) and freq.unit == TrainFrequencyUnit.STEP:  # else: episodes
        return freq.frequency * slots, f"train_freq {freq.frequency} x {slots} env slots"
    return slots, f"{slots} env slots"


def rounded_timesteps(asked: int, per_rollout: int) -> int:
    """The steps a run asked for ``asked`` takes: whole rollouts of ``per_rollout``.

    >>> rounded_timesteps(3072, 4096), rounded_timesteps(8192, 4096), rounded_timesteps(1, 64)
    (4096, 8192, 64)
    """
    return -(-int(asked) // int(per_rollout)) * int(per_rollout)
