"""One episode's state: everything ``reset()`` creates and ``step()`` advances, in one object.

The env's parts (task, radio, fusion stage, observation builder) live across episodes and are
reset by ``reset()``; what belongs to one episode only lives here, so a new episode cannot
inherit anything from the last by accident.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mrexplore.environment.evaluation import TruthMonitor
from mrexplore.sim import Simulation
from mrexplore.world import World


@dataclass(eq=False)
class EpisodeState:
    """The state of one episode.

    Attributes:
        world: the episode's world (drawn anew per episode for ``"random:..."`` worlds).
        sim: robots, lidars and own maps.
        truth: evaluation against the truth (infos only); None with ``evaluate=False``.
        collisions: (n,) int64 bumps per robot since reset; ``collided`` (n,) bool this step's.
        transforms: per agent, its estimated transforms (teammate -> 3x3, the teammate's cells
            into the agent's), as of the last fusion update.
        coverage: the team coverage of ``coverage_mode`` after the last reset/step, in [0, 1].
        obs: the last observation of every agent.
        done: the episode has ended (terminated or truncated).
    """

    world: World
    sim: Simulation
    truth: TruthMonitor | None
    collisions: NDArray[np.int64]
    collided: NDArray[np.bool_]
    transforms: dict[str, dict[str, NDArray[np.float64]]] = field(default_factory=dict)
    coverage: float = 0.0
    obs: dict[str, NDArray[Any]] = field(default_factory=dict)
    done: bool = False
