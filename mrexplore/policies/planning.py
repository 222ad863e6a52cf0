"""Shortest paths for a disc robot on an int8 occupancy grid, on a coarse planning grid.

Pipeline (vectorised numpy/OpenCV; each stage has a compiled kernel in
:mod:`mrexplore.kernels.planning`, used while :func:`mrexplore.kernels.enabled`, with the same
results):

1. **Crop** the map to the bounding box of its known cells (plus the robot, the goal and a
   margin): a robot's canvas is ~1500 x 1500 cells, of which a few hundred square are known.
2. **Inflate** occupied cells with ``cv2.dilate`` by a disc of radius
   ``robot_radius_m / resolution_m + 0.5`` cells: a robot centre outside the inflated set keeps its
   disc (almost) clear of the wall *cell*, not only of the cell's centre.
3. **Coarsen** by ``factor`` (fine cells per planning cell, 2 by default): a planning cell is
   traversable when *none* of its fine cells is inside the inflated obstacles (safety is strict)
   and *at least half* of them are known free (``unknown_is_free=False``, exploration) - "mostly
   known" rather than "all known", because lidar beams diverge and leave single unknown cells
   inside explored space that must not cut corridors in two. With ``unknown_is_free=True``
   (navigation to a goal, optimistic) unknown cells count as free.
4. **Distance field** from the robot: octile (8-connected, diagonal steps cost sqrt 2, no corner
   cutting) geodesic distance over traversable planning cells (:func:`distance_field`): a
   compiled Dijkstra with a bucket queue (:mod:`mrexplore.kernels.planning`), with a pure-numpy
   reference,
   :func:`distance_field_scan` (repeated *segmented min-plus scans* along rows, columns and both
   diagonals; one sweep per bend of the longest shortest path, 10-30 ms at that size), used when
   numba is missing and in the tests, which check that both agree exactly.
5. **Paths** by descending the field from the goal (:meth:`PlanningGrid.path_to`).

Distances returned by :class:`PlanningGrid` are in metres; cells are ``(col, row)`` in the map.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import lru_cache

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.errors import ConfigError, GridError
from mrexplore.grid import Int8Grid, free_mask, known_mask, occupied_mask

_planning = kernels.load("planning")

__all__ = [
    "PlanningGrid",
    "distance_field",
    "distance_field_scan",
    "inflate_obstacles",
    "planning_rounds",
]

_SQRT2 = math.sqrt(2.0)

# The eight neighbour offsets (drow, dcol) and their step costs, used by path descent.
_NEIGHBOURS: tuple[tuple[int, int, float], ...] = (
    (-1, 0, 1.0),
    (1, 0, 1.0),
    (0, -1, 1.0),
    (0, 1, 1.0),
    (-1, -1, _SQRT2),
    (-1, 1, _SQRT2),
    (1, -1, _SQRT2),
    (1, 1, _SQRT2),
)


def planning_rounds(
    factor: int,
    clearance_cells: float = 0.5,
    tight_clearance_cells: float | None = 0.0,
    fine_fallback: bool = True,
) -> list[tuple[int, float]]:
    """The ``(factor, clearance_cells)`` planning grids a policy tries in turn until one gets it
    where it wants to go: ``factor`` fine cells per planning cell with ``clearance_cells``;
    then (``fine_fallback``) the map's own cells, where coarse cells closed a gap the robot
    fits through; then (unless ``tight_clearance_cells`` is None) the simulator's own
    collision rule, which frees a robot whose own cell the clearance encloses.

    >>> planning_rounds(2)
    [(2, 0.5), (1, 0.5), (1, 0.0)]
    >>> planning_rounds(1, tight_clearance_cells=None)
    [(1, 0.5)]
    """
    rounds = [(int(factor), float(clearance_cells))]
    fine = 1 if fine_fallback else int(factor)
    if fine != factor:
        rounds.append((fine, float(clearance_cells)))
    if tight_clearance_cells is not None:
        rounds.append((fine, float(tight_clearance_cells)))
    return rounds


def inflate_obstacles(
    map_int8: Int8Grid,
    robot_radius_m: float,
    resolution_m: float,
    clearance_cells: float = 0.5,
) -> NDArray[np.bool_]:
    """bool (H, W): cells where a robot centre would touch an occupied cell.

    Occupied cells (``mrexplore.grid.occupied_mask``) dilated by a disc of radius
    ``robot_radius_m / resolution_m + clearance_cells`` cells. The default half cell covers the
    wall cell's own extent; ``clearance_cells=0`` blocks exactly the cells whose centre lies
    within the radius of a wall cell's centre, the simulator's own collision rule
    (:func:`mrexplore.robot.configuration_space`).
    """
    if robot_radius_m < 0 or resolution_m <= 0 or not clearance_cells >= 0:
        raise ConfigError(
            "robot_radius_m must be >= 0, resolution_m > 0 and clearance_cells >= 0, "
            f"got {robot_radius_m}, {resolution_m}, {clearance_cells}"
        )
    occ = occupied_mask(map_int8).view(np.uint8)
    disc = _disc(robot_radius_m / resolution_m + clearance_cells)
    if disc.shape[0] == 1:
        return occ.view(np.bool_).copy()
    return cv2.dilate(occ, disc).view(np.bool_)


@lru_cache(maxsize=16)
def _disc(r: float) -> NDArray[np.uint8]:
    """uint8 (2k+1, 2k+1), k = floor(r): the cells within ``r`` of the centre ((1, 1) for
    k < 1: the cell itself). Cached: read-only."""
    k = math.floor(r)
    if k < 1:
        disc = np.ones((1, 1), dtype=np.uint8)
    else:
        yy, xx = np.mgrid[-k : k + 1, -k : k + 1]
        disc = ((xx * xx + yy * yy) <= r * r + 1e-9).astype(np.uint8)
    disc.flags.writeable = False
    return disc


# --------------------------------------------------------------------------------------------
# Distance field: numba Dijkstra, and segmented min-plus scans in numpy (reference).
# --------------------------------------------------------------------------------------------


#: Integer step costs (exact arithmetic, so sweeps converge exactly): 10000 per straight step,
#: 14142 per diagonal step (sqrt 2 to 2e-5 relative).
_STRAIGHT = 10_000
_DIAG = 14_142


@dataclass(frozen=True)
class _Layout:
    """Index arrays laying an (h, w) grid out as lines, for one scan family.

    ``idx`` (L, M) flat indices into an ``h*w + 1`` buffer whose last element is a padding
    sentinel; ``corner_a``/``corner_b`` (L, M) the two orthogonal neighbours a diagonal step into a
    cell must keep free (pad index for straight families); ``step`` the cost per step.
    ``view`` is 0 for rows, 1 for columns (scanned through views, no gather), 2 for diagonals.
    """

    idx: NDArray[np.intp]
    corner_a: NDArray[np.intp] | None
    corner_b: NDArray[np.intp] | None
    ramp: NDArray[np.int64]
    view: int


@lru_cache(maxsize=32)
def _layouts(h: int, w: int) -> tuple[_Layout, ...]:
    """The four scan families (rows, columns, diagonals, anti-diagonals), cached per shape."""
    pad = h * w
    flat = np.arange(h * w, dtype=np.intp).reshape(h, w)
    out = [
        _Layout(flat, None, None, _STRAIGHT * np.arange(w, dtype=np.int64), 0),
        _Layout(
            np.ascontiguousarray(flat.T), None, None, _STRAIGHT * np.arange(h, dtype=np.int64), 1
        ),
    ]
    rr = np.arange(h)[None, :]
    kk = np.arange(h + w - 1)[:, None]
    for dc in (1, -1):
        # Diagonal k, position = row; dc=+1: col = k - (h-1) + row; dc=-1: col = k - row.
        cc = kk - (h - 1) + rr if dc == 1 else kk - rr
        ok = (cc >= 0) & (cc < w)
        ccl = np.clip(cc, 0, w - 1)
        idx = np.where(ok, rr * w + ccl, pad).astype(np.intp)
        # Step from (r-1, c-dc) into (r, c) needs (r-1, c) and (r, c-dc) free.
        inside = ok & (rr >= 1) & (cc - dc >= 0) & (cc - dc < w)
        ca = np.where(inside, (rr - 1) * w + ccl, pad).astype(np.intp)
        cb = np.where(inside, rr * w + np.clip(cc - dc, 0, w - 1), pad).astype(np.intp)
        out.append(_Layout(idx, ca, cb, _DIAG * np.arange(h, dtype=np.int64), 2))
    return tuple(out)


def _segment_offsets(
    free_flat: NDArray[np.bool_], lay: _Layout, big: int
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Forward and backward scan shifts ``ramp + segment * big`` of one family over one mask.

    A segment starts wherever the step from the previous cell of the line is blocked; the
    ``segment * big`` part of the shift makes every value of an earlier segment lose any min
    against the later segment, so a cumulative min never carries a distance across a blocked
    step. The ``ramp`` part (step cost times position) turns "distance plus steps" into a plain
    running minimum.
    """
    cell_ok = free_flat[lay.idx]
    edge = np.zeros_like(cell_ok)
    edge[:, 1:] = cell_ok[:, 1:] & cell_ok[:, :-1]
    if lay.corner_a is not None and lay.corner_b is not None:
        edge &= free_flat[lay.corner_a] & free_flat[lay.corner_b]
    seg_fwd = np.cumsum(~edge, axis=1, dtype=np.int64)
    edge_rev = np.zeros_like(edge)
    edge_rev[:, 1:] = edge[:, :0:-1]
    seg_bwd = np.cumsum(~edge_rev, axis=1, dtype=np.int64)
    seg_fwd *= big
    seg_fwd += lay.ramp
    seg_bwd *= big
    seg_bwd += lay.ramp
    return seg_fwd, seg_bwd


def _scan(lines: NDArray[np.int64], shift: NDArray[np.int64], axis: int = 1) -> None:
    """In place, per line: ``v[i] = min(v[i], min_j v[j] + ramp[i] - ramp[j])``.

    ``j`` runs over ``j <= i`` in the segment of ``i`` along ``axis``; ``shift`` = ramp +
    segment offsets, same shape as ``lines``.
    """
    x = lines - shift
    np.minimum.accumulate(x, axis=axis, out=x)
    x += shift
    np.minimum(lines, x, out=lines)


def _check_sources(
    free: NDArray[np.bool_], sources: NDArray[np.integer]
) -> tuple[NDArray[np.bool_], NDArray[np.int64]]:
    free = np.ascontiguousarray(free, dtype=bool)
    if free.ndim != 2 or free.size == 0:
        raise GridError(f"free must be a non-empty 2-D bool array, got shape {free.shape}")
    h, w = free.shape
    src = np.asarray(sources, dtype=np.int64).reshape(-1, 2)
    inside = (src[:, 0] >= 0) & (src[:, 0] < w) & (src[:, 1] >= 0) & (src[:, 1] < h)
    src = src[inside]
    return free, src[free[src[:, 1], src[:, 0]]]


def distance_field(
    free: NDArray[np.bool_], sources: NDArray[np.integer], method: str = "auto"
) -> NDArray[np.float64]:
    """Octile geodesic distance (cells) from ``sources`` over the ``free`` cells.

    8-connected: straight steps cost 1, diagonal steps sqrt(2) (as 1.4142: integer costs
    10000 / 14142, so both methods give the very same numbers) and need both orthogonal neighbours
    free (no squeezing between two diagonal obstacles).

    Args:
        free: bool (h, w), traversable cells.
        sources: int (K, 2) ``(col, row)`` cells with distance 0 (non-free sources are ignored).
        method: ``"dijkstra"`` (compiled, :func:`mrexplore.kernels.planning.distance_cells`:
            Dijkstra with a bucket queue, well under 1 ms for 200 x 200 cells), ``"scan"``
            (pure numpy segmented scans, :func:`distance_field_scan`: ~10-30 ms), or ``"auto"``
            (dijkstra while :func:`mrexplore.kernels.enabled`, else scan).

    Returns:
        float64 (h, w): distance in cells, ``np.inf`` where unreachable or blocked.
    """
    if method == "auto":
        method = "dijkstra" if kernels.enabled() and _planning is not None else "scan"
    if method == "scan":
        return distance_field_scan(free, sources)
    if method != "dijkstra":
        raise ConfigError(
            f"distance_field method must be 'auto', 'dijkstra' or 'scan', got {method!r}"
        )
    if _planning is None:
        raise ConfigError("distance_field method 'dijkstra' needs numba (pip install numba)")
    free, src = _check_sources(free, sources)
    h, w = free.shape
    if src.size == 0:
        return np.full((h, w), np.inf)
    out: NDArray[np.float64] = _planning.distance_cells(
        free, src[:, 1] * w + src[:, 0], _STRAIGHT, _DIAG
    )
    return out


def distance_field_scan(
    free: NDArray[np.bool_], sources: NDArray[np.integer], max_sweeps: int = 500
) -> NDArray[np.float64]:
    """:func:`distance_field` in pure numpy (the reference, and the fallback without numba).

    How: a *segmented min-plus scan* along a line computes, for every cell at once,
    ``d[i] = min_{j <= i, same free segment} d[j] + step * (i - j)`` as
    ``step * i + cummin(d[j] - step * j)``; segments are separated by subtracting
    ``segment_index * big`` so that ``np.minimum.accumulate`` never carries a value across a
    blocked step. One sweep scans rows, columns and both diagonals in both directions; sweeps
    repeat until nothing changes - their number grows with the bends of the longest shortest
    path, not with its length. Arithmetic is in integers (10000 per cell), so convergence is exact.

    Args:
        free: bool (h, w), traversable cells.
        sources: int (K, 2) ``(col, row)`` cells with distance 0 (non-free sources are ignored).
        max_sweeps: safety cap on sweeps.

    Returns:
        float64 (h, w): distance in cells, ``np.inf`` where unreachable or blocked.
    """
    free, src = _check_sources(free, sources)
    h, w = free.shape
    if src.size == 0:
        return np.full((h, w), np.inf)
    # "Unreached" is a finite sentinel above any real distance (< 1.5 * 10000 * h * w); big must
    # exceed any difference of values along one line.
    unreached = 2 * _DIAG * h * w
    big = 2 * unreached + 2 * _DIAG * (h + w)
    free_flat = np.append(free.ravel(), False)
    lays = _layouts(h, w)
    offs = [_segment_offsets(free_flat, lay, big) for lay in lays]
    # Columns are scanned in place along axis 0 (contiguous rows, no transposed copy).
    offs[1] = (np.ascontiguousarray(offs[1][0].T), np.ascontiguousarray(offs[1][1].T))
    buf = np.full(h * w + 1, unreached, dtype=np.int64)
    buf[src[:, 1] * w + src[:, 0]] = 0
    grid = buf[:-1].reshape(h, w)
    # Values only ever decrease, so an unchanged sum means an unchanged field: stop after a
    # sweep (all four families, both directions) that changed nothing - the field is then a
    # fixed point of every scan, i.e. the exact shortest-path distance.
    total = int(grid.sum())
    for _ in range(max_sweeps):
        for lay, (off_f, off_b) in zip(lays, offs, strict=True):
            if lay.view == 0:
                _scan(grid, off_f)
                _scan(grid[:, ::-1], off_b)
            elif lay.view == 1:
                _scan(grid, off_f, axis=0)
                _scan(grid[::-1, :], off_b, axis=0)
            else:
                lines = buf[lay.idx]
                _scan(lines, off_f)
                _scan(lines[:, ::-1], off_b)
                buf[lay.idx] = lines
                buf[-1] = unreached  # padding entries only ever hold the sentinel
        new_total = int(grid.sum())
        if new_total == total:
            break
        total = new_total
    out = grid.astype(np.float64) / _STRAIGHT
    out[(grid >= unreached) | ~free] = np.inf
    return out


def _nearest_free_cell(
    free: NDArray[np.bool_],
    col0: int,
    row0: int,
    factor: int,
    cell: tuple[float, float] | NDArray[np.floating],
) -> tuple[int, int] | None:
    """Planning cell of fine ``cell`` on ``free`` (offset ``col0, row0``), or the closest
    traversable one (None when nothing is traversable)."""
    c = np.rint(np.asarray(cell, dtype=np.float64)[:2])
    p = np.floor((c - np.array([col0, row0])) / factor).astype(np.int64)
    h, w = free.shape
    if 0 <= p[0] < w and 0 <= p[1] < h and free[p[1], p[0]]:
        return (int(p[0]), int(p[1]))
    rows, cols = np.nonzero(free)
    if rows.size == 0:
        return None
    k = int(np.argmin((cols - p[0]) ** 2 + (rows - p[1]) ** 2))
    return (int(cols[k]), int(rows[k]))


def _coarse_free(
    crop: Int8Grid,
    h: int,
    w: int,
    factor: int,
    robot_radius_m: float,
    resolution_m: float,
    clearance_cells: float,
    unknown_is_free: bool,
) -> NDArray[np.bool_]:
    """bool (h, w): planning cells whose ``factor x factor`` fine cells of ``crop`` are all
    clear of the inflated walls and at least half free (cells beyond the crop are blocked)."""
    blocked = inflate_obstacles(crop, robot_radius_m, resolution_m, clearance_cells)
    ok_fine = ~blocked
    known_free = free_mask(crop)
    if unknown_is_free:
        known_free = known_free | ~known_mask(crop)
    # Pool factor x factor blocks by summing the factor**2 strided sub-grids (a handful of
    # array additions; numpy's multi-axis reductions on a 4-D reshape are several times
    # slower). Padding beyond the crop counts as blocked.
    ch, cw = crop.shape
    ok_pad = np.zeros((h * factor, w * factor), dtype=np.uint8)
    ok_pad[:ch, :cw] = ok_fine
    kf_pad = np.zeros((h * factor, w * factor), dtype=np.uint8)
    kf_pad[:ch, :cw] = known_free & ok_fine
    n_ok = np.zeros((h, w), dtype=np.int32)
    n_free = np.zeros((h, w), dtype=np.int32)
    for a in range(factor):
        for b in range(factor):
            n_ok += ok_pad[a::factor, b::factor]
            n_free += kf_pad[a::factor, b::factor]
    free: NDArray[np.bool_] = (n_ok == factor * factor) & (2 * n_free >= factor * factor)
    return free


# --------------------------------------------------------------------------------------------
# Planning grid.
# --------------------------------------------------------------------------------------------


@dataclass
class PlanningGrid:
    """A coarse traversability grid over a crop of a map, with a distance field from the robot.

    Build one with :meth:`build`. Planning cell ``(i, j)`` (col, row) covers fine cells
    ``col0 + factor*i ... + factor - 1`` and likewise for rows.

    Attributes:
        free: bool (h, w) traversable planning cells.
        col0, row0: fine-cell offset of the crop.
        factor: fine cells per planning cell along each axis.
        resolution_m: metres per *fine* cell.
        field: float64 (h, w), octile distance in planning cells from the start, inf unreachable.
        start: ``(i, j)`` planning cell the field starts from (the robot's, or the nearest
            traversable one when the robot stands inside the inflation).
    """

    free: NDArray[np.bool_]
    col0: int
    row0: int
    factor: int
    resolution_m: float
    field: NDArray[np.float64]
    start: tuple[int, int] | None

    @classmethod
    def build(
        cls,
        map_int8: Int8Grid,
        resolution_m: float,
        robot_radius_m: float,
        start_cell: tuple[float, float],
        factor: int = 2,
        unknown_is_free: bool = False,
        extra_cells: NDArray[np.floating] | None = None,
        margin_m: float = 1.0,
        clearance_cells: float = 0.5,
        passable_path: NDArray[np.floating] | None = None,
    ) -> PlanningGrid:
        """Crop, inflate, coarsen ``map_int8`` and compute the distance field from ``start_cell``.

        Args:
            map_int8: int8 (H, W) map.
            resolution_m: metres per cell.
            robot_radius_m: robot radius in metres (inflation).
            start_cell: robot ``(col, row)`` in fine cells (floats allowed).
            factor: fine cells per planning cell (>= 1).
            unknown_is_free: treat unknown as traversable (optimistic navigation).
            extra_cells: (K, 2) ``(col, row)`` points the crop must contain (e.g. a goal).
            margin_m: margin around the known area (and extra points), metres; with
                ``unknown_is_free`` this is the room a path may take through unknown space.
            clearance_cells: inflation beyond the robot radius, fine cells
                (:func:`inflate_obstacles`).
            passable_path: (K, 2) fine ``(col, row)`` polyline known to be traversable whatever
                the map says (where the robot's centre has been, ending where it stands): the
                planning cells on it (4-connected) are traversable, and the field starts from
                the robot's own cell as well as from the nearest traversable cell the map alone
                gives. A robot that got into a gap which the map, seen better from inside, now
                shows narrower than the inflated robot can always plan its way back out.
        """
        if not isinstance(map_int8, np.ndarray) or map_int8.ndim != 2 or map_int8.dtype != np.int8:
            raise GridError(
                f"map must be a 2-D int8 array, got {getattr(map_int8, 'dtype', type(map_int8))}"
            )
        if factor < 1:
            raise ConfigError(f"factor must be >= 1 fine cells per planning cell, got {factor}")
        H, W = map_int8.shape
        known = known_mask(map_int8)
        pts = [np.asarray(start_cell[:2], dtype=np.float64).reshape(1, 2)]
        if extra_cells is not None:
            pts.append(np.asarray(extra_cells, dtype=np.float64).reshape(-1, 2))
        allp = np.concatenate(pts)
        rows_any = np.flatnonzero(known.any(axis=1))
        margin = math.ceil(margin_m / resolution_m) + factor
        if rows_any.size:
            cols_any = np.flatnonzero(known[rows_any[0] : rows_any[-1] + 1].any(axis=0))
            r_lo, r_hi = rows_any[0], rows_any[-1]
            c_lo, c_hi = cols_any[0], cols_any[-1]
        else:
            r_lo = r_hi = round(float(allp[0, 1]))
            c_lo = c_hi = round(float(allp[0, 0]))
        r_lo = min(r_lo, int(np.floor(allp[:, 1].min())))
        r_hi = max(r_hi, int(np.ceil(allp[:, 1].max())))
        c_lo = min(c_lo, int(np.floor(allp[:, 0].min())))
        c_hi = max(c_hi, int(np.ceil(allp[:, 0].max())))
        r0 = max(r_lo - margin, 0)
        c0 = max(c_lo - margin, 0)
        r1 = min(r_hi + margin + 1, H)
        c1 = min(c_hi + margin + 1, W)
        # Round the crop up to whole planning cells (cells beyond the canvas count as blocked).
        h = -(-(r1 - r0) // factor)
        w = -(-(c1 - c0) // factor)
        crop = map_int8[r0:r1, c0:c1]
        if _planning is not None and kernels.enabled():
            if robot_radius_m < 0 or resolution_m <= 0 or not clearance_cells >= 0:
                inflate_obstacles(crop, robot_radius_m, resolution_m, clearance_cells)  # raises
            disc = _disc(robot_radius_m / resolution_m + clearance_cells)
            free = _planning.coarse_free(crop, disc, factor, h, w, unknown_is_free)
        else:
            free = _coarse_free(
                crop, h, w, factor, robot_radius_m, resolution_m, clearance_cells, unknown_is_free
            )
        sources = []
        if passable_path is not None and len(passable_path):
            near = _nearest_free_cell(free, c0, r0, factor, start_cell)
            if near is not None:
                sources.append(near)
            pp = np.floor(
                (
                    np.rint(np.asarray(passable_path, dtype=np.float64).reshape(-1, 2))
                    - np.array([c0, r0])
                )
                / factor
            ).astype(np.int32)
            line = np.zeros((h, w), dtype=np.uint8)
            # 4-connected, so the octile field (no corner cutting) can follow it.
            cv2.polylines(line, [pp.reshape(-1, 1, 2)], False, 1, lineType=4)
            if len(pp) == 1:
                line[np.clip(pp[0, 1], 0, h - 1), np.clip(pp[0, 0], 0, w - 1)] = 1
            free |= line.view(np.bool_)
        grid = cls(
            free=free,
            col0=c0,
            row0=r0,
            factor=factor,
            resolution_m=float(resolution_m),
            field=np.full((h, w), np.inf),
            start=None,
        )
        grid.start = grid.nearest_free(start_cell)
        if grid.start is not None:
            grid.field = distance_field(free, np.array([grid.start, *sources]))
        return grid

    # -- coordinates -------------------------------------------------------------------------

    @property
    def shape(self) -> tuple[int, int]:
        """(h, w) planning cells."""
        return (int(self.free.shape[0]), int(self.free.shape[1]))

    def to_plan(self, cells: NDArray[np.floating] | NDArray[np.integer]) -> NDArray[np.int64]:
        """Fine ``(col, row)`` (N, 2) -> planning ``(i, j)`` (N, 2), possibly outside the grid."""
        c = np.asarray(cells, dtype=np.float64).reshape(-1, 2)
        off = np.array([self.col0, self.row0], dtype=np.float64)
        return np.floor((np.rint(c) - off) / self.factor).astype(np.int64)

    def to_fine(self, pcells: NDArray[np.integer]) -> NDArray[np.float64]:
        """Planning ``(i, j)`` (N, 2) -> fine ``(col, row)`` of the planning cell centre (N, 2)."""
        p = np.asarray(pcells, dtype=np.float64).reshape(-1, 2)
        off = np.array([self.col0, self.row0], dtype=np.float64)
        return off + p * self.factor + (self.factor - 1) / 2.0

    def inside(self, pcells: NDArray[np.integer]) -> NDArray[np.bool_]:
        """bool (N,): planning cells within the grid."""
        p = np.asarray(pcells).reshape(-1, 2)
        h, w = self.shape
        return (p[:, 0] >= 0) & (p[:, 0] < w) & (p[:, 1] >= 0) & (p[:, 1] < h)

    def nearest_free(
        self, cell: tuple[float, float] | NDArray[np.floating]
    ) -> tuple[int, int] | None:
        """Planning cell of fine ``cell``; if blocked, the closest traversable one (or None)."""
        return _nearest_free_cell(self.free, self.col0, self.row0, self.factor, cell)

    def clear(self, cells: NDArray[np.floating]) -> NDArray[np.bool_]:
        """bool (N,): fine ``(col, row)`` points (N, 2) that fall in traversable planning cells."""
        p = self.to_plan(cells)
        ok = self.inside(p)
        out = np.zeros(p.shape[0], dtype=bool)
        out[ok] = self.free[p[ok, 1], p[ok, 0]]
        return out

    # -- queries -----------------------------------------------------------------------------

    @property
    def cell_m(self) -> float:
        """Edge of a planning cell in metres."""
        return self.factor * self.resolution_m

    def approach(
        self, fine_cells: NDArray[np.integer], reach: int = 2
    ) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
        """For each fine cell, the closest reachable planning cell within ``reach`` planning cells.

        Frontier cells border unknown space, so their own planning cell is often not traversable;
        the robot only has to get near them (its lidar sees far beyond).

        Returns:
            ``dist_m`` float64 (N,): path length in metres to that planning cell (inf if none);
            ``pcell`` int64 (N, 2): its ``(i, j)``.
        """
        cells = np.asarray(fine_cells)
        if _planning is not None and kernels.enabled() and cells.dtype.kind in "iu":
            cells = np.ascontiguousarray(cells, dtype=np.int64).reshape(-1, 2)
            dist_m: NDArray[np.float64]
            off = (float(self.col0), float(self.row0))
            dist_m, pc = _planning.approach(
                self.field, cells, off[0], off[1], self.factor, reach, self.cell_m
            )
            return dist_m, pc
        p = self.to_plan(fine_cells)
        h, w = self.shape
        d = np.arange(-reach, reach + 1)
        dj, di = np.meshgrid(d, d, indexing="ij")
        offs = np.stack([di.ravel(), dj.ravel()], axis=1)  # (K, 2) (di, dj)
        cand = p[:, None, :] + offs[None, :, :]  # (N, K, 2)
        ok = (cand[..., 0] >= 0) & (cand[..., 0] < w) & (cand[..., 1] >= 0) & (cand[..., 1] < h)
        ci = np.clip(cand[..., 0], 0, w - 1)
        cj = np.clip(cand[..., 1], 0, h - 1)
        vals = np.where(ok, self.field[cj, ci], np.inf)
        best = np.argmin(vals, axis=1)
        n = np.arange(p.shape[0])
        dist = vals[n, best] * self.cell_m
        return dist, cand[n, best]

    def path_to(self, goal: tuple[int, int]) -> NDArray[np.float64] | None:
        """Path from the start to planning cell ``goal`` by descending the field.

        Returns:
            float64 (K, 2) fine ``(col, row)`` points (planning cell centres) from the start to the
            goal, or None when the goal is unreachable.
        """
        i, j = int(goal[0]), int(goal[1])
        h, w = self.shape
        if not (0 <= i < w and 0 <= j < h) or not np.isfinite(self.field[j, i]):
            return None
        if _planning is not None and kernels.enabled():
            down = _planning.descend(self.field, self.free, i, j)
            return self.to_fine(down[::-1])
        f = self.field
        free = self.free
        path = [(i, j)]
        # Each step moves to the neighbour that realises the field value (strictly smaller), so
        # the loop ends at the start after at most (number of cells) steps.
        for _ in range(h * w):
            cur = f[j, i]
            if cur == 0.0:
                break
            best_v, bi, bj = math.inf, i, j
            for dr, dc, cost in _NEIGHBOURS:
                jj, ii = j + dr, i + dc
                if not (0 <= ii < w and 0 <= jj < h) or not free[jj, ii]:
                    continue
                if dr and dc and not (free[j + dr, i] and free[j, i + dc]):
                    continue
                v = f[jj, ii] + cost
                if v < best_v and f[jj, ii] < cur:
                    best_v, bi, bj = v, ii, jj
            if (bi, bj) == (i, j):
                break  # cannot happen on a converged field; guards against an endless loop
            i, j = bi, bj
            path.append((i, j))
        path.reverse()
        return self.to_fine(np.array(path, dtype=np.int64))
