"""A random baseline."""

from __future__ import annotations

import numpy as np

from mrexplore.options import number, optional, validate
from mrexplore.policies.base import Policy
from mrexplore.robot import Action
from mrexplore.types import RobotView

__all__ = ["RandomPolicy"]


class RandomPolicy(Policy):
    """Random actions drawn from the generator given to :meth:`reset`.

    Args:
        forward_prob: ``None`` (default): uniform over all actions (FORWARD, TURN_LEFT,
            TURN_RIGHT, STAY), the plain baseline. A number in [0, 1]: FORWARD with that
            probability, otherwise TURN_LEFT or TURN_RIGHT with equal chance (never STAY) - a
            random walk that actually travels (0.6 to 0.8 explore far better than uniform).

    The view is ignored, except that its presence is required by the protocol.
    """

    def __init__(self, forward_prob: float | None = None) -> None:
        validate("RandomPolicy", "forward_prob", forward_prob, optional(number(0.0, 1.0)))
        self.forward_prob = forward_prob
        self.rng = np.random.default_rng(0)
        actions = list(Action)
        if forward_prob is None:
            self._actions = np.array([int(a) for a in actions])
            self._probs = np.full(len(actions), 1.0 / len(actions))
        else:
            self._actions = np.array(
                [int(Action.FORWARD), int(Action.TURN_LEFT), int(Action.TURN_RIGHT)]
            )
            turn = (1.0 - forward_prob) / 2.0
            self._probs = np.array([forward_prob, turn, turn])

    def reset(self, rng: np.random.Generator) -> None:
        self.rng = rng

    def act(self, view: RobotView) -> int:
        return int(self.rng.choice(self._actions, p=self._probs))
