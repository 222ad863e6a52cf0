"""Candidate goals for goal-level decisions: what a robot can choose, and how each looks.

A :class:`GoalExecutor` is one robot's frontier machine (:class:`~mrexplore.policies.explorers.
FrontierExplorer`: candidates, planner, path follower, stuck detection, blacklist) with the
*choice* taken out: :meth:`GoalExecutor.propose` lists the reachable frontiers of the robot's
own-or-fused map, an outside decision-maker (a learned policy) picks one, and
:meth:`GoalExecutor.commit` plans the path to it; :meth:`GoalExecutor.next_action` and
:meth:`GoalExecutor.observe` then drive the robot there step by step and say when a new decision
is due (goal reached, target no longer a frontier, stuck, collision, or ``replan_every`` steps).

:func:`candidate_features` turns a proposal into a fixed ``(K, F)`` float32 array: the ``K``
nearest candidates by path length (the robot's current target kept among them), one row each,
features in :data:`FEATURE_NAMES`, and a mask of the valid rows. Everything comes from the
robot's :class:`~mrexplore.types.RobotView` and from the targets teammates announced
(moved into this robot's frame with the *estimated* transforms, only once merged and only from
teammates in radio range) - never from the ground truth.

>>> FEATURE_NAMES[:3]
('valid', 'path_m', 'straight_m')
>>> len(FEATURE_NAMES)
16
>>> GAIN_FEATURE_NAMES
('unknown_near', 'unknown_range')

:func:`gain_features` adds, on request (``goal_gain=1`` of the goal-level env), what a frontier
may reveal: the share of unknown cells around each candidate's target in the robot's
own-or-fused map, within 1 m and within the sensor range.
"""

from __future__ import annotations

import math
from collections.abc import Mapping

import numpy as np
from numpy.typing import NDArray

from mrexplore.grid import apply_transform
from mrexplore.policies.explorers import FrontierCandidates, FrontierExplorer, PlanRound
from mrexplore.robot import Action
from mrexplore.types import RobotView

__all__ = [
    "FEATURE_NAMES",
    "FEATURE_SCALE_M",
    "GAIN_FEATURE_NAMES",
    "GoalExecutor",
    "candidate_features",
    "gain_features",
    "teammate_claims",
]

#: Per-candidate features (columns of the ``(K, F)`` array), all >= 0 and clipped to
#: ``[0, FEATURE_MAX]``. Distances are metres divided by :data:`FEATURE_SCALE_M`; "unknown"
#: distances (no teammate known) are :data:`FAR`.
FEATURE_NAMES: tuple[str, ...] = (
    "valid",  # 1 for a real candidate, 0 for an empty slot (its other features are 0)
    "path_m",  # planned path length to the frontier's approach cell
    "straight_m",  # straight distance robot -> frontier cell
    "size_m",  # frontier length (cells x resolution)
    "rank",  # rank by path length / K (0 = nearest)
    "path_rel",  # path length / longest candidate path (Burgard's normalised cost)
    "heading_err",  # |angle between heading and the direction to the frontier| / pi
    "is_current",  # 1 when within 1 m of the target this robot is heading for now
    "claim",  # Burgard's discount: sum over teammates' targets of max(0, 1 - d / 4 m)
    "mate_target_m",  # distance to the nearest teammate target (FAR when none known)
    "mate_pos_m",  # distance to the nearest known teammate position (FAR when none)
    "mate_path_adv",  # (path_m - straight distance of the nearest teammate) / scale, + 1
    "merged",  # 1 when the robot's map is merged with a teammate's
    "time",  # simulated time / 100 s
    "n_candidates",  # number of reachable frontiers / K (all, not only the K shown)
    "total_size",  # total frontier length of all candidates / 20 m
)
FEATURE_SCALE_M = 10.0
#: The optional information-gain columns (:func:`gain_features`), each in [0, 1].
GAIN_FEATURE_NAMES: tuple[str, ...] = (
    "unknown_near",  # share of unknown cells in the square of half-side 1 m around the target
    "unknown_range",  # the same within the sensor range (square of half-side sensor_range_m)
)
#: Half-side of the near square of :func:`gain_features`, metres.
GAIN_NEAR_M = 1.0
#: Value of a distance feature when nothing is known (30 m).
FAR = 3.0
#: Upper bound of every feature (the observation Box's high).
FEATURE_MAX = 10.0
_COL = {name: i for i, name in enumerate(FEATURE_NAMES)}


class GoalExecutor(FrontierExplorer):
    """One robot's frontier machine, driven by an outside choice (see the module docstring).

    Options: those of :class:`FrontierExplorer` (defaults as for the frontier policies).
    """

    def reset(self, rng: np.random.Generator) -> None:
        super().reset(rng)
        self.proposal: PlanRound | None = None
        self._hit = False  # set by _update_progress, read by _follow
        self.needs_decision = True

    def propose(self, view: RobotView) -> PlanRound | None:
        """Forget the current plan and list the reachable candidates (None or empty: none)."""
        pose = _pose(view)
        self.proposal = self._propose(view, pose)
        return self.proposal

    def commit(self, index: int, view: RobotView) -> None:
        """Plan the path to candidate ``index`` of the last proposal (-1 or no candidates: wait,
        ``done`` until the next proposal)."""
        cands = self.proposal
        if cands is None or not 0 <= index < len(cands):
            index = -1
            self.path, self.target, self._remaining = None, None, None
        self._commit(cands, index, view)
        self.needs_decision = False

    def next_action(self, view: RobotView) -> int:
        """The action for the next simulator step (follow the committed path; STAY without)."""
        pose = _pose(view)
        res = float(view.resolution_m)
        action = self._follow(pose, res)
        if action == Action.STAY and self.path is not None:
            # At the path end already: this decision is over (the next proposal blacklists a
            # frontier that did not go away).
            self._arrived = True
            self.needs_decision = True
        self._since_plan += 1
        self._last_pose = pose
        self._last_action = action
        self.n_acts += 1
        return action

    def observe(self, view: RobotView) -> bool:
        """After a simulator step: update progress and collisions; True when a new decision is
        due (FrontierExplorer's re-plan conditions)."""
        if self._progress(view, _pose(view), float(view.resolution_m)):
            self.needs_decision = True
        return self.needs_decision


def _pose(view: RobotView) -> tuple[float, float, float]:
    return (float(view.pose_cell[0]), float(view.pose_cell[1]), float(view.pose_cell[2]))


def teammate_claims(
    view: RobotView, targets: Mapping[str, tuple[int, int] | None]
) -> NDArray[np.float64] | None:
    """Teammates' announced targets (``targets[b]`` in b's own cells) in ``view``'s cells.

    Only teammates this robot is merged with (it has an estimated transform) and can talk to now
    (``view.in_range``) contribute, as in :class:`~mrexplore.policies.explorers.
    CoordinatedFrontierPolicy`. None when there are none.
    """
    pts = []
    for b, T in view.transforms.items():
        if b == view.agent or b not in view.in_range:
            continue
        tb = targets.get(b)
        if tb is not None:
            pts.append(apply_transform(T, np.array([tb], dtype=np.float64))[0])
    return np.array(pts, dtype=np.float64) if pts else None


def candidate_features(
    cands: FrontierCandidates | None,
    view: RobotView,
    k: int,
    current_target: tuple[int, int] | None = None,
    claims: NDArray[np.float64] | None = None,
    sensor_range_m: float = 4.0,
) -> tuple[NDArray[np.float32], NDArray[np.int8], NDArray[np.int64]]:
    """The ``(k, F)`` features, the ``(k,)`` mask and the candidate index of each row.

    Rows are the ``k`` candidates with the shortest paths, nearest first; when the robot's
    ``current_target`` (own cells) is near a candidate outside them, that candidate takes the
    last row. Empty rows have mask 0 and features 0 (index -1). With no candidate at all, row 0
    is the only valid choice and means *wait* (index -1, its ``valid`` feature 0).

    Args:
        cands: :meth:`GoalExecutor.propose`'s result.
        view: the robot's view (own or fused map, own pose).
        k: rows.
        current_target: the frontier cell the robot was heading for before this decision.
        claims: teammates' announced targets in this robot's cells (:func:`teammate_claims`).
        sensor_range_m: range of the claim discount (Burgard's, the lidar range).
    """
    f = len(FEATURE_NAMES)
    feats = np.zeros((k, f), dtype=np.float32)
    mask = np.zeros(k, dtype=np.int8)
    index = np.full(k, -1, dtype=np.int64)
    n = 0 if cands is None else len(cands)
    if n == 0 or cands is None:
        mask[0] = 1
        return feats, mask, index
    res = float(view.resolution_m)
    x, y, theta = _pose(view)
    order = np.argsort(cands.dist_m, kind="stable")
    rank_of = np.empty(n, dtype=np.int64)
    rank_of[order] = np.arange(n)
    tgt = cands.targets.astype(np.float64)
    cur = np.zeros(n, dtype=bool)
    if current_target is not None:
        d_cur = np.hypot(tgt[:, 0] - current_target[0], tgt[:, 1] - current_target[1]) * res
        cur = d_cur <= 1.0
    chosen = list(order[:k])
    if cur.any() and not cur[chosen].any():
        chosen[-1] = int(np.flatnonzero(cur)[np.argmin(cands.dist_m[cur])])
    sel = np.asarray(chosen, dtype=np.int64)
    m = sel.size
    s = FEATURE_SCALE_M
    dx, dy = tgt[sel, 0] - x, tgt[sel, 1] - y
    straight = np.hypot(dx, dy) * res
    bearing = np.arctan2(dy, dx) - theta
    heading = np.abs(np.arctan2(np.sin(bearing), np.cos(bearing)))
    cols = feats[:m]
    cols[:, _COL["valid"]] = 1.0
    cols[:, _COL["path_m"]] = cands.dist_m[sel] / s
    cols[:, _COL["straight_m"]] = straight / s
    cols[:, _COL["size_m"]] = cands.size_m[sel] / s
    cols[:, _COL["rank"]] = rank_of[sel] / k
    cols[:, _COL["path_rel"]] = cands.dist_m[sel] / max(float(cands.dist_m.max()), 1e-9)
    cols[:, _COL["heading_err"]] = heading / math.pi
    cols[:, _COL["is_current"]] = cur[sel]
    cols[:, _COL["merged"]] = float(view.merged)
    cols[:, _COL["time"]] = float(view.time_s) / 100.0
    cols[:, _COL["n_candidates"]] = n / k
    cols[:, _COL["total_size"]] = float(cands.size_m.sum()) / 20.0
    if claims is not None and len(claims):
        d = np.hypot(tgt[sel, None, 0] - claims[None, :, 0], tgt[sel, None, 1] - claims[None, :, 1])
        d_m = d * res
        cols[:, _COL["claim"]] = np.clip(1.0 - d_m / sensor_range_m, 0.0, None).sum(axis=1)
        cols[:, _COL["mate_target_m"]] = d_m.min(axis=1) / s
    else:
        cols[:, _COL["mate_target_m"]] = FAR
    if view.teammates:
        mates = np.array(list(view.teammates.values()), dtype=np.float64)
        dm = np.hypot(tgt[sel, None, 0] - mates[None, :, 0], tgt[sel, None, 1] - mates[None, :, 1])
        near = dm.min(axis=1) * res
        cols[:, _COL["mate_pos_m"]] = near / s
        cols[:, _COL["mate_path_adv"]] = (cands.dist_m[sel] - near) / s + 1.0
    else:
        cols[:, _COL["mate_pos_m"]] = FAR
        cols[:, _COL["mate_path_adv"]] = 0.0
    np.clip(feats, 0.0, FEATURE_MAX, out=feats)
    mask[:m] = 1
    index[:m] = sel
    return feats, mask, index


def gain_features(
    view: RobotView,
    cands: FrontierCandidates | None,
    index: NDArray[np.int64],
    sensor_range_m: float = 4.0,
) -> NDArray[np.float32]:
    """What each row's frontier may reveal: ``(k, 2)`` float32, columns
    :data:`GAIN_FEATURE_NAMES`.

    The share of unknown cells (value -1) of ``view.map`` in the axis-aligned squares of
    half-side :data:`GAIN_NEAR_M` and ``sensor_range_m`` around the candidate's target cell; the
    part of a square beyond the map's canvas counts as unknown. Frontier policies rank by
    path length and frontier size only; a frontier into a large unseen room and one into a
    closet look alike to them. Rows with ``index`` -1 (empty, or *wait*) are 0.

    Args:
        view: the robot's view (own or fused map, own cells).
        cands: the proposal the rows index into.
        index: ``(k,)`` candidate index per row (:func:`candidate_features`' third result).
        sensor_range_m: half-side of the far square, metres (the lidar range).
    """
    out = np.zeros((index.size, len(GAIN_FEATURE_NAMES)), dtype=np.float32)
    if cands is None:
        return out
    grid = view.map
    h, w = grid.shape
    res = float(view.resolution_m)
    for col_out, half_m in enumerate((GAIN_NEAR_M, sensor_range_m)):
        r = max(1, round(half_m / res))
        side = 2 * r + 1
        for row in np.flatnonzero(index >= 0):
            c, rr = (int(v) for v in cands.targets[index[row]])
            c0, c1, r0, r1 = max(c - r, 0), min(c + r + 1, w), max(rr - r, 0), min(rr + r + 1, h)
            inside = max(c1 - c0, 0) * max(r1 - r0, 0)
            unknown = side * side - inside  # off the canvas: never seen
            if inside:
                unknown += int(np.count_nonzero(grid[r0:r1, c0:c1] < 0))
            out[row, col_out] = unknown / (side * side)
    return out
