"""A frontier policy drives the real simulator on a small closed world to (near) full coverage.

The RobotView is built by hand from what the simulator gives a robot (its own map and pose
estimate), exactly what the env's ``robot_view`` does before any merge.
"""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from mrexplore.policies import CoordinatedFrontierPolicy, CostFrontierPolicy, NearestFrontierPolicy
from mrexplore.policies.explorers import FrontierExplorer
from mrexplore.policies.frontier_cells import find_frontiers
from mrexplore.policies.planning import PlanningGrid
from mrexplore.types import RobotView

sim_mod = pytest.importorskip(
    "mrexplore.sim", reason="mrexplore.sim (the simulator) is not available"
)
registry = pytest.importorskip(
    "mrexplore.world.registry", reason="the world registry is not available"
)

STEP_BUDGET = 1200  # 300 simulated seconds; small_office takes ~400 steps (100 s)


def _view(sim: Any, i: int) -> RobotView:
    return RobotView(
        agent=f"robot_{i}",
        map=sim.maps[i].to_int8(),
        resolution_m=sim.resolution_m,
        pose_cell=sim.pose_cell(i),
        robot_radius_m=sim.config.robot.radius_m,
        time_s=sim.time_s,
    )


def _reachable_frontiers(view: RobotView, pol: FrontierExplorer) -> int:
    """Frontiers the policy could still drive to (independent re-check after it says done)."""
    grid = PlanningGrid.build(view.map, view.resolution_m, view.robot_radius_m, view.pose_cell[:2])
    bl = np.asarray(pol.blacklist).reshape(-1, 2)
    n = 0
    for f in find_frontiers(view.map, pol.min_frontier_cells):
        d, _ = grid.approach(f.cells, pol.approach_cells)
        if bl.size:
            near = ((f.cells[:, None, :] - bl[None]) ** 2).sum(axis=2).min(axis=1)
            d = np.where(near <= (pol.blacklist_radius_m / view.resolution_m) ** 2, np.inf, d)
        n += int(np.isfinite(d).any())
    return n


@pytest.mark.parametrize(
    ("policy_cls", "seed"),
    [
        (NearestFrontierPolicy, 0),  # Yamauchi's nearest frontier
        (NearestFrontierPolicy, 3),  # another start pose
        (CostFrontierPolicy, 1),  # explore_lite's cost
    ],
)
def test_single_robot_covers_small_office(policy_cls: type[FrontierExplorer], seed: int) -> None:
    world = registry.load_world("small_office")
    sim = sim_mod.Simulation(world, 1)
    rng = np.random.default_rng(seed)
    sim.reset(rng)
    pol = policy_cls()
    pol.reset(np.random.default_rng(seed))
    stay_run = 0
    for _ in range(STEP_BUDGET):
        view = _view(sim, 0)
        action = pol.act(view)
        if pol.done:
            break
        # Never idle while not done: a policy that STAYs with frontiers left has stalled.
        stay_run = stay_run + 1 if action == 3 else 0
        assert stay_run < 3, "the policy stalled with frontiers left"
        sim.step(np.array([action]), rng)
    assert pol.done, f"exploration unfinished after {STEP_BUDGET} steps ({sim.coverage():.1%})"
    assert sim.coverage() >= 0.95
    assert _reachable_frontiers(_view(sim, 0), pol) == 0


def test_two_robots_unmerged_team_covers_small_office() -> None:
    """The coordinated team before any merge: each robot explores its own map; together they
    cover the world (coverage is the team's)."""
    world = registry.load_world("small_office")
    sim = sim_mod.Simulation(world, 2)
    rng = np.random.default_rng(7)
    sim.reset(rng)
    team = CoordinatedFrontierPolicy(["robot_0", "robot_1"])
    team.reset(np.random.default_rng(7))
    for _ in range(STEP_BUDGET):
        views = {f"robot_{i}": _view(sim, i) for i in range(2)}
        actions = team.act(views)
        if team.done:
            break
        sim.step(np.array([actions["robot_0"], actions["robot_1"]]), rng)
    assert team.done
    assert sim.coverage() >= 0.95
