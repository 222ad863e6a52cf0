"""The policy protocol, the per-robot-to-team lift, and a path follower.

Protocol (what the env, the experiments and users rely on):

* :class:`Policy` - one robot. ``reset(rng)`` once per episode with a
  ``numpy.random.Generator`` (the only source of randomness), then ``act(view) -> int`` every
  step, where ``view`` is the robot's :class:`~mrexplore.types.RobotView` (get it with
  ``env.unwrapped.robot_view(agent)``) and the result an :class:`mrexplore.robot.Action` value.
* :class:`TeamPolicy` - all robots at once: ``reset(rng)``, then
  ``act(views: Mapping[agent, RobotView]) -> {agent: action}``. Agents missing from ``views``
  (finished or absent) get no action. :class:`IndependentTeam` lifts a :class:`Policy` factory to
  a team with one independent copy per robot.

A policy sees only its ``RobotView``: the own or fused map in the robot's own frame, its own
pose estimate, and teammates and estimated transforms after a merge - never the ground truth.

>>> import numpy as np
>>> from mrexplore.robot import Action
>>> path = np.array([[0.0, 0.0], [10.0, 0.0]])          # a path along +col
>>> follow_path(path, (0.0, 0.0, np.pi / 2), turn_step_rad=np.pi / 8) == Action.TURN_RIGHT
True
"""

from __future__ import annotations

import math
from abc import ABC, abstractmethod
from collections.abc import Callable, Mapping, Sequence
from typing import Protocol

import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.errors import ConfigError
from mrexplore.robot import Action, RobotConfig
from mrexplore.types import RobotView

__all__ = [
    "DEFAULT_FORWARD_STEP_M",
    "DEFAULT_TURN_STEP_RAD",
    "IndependentTeam",
    "Policy",
    "TeamPolicy",
    "densify_path",
    "follow_path",
    "nearest_path_index",
]

_planning = kernels.load("planning")

_CFG = RobotConfig()
#: Heading change of one TURN_LEFT / TURN_RIGHT with the robot's defaults (radians; 22.5 deg).
DEFAULT_TURN_STEP_RAD: float = float(_CFG.turn_rad)
#: Distance of one FORWARD with the robot's defaults (metres; 0.125 m).
DEFAULT_FORWARD_STEP_M: float = float(_CFG.step_m)


class Policy(ABC):
    """One robot's policy: ``reset(rng)`` per episode, then ``act(view) -> int`` per step."""

    def reset(self, rng: np.random.Generator) -> None:  # noqa: B027 - optional hook, not abstract
        """Start an episode; ``rng`` is the only randomness the policy may use."""

    @abstractmethod
    def act(self, view: RobotView) -> int:
        """The action (an :class:`mrexplore.robot.Action` value) for this step."""


class TeamPolicy(ABC):
    """All robots' policy: ``reset(rng)`` per episode, then ``act(views) -> {agent: action}``."""

    def reset(self, rng: np.random.Generator) -> None:  # noqa: B027 - optional hook, not abstract
        """Start an episode; ``rng`` is the only randomness the team may use."""

    @abstractmethod
    def act(self, views: Mapping[str, RobotView]) -> dict[str, int]:
        """One action per agent present in ``views``."""


class IndependentTeam(TeamPolicy):
    """A team of independent copies of one per-robot policy (no coordination).

    Args:
        factory: builds a fresh :class:`Policy`; called once per agent.
        agents: agent names known up front (others are added when they first appear).

    Each agent's policy gets its own generator, derived from the team's in sorted agent order,
    so results do not depend on the order of ``views``.
    """

    def __init__(self, factory: Callable[[], Policy], agents: Sequence[str] = ()) -> None:
        self.factory = factory
        self.policies: dict[str, Policy] = {a: factory() for a in agents}
        self._seed_base: int | None = None

    def _child_rng(self, agent: str) -> np.random.Generator:
        # A child seed from the team generator and the agent's name: independent of call order.
        assert self._seed_base is not None
        return np.random.default_rng([self._seed_base, *agent.encode()])

    def reset(self, rng: np.random.Generator) -> None:
        self._seed_base = int(rng.integers(0, 2**63 - 1))
        for agent in sorted(self.policies):
            self.policies[agent].reset(self._child_rng(agent))

    def act(self, views: Mapping[str, RobotView]) -> dict[str, int]:
        if self._seed_base is None:
            raise RuntimeError("IndependentTeam.act() called before reset(rng)")
        actions: dict[str, int] = {}
        for agent in sorted(views):
            if agent not in self.policies:
                self.policies[agent] = self.factory()
                self.policies[agent].reset(self._child_rng(agent))
            actions[agent] = int(self.policies[agent].act(views[agent]))
        return actions


# --------------------------------------------------------------------------------------------
# Path following.
# --------------------------------------------------------------------------------------------


def _wrap(a: float) -> float:
    """Angle wrapped to (-pi, pi]."""
    return math.atan2(math.sin(a), math.cos(a))


def densify_path(path: NDArray[np.floating], spacing: float = 1.0) -> NDArray[np.float64]:
    """The same polyline with points at most ``spacing`` cells apart (K', 2), endpoints kept.

    The follower measures "closest point" and "look-ahead" on points, so a sparse path (a few
    corners) must be resampled first or the closest point can lie behind the robot.
    """
    p = np.asarray(path, dtype=np.float64).reshape(-1, 2)
    if p.shape[0] < 2:
        return p
    if _planning is not None and kernels.enabled():
        if _planning.max_step(p) <= spacing:
            return p
        out: NDArray[np.float64] = _planning.densify(p, float(spacing))
        return out
    seg = np.hypot(*np.diff(p, axis=0).T)
    if float(seg.max()) <= spacing:
        return p
    n = np.maximum(np.ceil(seg / spacing).astype(np.int64), 1)  # sub-steps per segment
    seg_idx = np.repeat(np.arange(seg.size), n)
    frac = (np.arange(int(n.sum())) - np.repeat(np.cumsum(n) - n, n)) / np.repeat(n, n)
    pts = p[seg_idx] + (p[seg_idx + 1] - p[seg_idx]) * frac[:, None]
    return np.vstack([pts, p[-1:]])


def nearest_path_index(
    path: NDArray[np.floating], pose: tuple[float, float, float] | Sequence[float]
) -> int:
    """Index of the path point closest to the robot (path (K, 2) ``(col, row)``; pose in cells)."""
    p = np.asarray(path, dtype=np.float64).reshape(-1, 2)
    if _planning is not None and kernels.enabled() and p.shape[0]:
        return int(_planning.nearest_index(p, float(pose[0]), float(pose[1])))
    d2 = (p[:, 0] - pose[0]) ** 2 + (p[:, 1] - pose[1]) ** 2
    return int(np.argmin(d2))


#: ``clear(points (N, 2) (col, row)) -> bool (N,)``: whether a robot centre may stand there.
ClearFn = Callable[[NDArray[np.float64]], NDArray[np.bool_]]


class TraversableGrid(Protocol):
    """A planning grid as the follower reads it (:class:`~mrexplore.policies.planning.
    PlanningGrid`): ``free`` bool (h, w) planning cells, the fine-cell offset ``col0, row0``,
    ``factor`` fine cells per planning cell, and ``clear`` (:data:`ClearFn`) on them."""

    free: NDArray[np.bool_]
    col0: int
    row0: int
    factor: int

    def clear(self, cells: NDArray[np.floating]) -> NDArray[np.bool_]: ...


def follow_path(
    path: NDArray[np.floating],
    pose: tuple[float, float, float] | Sequence[float],
    turn_step_rad: float = DEFAULT_TURN_STEP_RAD,
    lookahead_cells: float = 6.0,
    arrive_cells: float = 2.0,
    clear: ClearFn | None = None,
    blocked_ahead: bool = False,
    grid: TraversableGrid | None = None,
) -> int:
    """Pure pursuit on a discrete action set: the action that brings the robot along ``path``.

    The waypoint is the first path point at least ``lookahead_cells`` beyond the point closest
    to the robot (or the last point). With ``clear`` given, the waypoint is pulled back along
    the path until the straight segment to it is clear (sampled every half cell, ignoring the
    first 1.5 cells, where a robot that touched a wall stands): pure pursuit would otherwise cut
    the inside of corners into door frames. The robot turns (TURN_LEFT raises theta) while the
    heading error to the waypoint exceeds half a turn step - the best a 22.5 deg turn can do is
    then within +-11.25 deg - and goes FORWARD otherwise. A small slack (5 %) on the half step
    keeps a heading that sits exactly between two turn steps from flip-flopping.

    Args:
        path: float (K, 2) ``(col, row)`` points in map cells, start to goal (resampled to one
            point per cell if sparser).
        pose: ``(col, row, theta_rad)`` of the robot in the same cells; theta from +col to +row.
        turn_step_rad: heading change of one turn action (radians).
        lookahead_cells: look-ahead distance in cells.
        arrive_cells: within this distance (cells) of the last point the path is done: STAY.
        clear: optional traversability test for the line-of-sight check (see :data:`ClearFn`).
        blocked_ahead: FORWARD is known not to move the robot at its heading (it just
            collided): where FORWARD would be the answer, turn towards the waypoint's side
            instead, so that the next FORWARD, at most a turn step off the waypoint, slides
            along the obstacle rather than pushing into it again.
        grid: a planning grid whose traversable cells the line of sight keeps to, as
            ``clear=grid.clear`` does (the compiled follower reads the grid itself).

    Returns:
        An :class:`~mrexplore.robot.Action` value.
    """
    p = np.asarray(path, dtype=np.float64).reshape(-1, 2)
    if p.shape[0] == 0:
        raise ConfigError("follow_path needs a path with at least one point")
    p = densify_path(p)
    x, y, theta = float(pose[0]), float(pose[1]), float(pose[2])
    if math.hypot(p[-1, 0] - x, p[-1, 1] - y) <= arrive_cells:
        return int(Action.STAY)
    if grid is not None and clear is None and _planning is not None and kernels.enabled():
        j = int(
            _planning.waypoint(
                p,
                x,
                y,
                float(lookahead_cells),
                grid.free,
                float(grid.col0),
                float(grid.row0),
                grid.factor,
                True,
            )
        )
    else:
        if clear is None and grid is not None:
            clear = grid.clear
        d = np.hypot(p[:, 0] - x, p[:, 1] - y)
        k = int(np.argmin(d))
        ahead = np.flatnonzero(d[k:] >= lookahead_cells)
        j = k + int(ahead[0]) if ahead.size else p.shape[0] - 1
        if clear is not None and j > k:
            j = _line_of_sight(p, k, j, x, y, clear)
    wp = p[j]
    err = _wrap(math.atan2(wp[1] - y, wp[0] - x) - theta)
    if abs(err) <= 0.5 * turn_step_rad * 1.05:
        if not blocked_ahead:
            return int(Action.FORWARD)
        return int(Action.TURN_LEFT if err >= 0 else Action.TURN_RIGHT)
    return int(Action.TURN_LEFT if err > 0 else Action.TURN_RIGHT)


def _line_of_sight(
    p: NDArray[np.float64], k: int, j: int, x: float, y: float, clear: ClearFn
) -> int:
    """The farthest index in ``k+1 .. j`` with a clear segment from ``(x, y)``, else ``k+1``."""
    cand = np.arange(k + 1, j + 1)
    seg = p[cand] - np.array([x, y])
    length = np.hypot(seg[:, 0], seg[:, 1])
    n = max(int(np.ceil(length.max() / 0.5)), 1)
    t = np.arange(1, n + 1) / n  # (S,)
    pts = np.array([x, y]) + seg[:, None, :] * t[None, :, None]  # (C, S, 2)
    skip = (length[:, None] * t[None, :]) < 1.5  # near the robot: it may stand in the margin
    ok = clear(pts.reshape(-1, 2)).reshape(pts.shape[:2]) | skip
    good = np.flatnonzero(ok.all(axis=1))
    return int(cand[good[-1]]) if good.size else k + 1
