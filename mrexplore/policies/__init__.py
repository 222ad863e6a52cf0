"""Exploration and navigation policies that read only a robot's view (``RobotView``).

Protocol (see :mod:`mrexplore.policies.base`): a :class:`Policy` has ``reset(rng)`` and
``act(view) -> int`` (an :class:`mrexplore.robot.Action`); a :class:`TeamPolicy` has ``reset(rng)``
and ``act(views: Mapping[agent, RobotView]) -> {agent: action}``. Views come from
``env.unwrapped.robot_view(agent)``.

>>> from mrexplore.policies import make_team_policy
>>> team = make_team_policy("nearest-frontier", ["robot_0", "robot_1"])
>>> sorted(POLICIES)  # doctest: +NORMALIZE_WHITESPACE
['coordinated-frontier', 'coordinated-frontier-size', 'coordinated-frontier-verify',
 'cost-frontier', 'goal', 'nearest-frontier', 'random']

Names in :data:`POLICIES` map to a factory ``(agents) -> TeamPolicy``; per-robot policies are
lifted with :class:`IndependentTeam`. ``coordinated-frontier-size`` is Burgard's coordination with
a frontier-length term in the utility (``size_weight`` :data:`SIZE_WEIGHT`), the planner
counterpart of the shipped goal chooser's rule (``docs/goal_policy.md``).
``coordinated-frontier-verify`` adds, before a merge, utility for frontiers where the merger's
candidate transforms put a teammate's map (``verify_weight`` :data:`VERIFY_WEIGHT`: active
disambiguation, ``docs/merging_history.md``, "Going where the merger's candidates can be told
apart").
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

from mrexplore.errors import ConfigError
from mrexplore.policies.base import IndependentTeam, Policy, TeamPolicy, follow_path
from mrexplore.policies.explorers import (
    CoordinatedFrontierPolicy,
    CostFrontierPolicy,
    FrontierExplorer,
    NearestFrontierPolicy,
)
from mrexplore.policies.frontier_cells import Frontier, find_frontiers, frontier_mask
from mrexplore.policies.goal import GoalPolicy
from mrexplore.policies.planning import PlanningGrid, distance_field, inflate_obstacles
from mrexplore.policies.random_policy import RandomPolicy

__all__ = [
    "POLICIES",
    "SIZE_WEIGHT",
    "VERIFY_WEIGHT",
    "CoordinatedFrontierPolicy",
    "CostFrontierPolicy",
    "Frontier",
    "FrontierExplorer",
    "GoalPolicy",
    "IndependentTeam",
    "NearestFrontierPolicy",
    "PlanningGrid",
    "Policy",
    "RandomPolicy",
    "TeamPolicy",
    "distance_field",
    "find_frontiers",
    "follow_path",
    "frontier_mask",
    "inflate_obstacles",
    "make_team_policy",
]

#: The frontier-length weight of ``coordinated-frontier-size`` (utility per 10 m of frontier).
SIZE_WEIGHT = 2.0

#: The verification weight of ``coordinated-frontier-verify`` (utility of a frontier whose
#: surroundings a not-yet-merged teammate mapped under a merge candidate).
VERIFY_WEIGHT = 0.5

#: Policy name -> factory ``(agents) -> TeamPolicy``.
POLICIES: dict[str, Callable[[Sequence[str]], TeamPolicy]] = {
    "random": lambda agents: IndependentTeam(RandomPolicy, agents),
    "nearest-frontier": lambda agents: IndependentTeam(NearestFrontierPolicy, agents),
    "cost-frontier": lambda agents: IndependentTeam(CostFrontierPolicy, agents),
    "coordinated-frontier": lambda agents: CoordinatedFrontierPolicy(agents),
    "coordinated-frontier-size": lambda agents: CoordinatedFrontierPolicy(
        agents, size_weight=SIZE_WEIGHT
    ),
    "coordinated-frontier-verify": lambda agents: CoordinatedFrontierPolicy(
        agents, verify_weight=VERIFY_WEIGHT
    ),
    "goal": lambda agents: IndependentTeam(GoalPolicy, agents),
}


def make_team_policy(name: str, agents: Sequence[str]) -> TeamPolicy:
    """The team policy registered as ``name`` for ``agents`` (e.g. ``["robot_0", "robot_1"]``).

    Raises:
        ConfigError: ``name`` is not in :data:`POLICIES` (the message lists the names).
    """
    try:
        factory = POLICIES[name]
    except KeyError:
        raise ConfigError(f"unknown policy '{name}'; choose one of {sorted(POLICIES)}") from None
    return factory(list(agents))
