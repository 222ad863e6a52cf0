"""A 2-D range sensor (lidar) on an occupancy grid: an exact, vectorised grid traversal.

Geometry. A point on a grid is ``(col, row)`` with cell centres at integer points, so cell
``(c, r)`` covers ``[c - 0.5, c + 0.5) x [r - 0.5, r + 0.5)``. Internally the traversal works in
*corner coordinates* ``u = col + 0.5``, where cell ``c`` is ``floor(u)`` and grid lines are the
integers.

Traversal (shared by the sensor and by :mod:`mrexplore.mapping`). A ray ``p(t) = o + t d`` with
``|d| = 1`` (``t`` in cells) enters a new cell exactly when it crosses a vertical or a horizontal
grid line. The k-th vertical crossing happens at ``t = t0x + k / |dx|`` and enters column
``c0 + k * sign(dx)``; the k-th horizontal crossing likewise. Both sequences are arithmetic in
``t``, so all crossings of all beams of all robots are computed at once as ``(N, K)`` arrays,
with no Python loop over steps and no sort: the cells a textbook DDA (Amanatides & Woo) visits
are exactly the cells entered at these crossings. The hit distance is the smallest entry ``t``
over wall cells.

Corners. When a ray passes within :data:`CORNER_EPS` cells of a grid corner, the sensor tests
*both* cells beside the crossing point (and the diagonal one), so a ray cannot slip between two
wall cells that touch only at a corner (a diagonal staircase of walls is closed). The same rule
is used by :func:`cast_ray_reference`.

Cells outside the grid count as walls: a beam leaving the grid stops at the border.

Two implementations: the compiled per-beam kernels of :mod:`mrexplore.kernels.sensing` (used
while :func:`mrexplore.kernels.enabled`, the default) and the vectorised numpy traversal below
(the path with the kernels off, and an oracle of the tests). They evaluate the same float64
formulas, so they agree to the bit with
``Lidar.dtype = numpy.float64``.
"""

from __future__ import annotations

import itertools
import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.errors import ConfigError, GridError

# The compiled cast (None without numba); used while mrexplore.kernels.enabled().
_sensing = kernels.load("sensing")

#: Rays passing within this many cells of a grid corner test both cells beside the corner.
#: Larger than the float32 rounding of the per-slot positions (~2e-5 cells for beams of a few
#: hundred cells), so a crossing exactly at a corner is always recognised; 1e-4 cells is 5 um at
#: 0.05 m per cell.
CORNER_EPS: float = 1e-4

#: Crossing slots (per line family) of the first slice of a cast. Beams are traversed in two
#: slices: most indoor beams meet a wall within the first one and drop out, so the second
#: (up to the maximum range) only runs on the long beams. See ``mrexplore bench sensor``.
FIRST_SLICE_SLOTS: int = 40


#: Continuous cell coordinates are rounded to this lattice (cells) before anything takes their
#: floor. Robots start at cell centres and move 2.5 cells per step, so they sit exactly on cell
#: boundaries every other step; without the snap, 1e-15 rounding noise (which depends on where
#: the world happens to be placed) would pick the cell on either side.
SNAP_CELLS: float = 1e-9


def snap(u: NDArray[np.floating]) -> NDArray[np.float64]:
    """Round continuous cell coordinates to the :data:`SNAP_CELLS` lattice (see there)."""
    return np.asarray(np.round(np.asarray(u, dtype=np.float64) / SNAP_CELLS) * SNAP_CELLS)


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


@dataclass(frozen=True, eq=False)
class PaddedGrid:
    """A wall grid prepared for repeated casts (see :meth:`Lidar.prepare`).

    ``table`` is the grid padded by one ring of walls and stacked with its "pair" grids, flat:
    plane 0 = walls, plane 1 = ``walls[r] | walls[r+1]`` (a crossing of a vertical grid line
    near a corner), plane 2 = ``walls[:, c] | walls[:, c+1]`` (same for horizontal lines).
    One gather then tests one cell, or both cells beside a corner.
    """

    shape: tuple[int, int]
    table: NDArray[np.bool_]

    @property
    def padded_width(self) -> int:
        """Columns of the padded grid (W + 2)."""
        return self.shape[1] + 2

    @property
    def plane(self) -> int:
        """Cells in one padded plane, (H + 2) * (W + 2)."""
        return (self.shape[0] + 2) * (self.shape[1] + 2)


def _check_walls(walls: object) -> NDArray[np.bool_]:
    if not isinstance(walls, np.ndarray) or walls.ndim != 2 or walls.size == 0:
        raise GridError("walls must be a non-empty 2-D numpy bool array (rows, cols)")
    if walls.dtype != np.bool_:
        raise GridError(f"walls must be a bool array, got dtype {walls.dtype}")
    return walls


def prepare_walls(walls: NDArray[np.bool_]) -> PaddedGrid:
    """Pad ``walls`` (H, W) bool with a ring of walls and build the corner pair planes."""
    w = _check_walls(walls)
    h, wd = w.shape
    pad = np.ones((h + 2, wd + 2), dtype=np.bool_)
    pad[1:-1, 1:-1] = w
    pair_rows = pad.copy()
    pair_rows[:-1, :] |= pad[1:, :]
    pair_cols = pad.copy()
    pair_cols[:, :-1] |= pad[:, 1:]
    table = np.concatenate([pad.ravel(), pair_rows.ravel(), pair_cols.ravel()])
    return PaddedGrid(shape=(h, wd), table=table)


@dataclass(frozen=True, eq=False)
class Traversal:
    """The cells N rays enter at grid-line crossing slots ``k = k0 .. k0 + K - 1``.

    Both line families are stacked as 2N "columns": column ``j < N`` holds the crossings of ray
    ``j`` with vertical grid lines (integer corner x), column ``N + j`` those with horizontal
    lines. In column j, slot k is the crossing at ray parameter ``t = t0[j] + k * dt[j]``
    (cells; ``t0 = inf`` when the ray is parallel to that family) and ``idx[k - k0, j]`` is the
    flat index ``row * stride + col`` of the cell the ray enters there.

    Attributes:
        idx: int64 (K, 2N) flat cell indices, slot-major (garbage, but finite, for slots with
            ``t`` beyond the traversal's ``t_cap`` and for parallel columns).
        t0, dt: float64 (2N,) the arithmetic sequence of each column's crossing t.
        k0: first slot.
    """

    idx: NDArray[np.int64]
    t0: NDArray[np.float64]
    dt: NDArray[np.float64]
    k0: int

    @property
    def n_rays(self) -> int:
        """N, the number of rays (half the columns)."""
        return self.idx.shape[1] // 2

    def t_at(self, k: NDArray[np.integer] | int) -> NDArray[np.float64]:
        """Ray parameter of absolute slot ``k`` (scalar or (2N,)) in every column, (2N,)."""
        return self.t0 + k * self.dt

    def count_before(self, t_end: NDArray[np.float64]) -> NDArray[np.int64]:
        """Per column (2N,), the number of this traversal's slots with ``t < t_end`` (N,)."""
        t2 = np.concatenate([t_end, t_end])
        # Slot k is before t_end iff k < (t_end - t0) / dt. Parallel columns (dt = 0, t0 = inf)
        # have none: a huge finite t0 and a unit dt give a negative count, clipped to 0.
        par = self.dt == 0.0
        n_all = np.ceil((t2 - np.where(par, 1e30, self.t0)) / np.where(par, 1.0, self.dt))
        return np.clip(n_all - self.k0, 0, self.idx.shape[0]).astype(np.int64)

    def selected(
        self, counts: NDArray[np.int64], lo: int = 0, hi: int | None = None
    ) -> NDArray[np.int64]:
        """Flat indices of the first ``counts[j]`` slots of the columns of rays ``lo..hi-1``
        (both families), as one 1-D array (order: slot-major)."""
        n = self.n_rays
        hi = n if hi is None else hi
        slots = np.arange(self.idx.shape[0])[:, None]
        out = []
        for c0 in (lo, n + lo):
            c1 = c0 + (hi - lo)
            sel = slots < counts[None, c0:c1]
            out.append(self.idx[:, c0:c1][sel])
        return np.concatenate(out)


#: Flat indices are computed in float32 when every index is below this (exact integers).
_FLOAT32_EXACT: int = 1 << 24


def traverse(
    origins: NDArray[np.float64],
    directions: NDArray[np.float64],
    k0: int,
    n_slots: int,
    row_stride: int,
    t_cap: float,
    near_offsets: tuple[int, int] | None = None,
    dtype: type[np.floating] = np.float64,
    index_bound: int | None = None,
) -> Traversal:
    """Cells entered by N rays at crossing slots ``k0 .. k0 + n_slots - 1`` of each line family.

    The one traversal used by the sensor (on the padded world) and by the occupancy map (on the
    robot's canvas).

    Args:
        origins: (N, 2) ray origins in corner coordinates ``(col + 0.5, row + 0.5)`` of the
            grid whose flat index is ``row * row_stride + col``.
        directions: (N, 2) unit directions ``(dcol, drow)``.
        k0, n_slots: the slot window.
        row_stride: flat-index step of one row (the grid width).
        t_cap: the largest ray parameter (cells) the caller will use; indices of slots beyond
            it are garbage (finite, possibly outside the grid: gather with ``mode="clip"``).
        near_offsets: when given ``(off_x, off_y)``, a crossing within :data:`CORNER_EPS` of a
            corner gets ``off_x`` (vertical lines) or ``off_y`` (horizontal lines) added to its
            index: the sensor points those at planes that test both cells beside the corner.
            When None, the entered cell is ``floor`` of the position (biased by -CORNER_EPS).
        dtype: float type of the per-slot positions and index arithmetic (float32 is faster;
            relative coordinates keep it within ~1e-5 cells for beams of a few hundred cells).
        index_bound: an upper bound of the flat indices (the size of the gathered table);
            float32 is only used when it is below 2**24 (integers exact), else float64.

    Cost: about ten elementwise passes over (K, 2N) in ``dtype`` and one conversion to int64.
    Both families are stacked into one set of arrays and laid out slot-major, because numpy's
    per-call overhead and its slow broadcasting along short inner axes dominated the first,
    per-family (N, K) version (measured: ~2x slower).
    """
    if index_bound is None or index_bound >= _FLOAT32_EXACT:
        dtype = np.float64
    n = origins.shape[0]
    o = np.concatenate([origins[:, 0], origins[:, 1]])  # coordinate across the lines
    o_other = np.concatenate([origins[:, 1], origins[:, 0]])
    d = np.concatenate([directions[:, 0], directions[:, 1]])
    d_other = np.concatenate([directions[:, 1], directions[:, 0]])
    stride_self = np.repeat(np.array([1.0, float(row_stride)]), n)
    stride_other = np.repeat(np.array([float(row_stride), 1.0]), n)

    fo = np.floor(o)
    ad = np.abs(d)
    moving = ad > 0.0
    # A ray parallel to a family never crosses its lines: t0 = inf and the slope is taken as 0
    # so that the (unused) positions stay finite.
    inv = 1.0 / np.where(moving, ad, np.inf)
    first = np.where(d > 0.0, fo + 1.0 - o, o - fo)
    t0 = np.where(moving, first * inv, np.inf)
    # Other coordinate at slot k, relative to the origin's cell, plus an offset so it stays
    # positive and small (float32 keeps ~1e-5 cells): a = start, s = slope per slot. Slots with
    # t > t_cap are never used, so t0 and the slope are capped: no overflow near parallel.
    offset = math.ceil(t_cap) + 2
    fo_other = np.floor(o_other)
    a = (o_other - fo_other) + np.minimum(first * inv, t_cap) * d_other + (offset - CORNER_EPS)
    s = np.minimum(np.maximum(inv * d_other, -t_cap), t_cap)
    k = np.arange(k0, k0 + n_slots, dtype=dtype)[:, None]
    pos = k * s.astype(dtype)
    pos += a.astype(dtype)
    cell = np.floor(pos)
    # Flat index = origin cell + (k + 1) steps across the lines + cell along them: small
    # integers, exact in float32 (float64 is picked above for huge tables).
    step = np.where(d > 0.0, stride_self, -stride_self)
    base = fo * stride_self + (fo_other - offset) * stride_other + step
    idx_f = k * step.astype(dtype)
    idx_f += base.astype(dtype)
    if near_offsets is not None:
        # Within 2 * CORNER_EPS below the next line too: the crossing is at a corner, test the
        # "pair" plane (both cells beside it) with the same gather.
        pos -= cell
        near = pos >= (1.0 - 2.0 * CORNER_EPS)
        off = np.repeat(np.array(near_offsets, dtype=dtype), n)
        np.add(idx_f, off, out=idx_f, where=near)
    cell *= stride_other.astype(dtype)
    idx_f += cell
    return Traversal(idx=idx_f.astype(np.int64), t0=t0, dt=inv, k0=k0)


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
        corner, hd = self._check_origins(grid, origins_cells, headings)
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

    def _check_origins(
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
            corner,
            np.cos(hd),
            np.sin(hd),
            self._cos,
            self._sin,
            self.config.max_range_m / resolution_m,
            resolution_m,
            self.config.max_range_m,
            self._noise(rng, n_rob),
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
        corner, hd = self._check_origins(grid, origins_cells, headings)
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
            corner,
            np.cos(hd),
            np.sin(hd),
            self._cos,
            self._sin,
            self.config.max_range_m / resolution_m,
            resolution_m,
            self.config.max_range_m,
            self._noise(rng, n_rob),
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
