"""Point-to-point navigation through partly unknown space (the paper's navigation task)."""

from __future__ import annotations

import math
import time

import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import ConfigError, GridError
from mrexplore.grid import OCCUPIED, occupied_mask
from mrexplore.options import integer, non_negative, positive, validate
from mrexplore.policies.base import (
    DEFAULT_FORWARD_STEP_M,
    DEFAULT_TURN_STEP_RAD,
    Policy,
    densify_path,
    follow_path,
    nearest_path_index,
)
from mrexplore.policies.planning import PlanningGrid, planning_rounds
from mrexplore.robot import Action
from mrexplore.types import RobotView

__all__ = ["GoalPolicy"]


class GoalPolicy(Policy):
    """Drive to ``view.goal_cell``, treating unknown space as traversable (optimistic planning).

    Known occupied cells (inflated by the robot radius) are obstacles; unknown and free cells are
    not, so the first plan is a straight line through the unknown and later plans bend around the
    walls the lidar reveals - the way a merged map from a teammate shortens the trip. If the goal
    is enclosed by known walls, the robot goes to the reachable planning cell closest to it.

    Re-plans: every ``replan_every`` steps; when a known obstacle appears on a path cell; when the
    robot is stuck (no progress along the path for ``stuck_steps`` steps or ``bump_steps`` FORWARDs
    without motion). Returns STAY once within ``goal_tolerance_m`` of the goal.

    Args:
        goal_tolerance_m: arrival radius, metres.
        plan_factor: fine cells per planning cell.
        margin_m: room around the known area and the goal a path may use, metres.
        replan_every, stuck_steps, bump_steps, lookahead_m, turn_step_rad, forward_step_m: as in
            :class:`~mrexplore.policies.explorers.FrontierExplorer`.
    """

    def __init__(
        self,
        goal_tolerance_m: float = 0.25,
        plan_factor: int = 2,
        margin_m: float = 2.0,
        replan_every: int = 8,
        stuck_steps: int = 12,
        bump_steps: int = 3,
        lookahead_m: float = 0.3,
        turn_step_rad: float = DEFAULT_TURN_STEP_RAD,
        forward_step_m: float = DEFAULT_FORWARD_STEP_M,
    ) -> None:
        for name, value, check in (
            ("goal_tolerance_m", goal_tolerance_m, positive),
            ("plan_factor", plan_factor, integer(1)),
            ("margin_m", margin_m, non_negative),
            ("replan_every", replan_every, integer(1)),
        ):
            validate("GoalPolicy", name, value, check)
        self.goal_tolerance_m = float(goal_tolerance_m)
        self.plan_factor = int(plan_factor)
        self.margin_m = float(margin_m)
        self.replan_every = int(replan_every)
        self.stuck_steps = int(stuck_steps)
        self.bump_steps = int(bump_steps)
        self.lookahead_m = float(lookahead_m)
        self.turn_step_rad = float(turn_step_rad)
        self.forward_step_m = float(forward_step_m)
        self.reset(np.random.default_rng(0))

    def reset(self, rng: np.random.Generator) -> None:
        self.rng = rng
        self.path: NDArray[np.float64] | None = None
        self._since_plan = 0
        self._best_idx = 0
        self._no_progress = 0
        self._bumps = 0
        self._last_pose: tuple[float, float, float] | None = None
        self._last_action = int(Action.STAY)
        # Cells the robot bumped into (own map cells): what its bumper learned. The lidar can miss
        # a thin corner that the body hits; without this memory the same plan is made again and
        # the robot pushes against the same spot forever (seen: 3 of 20 navigation episodes).
        self.bumped: list[tuple[float, float]] = []
        self.n_plans = 0
        self.n_acts = 0
        self.plan_time_s = 0.0
        self.act_time_s = 0.0

    def act(self, view: RobotView) -> int:
        t0 = time.perf_counter()
        if view.goal_cell is None:
            raise ConfigError(
                f"GoalPolicy needs a navigation goal, but {view.agent}'s view has goal_cell=None"
            )
        m = view.map
        if not isinstance(m, np.ndarray) or m.ndim != 2 or m.dtype != np.int8:
            raise GridError(
                f"view.map must be a 2-D int8 occupancy grid, got {getattr(m, 'dtype', type(m))}"
            )
        res = float(view.resolution_m)
        pose = (float(view.pose_cell[0]), float(view.pose_cell[1]), float(view.pose_cell[2]))
        goal = (float(view.goal_cell[0]), float(view.goal_cell[1]))
        action = int(Action.STAY)
        if math.hypot(goal[0] - pose[0], goal[1] - pose[1]) > self.goal_tolerance_m / res:
            stuck = self._update_progress(pose, res, float(view.robot_radius_m))
            if (
                stuck
                or self.path is None
                or self._since_plan >= self.replan_every
                or self._blocked(m)
            ):
                self._plan(view, pose, goal)
            if self.path is not None:
                action = follow_path(
                    self.path,
                    pose,
                    turn_step_rad=self.turn_step_rad,
                    lookahead_cells=self.lookahead_m / res,
                    arrive_cells=min(self.goal_tolerance_m / res, 2.0),
                )
        self._since_plan += 1
        self._last_pose = pose
        self._last_action = action
        self.n_acts += 1
        self.act_time_s += time.perf_counter() - t0
        return action

    def _update_progress(
        self, pose: tuple[float, float, float], res: float, radius_m: float
    ) -> bool:
        if self._last_pose is not None and self._last_action == Action.FORWARD:
            moved = math.hypot(pose[0] - self._last_pose[0], pose[1] - self._last_pose[1])
            self._bumps = self._bumps + 1 if moved < 0.3 * self.forward_step_m / res else 0
            if self._bumps == self.bump_steps:
                ahead = radius_m / res + 1.5
                self.bumped.append(
                    (pose[0] + ahead * math.cos(pose[2]), pose[1] + ahead * math.sin(pose[2]))
                )
        if self.path is None:
            return False
        idx = nearest_path_index(self.path, pose)
        if idx > self._best_idx:
            self._best_idx, self._no_progress = idx, 0
        else:
            self._no_progress += 1
        return self._no_progress >= self.stuck_steps or self._bumps >= self.bump_steps

    def _blocked(self, m: NDArray[np.int8]) -> bool:
        """Whether a path point now lies on a known obstacle (the lidar saw a wall there)."""
        if self.path is None:
            return False
        c = np.clip(np.rint(self.path[:, 0]).astype(np.int64), 0, m.shape[1] - 1)
        r = np.clip(np.rint(self.path[:, 1]).astype(np.int64), 0, m.shape[0] - 1)
        return bool(occupied_mask(m[r, c]).any())

    def _plan(
        self, view: RobotView, pose: tuple[float, float, float], goal: tuple[float, float]
    ) -> None:
        t0 = time.perf_counter()
        self.n_plans += 1
        self._since_plan = 0
        self._best_idx = 0
        self._no_progress = 0
        self._bumps = 0
        m = view.map
        if self.bumped:
            m = m.copy()
            for c, r in self.bumped:
                c0, r0 = round(c), round(r)
                m[max(r0 - 1, 0) : r0 + 2, max(c0 - 1, 0) : c0 + 2] = OCCUPIED
        self.path = None
        # The frontier explorer's rounds: on tb3_office a robot put back at its start found its
        # own cell enclosed on coarse cells with the clearance, and stood there for 480 s.
        best: tuple[float, int, PlanningGrid, tuple[int, int], bool] | None = None
        for k, (factor, clearance) in enumerate(planning_rounds(self.plan_factor)):
            grid = PlanningGrid.build(
                m,
                float(view.resolution_m),
                float(view.robot_radius_m),
                pose[:2],
                factor=factor,
                unknown_is_free=True,
                extra_cells=np.array([goal]),
                margin_m=self.margin_m,
                clearance_cells=clearance,
            )
            if grid.start is None:
                continue
            g = grid.to_plan(np.array([goal]))[0]
            h, w = grid.shape
            if 0 <= g[0] < w and 0 <= g[1] < h and np.isfinite(grid.field[g[1], g[0]]):
                best = (0.0, k, grid, (int(g[0]), int(g[1])), True)
                break
            # Goal enclosed or blocked: the reachable cell nearest to it (ties: shorter path);
            # a later round is used only when its nearest cell is nearer (in fine cells).
            rows, cols = np.nonzero(np.isfinite(grid.field))
            d2 = (cols - g[0]) ** 2 + (rows - g[1]) ** 2
            j = int(np.lexsort((grid.field[rows, cols], d2))[0])
            gap = float(np.sqrt(d2[j])) * grid.factor
            if best is None or gap < best[0] - 1e-9:
                best = (gap, k, grid, (int(cols[j]), int(rows[j])), False)
        if best is not None:
            _, _, grid, target, at_goal = best
            path = grid.path_to(target)
            if path is not None:
                # End exactly at the goal when its cell is the target, so arrival is measured there.
                if at_goal:
                    path = np.vstack([path, np.array([goal])])
                self.path = densify_path(path)
        self.plan_time_s += time.perf_counter() - t0
