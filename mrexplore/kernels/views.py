"""Compiled kernels of the observation: occupancy shares per view block, the trail channel.

Measured against OpenCV's INTER_AREA path and the numpy trail drawing, which the tests hold
them to (see ``docs/speed.md``).
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

#: Bits of a block's free-cell count in the packed per-cell class code of :func:`view_shares`
#: (a block holds at most 16 cells: factor 4).
SHARE_BITS: int = 5


@numba.njit(cache=True, nogil=True, inline="always")
def _share_code(v: int, free_lo: int, free_hi: int, occ_lo: int) -> int:
    """1 for a free value, ``1 << SHARE_BITS`` for an occupied one, else 0 (branch-free)."""
    return ((v >= free_lo) & (v <= free_hi)) + ((v >= occ_lo) << SHARE_BITS)


@numba.njit(cache=True, nogil=True, inline="always")
def _add_blocks(
    row: NDArray[np.int8],
    acc: NDArray[np.int32],
    c0: int,
    size: int,
    stride: int,
    factor: int,
    free_lo: int,
    free_hi: int,
    occ_lo: int,
) -> None:
    """``acc[x] +=`` the packed class codes of ``row[c0 + stride * (factor * x + k)]``,
    k < factor (called with literal ``stride`` and ``factor``)."""
    for x in range(size):
        b = c0 + factor * stride * x
        t = 0
        for k in range(factor):
            t += _share_code(row[b + k * stride], free_lo, free_hi, occ_lo)
        acc[x] += t


@numba.njit(cache=True, nogil=True)
def view_shares(
    grid: NDArray[np.int8],
    r0: int,
    c0: int,
    stride: int,
    factor: int,
    lut: NDArray[np.uint8],
    code: NDArray[np.int32],
    bounds: NDArray[np.int8],
    acc: NDArray[np.int32],
    out_free: NDArray[np.uint8],
    out_occ: NDArray[np.uint8],
    known: NDArray[np.int64],
) -> None:
    """Free and occupied shares of a square window of an int8 map, in one pass.

    Pixel ``(y, x)`` of the ``(S, S)`` outputs covers the ``factor x factor`` block of window
    cells ``(r0 + stride * (factor * y + a), c0 + stride * (factor * x + b))``; cells outside
    the grid are unknown. ``code[v + 128]`` is 1 for a free value ``v``, ``1 << SHARE_BITS`` for
    an occupied one, else 0 (``bounds``: int8 ``free_lo, free_hi, occ_lo``, the same classes by
    comparisons: free ``free_lo <= v <= free_hi``, occupied ``v >= occ_lo``), so one sum per
    block counts both classes without a branch; a
    pixel's value is ``lut[count]`` (``lut`` reproduces OpenCV's INTER_AREA of 0/255 masks, whose
    output depends only on the count: checked when the lut is built). ``acc``: int32 (S,)
    scratch. Requires ``factor * factor < 2 ** SHARE_BITS``. ``known``: int64 ``(r0, r1, c0, c1)``,
    a half-open box of the grid holding every cell that is not unknown (the whole grid will do):
    the window is read only inside it, since an unknown cell adds nothing to either share.
    """
    h, w = grid.shape
    size = out_free.shape[0]
    mask = (1 << SHARE_BITS) - 1
    span = stride * (factor * size - 1)
    free_lo, free_hi, occ_lo = bounds[0], bounds[1], bounds[2]
    if not (r0 >= 0 and r0 + span < h and c0 >= 0 and c0 + span < w):
        _across_edge(grid, r0, c0, stride, factor, lut, code, bounds, acc, out_free, out_occ, known)
        return
    # The window lies inside the grid (the usual case): no bounds tests, and the block sums of
    # the usual (stride, factor) pairs with literal steps (measured: several times faster than
    # the generic loop with runtime steps, which LLVM does not vectorise). Only the rows and
    # blocks that meet the known box are read; the blocks' slices start at index 0 so that LLVM
    # sees no negative index and still vectorises.
    step = stride * factor
    kr0, kr1 = known[0], known[1]
    x0 = min(max(0, -((c0 + stride * (factor - 1) - known[2]) // step)), size)
    x1 = min(max(x0, (known[3] - 1 - c0) // step + 1), size)
    n = x1 - x0
    part = acc[x0:x1]
    for y in range(size):
        for x in range(size):
            acc[x] = 0
        for a in range(factor):
            r = r0 + stride * (factor * y + a)
            if r < kr0 or r >= kr1:
                continue
            row = grid[r, c0 + step * x0 :]
            # literal strides and factors, so that LLVM unrolls and vectorises each case
            if stride == 2 and factor == 4:
                _add_blocks(row, part, 0, n, 2, 4, free_lo, free_hi, occ_lo)
            elif stride == 1 and factor == 2:
                _add_blocks(row, part, 0, n, 1, 2, free_lo, free_hi, occ_lo)
            elif stride == 2 and factor == 2:
                _add_blocks(row, part, 0, n, 2, 2, free_lo, free_hi, occ_lo)
            elif stride == 1 and factor == 1:
                _add_blocks(row, part, 0, n, 1, 1, free_lo, free_hi, occ_lo)
            else:
                c = c0 + step * x0
                for x in range(n):
                    t = 0
                    for _ in range(factor):
                        t += code[grid[r, c] + 128]
                        c += stride
                    part[x] += t
        for x in range(size):
            out_free[y, x] = lut[acc[x] & mask]
            out_occ[y, x] = lut[acc[x] >> SHARE_BITS]


@numba.njit(cache=True, nogil=True)
def _across_edge(
    grid: NDArray[np.int8],
    r0: int,
    c0: int,
    stride: int,
    factor: int,
    lut: NDArray[np.uint8],
    code: NDArray[np.int32],
    bounds: NDArray[np.int8],
    acc: NDArray[np.int32],
    out_free: NDArray[np.uint8],
    out_occ: NDArray[np.uint8],
    known: NDArray[np.int64],
) -> None:
    """:func:`view_shares` of a window that crosses the grid's edge (cells outside the grid are
    unknown): the same rows and blocks read, with bounds tests on the blocks that cross."""
    h, w = grid.shape
    size = out_free.shape[0]
    mask = (1 << SHARE_BITS) - 1
    free_lo, free_hi, occ_lo = bounds[0], bounds[1], bounds[2]
    step = stride * factor
    reach = stride * (factor - 1)
    kr0, kr1 = max(known[0], 0), min(known[1], h)
    kc0, kc1 = max(known[2], 0), min(known[3], w)
    x0 = min(max(0, -((c0 + reach - kc0) // step)), size)
    x1 = min(max(x0, (kc1 - 1 - c0) // step + 1), size)
    # Of the blocks that meet the known box only the first and the last may cross a side edge:
    # they are summed cell by cell with bounds tests, the blocks between them by the fast sums.
    xa = x0 + 1 if x0 < x1 and c0 + step * x0 < 0 else x0
    xb = x1 - 1 if x1 - 1 >= xa and c0 + step * (x1 - 1) + reach >= w else x1
    n = xb - xa
    part = acc[xa:xb]
    for y in range(size):
        for x in range(size):
            acc[x] = 0
        for a in range(factor):
            r = r0 + stride * (factor * y + a)
            if r < kr0 or r >= kr1:
                continue
            for x in range(x0, xa):
                acc[x] += _edge_block(grid, code, r, c0 + step * x, stride, factor, w)
            for x in range(xb, x1):
                acc[x] += _edge_block(grid, code, r, c0 + step * x, stride, factor, w)
            if n > 0:
                row = grid[r, c0 + step * xa :]
                _row_blocks(row, part, n, stride, factor, code, free_lo, free_hi, occ_lo)
        for x in range(size):
            out_free[y, x] = lut[acc[x] & mask]
            out_occ[y, x] = lut[acc[x] >> SHARE_BITS]


@numba.njit(cache=True, nogil=True, inline="always")
def _row_blocks(
    row: NDArray[np.int8],
    part: NDArray[np.int32],
    n: int,
    stride: int,
    factor: int,
    code: NDArray[np.int32],
    free_lo: int,
    free_hi: int,
    occ_lo: int,
) -> None:
    """``part[x] +=`` the packed class codes of block x of ``row`` (x < n; ``row`` starts at
    block 0), as :func:`view_shares`' inside loop sums them. That loop keeps its own copy of
    these branches: called through this helper it ran 10-20 % slower (measured)."""
    if stride == 2 and factor == 4:
        _add_blocks(row, part, 0, n, 2, 4, free_lo, free_hi, occ_lo)
    elif stride == 1 and factor == 2:
        _add_blocks(row, part, 0, n, 1, 2, free_lo, free_hi, occ_lo)
    elif stride == 2 and factor == 2:
        _add_blocks(row, part, 0, n, 2, 2, free_lo, free_hi, occ_lo)
    elif stride == 1 and factor == 1:
        _add_blocks(row, part, 0, n, 1, 1, free_lo, free_hi, occ_lo)
    else:
        c = 0
        for x in range(n):
            t = 0
            for _ in range(factor):
                t += code[row[c] + 128]
                c += stride
            part[x] += t


@numba.njit(cache=True, nogil=True, inline="always")
def _edge_block(
    grid: NDArray[np.int8],
    code: NDArray[np.int32],
    r: int,
    c: int,
    stride: int,
    factor: int,
    w: int,
) -> int:
    """The packed class codes of row ``r``'s block of ``factor`` cells from column ``c``,
    ``stride`` apart, summed over those inside the grid's ``w`` columns."""
    t = 0
    for k in range(factor):
        cc = c + k * stride
        if cc >= 0 and cc < w:
            t += code[grid[r, cc] + 128]
    return t


@numba.njit(cache=True, nogil=True)
def trail_dots(
    channel: NDArray[np.uint8],
    cells: NDArray[np.float64],
    cx: float,
    cy: float,
    scale: float,
) -> None:
    """Set pixel ``floor((cell - centre) * scale + S / 2)`` of every trail cell (N, 2)
    ``(col, row)`` inside the ``(S, S)`` channel to 255 (the same float64 operations, in the same
    order, as the numpy drawing of an axis-aligned view)."""
    s = channel.shape[0]
    half = s / 2
    for k in range(cells.shape[0]):
        px = math.floor((cells[k, 0] - cx) * scale + half)
        py = math.floor((cells[k, 1] - cy) * scale + half)
        if px >= 0 and px < s and py >= 0 and py < s:
            channel[py, px] = 255


@numba.njit(cache=True, nogil=True)
def turned_trail_dots(
    channel: NDArray[np.uint8],
    cells: NDArray[np.float64],
    cx: float,
    cy: float,
    scale: float,
    cs: float,
    sn: float,
) -> None:
    """:func:`trail_dots` of a view turned by the angle whose cosine and sine are ``cs``,
    ``sn``: each offset ``(dx, dy)`` from the centre is turned to ``(dx cs - dy sn, dx sn +
    dy cs)`` first (the same float64 operations, in the same order, as the numpy drawing)."""
    s = channel.shape[0]
    half = s / 2
    for k in range(cells.shape[0]):
        dx = cells[k, 0] - cx
        dy = cells[k, 1] - cy
        px = math.floor((dx * cs - dy * sn) * scale + half)
        py = math.floor((dx * sn + dy * cs) * scale + half)
        if px >= 0 and px < s and py >= 0 and py < s:
            channel[py, px] = 255
