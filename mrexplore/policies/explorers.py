"""The frontier family: nearest frontier, explore_lite's cost, and Burgard et al.'s coordination.

All three share one per-robot machine, :class:`FrontierExplorer`, and differ only in how they
*choose* among the reachable frontiers:

* :class:`NearestFrontierPolicy` - the smallest path length (Yamauchi 1997).
* :class:`CostFrontierPolicy` - explore_lite's ``cost = distance_weight * distance_m -
  size_weight * size_m`` (defaults 3.0 and 1.0). Units: explore_lite multiplies both its distance
  (cells) and its frontier size (cells) by the map resolution, so both are metres: here
  ``distance_m`` is the *path* length in metres to the frontier (explore_lite uses the straight
  distance to its nearest cell) and ``size_m`` the frontier length, number of cells x resolution.
* :class:`CoordinatedFrontierPolicy` - a :class:`~mrexplore.policies.base.TeamPolicy`:
  Burgard, Moors, Stachniss, Schneider, "Coordinated multi-robot exploration" (IEEE T-RO 2005).
  Robots choose in turn; each maximises ``U_t - beta * V_t`` with ``V_t`` its path cost to
  frontier ``t`` normalised by its largest reachable cost, and ``U_t`` a utility that starts at 1
  and drops by ``max(0, 1 - d / sensor_range)`` for every target ``t'`` teammates chose, ``d`` the
  distance between ``t`` and ``t'`` (what a teammate at ``t'`` will see, this robot need not
  visit). Teammates' targets come from *their* frames and are moved into this robot's frame by
  the estimated transforms of its :class:`~mrexplore.types.RobotView`; before a merge
  a robot has no teammate transforms and so plans alone on its own map.

The machine (per robot, every step):

1. Re-plan when: there is no plan; the plan is ``replan_every`` steps old; the robot reached the
   end of its path; the target cell stopped being a frontier; or the robot is *stuck* (no progress
   along the path for ``stuck_steps`` steps, or ``bump_steps`` FORWARDs in a row that did not move
   it - a collision).
2. Plan: frontiers of the map (:func:`~mrexplore.policies.frontier_cells.find_frontiers`), a
   planning grid with a distance field from the robot
   (:class:`~mrexplore.policies.planning.PlanningGrid`; 2x2 map cells by default), each
   frontier's path length to the nearest reachable planning cell within ``approach_cells``
   planning cells of any of its cells; choose among the reachable, non-blacklisted frontiers;
   path by descending the field. With ``backtrack_trail`` the cells the robot's centre has been
   on are always traversable. When no frontier is reachable, the round is repeated on the map's
   own cells (``fine_fallback``: coarse cells close gaps the robot fits through), and then with
   ``tight_clearance_cells`` instead of ``clearance_cells``: the simulator's own collision rule,
   so a gap the robot's body fits through is never given up for a safety margin.
3. Blacklist (never retried): a target the robot got stuck on twice; a frontier that is still
   there when the robot stands at its approach cell (it cannot be seen from where one can stand).
   Frontiers unreachable on the planning grid are simply never chosen while unreachable, so
   nothing is retried in a loop; when no reachable frontier is left, the policy reports ``done``
   and returns STAY (and looks again every ``replan_every`` steps, since a merge can reveal new
   frontiers).
4. Follow the path with :func:`~mrexplore.policies.base.follow_path`; after a FORWARD that
   did not move the robot, turn towards the waypoint's side rather than push again
   (``slide_on_bump``).
"""

from __future__ import annotations

import math
import time
from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import ConfigError, GridError
from mrexplore.grid import apply_transform, invert_transform, map_points
from mrexplore.options import (
    boolean,
    integer,
    non_negative,
    number,
    optional,
    positive,
    validate,
)
from mrexplore.policies.base import (
    DEFAULT_FORWARD_STEP_M,
    DEFAULT_TURN_STEP_RAD,
    Policy,
    TeamPolicy,
    densify_path,
    follow_path,
    nearest_path_index,
)
from mrexplore.policies.frontier_cells import find_frontiers, frontier_near, known_bbox
from mrexplore.policies.planning import PlanningGrid, planning_rounds
from mrexplore.robot import Action
from mrexplore.types import RobotView

__all__ = [
    "CoordinatedFrontierPolicy",
    "CostFrontierPolicy",
    "FrontierCandidates",
    "FrontierExplorer",
    "NearestFrontierPolicy",
]


class FrontierCandidates:
    """The reachable, allowed frontiers of one planning round (arrays of length F).

    Attributes:
        targets: int64 (F, 2) the frontier cell aimed at, ``(col, row)`` (own map cells): the
            cell of the frontier with the shortest path to where the robot can stand near it.
        size_m: float64 (F,) frontier length in metres (cells x resolution).
        dist_m: float64 (F,) path length in metres from the robot to the frontier's approach cell.
        goals: int64 (F, 2) planning cells of the approach (where the path ends).
    """

    def __init__(
        self,
        targets: NDArray[np.int64],
        size_m: NDArray[np.float64],
        dist_m: NDArray[np.float64],
        goals: NDArray[np.int64],
    ) -> None:
        self.targets = targets
        self.size_m = size_m
        self.dist_m = dist_m
        self.goals = goals

    def __len__(self) -> int:
        return int(self.targets.shape[0])


class FrontierExplorer(Policy):
    """Frontier exploration for one robot; subclasses choose among frontiers (:meth:`choose`).

    Args:
        min_frontier_cells: smallest frontier kept, cells (8 = 0.4 m at 0.05 m/cell).
        plan_factor: fine cells per planning cell of the first round. A planning cell is
            traversable only when all its fine cells are, so 2 (0.1 m cells, 4x fewer) keeps
            paths a little farther from the walls than the inflation alone - margin a robot
            with 22.5 degree headings needs on a map rotated against the world's grid (random
            start headings), where planning on the map's own cells runs it into wall corners
            (symmetric_office seed 1004: wedged for 80 s) - but loses up to a fine cell of
            every gap to the grid's alignment, enough to close the 0.35-0.4 m passages of a
            real office to a 0.3 m robot: see ``fine_fallback``.
        approach_cells: a frontier cell is reachable when a traversable planning cell lies within
            this many planning cells of it (frontier cells border unknown space, which the
            planner treats as an obstacle, so the robot can only get *near* them); the fine
            rounds use the same distance in fine cells.
        replan_every: steps between re-plans at the latest.
        min_replan_steps: a target that stopped being a frontier triggers a re-plan only once the
            plan is this many steps old (the frontier recedes while the robot approaches it; a
            re-plan at every step would cost a field per step for little gain).
        stuck_steps: steps without progress along the path that count as stuck (a strike on the
            target; the second strike near the same place blacklists it).
        bump_steps: FORWARD actions in a row that did not move the robot (collisions) before a
            re-plan from the nearest free planning cell.
        blacklist_radius_m: frontier cells this close to a blacklisted point are never targets.
        clearance_cells: inflation of the walls beyond the robot's radius, fine cells (0.5 covers
            the wall cell's own extent; :func:`~mrexplore.policies.planning.inflate_obstacles`).
        tight_clearance_cells: the clearance of the last round, when no frontier is reachable
            with ``clearance_cells`` (0: exactly the simulator's collision rule); None: no such
            round.
        fine_fallback: when no frontier is reachable on ``plan_factor`` cells, plan again on
            the map's own cells (with ``clearance_cells``, then ``tight_clearance_cells``), so
            narrow passages are planned through only when nothing else is left.
        backtrack_trail: the robot's own trail is always traversable (it can go back the way it
            came even when its map, seen better from inside a gap, shows the gap narrower than
            the inflated robot). Off by default: the tight-clearance round already frees such
            robots on tb3_office, and on depot (seed 1008, random headings) the trail led a
            robot to plan along a shelf corner it stayed wedged against.
        slide_on_bump: after a FORWARD that did not move the robot, turn one step towards the
            side of the path's waypoint instead of repeating it (the re-plan after a collision
            gives the same path, so the follower would push into the same wall corner for
            ever); the next FORWARD then slides along the obstacle.
        lookahead_m: path-follower look-ahead, metres.
        arrive_m: the path end counts as reached within this distance, metres.
        turn_step_rad: heading change of one turn action (the robot's default).
        forward_step_m: distance of one FORWARD (the robot's default), for collision detection.

    Attributes (read-only for callers): ``done`` (no reachable frontier left at the last plan),
    ``target`` (the frontier cell the robot is heading for, or None), ``blacklist``,
    ``n_plans``, ``n_acts``, ``plan_time_s`` and ``act_time_s`` (cumulative wall-clock seconds
    spent planning / in ``act``).
    """

    def __init__(
        self,
        min_frontier_cells: int = 8,
        plan_factor: int = 2,
        approach_cells: int = 2,
        replan_every: int = 10,
        min_replan_steps: int = 2,
        stuck_steps: int = 12,
        bump_steps: int = 3,
        blacklist_radius_m: float = 0.5,
        clearance_cells: float = 0.5,
        tight_clearance_cells: float | None = 0.0,
        fine_fallback: bool = True,
        backtrack_trail: bool = False,
        slide_on_bump: bool = True,
        lookahead_m: float = 0.3,
        arrive_m: float = 0.15,
        turn_step_rad: float = DEFAULT_TURN_STEP_RAD,
        forward_step_m: float = DEFAULT_FORWARD_STEP_M,
    ) -> None:
        owner = type(self).__name__
        for name, value, check in (
            ("min_frontier_cells", min_frontier_cells, integer(1)),
            ("plan_factor", plan_factor, integer(1)),
            ("approach_cells", approach_cells, integer(0)),
            ("replan_every", replan_every, integer(1)),
            ("min_replan_steps", min_replan_steps, integer(0)),
            ("stuck_steps", stuck_steps, integer(1)),
            ("bump_steps", bump_steps, integer(1)),
            ("blacklist_radius_m", blacklist_radius_m, non_negative),
            ("clearance_cells", clearance_cells, non_negative),
            ("tight_clearance_cells", tight_clearance_cells, optional(non_negative)),
            ("fine_fallback", fine_fallback, boolean),
            ("backtrack_trail", backtrack_trail, boolean),
            ("slide_on_bump", slide_on_bump, boolean),
            ("lookahead_m", lookahead_m, positive),
            ("arrive_m", arrive_m, positive),
            ("turn_step_rad", turn_step_rad, number(0.0, math.pi, low_open=True)),
            ("forward_step_m", forward_step_m, positive),
        ):
            validate(owner, name, value, check)
        if min_replan_steps > replan_every:
            raise ConfigError(
                f"{owner}: option min_replan_steps ({min_replan_steps}) must be at most "
                f"replan_every ({replan_every})"
            )
        self.min_frontier_cells = int(min_frontier_cells)
        self.plan_factor = int(plan_factor)
        self.approach_cells = int(approach_cells)
        self.replan_every = int(replan_every)
        self.min_replan_steps = int(min_replan_steps)
        self.stuck_steps = int(stuck_steps)
        self.bump_steps = int(bump_steps)
        self.blacklist_radius_m = float(blacklist_radius_m)
        self.clearance_cells = float(clearance_cells)
        self.backtrack_trail = bool(backtrack_trail)
        self.tight_clearance_cells = (
            None if tight_clearance_cells is None else float(tight_clearance_cells)
        )
        self.fine_fallback = bool(fine_fallback)
        self.slide_on_bump = bool(slide_on_bump)
        #: The planning rounds ``(factor, approach_cells, clearance_cells)``, tried in turn
        #: until one has a reachable frontier.
        #: The approach distance is the same in metres on every grid.
        self.rounds: list[tuple[int, int, float]] = [
            (factor, self.approach_cells * self.plan_factor // factor, clearance)
            for factor, clearance in planning_rounds(
                self.plan_factor,
                self.clearance_cells,
                self.tight_clearance_cells,
                self.fine_fallback,
            )
        ]
        self.lookahead_m = float(lookahead_m)
        self.arrive_m = float(arrive_m)
        self.turn_step_rad = float(turn_step_rad)
        self.forward_step_m = float(forward_step_m)
        self.reset(np.random.default_rng(0))

    # -- protocol ----------------------------------------------------------------------------

    def reset(self, rng: np.random.Generator) -> None:
        """Forget the episode: plan, blacklist, counters (the policy is deterministic; ``rng``
        is kept for subclasses)."""
        self.rng = rng
        self.path: NDArray[np.float64] | None = None
        self.target: tuple[int, int] | None = None
        self.done = False
        self._grid: PlanningGrid | None = None
        self._since_plan = 0
        self._remaining: NDArray[np.float64] | None = None  # path length left from each point
        self._best_left = math.inf
        self._stall = 0
        self._bumps = 0
        self._last_pose: tuple[float, float, float] | None = None
        self._last_action = int(Action.STAY)
        self._arrived = False
        self._old_target: tuple[int, int] | None = None
        self.blacklist: list[tuple[float, float]] = []
        # Own-map cells the robot's centre has been on (its estimated trail), for the planner.
        self._trail: list[tuple[float, float]] = []
        self._strikes: list[tuple[float, float]] = []
        self.n_plans = 0
        self.n_acts = 0
        self.plan_time_s = 0.0
        self.act_time_s = 0.0

    def act(self, view: RobotView) -> int:
        """The next action for ``view`` (an :class:`~mrexplore.robot.Action` value)."""
        return self.step(view)

    # -- the machine -------------------------------------------------------------------------

    def clear_target(self) -> None:
        """Drop the current plan so the next :meth:`step` re-plans (used for team re-assignment)."""
        self.path = None
        self.target = None
        self.done = False

    def step(
        self,
        view: RobotView,
        claims: NDArray[np.float64] | None = None,
        force_replan: bool = False,
    ) -> int:
        """One step: maybe re-plan (with teammates' targets ``claims`` (K, 2) in this robot's
        cells, for :meth:`choose`), then follow the path."""
        t0 = time.perf_counter()
        m = view.map
        if not isinstance(m, np.ndarray) or m.ndim != 2 or m.dtype != np.int8:
            raise GridError(
                f"view.map must be a 2-D int8 occupancy grid, got {getattr(m, 'dtype', type(m))}"
            )
        pose = (float(view.pose_cell[0]), float(view.pose_cell[1]), float(view.pose_cell[2]))
        res = float(view.resolution_m)
        if self._progress(view, pose, res, force_replan):
            self._plan(view, pose, claims)
        action = self._follow(pose, res)
        if action == Action.STAY and self.path is not None:
            # At the path end already (e.g. a fresh plan to where we stand): plan again now
            # rather than idle one step; _plan blacklists a frontier that did not go away.
            self._arrived = True
            self._plan(view, pose, claims)
            action = self._follow(pose, res)
        self._since_plan += 1
        self._last_pose = pose
        self._last_action = action
        self.n_acts += 1
        self.act_time_s += time.perf_counter() - t0
        return action

    def _follow(self, pose: tuple[float, float, float], res: float) -> int:
        if self.path is None:
            return int(Action.STAY)
        return follow_path(
            self.path,
            pose,
            turn_step_rad=self.turn_step_rad,
            lookahead_cells=self.lookahead_m / res,
            arrive_cells=self.arrive_m / res,
            blocked_ahead=self.slide_on_bump and self._hit,
            grid=self._grid,
        )

    def _progress(
        self, view: RobotView, pose: tuple[float, float, float], res: float, force: bool = False
    ) -> bool:
        """After a move: extend the backtrack trail, count progress and bumps, strike a target
        the robot is stuck on; whether a re-plan is due (``force``, stuck, bumped, or
        :meth:`_needs_replan`, asked only when none of the others holds)."""
        if self.backtrack_trail and (
            not self._trail
            or math.hypot(pose[0] - self._trail[-1][0], pose[1] - self._trail[-1][1]) >= 0.5
        ):
            self._trail.append((pose[0], pose[1]))
        stuck, bumped = self._update_progress(pose, res)
        if stuck and self.target is not None:
            self._strike(self.target, res)
            self._stall = 0
        return force or stuck or bumped or self._needs_replan(view, pose, res)

    def _update_progress(self, pose: tuple[float, float, float], res: float) -> tuple[bool, bool]:
        """Track progress along the path and collisions: ``(stuck, bumped)``."""
        if self._last_pose is not None and self._last_action == Action.FORWARD:
            moved = math.hypot(pose[0] - self._last_pose[0], pose[1] - self._last_pose[1])
            self._hit = moved < 0.3 * self.forward_step_m / res
            self._bumps = self._bumps + 1 if self._hit else 0
        else:
            self._hit = False
        bumped = self._bumps >= self.bump_steps
        if self.path is None or self._remaining is None:
            return False, bumped
        # Progress = less path left to the target. Measured on the path's arc length, so it is
        # comparable across re-plans to the same target and is not fooled by detours; it is
        # reset only when the target moves elsewhere (see _plan), so collisions that trigger
        # re-plans still add up to "stuck".
        left = float(self._remaining[nearest_path_index(self.path, pose)])
        if left < self._best_left - 0.5:
            self._best_left = left
            self._stall = 0
        else:
            self._stall += 1
        return self._stall >= self.stuck_steps, bumped

    def _strike(self, target: tuple[int, int], res: float) -> None:
        """Stuck on ``target``: the second time near the same place blacklists it."""
        r2 = (self.blacklist_radius_m / res) ** 2
        if any((s[0] - target[0]) ** 2 + (s[1] - target[1]) ** 2 <= r2 for s in self._strikes):
            self.blacklist.append((float(target[0]), float(target[1])))
        else:
            self._strikes.append((float(target[0]), float(target[1])))

    def _needs_replan(self, view: RobotView, pose: tuple[float, float, float], res: float) -> bool:
        if self.path is None:
            # Nothing to do: look again at once, or (when done) every replan_every steps, since
            # a merge can bring new frontiers.
            return not self.done or self._since_plan >= self.replan_every
        if self._since_plan >= self.replan_every:
            return True
        end = self.path[-1]
        if math.hypot(end[0] - pose[0], end[1] - pose[1]) <= self.arrive_m / res:
            self._arrived = True
            return True
        return (
            self._since_plan >= self.min_replan_steps
            and self.target is not None
            and not self._still_frontier(view.map, self.target)
        )

    @staticmethod
    def _still_frontier(m: NDArray[np.int8], cell: tuple[int, int], radius: int = 2) -> bool:
        """Whether a frontier cell lies within ``radius`` cells of ``cell`` (a local check)."""
        return frontier_near(m, cell, radius)

    def replan(self, view: RobotView) -> None:
        """Plan now from ``view`` (choose a frontier and a path), as :meth:`act` does when a
        re-plan is due (what ``mrexplore bench policies`` times)."""
        self._plan(view, view.pose_cell, None)

    def _plan(
        self, view: RobotView, pose: tuple[float, float, float], claims: NDArray[np.float64] | None
    ) -> None:
        t0 = time.perf_counter()
        cands = self._propose(view, pose)
        k = -1 if cands is None or len(cands) == 0 else self.choose(cands, view, claims)
        self._commit(cands, k, view)
        self.plan_time_s += time.perf_counter() - t0

    def _propose(self, view: RobotView, pose: tuple[float, float, float]) -> PlanRound | None:
        """First half of a plan: forget the current plan and list the candidates.

        The goal-level env (:mod:`mrexplore.environment.goal_actions`) calls this and
        :meth:`_commit` with a learned choice in between; :meth:`_plan` with :meth:`choose`.
        """
        self.n_plans += 1
        self._since_plan = 0
        self._bumps = 0
        m = view.map
        if self._arrived and self.target is not None and self._still_frontier(m, self.target):
            # We stand where the planner said this frontier cell is reachable from and it is
            # still there: it cannot be seen from where one can stand. Never retry that spot
            # (the rest of a long frontier stays available).
            self.blacklist.append((float(self.target[0]), float(self.target[1])))
        self._arrived = False
        self._old_target = self.target
        self.path = None
        self.target = None
        self._remaining = None
        return self._candidates(view, pose)

    def _commit(self, cands: PlanRound | None, k: int, view: RobotView) -> None:
        """Second half of a plan: follow candidate ``k`` of ``cands`` (none: ``done``)."""
        if cands is None or len(cands) == 0 or k < 0:
            self.done = True
            return
        self.done = False
        self._grid = cands.grid
        path = cands.grid.path_to((int(cands.goals[k, 0]), int(cands.goals[k, 1])))
        self.path = None if path is None else densify_path(path)
        self.target = (int(cands.targets[k, 0]), int(cands.targets[k, 1]))
        if self.path is not None:
            seg = np.hypot(*np.diff(self.path, axis=0).T)
            self._remaining = np.concatenate([np.cumsum(seg[::-1])[::-1], [0.0]])
        old_target = self._old_target
        near_old = old_target is not None and math.hypot(
            old_target[0] - self.target[0], old_target[1] - self.target[1]
        ) <= self.blacklist_radius_m / float(view.resolution_m)
        if not near_old:
            self._best_left = math.inf
            self._stall = 0

    def _candidates(self, view: RobotView, pose: tuple[float, float, float]) -> PlanRound | None:
        """Reachable, allowed frontiers with their path lengths (None: nothing to plan on).

        Per frontier, the *aim* is its cell with the shortest path to a planning cell within
        ``approach_cells``; cells near blacklisted points are left out first. Planned in
        :attr:`rounds` until one leaves a frontier.
        """
        m = view.map
        res = float(view.resolution_m)
        box = known_bbox(m, margin=1 + self.plan_factor, within=view.known_box)
        if box is None:
            return None
        r0, r1, c0, c1 = box
        crop = m[r0:r1, c0:c1]
        fronts = find_frontiers(crop, self.min_frontier_cells)
        if not fronts:
            return None
        off = np.array([c0, r0], dtype=np.int64)
        cells = np.concatenate([f.cells for f in fronts]) + off
        counts = np.array([f.size for f in fronts])
        # The trail ends where the robot stands now.
        trail = (
            np.array([*self._trail, pose[:2]], dtype=np.float64) - off
            if self.backtrack_trail
            else None
        )
        out: PlanRound | None = None
        for factor, approach, clearance in self.rounds:
            grid = PlanningGrid.build(
                crop,
                res,
                float(view.robot_radius_m),
                (pose[0] - c0, pose[1] - r0),
                factor=factor,
                margin_m=0.0,
                clearance_cells=clearance,
                passable_path=trail,
            )
            # From crop cells to map cells: shifting the grid's offset is all it takes.
            grid.col0 += c0
            grid.row0 += r0
            if grid.start is None:
                continue
            out = self._round(grid, cells, counts, res, approach)
            if len(out):
                break
        return out

    def _round(
        self,
        grid: PlanningGrid,
        cells: NDArray[np.int64],
        counts: NDArray[np.int64],
        res: float,
        approach: int,
    ) -> PlanRound:
        """The reachable, allowed frontiers on one planning grid (``cells`` (N, 2) all frontier
        cells in map cells, grouped by frontier; ``counts`` (F,) cells per frontier)."""
        starts = np.concatenate([[0], np.cumsum(counts)[:-1]])
        dist, pcell = grid.approach(cells, approach)
        if self.blacklist:
            bl = np.asarray(self.blacklist, dtype=np.float64)
            near = np.zeros(cells.shape[0], dtype=bool)
            r2 = (self.blacklist_radius_m / res) ** 2
            for b in bl:  # loop over blacklisted points (few), vectorised over cells
                near |= ((cells[:, 0] - b[0]) ** 2 + (cells[:, 1] - b[1]) ** 2) <= r2
            dist[near] = np.inf
        # Per frontier: the best of its cells (reduceat on the concatenated cells).
        best = np.minimum.reduceat(dist, starts)
        owner = np.repeat(np.arange(len(counts)), counts)
        hit = np.flatnonzero(dist == best[owner])
        first = np.full(len(counts), -1, dtype=np.int64)
        first[owner[hit[::-1]]] = hit[::-1]  # reversed assignment keeps each frontier's first hit
        ok = np.isfinite(best)
        # A frontier cell reachable at (almost) zero distance is one we stand at and still cannot
        # see past: blacklist that spot now instead of "driving" there.
        here = np.flatnonzero(ok & (best <= self.arrive_m))
        for i in here:
            c = cells[first[i]]
            self.blacklist.append((float(c[0]), float(c[1])))
        ok[here] = False
        sel = np.flatnonzero(ok)
        return PlanRound(
            targets=cells[first[sel]],
            size_m=counts[sel].astype(np.float64) * res,
            dist_m=best[sel],
            goals=pcell[first[sel]],
            grid=grid,
        )

    def choose(
        self, cands: FrontierCandidates, view: RobotView, claims: NDArray[np.float64] | None
    ) -> int:
        """Index of the chosen candidate; the default is the nearest by path length."""
        return int(np.argmin(cands.dist_m))


class PlanRound(FrontierCandidates):
    """Candidates plus the planning grid they were measured on."""

    def __init__(
        self,
        targets: NDArray[np.int64],
        size_m: NDArray[np.float64],
        dist_m: NDArray[np.float64],
        goals: NDArray[np.int64],
        grid: PlanningGrid,
    ) -> None:
        super().__init__(targets, size_m, dist_m, goals)
        self.grid = grid


class NearestFrontierPolicy(FrontierExplorer):
    """Go to the frontier with the shortest path (Yamauchi 1997).

    Options: those of :class:`FrontierExplorer`.
    """


class CostFrontierPolicy(FrontierExplorer):
    """explore_lite's choice: minimise ``distance_weight * distance_m - size_weight * size_m``.

    Args:
        distance_weight: explore_lite's ``potential_scale`` (3.0), per metre of path.
        size_weight: explore_lite's ``gain_scale`` (1.0), per metre of frontier length.
        **options: :class:`FrontierExplorer` options.
    """

    def __init__(
        self, distance_weight: float = 3.0, size_weight: float = 1.0, **options: float
    ) -> None:
        self.distance_weight = float(distance_weight)
        self.size_weight = float(size_weight)
        super().__init__(**options)  # type: ignore[arg-type]

    def choose(
        self, cands: FrontierCandidates, view: RobotView, claims: NDArray[np.float64] | None
    ) -> int:
        cost = self.distance_weight * cands.dist_m - self.size_weight * cands.size_m
        return int(np.argmin(cost))


#: Frontier length that adds ``size_weight`` to a frontier's utility in Burgard's choice (metres;
#: the goal-level candidates' ``size_m`` feature is in the same unit).
SIZE_UNIT_M = 10.0


#: Half-width (metres) of the window around a frontier, mapped into a teammate's map by a
#: merge candidate, whose known share is the frontier's verification value (``verify_weight``).
VERIFY_WINDOW_M = 1.0

#: Window samples per side (an even grid: the known share is read at this many x this many
#: cells, not the whole window; a frontier is scored in microseconds).
VERIFY_SAMPLES = 9


def verification_value(
    targets: NDArray[np.floating] | NDArray[np.integer],
    hypotheses: Mapping[str, tuple[Sequence[NDArray[np.float64]], NDArray[np.int8]]],
    resolution_m: float,
) -> NDArray[np.float64]:
    """Per frontier target (K, 2) ``(col, row)`` in the robot's cells: the largest share, over
    every teammate and every merge candidate (``RobotView.hypotheses``), of known cells of the
    teammate's map in the window of +-:data:`VERIFY_WINDOW_M` around where the candidate puts
    the target. Exploring there puts the robot's walls on the teammate's under that candidate,
    which confirms it (shared space grows) or contradicts it: either way the merger can tell
    its candidates apart. (K,) float64 in [0, 1]; zeros without candidates.

    >>> import numpy as np
    >>> mate = np.full((100, 100), -1, np.int8); mate[20:80, 20:80] = 0
    >>> shift = np.array([[1.0, 0, -30], [0, 1, -30], [0, 0, 1]])  # mate's cells -> ours
    >>> t = np.array([[20.0, 20.0], [80.0, 80.0]])
    >>> verification_value(t, {"robot_1": ([shift], mate)}, 0.05).round(2).tolist()
    [1.0, 0.0]
    """
    k = np.asarray(targets, dtype=np.float64).reshape(-1, 2)
    best = np.zeros(k.shape[0])
    if not hypotheses or k.shape[0] == 0:
        return best
    half = VERIFY_WINDOW_M / float(resolution_m)
    offs = np.linspace(-half, half, VERIFY_SAMPLES)
    dx, dy = (g.ravel() for g in np.meshgrid(offs, offs))
    for cands, m in hypotheses.values():
        h, w = m.shape
        for T in cands:
            cx, cy = map_points(k, invert_transform(T))  # elementwise: same bits on any CPU
            cols = np.floor(cx[:, None] + dx[None, :] + 0.5).astype(np.int64)
            rows = np.floor(cy[:, None] + dy[None, :] + 0.5).astype(np.int64)
            inside = (cols >= 0) & (cols < w) & (rows >= 0) & (rows < h)
            known = np.zeros(cols.shape, dtype=bool)
            known[inside] = m[rows[inside], cols[inside]] != -1
            np.maximum(best, known.mean(axis=1), out=best)
    return best


class _BurgardExplorer(FrontierExplorer):
    """One robot of :class:`CoordinatedFrontierPolicy`: utility minus normalised cost."""

    def __init__(
        self,
        beta: float,
        sensor_range_m: float,
        size_weight: float = 0.0,
        verify_weight: float = 0.0,
        **options: float,
    ) -> None:
        self.beta = float(beta)
        self.sensor_range_m = float(sensor_range_m)
        self.size_weight = float(size_weight)
        self.verify_weight = float(verify_weight)
        super().__init__(**options)  # type: ignore[arg-type]

    def choose(
        self, cands: FrontierCandidates, view: RobotView, claims: NDArray[np.float64] | None
    ) -> int:
        cost = cands.dist_m / max(float(cands.dist_m.max()), 1e-9)
        utility = np.ones(len(cands))
        if claims is not None and len(claims):
            rng_cells = self.sensor_range_m / float(view.resolution_m)
            d = np.hypot(
                cands.targets[:, None, 0] - claims[None, :, 0],
                cands.targets[:, None, 1] - claims[None, :, 1],
            )
            utility -= np.clip(1.0 - d / rng_cells, 0.0, None).sum(axis=1)
        if self.size_weight:
            utility += self.size_weight * cands.size_m / SIZE_UNIT_M
        if self.verify_weight and view.hypotheses:
            utility += self.verify_weight * verification_value(
                cands.targets, view.hypotheses, view.resolution_m
            )
        return int(np.argmax(utility - self.beta * cost))


class CoordinatedFrontierPolicy(TeamPolicy):
    """Burgard et al. (2005) coordinated frontier exploration for a team (see the module doc).

    Args:
        agents: agent names known up front (others are added when they first appear).
        beta: weight of the normalised path cost against the utility (Burgard's beta, 1.0).
        sensor_range_m: range of the discount around a teammate's target (the lidar range, 4 m).
        size_weight: utility per :data:`SIZE_UNIT_M` of frontier length (0: Burgard's, every
            frontier worth 1). The goal-level rule :func:`~mrexplore.policies.goal_rules.
            keep_or_burgard` has the same term; ``docs/goal_policy.md`` measures both at 2.
        verify_weight: before a robot's map is merged with a teammate's, utility for a
            frontier whose surroundings the teammate has mapped under one of the merger's
            candidate transforms (:func:`verification_value` x this; 0: off, the default).
            Going there gives the merger the evidence that confirms or rules out a candidate
            (active disambiguation; ``docs/merging_history.md``, "Going where the merger's
            candidates can be told apart").
        **options: :class:`FrontierExplorer` options for every robot.

    Robots are handled in sorted name order ("in turn"); a robot that re-plans sees the current
    targets of the teammates it is merged with as claims. When a robot's merge status turns on, all
    merged robots drop their targets and are re-assigned in turn, so the first robot picks freely
    and the next one is pushed away from it.
    """

    def __init__(
        self,
        agents: Sequence[str] = (),
        beta: float = 1.0,
        sensor_range_m: float = 4.0,
        size_weight: float = 0.0,
        verify_weight: float = 0.0,
        **options: float,
    ) -> None:
        for name, value in (
            ("beta", beta),
            ("size_weight", size_weight),
            ("verify_weight", verify_weight),
        ):
            if not value >= 0:
                raise ConfigError(f"CoordinatedFrontierPolicy: {name} must be >= 0, got {value}")
        if not sensor_range_m > 0:
            raise ConfigError(
                f"CoordinatedFrontierPolicy: sensor_range_m must be > 0, got {sensor_range_m}"
            )
        self.beta = float(beta)
        self.sensor_range_m = float(sensor_range_m)
        self.size_weight = float(size_weight)
        self.verify_weight = float(verify_weight)
        self.options = dict(options)
        self.robots: dict[str, _BurgardExplorer] = {a: self._make() for a in agents}
        self._was_merged: set[str] = set()

    def _make(self) -> _BurgardExplorer:
        return _BurgardExplorer(
            self.beta, self.sensor_range_m, self.size_weight, self.verify_weight, **self.options
        )

    def reset(self, rng: np.random.Generator) -> None:
        self._was_merged = set()
        for robot in self.robots.values():
            robot.reset(rng)

    def act(self, views: Mapping[str, RobotView]) -> dict[str, int]:
        for a in views:
            if a not in self.robots:
                self.robots[a] = self._make()
        merged = {a for a, v in views.items() if v.merged}
        force = merged if merged - self._was_merged else set()
        self._was_merged = merged
        for a in force:
            self.robots[a].clear_target()
        actions: dict[str, int] = {}
        for a in sorted(views):
            view = views[a]
            pts = []
            for b, T in view.transforms.items():
                # Targets travel over the radio: only teammates in range share theirs.
                if b not in view.in_range:
                    continue
                tb = self.robots[b].target if b in self.robots else None
                if tb is not None and b != a:
                    pts.append(apply_transform(T, np.array([tb], dtype=np.float64))[0])
            claims = np.array(pts) if pts else None
            actions[a] = self.robots[a].step(view, claims, force_replan=a in force)
        return actions

    @property
    def done(self) -> bool:
        """True when every robot found no reachable frontier at its last plan."""
        return bool(self.robots) and all(r.done for r in self.robots.values())
