"""What both trainers (SB3 in :mod:`~mrexplore.experiments.train`, RLlib in
:mod:`~mrexplore.experiments.train_rllib`) decide alike: the training worlds and the size of
the final evaluation.
"""

from __future__ import annotations

__all__ = ["final_eval_seed_count", "training_world"]


def training_world(world: str | None, default: str) -> str:
    """A generator name becomes ``random:<name>`` (a new world per episode); other specs stay."""
    if world is None:
        return default
    from mrexplore.world import GENERATORS

    if world in GENERATORS:
        return f"random:{world}"
    return world


def final_eval_seed_count(timesteps: int) -> int:
    """Held-out seeds of the final evaluation, scaled to the run: 2 for a smoke test, one per
    15,000 steps, at most 20 (a 2,000-step run used to spend 9 of its 10 minutes on 20 seeds)."""
    return max(2, min(20, int(timesteps) // 15_000))
