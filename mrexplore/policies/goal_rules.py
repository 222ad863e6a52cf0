"""A hand-written chooser for the goal-level env: keep the current target, else Burgard's pick.

:func:`keep_or_burgard` reads one robot's goal-level observation (the ``(K, F)`` candidate
features of :mod:`mrexplore.policies.candidates`, with or without the memory and gain columns
after them) and its mask, and returns a row. It is the teacher of ``mrexplore imitate``
(behaviour cloning before PPO): a learned chooser starts from it instead of from a
random network.

Why "keep": at a goal-level decision every robot chooses again, also one still on its way (the
decision ends for the whole team when one robot needs a new goal). Re-choosing Burgard's best
there (what :class:`~mrexplore.policies.explorers.CoordinatedFrontierPolicy` does on its own
2.5 s cycle) makes two robots trade targets at every decision (``docs/goal_policy.md``); keeping
a target until it is reached or gone does not.

>>> import numpy as np
>>> x = np.zeros((3, len(FEATURE_NAMES)), dtype=np.float32)
>>> x[:, COL["path_rel"]] = [0.2, 0.5, 1.0]
>>> x[0, COL["claim"]] = 0.9  # a teammate heads near the nearest frontier
>>> keep_or_burgard(x, np.array([1, 1, 1], dtype=np.int8))
1
>>> x[:, COL["size_m"]] = [0.05, 0.05, 0.6]  # 0.5 m, 0.5 m and 6 m of frontier
>>> keep_or_burgard(x, np.array([1, 1, 1], dtype=np.int8), size_weight=2.0)
2
>>> x[2, COL["is_current"]] = 1.0  # on its way to the farthest: keep it
>>> keep_or_burgard(x, np.array([1, 1, 1], dtype=np.int8))
2
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mrexplore.policies.candidates import FEATURE_NAMES

__all__ = ["COL", "KeepOrBurgardTeam", "keep_or_burgard"]

#: Column of each feature name in a goal-level observation row.
COL = {name: i for i, name in enumerate(FEATURE_NAMES)}


def keep_or_burgard(
    observation: NDArray[np.floating[Any]],
    mask: NDArray[np.integer[Any]],
    beta: float = 1.0,
    size_weight: float = 0.0,
) -> int:
    """The row to choose: the current target if it is a valid row, else Burgard's best.

    Burgard's best maximises ``1 - claim - beta * path_rel + size_weight * size_m`` over the
    valid rows (utility discounted by teammates' announced targets, minus the normalised path
    cost; beta 1.0 and size_weight 0 as
    :class:`~mrexplore.policies.explorers.CoordinatedFrontierPolicy`). ``size_m`` is the
    frontier's length in tens of metres, so ``size_weight`` 2 values a 1 m frontier like 20 %
    of the longest path: a long frontier opens more unknown space, and a team that stops at
    95 % coverage can leave short ones in corners for last or never. Only the ``K`` rows shown
    are considered. With no valid row, row 0 (the env's *wait*).

    Args:
        observation: ``(K, F')`` float features, the first ``len(FEATURE_NAMES)`` columns in
            :data:`~mrexplore.policies.candidates.FEATURE_NAMES` order.
        mask: ``(K,)`` 1 for a valid row.
        beta: weight of the path cost.
        size_weight: weight of the frontier length (``size_m``) in the utility.
    """
    valid = np.asarray(mask).astype(bool)
    if not valid.any():
        return 0
    x = np.asarray(observation)
    current = valid & (x[:, COL["is_current"]] > 0.5)
    if current.any():
        return int(np.flatnonzero(current)[0])
    score = 1.0 - x[:, COL["claim"]] - beta * x[:, COL["path_rel"]]
    if size_weight:
        score = score + size_weight * x[:, COL["size_m"]]
    return int(np.argmax(np.where(valid, score, -np.inf)))


class KeepOrBurgardTeam:
    """:func:`keep_or_burgard` for every robot: a team policy of the goal-level env.

    It reads observations (``uses_observations = True``), so ``run_episode`` and ``mrexplore
    evaluate``'s machinery drive it like a trained policy.
    """

    uses_observations = True

    def __init__(self, agents: Sequence[str], beta: float = 1.0, size_weight: float = 0.0) -> None:
        self.agents = list(agents)
        self.beta = float(beta)
        self.size_weight = float(size_weight)

    def reset(self, rng: np.random.Generator) -> None:
        """Nothing to reset (the rule keeps no state)."""

    def act_obs(self, observations: Mapping[str, Mapping[str, Any]]) -> dict[str, int]:
        """One row per robot from its ``{"observation", "action_mask"}``."""
        return {
            a: keep_or_burgard(o["observation"], o["action_mask"], self.beta, self.size_weight)
            for a, o in observations.items()
        }

    def act(self, views: Mapping[str, Any]) -> dict[str, int]:
        raise TypeError("KeepOrBurgardTeam acts on observations: call act_obs(observations)")
