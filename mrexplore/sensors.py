"""A 2-D range sensor (lidar) on an occupancy grid, cast with the exact traversal of
:mod:`mrexplore.traversal` (its geometry and corner rule are described there).

Cells outside the grid count as walls: a beam leaving the grid stops at the border.

Two implementations: the compiled per-beam kernels of :mod:`mrexplore.kernels.sensing` (used
while :func:`mrexplore.kernels.enabled`, the default) and the vectorised numpy traversal (the
path with the kernels off, and an oracle of the tests). They evaluate the same float64
formulas, so they agree to the bit with ``Lidar.dtype = numpy.float64``;
:func:`cast_ray_reference` (one ray, cell by cell) is the slow, obvious oracle of both.
"""

from __future__ import annotations

import itertools
import math
import sys
import types
import warnings
from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.errors import ConfigError, GridError
from mrexplore.traversal import (
    CORNER_EPS,
    SNAP_CELLS,
    PaddedGrid,
    Traversal,
    prepare_walls,
    snap,
    traverse,
)

if TYPE_CHECKING:
    from mrexplore.world import World

# The compiled cast (None without numba); used while mrexplore.kernels.enabled().
_sensing = kernels.load("sensing")

#: Crossing slots (per line family) of the first slice of a cast. Beams are traversed in two
#: slices: most indoor beams meet a wall within the first one and drop out, so the second
#: (up to the maximum range) only runs on the long beams. See ``mrexplore bench sensor``.
FIRST_SLICE_SLOTS: int = 40


@dataclass(frozen=True)
class LidarConfig:
    """Options of the range sensor.

    Attributes:
        n_beams: number of beams (>= 1).
        fov_rad: field of view in radians, in (0, 2 pi]. A full circle spaces the beams by
            ``2 pi / n_beams`` starting at ``-pi`` (ROS ``angle_min``); a smaller field of view
            spans ``[-fov/2, +fov/2]`` with both ends included.
        max_range_m: maximum range in metres (> 0). A beam that meets no wall within it
            reports ``max_range_m`` and ``hit = False``.
        noise_std_m: standard deviation in metres of the Gaussian noise added to the ranges of
            beams that hit (>= 0); only applied when a generator is passed to ``cast``.
    """

    n_beams: int = 360
    fov_rad: float = 2.0 * math.pi
    max_range_m: float = 4.0
    noise_std_m: float = 0.01

    def __post_init__(self) -> None:
        if int(self.n_beams) != self.n_beams or self.n_beams < 1:
            raise ConfigError(f"LidarConfig.n_beams must be a positive integer, got {self.n_beams}")
        if not (0.0 < self.fov_rad <= 2.0 * math.pi + 1e-12):
            raise ConfigError(f"LidarConfig.fov_rad must be in (0, 2 pi], got {self.fov_rad}")
        if not (math.isfinite(self.max_range_m) and self.max_range_m > 0.0):
            raise ConfigError(
                f"LidarConfig.max_range_m must be a positive number, got {self.max_range_m}"
            )
        if not (math.isfinite(self.noise_std_m) and self.noise_std_m >= 0.0):
            raise ConfigError(
                f"LidarConfig.noise_std_m must be a non-negative number, got {self.noise_std_m}"
            )


@dataclass(frozen=True, eq=False)
class Scan:
    """One scan of R robots with B beams each.

    Attributes:
        ranges_m: float32 (R, B): distance in metres from the sensor to the boundary of the first
            wall cell along each beam, capped at the maximum range; noisy when a generator was
            passed.
        hit: bool (R, B): a wall lies within the maximum range along the beam.
        angles: float64 (B,): beam angles in radians relative to the robot's heading.
        visible_flat: when requested, one int64 array per robot of flat indices into
            ``walls.ravel()`` of the cells its beams passed through (free cells before the hit,
            and the hit cell itself; noise-free; duplicates possible). Else None.
    """

    ranges_m: NDArray[np.float32]
    hit: NDArray[np.bool_]
    angles: NDArray[np.float64]
    visible_flat: tuple[NDArray[np.int64], ...] | None = None


def _beam_angles(cfg: LidarConfig) -> NDArray[np.float64]:
    """Beam angles (B,) relative to the heading, radians (see :class:`LidarConfig`)."""
    if cfg.fov_rad >= 2.0 * math.pi - 1e-12:
        return -math.pi + np.arange(cfg.n_beams, dtype=np.float64) * (2.0 * math.pi / cfg.n_beams)
    if cfg.n_beams == 1:
        return np.zeros(1, dtype=np.float64)
    return np.linspace(-cfg.fov_rad / 2.0, cfg.fov_rad / 2.0, cfg.n_beams, dtype=np.float64)


class Lidar:
    """A 2-D lidar: casts all beams of all robots at once on a wall grid.

    >>> import numpy as np
    >>> walls = np.zeros((5, 9), dtype=bool); walls[:, 8] = True
    >>> lidar = Lidar(LidarConfig(n_beams=4, max_range_m=10.0, noise_std_m=0.0))
    >>> scan = lidar.cast(walls, np.array([[2.0, 2.0]]), np.array([0.0]), resolution_m=1.0)
    >>> float(scan.ranges_m[0, 2])  # beam straight ahead: from the centre of col 2 to col 8
    5.5
    """

    def __init__(self, config: LidarConfig | None = None) -> None:
        self.config = config if config is not None else LidarConfig()
        #: float64 (B,): beam angles relative to the heading, radians.
        self.angles = _beam_angles(self.config)
        self._cos = np.cos(self.angles)
        self._sin = np.sin(self.angles)
        #: Float type of the per-slot positions (see :func:`traverse`).
        self.dtype: type[np.floating] = np.float32

    @staticmethod
    def prepare(walls: NDArray[np.bool_]) -> PaddedGrid:
        """Prepare a wall grid once for many casts (saves an O(H W) pad per cast)."""
        return prepare_walls(walls)

    def directions(self, headings: NDArray[np.floating]) -> NDArray[np.float64]:
        """Unit beam directions (R * B, 2) as (dcol, drow) for headings (R,) radians."""
        h = np.asarray(headings, dtype=np.float64).reshape(-1, 1)
        ch, sh = np.cos(h), np.sin(h)
        dx = ch * self._cos - sh * self._sin
        dy = sh * self._cos + ch * self._sin
        return np.stack([dx.ravel(), dy.ravel()], axis=1)

    def cast(
        self,
        walls: NDArray[np.bool_] | PaddedGrid,
        origins_cells: NDArray[np.floating],
        headings: NDArray[np.floating],
        resolution_m: float,
        rng: np.random.Generator | None = None,
        want_visible: bool = False,
    ) -> Scan:
        """Cast every beam of R robots.

        Args:
            walls: bool (H, W) wall grid (True = wall), or a :class:`PaddedGrid` from
                :meth:`prepare` (faster when casting on the same grid many times).
            origins_cells: (R, 2) sensor positions as continuous ``(col, row)`` cells (cell
                centres are integers); each must lie inside the grid.
            headings: (R,) headings in radians (from +col towards +row).
            resolution_m: metres per cell (> 0).
            rng: when given, Gaussian noise N(0, noise_std_m) is added to the ranges of beams
                that hit, clipped to [0, max_range_m].
            want_visible: also return the cells each robot's beams passed through
                (:attr:`Scan.visible_flat`, noise-free), for coverage.
        """
        grid = walls if isinstance(walls, PaddedGrid) else prepare_walls(walls)
        if not (math.isfinite(resolution_m) and resolution_m > 0.0):
            raise GridError(f"resolution_m must be a positive number, got {resolution_m}")
        corner, hd = self.check_origins(grid, origins_cells, headings)
        n_rob = corner.shape[0]
        if kernels.enabled():
            return self._cast_numba(grid, corner, hd, resolution_m, rng, want_visible)
        n_b = self.angles.shape[0]
        max_cells = self.config.max_range_m / resolution_m
        dirs = self.directions(hd)
        origins = np.repeat(corner, n_b, axis=0)
        n = origins.shape[0]
        best = np.full(n, np.inf)
        # A sensor inside a wall cell sees nothing: range 0.
        oc = np.floor(corner).astype(np.int64)
        origin_wall = grid.table[(oc[:, 1] + 1) * grid.padded_width + oc[:, 0] + 1]
        best[np.repeat(origin_wall, n_b)] = 0.0

        k_total = math.ceil(max_cells) + 1
        bounds = [0, min(FIRST_SLICE_SLOTS, k_total), k_total]
        active = np.flatnonzero(~np.isfinite(best))
        t_cap = max_cells + 2.0
        # Ray origins in the padded grid (one ring of walls around the world).
        origins_p = origins + 1.0
        wp = grid.padded_width
        near = (grid.plane, 2 * grid.plane)
        kept: list[tuple[NDArray[np.int64], Traversal]] = []
        for k_a, k_b in itertools.pairwise(bounds):
            if k_b <= k_a or active.size == 0:
                continue
            tr = traverse(
                origins_p[active],
                dirs[active],
                k_a,
                k_b - k_a,
                wp,
                t_cap,
                near,
                self.dtype,
                index_bound=grid.table.size,
            )
            m = active.size
            wall = np.take(grid.table, tr.idx, mode="clip")  # (K, 2m)
            # Crossing t grows with the slot, so a column's first wall slot is its nearest wall.
            k_first = wall.argmax(axis=0)
            has = wall[k_first, np.arange(2 * m)]
            t_first = np.where(has, tr.t_at(k_first + k_a), np.inf)
            best[active] = np.minimum(best[active], np.minimum(t_first[:m], t_first[m:]))
            if want_visible:
                kept.append((active, tr))
            # Every crossing with t <= covered has been tested for these rays.
            t_last = tr.t_at(k_b - 1)
            covered = np.minimum(t_last[:m], t_last[m:])
            done = (best[active] <= covered) | (covered >= max_cells)
            active = active[~done]

        hit = best <= max_cells
        ranges_cells = np.where(hit, best, max_cells)
        ranges = (ranges_cells * resolution_m).astype(np.float32)
        if rng is not None and self.config.noise_std_m > 0.0:
            noise = np.asarray(rng.normal(0.0, self.config.noise_std_m, size=n), dtype=np.float32)
            ranges = np.where(hit, np.clip(ranges + noise, 0.0, self.config.max_range_m), ranges)
            ranges = ranges.astype(np.float32)

        visible: tuple[NDArray[np.int64], ...] | None = None
        if want_visible:
            visible = self._visible(grid, kept, ranges_cells, oc, n_rob, n_b)
        return Scan(
            ranges_m=ranges.reshape(n_rob, n_b),
            hit=hit.reshape(n_rob, n_b),
            angles=self.angles,
            visible_flat=visible,
        )

    def check_origins(
        self, grid: PaddedGrid, origins_cells: NDArray[np.floating], headings: NDArray[np.floating]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Validated ``(corner (R, 2) snapped corner coordinates, headings (R,))``."""
        org = np.asarray(origins_cells, dtype=np.float64).reshape(-1, 2)
        hd = np.asarray(headings, dtype=np.float64).reshape(-1)
        if hd.shape[0] != org.shape[0]:
            raise GridError(f"got {org.shape[0]} origins but {hd.shape[0]} headings")
        h, w = grid.shape
        corner = snap(org + 0.5)
        # One reduction instead of four (this runs every simulator step).
        if not (corner.min() >= 0.0 and (corner < np.array([w, h])).all()):
            raise GridError(f"sensor origins {org.tolist()} must lie inside the {h}x{w} grid")
        return corner, hd

    def corners_of(
        self, grid: PaddedGrid, poses_m: NDArray[np.float64], world: World
    ) -> NDArray[np.float64]:
        """:meth:`check_origins` of ``world.cell_of`` of the world poses ``poses_m`` (R, 3)
        (metres): the snapped corners (R, 2). The same IEEE operations in the same order on
        Python floats, since numpy's per-call overhead on R-row arrays cost more than the
        arithmetic (the simulator calls this every step); the same error outside the grid."""
        h, w = grid.shape
        (ox, oy), res = world.origin_m, world.resolution_m
        out = np.empty((len(poses_m), 2))
        for i, (x, y, _) in enumerate(poses_m.tolist()):
            u = ((x - ox) / res - 0.5 + 0.5) / SNAP_CELLS
            v = ((y - oy) / res - 0.5 + 0.5) / SNAP_CELLS
            # np.round is Python's round (half to even); the int scales back exactly
            inside = math.isfinite(u) and math.isfinite(v)
            cx = round(u) * SNAP_CELLS if inside else -1.0
            cy = round(v) * SNAP_CELLS if inside else -1.0
            if not (0.0 <= cx < w and 0.0 <= cy < h):
                self.check_origins(grid, world.cell_of(poses_m[:, :2]), poses_m[:, 2])  # raises
            out[i, 0], out[i, 1] = cx, cy
        return out

    def kernel_args(
        self,
        corner: NDArray[np.float64],
        hd: NDArray[np.float64],
        resolution_m: float,
        rng: np.random.Generator | None,
    ) -> tuple[Any, ...]:
        """The compiled cast's arguments after the grid's, ``corners`` to ``noise``
        (:func:`mrexplore.kernels.sensing.cast_observe`), for R robots at ``corner`` and
        ``hd`` (:meth:`check_origins`); the range noise is drawn from ``rng`` here."""
        return (
            corner,
            np.cos(hd),
            np.sin(hd),
            self._cos,
            self._sin,
            self.config.max_range_m / resolution_m,
            resolution_m,
            self.config.max_range_m,
            self._noise(rng, corner.shape[0]),
        )

    def _noise(self, rng: np.random.Generator | None, n_rob: int) -> NDArray[np.float64]:
        """(R, B) range noise in metres from ``rng`` (one draw), or an empty array for none."""
        if rng is None or self.config.noise_std_m <= 0.0:
            return _NO_NOISE
        return rng.normal(0.0, self.config.noise_std_m, size=(n_rob, self.angles.shape[0]))

    def _cast_numba(
        self,
        grid: PaddedGrid,
        corner: NDArray[np.float64],
        hd: NDArray[np.float64],
        resolution_m: float,
        rng: np.random.Generator | None,
        want_visible: bool,
    ) -> Scan:
        """:meth:`cast` with the compiled kernel (``corner``: validated corner coordinates)."""
        n_rob, n_b = corner.shape[0], self.angles.shape[0]
        h, w = grid.shape
        ranges = np.empty((n_rob, n_b), dtype=np.float32)
        hit = np.empty((n_rob, n_b), dtype=np.bool_)
        if want_visible:
            # The kernel marks cells into a mask; the visible cells are its nonzero entries
            # (O(H W): the simulator uses cast_observe, which marks its own masks directly).
            obs = np.zeros((n_rob, h * w), dtype=np.bool_)
            flat = np.zeros(h * w, dtype=np.bool_)
            newly = np.zeros(n_rob, dtype=np.int64)
        else:
            obs, flat, newly = _NO_OBS, _NO_FLAT, _NO_NEWLY
        assert _sensing is not None
        _sensing.cast_observe(
            grid.table,
            h + 2,
            w + 2,
            *self.kernel_args(corner, hd, resolution_m, rng),
            ranges,
            hit,
            want_visible,
            obs,
            flat,
            flat,
            newly,
        )
        visible = tuple(np.flatnonzero(o) for o in obs) if want_visible else None
        return Scan(ranges_m=ranges, hit=hit, angles=self.angles, visible_flat=visible)

    def cast_observe(
        self,
        grid: PaddedGrid,
        origins_cells: NDArray[np.floating],
        headings: NDArray[np.floating],
        resolution_m: float,
        rng: np.random.Generator | None,
        observed: NDArray[np.bool_],
        reachable: NDArray[np.bool_],
        team_observed: NDArray[np.bool_],
    ) -> tuple[Scan, NDArray[np.int64], int]:
        """Cast every beam of R robots and mark what they observed (the simulator's step).

        Args:
            grid: the wall grid from :meth:`prepare` (H, W).
            origins_cells, headings, resolution_m, rng: as :meth:`cast`.
            observed: bool (R, H, W), C-contiguous, per robot the world cells observed so far;
                updated in place with the robot's own cell and, per beam, the cells entered up
                to the hit (hit cell included) or the maximum range (``Scan.visible_flat``).
            reachable: bool (H, W) the cells that count for coverage.
            team_observed: bool (H, W), C-contiguous, cells observed by any robot; updated.

        Returns:
            ``(scan, newly (R,) int64 cells each robot observed for the first time, number of
            reachable cells the team observed for the first time)``. ``scan.visible_flat`` is
            None.
        """
        if not (math.isfinite(resolution_m) and resolution_m > 0.0):
            raise GridError(f"resolution_m must be a positive number, got {resolution_m}")
        corner, hd = self.check_origins(grid, origins_cells, headings)
        n_rob, n_b = corner.shape[0], self.angles.shape[0]
        h, w = grid.shape
        if (
            observed.shape != (n_rob, h, w)
            or reachable.shape != (h, w)
            or team_observed.shape != (h, w)
            or not (observed.flags.c_contiguous and team_observed.flags.c_contiguous)
        ):
            raise GridError(
                f"observed must be C-contiguous bool ({n_rob}, {h}, {w}) and reachable, "
                f"team_observed bool ({h}, {w})"
            )
        if not kernels.enabled():
            scan = self.cast(grid, origins_cells, headings, resolution_m, rng, want_visible=True)
            newly, covered = _observe_numpy(scan, observed, reachable, team_observed)
            return Scan(scan.ranges_m, scan.hit, scan.angles), newly, covered
        ranges = np.empty((n_rob, n_b), dtype=np.float32)
        hit = np.empty((n_rob, n_b), dtype=np.bool_)
        newly = np.zeros(n_rob, dtype=np.int64)
        assert _sensing is not None
        covered = _sensing.cast_observe(
            grid.table,
            h + 2,
            w + 2,
            *self.kernel_args(corner, hd, resolution_m, rng),
            ranges,
            hit,
            True,
            observed.reshape(n_rob, h * w),
            np.ascontiguousarray(reachable).reshape(-1),
            team_observed.reshape(-1),
            newly,
        )
        return Scan(ranges_m=ranges, hit=hit, angles=self.angles), newly, int(covered)

    @staticmethod
    def _visible(
        grid: PaddedGrid,
        kept: list[tuple[NDArray[np.int64], Traversal]],
        limit: NDArray[np.float64],
        origin_cells: NDArray[np.int64],
        n_rob: int,
        n_b: int,
    ) -> tuple[NDArray[np.int64], ...]:
        """Per robot, flat (H, W) indices of the cells entered at t <= the beam's range
        (the free cells it crossed and the wall cell it hit), plus the robot's own cell."""
        h, w = grid.shape
        wp = grid.padded_width
        parts: list[list[NDArray[np.int64]]] = [[] for _ in range(n_rob)]
        for active, tr in kept:
            # A hair above the range so the hit cell (entered exactly at the range) counts.
            counts = tr.count_before(limit[active] + 1e-9)
            # active is sorted: each robot's rays are one contiguous block of columns.
            cuts = np.searchsorted(active, np.arange(n_rob + 1) * n_b)
            for i in range(n_rob):
                if cuts[i + 1] > cuts[i]:
                    parts[i].append(tr.selected(counts, int(cuts[i]), int(cuts[i + 1])))
        out = []
        for i in range(n_rob):
            e = np.concatenate(parts[i]) if parts[i] else np.zeros(0, dtype=np.int64)
            # Corner crossings point into the pair planes: back to plane 0 (rare).
            big = e >= grid.plane
            if big.any():
                e[big] %= grid.plane
            r_p = e // wp
            c_p = e - r_p * wp
            # Pad cells (the hit cell of a beam leaving the grid) are not world cells.
            ok = (r_p >= 1) & (r_p <= h) & (c_p >= 1) & (c_p <= w)
            flat = (e - 2 * r_p - (w + 1))[ok]
            oc = origin_cells[i]
            out.append(np.concatenate([flat, np.array([oc[1] * w + oc[0]], dtype=np.int64)]))
        return tuple(out)


#: Placeholders for the kernel's unused arguments (no noise, no marking).
_NO_NOISE: NDArray[np.float64] = np.zeros((0, 0), dtype=np.float64)
_NO_OBS: NDArray[np.bool_] = np.zeros((1, 1), dtype=np.bool_)
_NO_FLAT: NDArray[np.bool_] = np.zeros(1, dtype=np.bool_)
_NO_NEWLY: NDArray[np.int64] = np.zeros(1, dtype=np.int64)


def _observe_numpy(
    scan: Scan,
    observed: NDArray[np.bool_],
    reachable: NDArray[np.bool_],
    team_observed: NDArray[np.bool_],
) -> tuple[NDArray[np.int64], int]:
    """The numpy bookkeeping of :meth:`Lidar.cast_observe` from ``scan.visible_flat``."""
    assert scan.visible_flat is not None
    n_rob = observed.shape[0]
    newly = np.zeros(n_rob, dtype=np.int64)
    covered = 0
    team = team_observed.reshape(-1)
    reach = reachable.reshape(-1)
    for i in range(n_rob):
        vis = scan.visible_flat[i]
        obs = observed[i].reshape(-1)
        fresh = vis[~obs[vis]]
        if fresh.size:
            fresh = np.unique(fresh)
            obs[fresh] = True
            newly[i] = fresh.size
            team_new = fresh[~team[fresh]]
            team[team_new] = True
            covered += int(np.count_nonzero(reach[team_new]))
    return newly, covered


def cast_ray_reference(
    walls: NDArray[np.bool_],
    origin_cell: tuple[float, float],
    angle_rad: float,
    max_range_cells: float,
) -> tuple[float, bool]:
    """One ray, the textbook way (a DDA loop in Python): for tests of :meth:`Lidar.cast`.

    Walks the grid-line crossings in order of the ray parameter t (cells) with the running
    ``t_max_x`` / ``t_max_y`` of Amanatides & Woo, and stops at the first wall cell entered
    (cells outside the grid are walls). Near a corner (within :data:`CORNER_EPS` cells) both
    cells beside the crossing are tested, as in the vectorised cast.

    Returns:
        (range in cells, hit): distance from the origin to the boundary of the first wall cell,
        or ``(max_range_cells, False)`` when there is none within range.
    """
    h, w = walls.shape
    ox, oy = origin_cell[0] + 0.5, origin_cell[1] + 0.5
    dx, dy = math.cos(angle_rad), math.sin(angle_rad)

    def is_wall(c: int, r: int) -> bool:
        return not (0 <= c < w and 0 <= r < h) or bool(walls[r, c])

    c, r = math.floor(ox), math.floor(oy)
    if is_wall(c, r):
        return 0.0, True
    step_x = 1 if dx > 0 else -1
    step_y = 1 if dy > 0 else -1
    t_max_x = ((c + 1 - ox) / dx if dx > 0 else (ox - c) / -dx) if dx != 0 else math.inf
    t_max_y = ((r + 1 - oy) / dy if dy > 0 else (oy - r) / -dy) if dy != 0 else math.inf
    t_delta_x = 1.0 / abs(dx) if dx != 0 else math.inf
    t_delta_y = 1.0 / abs(dy) if dy != 0 else math.inf
    while True:
        if t_max_x <= t_max_y:
            t = t_max_x
            c += step_x
            t_max_x += t_delta_x
            y = oy + t * dy
            r_lo = math.floor(y - CORNER_EPS)
            wall = is_wall(c, r_lo) or (y + CORNER_EPS >= r_lo + 1 and is_wall(c, r_lo + 1))
        else:
            t = t_max_y
            r += step_y
            t_max_y += t_delta_y
            x = ox + t * dx
            c_lo = math.floor(x - CORNER_EPS)
            wall = is_wall(c_lo, r) or (x + CORNER_EPS >= c_lo + 1 and is_wall(c_lo + 1, r))
        if t > max_range_cells:
            return float(max_range_cells), False
        if wall:
            return float(t), True


class _Sensors(types.ModuleType):
    """``sensors.USE_NUMBA`` / ``HAVE_NUMBA``: the switch's old home, forwarded (reading and
    setting) to :mod:`mrexplore.kernels` with a deprecation warning, so old code that set
    ``sensors.USE_NUMBA = False`` still switches the kernels off."""

    @property
    def USE_NUMBA(self) -> bool:
        warnings.warn("use mrexplore.kernels.USE_NUMBA", DeprecationWarning, stacklevel=2)
        return kernels.USE_NUMBA

    @USE_NUMBA.setter
    def USE_NUMBA(self, value: bool) -> None:
        warnings.warn("use mrexplore.kernels.USE_NUMBA", DeprecationWarning, stacklevel=2)
        kernels.USE_NUMBA = bool(value)

    @property
    def HAVE_NUMBA(self) -> bool:
        return kernels.HAVE_NUMBA


sys.modules[__name__].__class__ = _Sensors
