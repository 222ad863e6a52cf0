"""PyTorch's intra-op threads while a stable-baselines3 run collects and while it learns.

Collecting a rollout steps the env and runs the policy's forward passes in turn: on a machine
with few cores, PyTorch's helper threads would take the cores the env (its merge worker, its
worker processes) runs on, so collection keeps ``torch_threads`` (1 in the shipped files).
The update runs while the env waits, so it may use more (``update_threads``). Both are fixed
numbers from the hyperparameter file, not the machine's core count: the thread count of a
reduction changes its rounding, so a run's bits follow the file, the same on any machine.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import torch
from stable_baselines3.common.callbacks import BaseCallback

from mrexplore.options import integer_argument

__all__ = ["PhaseThreads", "phase_threads"]


def phase_threads(cfg: Mapping[str, Any], owner: str = "train") -> tuple[int, int]:
    """``(torch_threads, update_threads)`` of a hyperparameter file's settings ``cfg``:
    ``torch_threads`` (default 1) while collecting, ``update_threads`` (default: the same)
    while learning; a ``ConfigError`` naming the key when either is not an integer >= 1.

    >>> phase_threads({"torch_threads": 1, "update_threads": 2})
    (1, 2)
    >>> phase_threads({})
    (1, 1)
    >>> phase_threads({"update_threads": 0})
    Traceback (most recent call last):
    ...
    mrexplore.errors.ConfigError: train: argument update_threads must be an integer >= 1, got 0
    """
    collect = integer_argument(owner, "torch_threads", cfg.get("torch_threads", 1), 1)
    update = integer_argument(owner, "update_threads", cfg.get("update_threads", collect), 1)
    return collect, update


class PhaseThreads(BaseCallback):
    """A callback that sets PyTorch's intra-op threads to ``collect`` while the algorithm
    collects (from the start of each rollout, evaluations in other callbacks included) and to
    ``update`` from the end of each rollout, where stable-baselines3's on- and off-policy
    algorithms call ``train()``. Add it to ``learn(callback=...)``; it saves nothing with the
    model."""

    def __init__(self, collect: int, update: int) -> None:
        super().__init__()
        self.collect, self.update = collect, update

    def _on_training_start(self) -> None:
        torch.set_num_threads(self.collect)

    def _on_rollout_start(self) -> None:
        torch.set_num_threads(self.collect)

    def _on_rollout_end(self) -> None:
        torch.set_num_threads(self.update)

    def _on_step(self) -> bool:
        return True

    def _on_training_end(self) -> None:
        torch.set_num_threads(self.collect)
