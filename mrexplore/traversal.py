"""Exact traversal of rays on a grid: the geometry the lidar cast and the own-map update share.

Geometry. A point on a grid is ``(col, row)`` with cell centres at integer points, so cell
``(c, r)`` covers ``[c - 0.5, c + 0.5) x [r - 0.5, r + 0.5)``. Internally the traversal works in
*corner coordinates* ``u = col + 0.5``, where cell ``c`` is ``floor(u)`` and grid lines are the
integers.

Traversal. A ray ``p(t) = o + t d`` with ``|d| = 1`` (``t`` in cells) enters a new cell exactly
when it crosses a vertical or a horizontal grid line. The k-th vertical crossing happens at
``t = t0x + k / |dx|`` and enters column ``c0 + k * sign(dx)``; the k-th horizontal crossing
likewise. Both sequences are arithmetic in ``t``, so all crossings of all beams of all robots
are computed at once as ``(N, K)`` arrays, with no Python loop over steps and no sort: the cells
a textbook DDA (Amanatides & Woo) visits are exactly the cells entered at these crossings.

Corners. When a ray passes within :data:`CORNER_EPS` cells of a grid corner, both cells beside
the crossing point (and the diagonal one) are tested, so a ray cannot slip between two wall
cells that touch only at a corner (a diagonal staircase of walls is closed). The compiled
kernels (:mod:`mrexplore.kernels.sensing`) evaluate the same formulas.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import GridError

#: Rays passing within this many cells of a grid corner test both cells beside the corner.
#: Larger than the float32 rounding of the per-slot positions (~2e-5 cells for beams of a few
#: hundred cells), so a crossing exactly at a corner is always recognised; 1e-4 cells is 5 um at
#: 0.05 m per cell.
CORNER_EPS: float = 1e-4

#: Continuous cell coordinates are rounded to this lattice (cells) before anything takes their
#: floor. Robots start at cell centres and move 2.5 cells per step, so they sit exactly on cell
#: boundaries every other step; without the snap, 1e-15 rounding noise (which depends on where
#: the world happens to be placed) would pick the cell on either side.
SNAP_CELLS: float = 1e-9


def snap(u: NDArray[np.floating]) -> NDArray[np.float64]:
    """Round continuous cell coordinates to the :data:`SNAP_CELLS` lattice (see there)."""
    return np.asarray(np.round(np.asarray(u, dtype=np.float64) / SNAP_CELLS) * SNAP_CELLS)


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


def check_walls(walls: object) -> NDArray[np.bool_]:
    if not isinstance(walls, np.ndarray) or walls.ndim != 2 or walls.size == 0:
        raise GridError("walls must be a non-empty 2-D numpy bool array (rows, cols)")
    if walls.dtype != np.bool_:
        raise GridError(f"walls must be a bool array, got dtype {walls.dtype}")
    return walls


def prepare_walls(walls: NDArray[np.bool_]) -> PaddedGrid:
    """Pad ``walls`` (H, W) bool with a ring of walls and build the corner pair planes."""
    w = check_walls(walls)
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
