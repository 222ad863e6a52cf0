"""The team's task: explore (cover the world) or navigate (``robot_0`` to a goal).

A :class:`Task` owns what differs between the two: the navigation goal (placed from the truth,
given to ``robot_0`` in its own map frame after a warm-up), when the task's clock starts, when
it is done, and the reward. The env calls it at fixed points of ``reset`` and ``step``; the
truth it reads (true poses, reachable cells) decides the task, it never reaches a robot except
as the goal, which is the task's definition.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mrexplore.environment.config import EnvConfig
from mrexplore.grid import apply_transform, invert_transform
from mrexplore.sim import Simulation

#: Slack for comparing simulated times that are sums of ``dt_s``: 600 s / 0.25 s ends at step
#: 2400, not 2401.
TIME_EPS_S = 1e-9


@dataclass(frozen=True)
class Goal:
    """A navigation goal: ``world_xy`` (metres, the truth: termination only) and ``cell``, the
    same point in ``robot_0``'s own map cells (col, row): what the robot is given."""

    world_xy: NDArray[np.float64]
    cell: tuple[float, float]


class Task:
    """Explore: done when the coverage reaches ``target_coverage``; the clock starts at reset.

    The reward and the time limit are the same for both tasks (:meth:`reward`,
    :meth:`truncated`). To define another task, subclass it and pass an instance as the env's
    ``task`` option (``parallel_env(task=MyTask())``); the env binds it to its options.
    """

    name = "explore"

    def __init__(self, config: EnvConfig | None = None) -> None:
        if config is not None:
            self.config = config
        self.goal: Goal | None = None

    def bind(self, config: EnvConfig) -> Task:
        """Use the env's options ``config`` (the env calls it once, at construction)."""
        self.config = config
        return self

    def reset(
        self,
        sim: Simulation,
        goal_rng: np.random.Generator,
        start_rng: np.random.Generator,
        starts: NDArray[np.float64] | None,
    ) -> None:
        """A new episode on ``sim`` (already reset). ``start_rng`` is a copy of the stream the
        starts were drawn from (before the draw); ``starts`` the fixed starts, if any."""
        self.goal = None

    def given(self, sim: Simulation) -> bool:
        """Whether ``robot_0`` has been given its navigation goal (never when exploring)."""
        return False

    def reached(self, sim: Simulation) -> bool:
        """Whether ``robot_0`` is at its goal (never when exploring)."""
        return False

    def goal_cell(self, i: int, sim: Simulation) -> tuple[float, float] | None:
        """The goal robot ``i`` is given now, in its own map cells, or None."""
        return None

    def time_s(self, sim: Simulation) -> float:
        """Seconds of the task so far (the ``task_time_s`` info)."""
        return float(sim.time_s)

    def after_move(self, sim: Simulation, given_before: bool) -> None:
        """Called after the robots moved (before sensing is read by anyone else)."""

    def terminated(self, sim: Simulation, coverage: float) -> bool:
        """Done: the team's ``coverage`` (``coverage_mode``) reached ``target_coverage``."""
        return coverage >= self.config.target_coverage

    def truncated(self, sim: Simulation) -> bool:
        """The time limit: ``max_cycles`` steps or ``max_time_s`` simulated seconds."""
        cfg = self.config
        if cfg.max_cycles is not None and sim.steps >= cfg.max_cycles:
            return True
        return bool(sim.time_s >= cfg.max_time_s - TIME_EPS_S)

    def reward(self, gain: float, sim: Simulation, resolution_m: float) -> float:
        """The team reward of one step: ``"time"``: ``-dt_s`` (the return is minus the task
        time); ``"coverage"``: ``coverage_reward_per_m2`` per newly covered m^2 (``gain`` is the
        step's coverage gain, a share of the reachable cells) minus the time penalty."""
        cfg = self.config
        if cfg.reward_mode == "time":
            return -cfg.dt_s
        area_m2 = gain * sim.reachable_cells * resolution_m**2
        return float(cfg.coverage_reward_per_m2 * area_m2 - cfg.time_penalty_per_s * cfg.dt_s)


class NavigateTask(Task):
    """Navigate: ``robot_0`` must come within ``goal_radius_m`` of a goal. The team explores for
    ``nav_warmup_s`` first; the goal and the clock start then (``robot_0`` is put back at its
    start pose if ``nav_return_to_start``). The goal is drawn the same for every team size."""

    name = "navigate"

    def reset(
        self,
        sim: Simulation,
        goal_rng: np.random.Generator,
        start_rng: np.random.Generator,
        starts: NDArray[np.float64] | None,
    ) -> None:
        mate = None
        if self.config.nav_goal == "teammate":
            # where robot_1 starts, also for a 1-robot team (its draw from the same stream)
            if starts is not None:
                mate = starts[1, :2].copy() if starts.shape[0] > 1 else None
            else:
                mate = sim.sample_starts(start_rng, 2)[1, :2]
        self.goal = self._place_goal(sim, goal_rng, mate)

    def given(self, sim: Simulation) -> bool:
        return bool(sim.time_s >= self.config.nav_warmup_s - TIME_EPS_S)

    def reached(self, sim: Simulation) -> bool:
        assert self.goal is not None, "reset() places the goal"
        d = float(np.hypot(*(sim.true_poses[0, :2] - self.goal.world_xy)))
        return d <= self.config.goal_radius_m

    def goal_cell(self, i: int, sim: Simulation) -> tuple[float, float] | None:
        if i != 0 or self.goal is None or not self.given(sim):
            return None
        return self.goal.cell

    def time_s(self, sim: Simulation) -> float:
        return max(0.0, float(sim.time_s) - self.config.nav_warmup_s)

    def after_move(self, sim: Simulation, given_before: bool) -> None:
        cfg = self.config
        warm_up_ended = cfg.nav_warmup_s > 0 and not given_before and self.given(sim)
        if cfg.nav_return_to_start and warm_up_ended:
            # The warm-up is over: robot_0 navigates from its start with the map it has.
            sim.place(0, sim.start_poses[0])

    def terminated(self, sim: Simulation, coverage: float) -> bool:
        return self.given(sim) and self.reached(sim)

    def _place_goal(
        self,
        sim: Simulation,
        rng: np.random.Generator,
        mate_start: NDArray[np.float64] | None,
    ) -> Goal:
        """A reachable free cell at least ``goal_min_distance_m`` from ``robot_0``'s start (and,
        given ``mate_start``, within ``nav_teammate_radius_m`` of it, else the far cells nearest
        to it)."""
        cfg, world = self.config, sim.world
        rows, cols = np.nonzero(sim.reachable_cspace)
        start = world.cell_of(sim.true_poses[0, :2])[0]
        d_m = np.hypot(cols - start[0], rows - start[1]) * world.resolution_m
        far = np.nonzero(d_m >= cfg.goal_min_distance_m)[0]
        pool = far if len(far) else np.arange(len(rows))
        if mate_start is not None:
            mate = world.cell_of(mate_start[None])[0]
            d_mate = np.hypot(cols[pool] - mate[0], rows[pool] - mate[1]) * world.resolution_m
            near = d_mate <= cfg.nav_teammate_radius_m
            # none that near: the far cells nearest to the teammate's start (within a cell)
            pool = pool[near] if near.any() else pool[d_mate <= d_mate.min() + world.resolution_m]
        k = int(pool[int(rng.integers(len(pool)))])
        goal_world_cell = np.array([cols[k], rows[k]], dtype=np.float64)
        g = apply_transform(invert_transform(sim.world_from_map(0)), goal_world_cell[None])[0]
        return Goal(world.xy_of(goal_world_cell[None])[0], (float(g[0]), float(g[1])))


def make_task(config: EnvConfig) -> Task:
    """The task ``config.task`` names, or the :class:`Task` object it holds (bound to
    ``config``)."""
    if isinstance(config.task, Task):
        return config.task.bind(config)
    return NavigateTask(config) if config.task == "navigate" else Task(config)
