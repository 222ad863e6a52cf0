"""The simulation core: robots move on the true world, sense it, and map it in their own frames.

One step, in order (:meth:`Simulation.step`):

1. move every robot (true poses, :class:`mrexplore.robot.Motion`, collisions with walls);
2. odometry: each robot's pose *estimate* in its own start frame, drifting when odometry noise
   is enabled;
3. one lidar cast of all robots at once on the true world (:class:`mrexplore.sensors.Lidar`);
4. each robot's own map is updated with the scan at its *estimated* pose;
5. the ground-truth bookkeeping: which world cells each robot has observed (for coverage).

Canvas rule (:func:`canvas_for`): a robot does not know the world, so its map canvas must hold
any world seen from any start. Everything a robot senses lies inside the world, hence within
one world diagonal of its start: the canvas is a square of side ``2 * half + 1`` cells with the
start at the centre cell ``(half, half)``, ``half = ceil(diagonal / res) + 16`` (plus half a
diagonal when odometry noise is on, since the estimate may drift away from the truth), rounded
up to a multiple of 64 so that the canvas indices do not depend on the world's exact size.

All randomness comes from the Generator passed to :meth:`Simulation.reset` and
:meth:`Simulation.step`: the same seed and actions give the same poses, scans and maps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.errors import ConfigError
from mrexplore.grid import Transform
from mrexplore.mapping import L_FREE_DEFAULT, L_OCC_DEFAULT, MapStack, OccupancyMap
from mrexplore.options import is_number
from mrexplore.robot import (
    Motion,
    RobotConfig,
    largest_component,
    sample_start_poses,
    wrap_angle,
    wrap_angle_scalar,
)
from mrexplore.sensors import Lidar, LidarConfig, Scan
from mrexplore.truth import T_world_from_map, reachable_cspace, reachable_free
from mrexplore.truth import true_transform as _true_transform
from mrexplore.world.world import World

# The compiled sensing step (None without numba); used while mrexplore.kernels.enabled().
_sensing = kernels.load("sensing")

#: Extra cells around the world diagonal on each side of a robot's canvas.
CANVAS_MARGIN_CELLS: int = 16
#: The start cell (and half the canvas side) is rounded up to a multiple of this.
CANVAS_ALIGN_CELLS: int = 64


@dataclass(frozen=True)
class SimConfig:
    """Options of the simulation.

    Attributes:
        robot: body and motion (:class:`RobotConfig`).
        lidar: range sensor (:class:`LidarConfig`).
        aligned_headings: all robots start with heading 0 in the world (the paper's setting);
            else headings are uniform in (-pi, pi].
        odom_noise_trans: standard deviation of the odometry's translation error as a fraction
            of the distance moved (>= 0; 0.02 = 2 %).
        odom_noise_rot: standard deviation of the heading error in radians per radian turned
            (>= 0).
        odom_noise_rot_per_m: standard deviation of the heading error in radians per metre
            driven (>= 0): the small drift of a robot going straight.
        min_start_separation_m: robots start at least this far apart (>= 0).
        map_l_free, map_l_occ: the own maps' log-odds increments of a free and an occupied
            observation (:class:`~mrexplore.mapping.OccupancyMap`'s ``l_free``, ``l_occ``).
    """

    robot: RobotConfig = field(default_factory=RobotConfig)
    lidar: LidarConfig = field(default_factory=LidarConfig)
    aligned_headings: bool = True
    odom_noise_trans: float = 0.0
    odom_noise_rot: float = 0.0
    odom_noise_rot_per_m: float = 0.0
    min_start_separation_m: float = 0.0
    map_l_free: float = L_FREE_DEFAULT
    map_l_occ: float = L_OCC_DEFAULT

    def __post_init__(self) -> None:
        if not isinstance(self.robot, RobotConfig):
            raise ConfigError(
                f"SimConfig.robot must be a RobotConfig, got {type(self.robot).__name__}"
            )
        if not isinstance(self.lidar, LidarConfig):
            raise ConfigError(
                f"SimConfig.lidar must be a LidarConfig, got {type(self.lidar).__name__}"
            )
        for name in (
            "odom_noise_trans",
            "odom_noise_rot",
            "odom_noise_rot_per_m",
            "min_start_separation_m",
        ):
            v = getattr(self, name)
            if not (isinstance(v, (int, float)) and math.isfinite(v) and v >= 0.0):
                raise ConfigError(f"SimConfig.{name} must be a non-negative number, got {v!r}")
        lf, lo = self.map_l_free, self.map_l_occ
        if not (is_number(lf) and is_number(lo) and -5.0 <= lf < 0.0 < lo <= 5.0):
            raise ConfigError(
                "SimConfig.map_l_free and map_l_occ must be numbers with "
                f"-5 <= map_l_free < 0 < map_l_occ <= 5 (the maps' log-odds clamp), got "
                f"{lf!r} and {lo!r}"
            )

    @property
    def odometry_noisy(self) -> bool:
        """Whether any odometry noise is enabled."""
        return (
            self.odom_noise_trans > 0.0
            or self.odom_noise_rot > 0.0
            or self.odom_noise_rot_per_m > 0.0
        )


@dataclass(frozen=True, eq=False)
class StepInfo:
    """What happened in one step.

    Attributes:
        collided: bool (R,): a FORWARD was stopped by a wall.
        newly_observed: int64 (R,): world cells this robot observed for the first time.
    """

    collided: NDArray[np.bool_]
    newly_observed: NDArray[np.int64]


def canvas_for(
    world: World, map_resolution_m: float, noisy_odometry: bool = False
) -> tuple[tuple[int, int], tuple[int, int]]:
    """``((H, W), (c0, r0))``: a robot's canvas and the cell of its start (see the module doc)."""
    diag_m = math.hypot(*world.size_m)
    half = math.ceil(diag_m / map_resolution_m) + CANVAS_MARGIN_CELLS
    if noisy_odometry:
        half += math.ceil(0.5 * diag_m / map_resolution_m)
    # The start cell index is a multiple of CANVAS_ALIGN_CELLS, so whatever aligns on canvas
    # indices (round-half-to-even of a pose 2.5 cells away, 2**k pyramids) behaves the same for
    # every world size: the canvas must not leak the world's size into a robot's view.
    half = -(-half // CANVAS_ALIGN_CELLS) * CANVAS_ALIGN_CELLS
    side = 2 * half + 1
    return (side, side), (half, half)


class _Trail:
    """A growable (N, 2) float64 buffer of own-frame cells."""

    def __init__(self) -> None:
        self._buf = np.zeros((64, 2), dtype=np.float64)
        self._n = 0

    def append(self, col: float, row: float) -> None:
        if self._n == self._buf.shape[0]:
            self._buf = np.concatenate([self._buf, np.zeros_like(self._buf)])
        self._buf[self._n] = (col, row)
        self._n += 1

    def view(self) -> NDArray[np.float64]:
        out = self._buf[: self._n]
        out.flags.writeable = False
        return out


class Simulation:
    """R robots exploring one world, each mapping in its own frame.

    Args:
        world: the ground truth.
        n_robots: R >= 1.
        config: :class:`SimConfig`.

    Attributes (after :meth:`reset`):
        true_poses: float64 (R, 3) ``[x_m, y_m, theta]`` in world metres (truth).
        est_poses: float64 (R, 3) each robot's odometry estimate in its own start frame.
        start_poses: float64 (R, 3) true start poses (world metres).
        maps: one :class:`OccupancyMap` per robot, own frame, at the world's resolution.
        observed: bool (R, H, W) world cells each robot has observed (truth side).
        reachable: bool (H, W) world cells that count for coverage
            (:func:`mrexplore.truth.reachable_free` seeded at the starts).
        reachable_cspace: bool (H, W) cells the robots' centres can reach from their starts.
        reachable_cells: number of ``reachable`` cells.
        time_s, steps: simulated time (s) and steps since reset.
        last_scan: the last :class:`mrexplore.sensors.Scan` (for rendering beams).
    """

    def __init__(self, world: World, n_robots: int, config: SimConfig | None = None) -> None:
        if not isinstance(world, World):
            raise ConfigError(f"world must be a World, got {type(world).__name__}")
        if int(n_robots) != n_robots or n_robots < 1:
            raise ConfigError(f"n_robots must be a positive integer, got {n_robots}")
        self.world = world
        self.n_robots = int(n_robots)
        self.config = config if config is not None else SimConfig()
        self.motion = Motion(world, self.config.robot)
        self.lidar = Lidar(self.config.lidar)
        self._grid = self.lidar.prepare(world.walls)
        self.resolution_m = world.resolution_m
        self.canvas_shape, self.canvas_origin = canvas_for(
            world, self.resolution_m, self.config.odometry_noisy
        )
        self._free_cspace_main = largest_component(~self.motion.cspace)
        r, h, w = self.n_robots, *world.shape
        self.true_poses = np.zeros((r, 3))
        self.est_poses = np.zeros((r, 3))
        self.start_poses = np.zeros((r, 3))
        # cos / sin of the start headings, keyed by them (see _own_frame)
        self._start_key: bytes | None = None
        self._start_cs: tuple[list[float], list[float]] = ([], [])
        self.maps: list[OccupancyMap] = []
        self.observed = np.zeros((r, h, w), dtype=bool)
        self.reachable = np.zeros((h, w), dtype=bool)
        self.reachable_cspace = self._free_cspace_main
        self.reachable_cells = 0
        self.time_s = 0.0
        self.steps = 0
        self.last_scan: Scan | None = None
        self._team_observed = np.zeros((h, w), dtype=bool)
        self._team_covered = 0
        self._trails: list[_Trail] = []
        self._world_from_map: list[Transform | None] = [None] * self.n_robots

    def __getstate__(self) -> dict[str, Any]:
        # the maps carry their arrays; the stack they view is rebuilt on unpickling
        state = self.__dict__.copy()
        state.pop("_stack", None)
        return state

    def __setstate__(self, state: dict[str, Any]) -> None:
        self.__dict__.update(state)
        if self.maps:  # pickling copied each map's views apart from the stack: one stack again
            self._stack = MapStack.allocate(self.n_robots, *self.canvas_shape)
            for i, m in enumerate(self.maps):
                m.move_to(self._stack.row(i))

    # ------------------------------------------------------------------ lifecycle
    def reset(self, rng: np.random.Generator, starts: NDArray[np.floating] | None = None) -> None:
        """Place the robots (``starts`` (R, 3) world metres, or sampled from ``rng``, robot 0
        first), create their maps and take a first scan."""
        world = self.world
        if starts is None:
            poses = self.sample_starts(rng, self.n_robots)
        else:
            poses = np.array(starts, dtype=np.float64).reshape(-1, 3)
            if poses.shape[0] != self.n_robots or not np.isfinite(poses).all():
                raise ConfigError(
                    f"starts must be a finite ({self.n_robots}, 3) array, "
                    f"got shape {np.shape(starts)}"
                )
            free = self.motion.is_free(poses[:, :2])
            if not free.all():
                bad = int(np.flatnonzero(~free)[0])
                raise ConfigError(
                    f"start of robot {bad} {poses[bad].tolist()} is in collision with a wall"
                )
            poses[:, 2] = wrap_angle(poses[:, 2])
        self.start_poses = poses.copy()
        self._world_from_map = [None] * self.n_robots
        self.true_poses = poses.copy()
        self.est_poses = np.zeros_like(poses)
        # drift a placement erased from the estimate but not from the map (drift_allowance_at)
        self._placed_drift = np.zeros((self.n_robots, 2))
        # one stack for the team's maps: the compiled sensing step updates them in one call
        self._stack = MapStack.allocate(self.n_robots, *self.canvas_shape)
        self.maps = [
            OccupancyMap(
                self.canvas_shape,
                self.resolution_m,
                self.canvas_origin,
                l_free=self.config.map_l_free,
                l_occ=self.config.map_l_occ,
                rows=self._stack.row(i),
            )
            for i in range(self.n_robots)
        ]
        seeds = self.motion.cell_index(poses[:, :2])
        self.reachable_cspace = reachable_cspace(world, self.config.robot.radius_m, seeds)
        self.reachable = reachable_free(world, self.config.robot.radius_m, seeds)
        self.reachable_cells = int(np.count_nonzero(self.reachable))
        self.observed[:] = False
        self._team_observed[:] = False
        self._team_covered = 0
        self.time_s = 0.0
        self.steps = 0
        self._trails = [_Trail() for _ in range(self.n_robots)]
        self._sense(rng)

    def sample_starts(self, rng: np.random.Generator, n: int) -> NDArray[np.float64]:
        """Start poses (n, 3) world metres as :meth:`reset` draws them; robot k's start does not
        depend on n (robots are drawn in order)."""
        return sample_start_poses(
            self.world,
            n,
            rng,
            self.config.robot.radius_m,
            aligned=self.config.aligned_headings,
            min_separation_m=self.config.min_start_separation_m,
            reachable=self._free_cspace_main,
        )

    def step(self, actions: NDArray[np.integer], rng: np.random.Generator) -> StepInfo:
        """Advance one step of ``dt_s``: move, odometry, sense, map (see the module doc)."""
        if not self.maps:
            raise RuntimeError("Simulation.step() called before reset()")
        act = np.asarray(actions).reshape(-1)
        if act.shape[0] != self.n_robots:
            raise ConfigError(f"expected {self.n_robots} actions, got {act.shape[0]}")
        old = self.true_poses
        new, collided = self.motion.step(old, act)
        self._odometry(old, new, rng)
        self.true_poses = new
        newly = self._sense(rng)
        self.time_s += self.config.robot.dt_s
        self.steps += 1
        return StepInfo(collided=collided, newly_observed=newly)

    # ------------------------------------------------------------------ step parts
    def _odometry(
        self, old: NDArray[np.float64], new: NDArray[np.float64], rng: np.random.Generator
    ) -> None:
        """Update ``est_poses`` from the true motion of this step (with drift noise if enabled)."""
        cfg = self.config
        if not cfg.odometry_noisy:
            # Exact: the true pose seen from the start pose (no rounding drift over long runs).
            self.est_poses = self._own_frame(new)
            return
        dist = np.hypot(new[:, 0] - old[:, 0], new[:, 1] - old[:, 1])
        dth = wrap_angle(new[:, 2] - old[:, 2])
        n = self.n_robots
        dist_meas = dist * (1.0 + cfg.odom_noise_trans * rng.standard_normal(n))
        rot_std = cfg.odom_noise_rot * np.abs(dth) + cfg.odom_noise_rot_per_m * dist
        dth_meas = dth + rot_std * rng.standard_normal(n)
        est = self.est_poses.copy()
        # A step is a turn or a straight move: translate along the current estimate, then turn.
        est[:, 0] += dist_meas * np.cos(est[:, 2])
        est[:, 1] += dist_meas * np.sin(est[:, 2])
        est[:, 2] = wrap_angle(est[:, 2] + dth_meas)
        self.est_poses = est

    def drift_allowance(self, i: int, j: int, cells_j: NDArray[np.float64]) -> float:
        """How far (cells, mean over j's map cells ``cells_j`` (N, 2) ``(col, row)``) odometry
        drift alone can move a correct merge of j's map into i's away from the start-frame truth:
        both robots' position drift plus their heading drift times the mean distance of the cells
        from j's start. 0 with exact odometry (evaluation only)."""
        return self.drift_allowance_at(i, j, self.drift_radius(j, cells_j))

    def drift_radius(self, j: int, cells_j: NDArray[np.float64]) -> float:
        """The mean distance (cells) of j's map cells ``cells_j`` (N, 2) ``(col, row)`` from
        j's start (0 without cells): the lever arm of heading drift (evaluation only)."""
        origin = np.asarray(self.maps[j].origin_cell, dtype=np.float64)
        cells = np.asarray(cells_j, dtype=np.float64).reshape(-1, 2)
        return float(np.linalg.norm(cells - origin, axis=1).mean()) if len(cells) else 0.0

    def drift_allowance_at(self, i: int, j: int, radius: float) -> float:
        """:meth:`drift_allowance` for cells at mean distance ``radius`` (cells) from j's start
        (``maps[j].origin_cell``); evaluation only. The drift a :meth:`place` erased from a
        robot's estimate is added: its map still holds it."""
        pos, hdg = self._pose_drift()
        pos = pos + self._placed_drift[:, 0]
        hdg = hdg + self._placed_drift[:, 1]
        return float(pos[i] + pos[j] + (hdg[i] + hdg[j]) * radius)

    def _pose_drift(self) -> NDArray[np.float64]:
        """(2, R): each robot's position drift (cells) and heading drift (rad) now."""
        own = self.own_frame_truth()
        pos = np.hypot(*(self.est_poses[:, :2] - own[:, :2]).T) / self.resolution_m
        hdg = np.abs(np.angle(np.exp(1j * (self.est_poses[:, 2] - own[:, 2]))))
        return np.stack([pos, hdg])

    def own_frame_truth(self) -> NDArray[np.float64]:
        """The robots' true poses (R, 3) in their own start frames: what ``est_poses`` would be
        with exact odometry (evaluation only)."""
        return self._own_frame(self.true_poses)

    def _own_frame(self, poses: NDArray[np.float64]) -> NDArray[np.float64]:
        """True world poses (R, 3) -> each robot's own start frame (R, 3): metres, radians."""
        s = self.start_poses
        # cos / sin of the start headings by numpy (its SIMD results, not libm's), once per set
        # of start headings; the rest per robot in float math: the same IEEE operations as the
        # elementwise numpy expressions, without their per-call overhead on R-element arrays.
        key = s[:, 2].tobytes()  # bit for bit (-0.0 is not 0.0 here)
        if key != self._start_key:
            self._start_key = key
            self._start_cs = (np.cos(s[:, 2]).tolist(), np.sin(s[:, 2]).tolist())
        cs, sn = self._start_cs
        out = np.empty_like(poses)
        for i, (px, py, pth) in enumerate(poses.tolist()):
            sx, sy, sth = s[i].tolist()
            dx, dy = px - sx, py - sy
            c, si = cs[i], sn[i]
            out[i, 0] = c * dx + si * dy
            out[i, 1] = -si * dx + c * dy
            out[i, 2] = wrap_angle_scalar(pth - sth)
        return out

    def _sense(self, rng: np.random.Generator) -> NDArray[np.int64]:
        """Cast all robots on the truth, mark the observed cells, update the own maps.

        One call casts every beam of every robot and marks ``observed`` / the team's cells
        (:meth:`mrexplore.sensors.Lidar.cast_observe`, incremental coverage); then one map
        update per robot at its *estimated* pose.
        """
        if kernels.enabled():
            scan, newly, covered = self._sense_compiled(rng)
        else:
            scan, newly, covered = self.cast(rng)
            for i in range(self.n_robots):
                self.integrate(i, scan)
        for i, (x, y, _) in enumerate(self.est_poses.tolist()):  # where each scan was mapped
            self._trails[i].append(*self.maps[i].cell_of(x, y))
        self.last_scan = scan
        self._team_covered += covered
        return newly

    def _sense_compiled(self, rng: np.random.Generator) -> tuple[Scan, NDArray[np.int64], int]:
        """:meth:`cast` and every robot's :meth:`integrate` in one compiled call
        (:func:`mrexplore.kernels.sensing.sense_world`), with the same results bit for bit;
        the trig and the range noise are drawn here by numpy, in the same order."""
        assert _sensing is not None
        lidar, grid, n = self.lidar, self._grid, self.n_robots
        poses = self.true_poses
        corner = lidar.corners_of(grid, poses, self.world)
        cast_args = lidar.kernel_args(corner, poses[:, 2], self.resolution_m, rng)
        n_b = lidar.angles.shape[0]
        sensors = np.empty((n, 2))
        dx = np.empty((n, n_b))
        dy = np.empty((n, n_b))
        scan_ids = np.empty(n, dtype=np.int64)
        for i, (m, (x, y, th)) in enumerate(zip(self.maps, self.est_poses.tolist(), strict=True)):
            sensors[i] = m.sensor_corner(x, y)
            dx[i], dy[i] = m.beam_directions(th, lidar.angles)
            scan_ids[i] = m.next_scan_id()
        ranges = np.empty((n, n_b), dtype=np.float32)
        hit = np.empty((n, n_b), dtype=np.bool_)
        newly = np.zeros(n, dtype=np.int64)
        h, w = grid.shape
        stack = self._stack
        covered = _sensing.sense_world(
            grid.table,
            h + 2,
            w + 2,
            *cast_args,
            ranges,
            hit,
            self.observed.reshape(n, h * w),
            np.ascontiguousarray(self.reachable).reshape(-1),
            self._team_observed.reshape(-1),
            newly,
            stack.logodds,
            stack.int8,
            stack.stamp,
            scan_ids,
            *self.canvas_shape,
            sensors,
            dx,
            dy,
            *self.maps[0].kernel_constants(),
            stack.bbox,
            stack.changed,
            stack.cells,
        )
        for m in self.maps:
            m.note_change()
        return Scan(ranges_m=ranges, hit=hit, angles=lidar.angles), newly, int(covered)

    def cast(self, rng: np.random.Generator) -> tuple[Scan, NDArray[np.int64], int]:
        """Every robot's lidar cast on the truth, ``observed`` and the team's cells marked:
        (scan, newly observed cells per robot (R,), reachable cells the team saw first)."""
        scan, newly, covered = self.lidar.cast_observe(
            self._grid,
            self.world.cell_of(self.true_poses[:, :2]),
            self.true_poses[:, 2],
            self.resolution_m,
            rng,
            self.observed,
            self.reachable,
            self._team_observed,
        )
        return scan, newly, covered

    def integrate(self, i: int, scan: Scan) -> tuple[float, float]:
        """Robot ``i``'s own-map update with its beams of ``scan`` at its *estimated* pose;
        returns that pose's (x, y), metres."""
        x, y, th = (float(v) for v in self.est_poses[i])
        self.maps[i].integrate_trusted(x, y, th, scan.angles, scan.ranges_m[i], scan.hit[i])
        return x, y

    # ------------------------------------------------------------------ queries
    def place(self, i: int, pose_world: NDArray[np.float64]) -> None:
        """Put robot ``i`` at ``pose_world`` (x_m, y_m, theta) and tell it where it is (its own
        estimate becomes exact). An experimental protocol step (e.g. "navigate from the start
        again"), not a motion: nothing is sensed on the way."""
        pose = np.asarray(pose_world, dtype=np.float64).reshape(3)
        if not self.motion.is_free(pose[None, :2])[0]:
            raise ConfigError(f"cannot place robot {i} at {pose.tolist()}: not free for its body")
        # the map keeps the drift it was built with: the merge-error allowance keeps it too
        self._placed_drift[i] += self._pose_drift()[:, i]
        self.true_poses = self.true_poses.copy()
        self.true_poses[i] = pose
        self.est_poses = self.est_poses.copy()
        self.est_poses[i] = self._own_frame(self.true_poses)[i]

    def pose_cell(self, i: int) -> tuple[float, float, float]:
        """Robot ``i``'s estimated pose in its own map cells: ``(col, row, theta_rad)``."""
        x, y, th = self.est_poses[i]
        c, r = self.maps[i].cell_of(float(x), float(y))
        return (float(c), float(r), float(th))

    def trail_cells(self, i: int) -> NDArray[np.float64]:
        """Read-only (N, 2) own-frame cells ``(col, row)`` of robot ``i``'s estimated path."""
        return self._trails[i].view()

    @property
    def trails(self) -> list[NDArray[np.float64]]:
        """Every robot's :meth:`trail_cells`."""
        return [t.view() for t in self._trails]

    def world_from_map(self, i: int) -> Transform:
        """3x3 transform from robot ``i``'s map cells to world cells (truth)."""
        # Fixed for an episode (start pose and canvas): computed once per reset (the env's
        # map-accuracy infos ask for it every step).
        T = self._world_from_map[i]
        if T is None:
            T = T_world_from_map(
                self.start_poses[i], self.maps[i].origin_cell, self.resolution_m, self.world
            )
            self._world_from_map[i] = T
        return T.copy()

    def true_transform(self, a: int, b: int) -> Transform:
        """``T_ab``: robot b's map cells -> robot a's map cells (truth)."""
        return _true_transform(
            self.start_poses[a],
            self.maps[a].origin_cell,
            self.start_poses[b],
            self.maps[b].origin_cell,
            self.world,
            self.resolution_m,
        )

    def coverage(self, robots: list[int] | None = None) -> float:
        """Share of the reachable cells observed by the team (or by ``robots``), in [0, 1]."""
        if self.reachable_cells == 0:
            return 0.0
        if robots is None:
            return self._team_covered / self.reachable_cells
        seen = self.observed[list(robots)].any(axis=0)
        return float(np.count_nonzero(seen & self.reachable)) / self.reachable_cells
