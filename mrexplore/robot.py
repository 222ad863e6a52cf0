"""Robots: discrete actions, a disc-shaped body, motion with collisions, start poses.

A robot is a disc of radius ``radius_m`` moving on the ground-truth grid. Poses are
``(x_m, y_m, theta_rad)`` in world metres (the frame of :class:`mrexplore.world.World`), theta
from +x towards +y, wrapped to (-pi, pi].

Collisions are checked against the *configuration space*: the walls dilated once by the robot's
radius (a disc kernel), so the robot's centre may stand on any free C-space cell. Cells outside
the grid are walls. Robots do not collide with each other (they may overlap): the paper's
robots avoid each other with their local planners, and checking pairs would make motion
order-dependent for no gain in a coverage study.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from enum import IntEnum

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.errors import ConfigError, WorldError
from mrexplore.traversal import SNAP_CELLS, snap
from mrexplore.world.world import World

# The compiled motion (None without numba); used while mrexplore.kernels.enabled().
_sensing = kernels.load("sensing")


class Action(IntEnum):
    """The discrete actions of every robot."""

    FORWARD = 0
    TURN_LEFT = 1
    TURN_RIGHT = 2
    STAY = 3


# The actions as plain ints: compared every step, where an enum member's lookup costs more.
_FORWARD, _TURN_LEFT, _TURN_RIGHT, _STAY = (int(a) for a in Action)


@dataclass(frozen=True)
class RobotConfig:
    """Body and motion of a robot.

    With the defaults one step lasts 0.25 s: FORWARD moves 0.125 m (2.5 cells at 0.05 m/cell)
    and a turn changes the heading by 22.5 degrees (16 turns make a full circle).

    Attributes:
        radius_m: body radius in metres (> 0).
        speed_mps: forward speed in metres per second (> 0).
        turn_rate_rps: turn rate in radians per second (> 0).
        dt_s: duration of one step in seconds (> 0).
    """

    radius_m: float = 0.15
    speed_mps: float = 0.5
    turn_rate_rps: float = math.pi / 2.0
    dt_s: float = 0.25

    def __post_init__(self) -> None:
        for name in ("radius_m", "speed_mps", "turn_rate_rps", "dt_s"):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v > 0.0):
                raise ConfigError(f"RobotConfig.{name} must be a positive number, got {v!r}")

    @property
    def step_m(self) -> float:
        """Distance of one FORWARD step, metres."""
        return self.speed_mps * self.dt_s

    @property
    def turn_rad(self) -> float:
        """Heading change of one turn step, radians."""
        return self.turn_rate_rps * self.dt_s


def wrap_angle(theta: NDArray[np.floating] | float) -> NDArray[np.float64]:
    """Wrap angles (radians) to (-pi, pi]."""
    t = np.asarray(theta, dtype=np.float64)
    w = np.mod(t + math.pi, 2.0 * math.pi) - math.pi
    return np.where(w <= -math.pi, w + 2.0 * math.pi, w)


def wrap_angle_scalar(theta: float) -> float:
    """:func:`wrap_angle` of one angle (radians) with plain float math, to the same bits.

    Python's float ``%`` is numpy's ``np.mod`` (``fmod``, then the divisor's sign), and the
    other steps are the same IEEE operations in the same order; a 0-d numpy call costs ~5 us,
    this ~0.2 us (the simulator wraps one heading per turning robot per step).
    """
    w = (theta + math.pi) % (2.0 * math.pi) - math.pi
    return w + 2.0 * math.pi if w <= -math.pi else w


def disc_kernel(radius_cells: float) -> NDArray[np.uint8]:
    """uint8 square kernel with ones on the cells whose centre is within ``radius_cells``."""
    n = math.floor(radius_cells)
    yy, xx = np.mgrid[-n : n + 1, -n : n + 1]
    return (np.hypot(xx, yy) <= radius_cells + 1e-9).astype(np.uint8)


def configuration_space(walls: NDArray[np.bool_], radius_cells: float) -> NDArray[np.bool_]:
    """Blocked cells for the centre of a disc robot: ``walls`` dilated by a disc of
    ``radius_cells`` (cells whose centre lies within the radius of a wall cell's centre).
    Cells outside the grid count as walls (the border is dilated inwards too)."""
    pad = math.floor(radius_cells) + 1
    padded = cv2.copyMakeBorder(
        walls.astype(np.uint8), pad, pad, pad, pad, cv2.BORDER_CONSTANT, value=1
    )
    dil = cv2.dilate(padded, disc_kernel(radius_cells))
    return dil[pad:-pad, pad:-pad].astype(bool)


def largest_component(free: NDArray[np.bool_]) -> NDArray[np.bool_]:
    """The largest 4-connected component of ``free`` (bool (H, W)); all False if none."""
    n, labels = cv2.connectedComponents(free.astype(np.uint8), connectivity=4)
    if n <= 1:
        return np.zeros_like(free)
    counts = np.bincount(labels.ravel(), minlength=n)
    counts[0] = 0
    return np.asarray(labels == int(np.argmax(counts)))


class Motion:
    """Moves robots on one world with collision checking (vectorised over robots).

    Args:
        world: the ground truth.
        config: the robots' body and motion.

    The configuration space is computed once here: ``cspace`` is bool (H, W), True where a
    robot's centre may not be.
    """

    def __init__(self, world: World, config: RobotConfig | None = None) -> None:
        self.world = world
        self.config = config if config is not None else RobotConfig()
        self.radius_cells = self.config.radius_m / world.resolution_m
        #: bool (H, W): cells the robot's centre cannot occupy.
        self.cspace = configuration_space(world.walls, self.radius_cells)
        h, w = world.shape
        self._blocked = np.ones((h + 2, w + 2), dtype=bool)  # padded: outside = blocked
        self._blocked[1:-1, 1:-1] = self.cspace
        step_cells = self.config.step_m / world.resolution_m
        # Sub-steps of at most half a cell: a straight move then never skips a cell.
        self._n_sub = max(1, math.ceil(step_cells / 0.5))
        # Distance (m) of each sub-step from the start, 0 .. step_m.
        self._dist = self.config.step_m * (
            np.arange(self._n_sub + 1, dtype=np.float64) / self._n_sub
        )

    def cell_index(self, xy_m: NDArray[np.floating]) -> NDArray[np.int64]:
        """World metres (..., 2) -> integer cells (..., 2) as (col, row) (rounded centres)."""
        xy = np.asarray(xy_m, dtype=np.float64)
        res = self.world.resolution_m
        org = np.asarray(self.world.origin_m)
        # Snapped first: positions on a cell boundary must not flip with rounding noise.
        return np.floor(snap((xy - org) / res)).astype(np.int64)

    def is_free(self, xy_m: NDArray[np.floating]) -> NDArray[np.bool_]:
        """Whether robot centres at world metres (..., 2) are collision-free."""
        cr = self.cell_index(xy_m)
        return ~self._blocked[
            cr[..., 1].clip(-1, self.world.shape[0]) + 1,
            cr[..., 0].clip(-1, self.world.shape[1]) + 1,
        ]

    def step(
        self, poses: NDArray[np.floating], actions: NDArray[np.integer]
    ) -> tuple[NDArray[np.float64], NDArray[np.bool_]]:
        """Apply one action per robot.

        Args:
            poses: (R, 3) float64 ``[x_m, y_m, theta_rad]`` in world metres.
            actions: (R,) ints, values of :class:`Action`.

        Returns:
            ``(new_poses (R, 3), collided (R,) bool)``. Turns change theta only. FORWARD moves
            along theta in sub-steps of at most half a cell and stops at the last sub-step
            whose cell is free in C-space; when a sub-step changes both row and column, the two
            axis-aligned neighbour cells must be free too, so a robot never squeezes through a
            diagonal gap between cells that touch at a corner. ``collided`` is True when a
            FORWARD was cut short.
        """
        p = np.array(poses, dtype=np.float64, copy=True).reshape(-1, 3)
        a = np.asarray(actions).reshape(-1)
        if a.shape[0] != p.shape[0]:
            raise ConfigError(f"got {p.shape[0]} poses but {a.shape[0]} actions")
        # Per robot in plain Python (a handful of robots: numpy's per-call overhead on 0-d and
        # 1-element arrays was most of this function).
        acts = a.tolist()
        if acts and (min(acts) < 0 or max(acts) > _STAY):
            raise ConfigError(f"actions must be in 0..{int(Action.STAY)}, got {acts}")
        turn = self.config.turn_rad
        # Only turning robots are wrapped: the others keep their heading bit for bit.
        for j, act in enumerate(acts):
            if act == _TURN_LEFT:
                p[j, 2] = wrap_angle_scalar(float(p[j, 2]) + turn)
            elif act == _TURN_RIGHT:
                p[j, 2] = wrap_angle_scalar(float(p[j, 2]) - turn)
        collided = np.zeros(p.shape[0], dtype=bool)
        fwd = np.flatnonzero(a == _FORWARD)
        if fwd.size == 0:
            return p, collided
        if kernels.enabled():
            assert _sensing is not None
            # The same sub-steps and checks, compiled: numpy's per-call overhead on a handful
            # of robots was ~0.2 ms per step.
            th = p[fwd, 2]
            nx = np.empty(fwd.size)
            ny = np.empty(fwd.size)
            last_ok = _sensing.motion_forward(
                self._blocked,
                p[fwd, 0],
                p[fwd, 1],
                np.cos(th),
                np.sin(th),
                self._dist,
                float(self.world.origin_m[0]),
                float(self.world.origin_m[1]),
                float(self.world.resolution_m),
                SNAP_CELLS,
                nx,
                ny,
            )
            p[fwd, 0] = nx
            p[fwd, 1] = ny
            collided[fwd] = last_ok < self._n_sub
            return p, collided
        h, w = self.world.shape
        dist = self._dist  # (S+1,)
        th = p[fwd, 2]
        xs = p[fwd, 0, None] + np.cos(th)[:, None] * dist[None, :]
        ys = p[fwd, 1, None] + np.sin(th)[:, None] * dist[None, :]
        cells = self.cell_index(np.stack([xs, ys], axis=-1))  # (F, S+1, 2)
        col = cells[..., 0].clip(-1, w) + 1
        row = cells[..., 1].clip(-1, h) + 1
        blk = self._blocked
        bad = blk[row, col]
        # Between consecutive sub-steps: both axis-aligned cells must be free when the move
        # changes row and column at once (they equal the endpoints otherwise).
        bad[:, 1:] |= blk[row[:, :-1], col[:, 1:]] | blk[row[:, 1:], col[:, :-1]]
        # Sub-step 0 is the current pose; a robot already in collision may still turn but not move.
        ok_prefix = np.cumprod(~bad, axis=1).astype(bool)
        last_ok = ok_prefix.sum(axis=1) - 1  # -1: start cell blocked
        stay = last_ok < 0
        last = np.maximum(last_ok, 0)
        rows_i = np.arange(fwd.size)
        p[fwd, 0] = np.where(stay, p[fwd, 0], xs[rows_i, last])
        p[fwd, 1] = np.where(stay, p[fwd, 1], ys[rows_i, last])
        collided[fwd] = last_ok < self._n_sub
        return p, collided


def sample_start_poses(
    world: World,
    n: int,
    rng: np.random.Generator,
    radius_m: float,
    aligned: bool = True,
    min_separation_m: float = 0.0,
    reachable: NDArray[np.bool_] | None = None,
) -> NDArray[np.float64]:
    """Sample ``n`` start poses ``(n, 3)`` ``[x_m, y_m, theta]`` at free C-space cell centres.

    Cells are drawn uniformly from ``reachable`` (default: the largest 4-connected free
    component of the configuration space, so every start can reach every other). Robots are
    drawn one after the other, robot 0 first, each taking its cell and then (when not
    ``aligned``) its heading from ``rng``: robot 0's start therefore does not depend on ``n``.
    ``aligned`` gives every robot heading 0 (the paper's setting); otherwise headings are
    uniform in (-pi, pi]. Later robots keep at least ``min_separation_m`` from earlier ones.
    """
    if int(n) != n or n < 1:
        raise ConfigError(f"number of robots must be a positive integer, got {n}")
    if not (math.isfinite(min_separation_m) and min_separation_m >= 0.0):
        raise ConfigError(f"min_separation_m must be >= 0, got {min_separation_m}")
    res = world.resolution_m
    if reachable is None:
        reachable = largest_component(~configuration_space(world.walls, radius_m / res))
    elif reachable.shape != world.shape or reachable.dtype != np.bool_:
        raise ConfigError(f"reachable must be a bool array of shape {world.shape}")
    rows, cols = np.nonzero(reachable)
    if rows.size == 0:
        raise WorldError(
            f"world '{world.name}' has no free cell for a robot of radius {radius_m} m"
        )
    centres = world.xy_of(np.stack([cols, rows], axis=1).astype(np.float64))  # (M, 2) metres
    poses = np.zeros((int(n), 3), dtype=np.float64)
    allowed = np.ones(rows.size, dtype=bool)
    for i in range(int(n)):
        pool = np.flatnonzero(allowed)
        if pool.size == 0:
            raise WorldError(
                f"cannot place robot {i} at least {min_separation_m} m from the others in "
                f"world '{world.name}'"
            )
        k = int(pool[int(rng.integers(pool.size))])
        poses[i, :2] = centres[k]
        if not aligned:
            # uniform in (-pi, pi]: 1 - U is in (0, 1]
            poses[i, 2] = math.pi - 2.0 * math.pi * float(rng.random())
        if min_separation_m > 0.0:
            allowed &= np.hypot(*(centres - centres[k]).T) >= min_separation_m
    return poses
