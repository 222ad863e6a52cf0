"""Compiled kernels of the frontier planners: frontiers, the planning grid, paths, the follower.

Each kernel computes, with the same IEEE operations in the same order, what the numpy/OpenCV
path of :mod:`mrexplore.policies` computes (``math.hypot`` here is the C library's, as numpy's
``hypot``); the tests hold every kernel to that path, and a team's rollout to its actions.
Cells are ``(col, row)``; grids are indexed ``[row, col]``.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

#: int8 map values: unknown, and the free band (``mrexplore.grid``).
_UNKNOWN = -1
_FREE_HI = 25
_OCC_LO = 65


@numba.njit(cache=True, nogil=True, inline="always")
def _is_free(v: int) -> bool:
    return v >= 0 and v <= _FREE_HI


@numba.njit(cache=True, nogil=True)
def frontier_near(grid: NDArray[np.int8], col: int, row: int, radius: int) -> bool:
    """Whether a frontier cell (free, with an unknown 4-neighbour on the grid) lies in the square
    of half-side ``radius`` cells around ``(col, row)`` (a cell on the grid)."""
    h, w = grid.shape
    for r in range(max(row - radius, 0), min(row + radius + 1, h)):
        for c in range(max(col - radius, 0), min(col + radius + 1, w)):
            if not _is_free(grid[r, c]):
                continue
            if (
                (r > 0 and grid[r - 1, c] == _UNKNOWN)
                or (r + 1 < h and grid[r + 1, c] == _UNKNOWN)
                or (c > 0 and grid[r, c - 1] == _UNKNOWN)
                or (c + 1 < w and grid[r, c + 1] == _UNKNOWN)
            ):
                return True
    return False


@numba.njit(cache=True, nogil=True)
def _find(parent: NDArray[np.int32], i: int) -> int:
    while parent[i] != i:
        parent[i] = parent[parent[i]]
        i = parent[i]
    return i


@numba.njit(cache=True, nogil=True)
def frontier_clusters(
    grid: NDArray[np.int8], min_size: int
) -> tuple[
    NDArray[np.int64],
    NDArray[np.int64],
    NDArray[np.int64],
    NDArray[np.float64],
    NDArray[np.int64],
]:
    """The 8-connected clusters of frontier cells with at least ``min_size`` cells.

    A frontier cell is free with an unknown 4-neighbour inside the window of the known cells
    grown by one cell (clipped to the grid); centroids and targets are measured in that
    window's cells, as OpenCV's connected-component statistics are (sums over the cells as
    integers, divided as float64).

    Returns:
        ``cells`` int64 (N, 2) ``(col, row)`` grid cells, grouped by cluster, raster order
        within one; ``starts`` int64 (K + 1,) the groups' bounds; ``window`` int64 (2,)
        ``(col0, row0)`` of the window; ``centroids`` float64 (K, 2) in window cells;
        ``targets`` int64 (K,) index into ``cells`` of each cluster's cell nearest its centroid
        (the first in raster order on ties). K = 0 when nothing qualifies.
    """
    h, w = grid.shape
    r_lo, r_hi, c_lo, c_hi = h, -1, w, -1
    for r in range(h):
        # each row's first and last known cell, looked for from either end
        first = 0
        while first < w and grid[r, first] == _UNKNOWN:
            first += 1
        if first == w:
            continue
        last = w - 1
        while grid[r, last] == _UNKNOWN:
            last -= 1
        if r < r_lo:
            r_lo = r
        r_hi = r
        c_lo = min(c_lo, first)
        c_hi = max(c_hi, last)
    window = np.zeros(2, dtype=np.int64)
    if r_hi < 0:
        return (
            np.zeros((0, 2), dtype=np.int64),
            np.zeros(1, dtype=np.int64),
            window,
            np.zeros((0, 2)),
            np.zeros(0, dtype=np.int64),
        )
    r0, r1 = max(r_lo - 1, 0), min(r_hi + 2, h)
    c0, c1 = max(c_lo - 1, 0), min(c_hi + 2, w)
    window[0], window[1] = c0, r0
    hh, ww = r1 - r0, c1 - c0
    parent = np.full(hh * ww, -1, dtype=np.int32)
    # the frontier cells' flat indices in raster order: the later passes visit only them
    found = np.empty(hh * ww, dtype=np.int64)
    n_found = 0
    for y in range(hh):
        r = r0 + y
        for x in range(ww):
            c = c0 + x
            if not _is_free(grid[r, c]):
                continue
            if not (
                (y > 0 and grid[r - 1, c] == _UNKNOWN)
                or (y + 1 < hh and grid[r + 1, c] == _UNKNOWN)
                or (x > 0 and grid[r, c - 1] == _UNKNOWN)
                or (x + 1 < ww and grid[r, c + 1] == _UNKNOWN)
            ):
                continue
            i = y * ww + x
            parent[i] = i
            found[n_found] = i
            n_found += 1
            # the four neighbours already visited: west, north-west, north, north-east
            for dy, dx in ((0, -1), (-1, -1), (-1, 0), (-1, 1)):
                yy, xx = y + dy, x + dx
                if yy < 0 or xx < 0 or xx >= ww:
                    continue
                j = yy * ww + xx
                if parent[j] < 0:
                    continue
                a, b = _find(parent, i), _find(parent, j)
                if a != b:
                    if a < b:
                        parent[b] = a
                    else:
                        parent[a] = b
    # clusters numbered by their first cell in raster order; sizes and coordinate sums
    frontier = found[:n_found]
    label = np.full(hh * ww, -1, dtype=np.int32)
    n = 0
    for i in frontier:
        root = _find(parent, i)
        if label[root] < 0:
            label[root] = n
            n += 1
    size = np.zeros(n, dtype=np.int64)
    sx = np.zeros(n, dtype=np.int64)
    sy = np.zeros(n, dtype=np.int64)
    for i in frontier:
        k = label[_find(parent, i)]
        size[k] += 1
        sx[k] += i % ww
        sy[k] += i // ww
    keep = np.full(n, -1, dtype=np.int64)
    n_keep = 0
    total = 0
    for k in range(n):
        if size[k] >= min_size:
            keep[k] = n_keep
            n_keep += 1
            total += size[k]
    starts = np.zeros(n_keep + 1, dtype=np.int64)
    centroids = np.zeros((n_keep, 2))
    for k in range(n):
        if keep[k] >= 0:
            q = keep[k]
            starts[q + 1] = size[k]
            centroids[q, 0] = float(sx[k]) / float(size[k])
            centroids[q, 1] = float(sy[k]) / float(size[k])
    for q in range(n_keep):
        starts[q + 1] += starts[q]
    cells = np.empty((total, 2), dtype=np.int64)
    fill = starts[:-1].copy()
    targets = np.full(n_keep, -1, dtype=np.int64)
    best = np.full(n_keep, np.inf)
    for i in frontier:
        q = keep[label[_find(parent, i)]]
        if q < 0:
            continue
        x, y = i % ww, i // ww
        dx = x - centroids[q, 0]
        dy = y - centroids[q, 1]
        d2 = dx * dx + dy * dy
        if d2 < best[q]:
            best[q] = d2
            targets[q] = fill[q]
        cells[fill[q], 0] = x + c0
        cells[fill[q], 1] = y + r0
        fill[q] += 1
    return cells, starts, window, centroids, targets


@numba.njit(cache=True, nogil=True)
def _blocked(crop: NDArray[np.int8], disc: NDArray[np.uint8]) -> NDArray[np.uint8]:
    """uint8 (H, W) of ``crop``: 1 where the occupied cells dilated by ``disc`` (odd square,
    centred, convex and symmetric) reach. The disc is one run of columns per row offset, so the
    dilation is the occupied cells dilated along the rows by each run's half width, shifted by
    its row offset: whole-row passes that LLVM vectorises."""
    ch, cw = crop.shape
    k = disc.shape[0] // 2
    half = np.empty(2 * k + 1, dtype=np.int64)
    for d in range(2 * k + 1):
        half[d] = (np.count_nonzero(disc[d]) - 1) // 2  # -1: an empty row
    widest = 0
    for d in range(2 * k + 1):
        widest = max(widest, half[d])
    # along[wd]: the occupied cells dilated along the rows by wd cells, wd = 0 .. widest
    along = np.zeros((widest + 1, ch, cw), dtype=np.uint8)
    occ = along[0]
    for r in range(ch):
        for c in range(cw):
            occ[r, c] = crop[r, c] >= _OCC_LO
    for wd in range(1, widest + 1):
        prev = along[wd - 1]
        cur = along[wd]
        n = cw - wd
        for r in range(ch):
            pr = prev[r]
            cr = cur[r]
            orow = occ[r]
            for c in range(cw):
                cr[c] = pr[c]
            if n <= 0:
                continue
            # slices that start at index 0: LLVM sees no negative index and vectorises
            shifted = cr[wd:]
            left = orow[:n]
            for c in range(n):
                shifted[c] |= left[c]
            right = orow[wd:]
            for c in range(n):
                cr[c] |= right[c]
    blocked = np.zeros((ch, cw), dtype=np.uint8)
    for d in range(2 * k + 1):
        if half[d] < 0:
            continue
        s = d - k  # row a of the result takes row a - s of the dilation
        dil = along[half[d]]
        for a in range(max(0, s), min(ch, ch + s)):
            src = dil[a - s]
            dst = blocked[a]
            for c in range(cw):
                dst[c] |= src[c]
    return blocked


@numba.njit(cache=True, nogil=True)
def coarse_free(
    crop: NDArray[np.int8],
    disc: NDArray[np.uint8],
    factor: int,
    h: int,
    w: int,
    unknown_is_free: bool,
) -> NDArray[np.bool_]:
    """Traversable planning cells, bool (h, w): all ``factor x factor`` fine cells clear of the
    occupied cells dilated by ``disc`` (odd square, centred; cells beyond ``crop`` blocked) and
    at least half of them free (known free, or unknown with ``unknown_is_free``)."""
    ch, cw = crop.shape
    blocked = _blocked(crop, disc)
    unk = np.int8(-128 if not unknown_is_free else _UNKNOWN)
    need = factor * factor
    free = np.zeros((h, w), dtype=np.bool_)
    if factor == 1:
        for j in range(h):
            for i in range(w):
                v = crop[j, i]
                free[j, i] = (blocked[j, i] == 0) & (((v >= 0) & (v <= _FREE_HI)) | (v == unk))
        return free
    if factor == 2:
        # the planners' factor: each planning cell's four fine cells read in place (a planning
        # cell reaching beyond the crop has blocked cells: not traversable)
        for j in range(min(h, ch // 2)):
            top, bottom = crop[2 * j], crop[2 * j + 1]
            btop, bbottom = blocked[2 * j], blocked[2 * j + 1]
            for i in range(min(w, cw // 2)):
                n_ok = 0
                n_free = 0
                for v, bl in (
                    (top[2 * i], btop[2 * i]),
                    (top[2 * i + 1], btop[2 * i + 1]),
                    (bottom[2 * i], bbottom[2 * i]),
                    (bottom[2 * i + 1], bbottom[2 * i + 1]),
                ):
                    ok = 1 - bl
                    n_ok += ok
                    n_free += ok & (((v >= 0) & (v <= _FREE_HI)) | (v == unk))
                free[j, i] = (n_ok == 4) & (2 * n_free >= 4)
        return free
    # per planning cell: fine cells clear of the walls, and of those the free ones
    n_ok_all = np.zeros((h, w), dtype=np.int32)
    n_free_all = np.zeros((h, w), dtype=np.int32)
    col = np.arange(cw) // factor
    for a in range(ch):
        j = a // factor
        for b in range(cw):
            v = crop[a, b]
            ok = 1 - blocked[a, b]
            fr = ((v >= 0) & (v <= _FREE_HI)) | (v == unk)
            n_ok_all[j, col[b]] += ok
            n_free_all[j, col[b]] += ok & fr
    for j in range(h):
        for i in range(w):
            free[j, i] = (n_ok_all[j, i] == need) & (2 * n_free_all[j, i] >= need)
    return free


@numba.njit(cache=True, nogil=True)
def distance_cells(
    free: NDArray[np.bool_], starts: NDArray[np.int64], straight: int, diag: int
) -> NDArray[np.float64]:
    """Octile distance (cells, float64 (h, w)) from the flat indices ``starts`` over ``free``
    (bool (h, w)); ``inf`` where unreachable or blocked. Integer step costs ``straight`` and
    ``diag`` (no corner cutting); a bucket queue of width ``straight``: a cell's distance is
    final when its bucket is reached, since a step (at least ``straight``, less than
    ``2 * straight``) lands one or two buckets later."""
    h, w = free.shape
    # a blocked ring around the grid: the neighbours of a cell need no bounds tests
    W = w + 2
    ring = np.zeros((h + 2) * W, dtype=np.bool_)
    for j in range(h):
        row = free[j]
        base = (j + 1) * W + 1
        for i in range(w):
            ring[base + i] = row[i]
    unreached = 2 * diag * h * w
    dist = np.full(ring.size, unreached, dtype=np.int64)
    # three ring buckets of cell indices (lazy deletion: stale entries are skipped)
    cap = 8 * h * w + starts.size + 1
    buckets = np.empty((3, cap), dtype=np.int64)
    fill = np.zeros(3, dtype=np.int64)
    for s in starts:
        r = s // w
        p = (r + 1) * W + (s - r * w) + 1
        dist[p] = 0
        buckets[0, fill[0]] = p
        fill[0] += 1
    level = 0
    pending = starts.size
    while pending > 0:
        b = level % 3
        i = 0
        while i < fill[b]:
            u = buckets[b, i]
            i += 1
            pending -= 1
            d = dist[u]
            if d // straight != level:
                continue  # stale: reached later with a shorter distance
            nd = d + straight
            for v in (u - W, u + W, u - 1, u + 1):
                if ring[v] and nd < dist[v]:
                    dist[v] = nd
                    nb = (nd // straight) % 3
                    buckets[nb, fill[nb]] = v
                    fill[nb] += 1
                    pending += 1
            # a diagonal step needs both cells it passes beside free (no corner cutting)
            nd = d + diag
            up, down, left, right = ring[u - W], ring[u + W], ring[u - 1], ring[u + 1]
            for v, ok in (
                (u - W - 1, up and left),
                (u - W + 1, up and right),
                (u + W - 1, down and left),
                (u + W + 1, down and right),
            ):
                if ok and ring[v] and nd < dist[v]:
                    dist[v] = nd
                    nb = (nd // straight) % 3
                    buckets[nb, fill[nb]] = v
                    fill[nb] += 1
                    pending += 1
        fill[b] = 0
        level += 1
    out = np.empty((h, w))
    for j in range(h):
        base = (j + 1) * W + 1
        for i in range(w):
            v = dist[base + i]
            out[j, i] = np.inf if v >= unreached or not free[j, i] else float(v) / straight
    return out


@numba.njit(cache=True, nogil=True, inline="always")
def _plan_cell(v: float, off: float, factor: int) -> int:
    """Planning index of a fine coordinate (``PlanningGrid.to_plan``)."""
    return int(np.floor((np.rint(v) - off) / factor))


@numba.njit(cache=True, nogil=True)
def approach(
    field: NDArray[np.float64],
    cells: NDArray[np.int64],
    col0: float,
    row0: float,
    factor: int,
    reach: int,
    cell_m: float,
) -> tuple[NDArray[np.float64], NDArray[np.int64]]:
    """Per fine cell (N, 2): the smallest ``field`` value (planning cells) within ``reach``
    planning cells (the first in row-then-column offset order on ties) times ``cell_m``
    (metres; inf when none is finite) and that planning cell (N, 2) ``(i, j)``."""
    h, w = field.shape
    n = cells.shape[0]
    dist = np.empty(n)
    pcell = np.empty((n, 2), dtype=np.int64)
    for q in range(n):
        pi = _plan_cell(float(cells[q, 0]), col0, factor)
        pj = _plan_cell(float(cells[q, 1]), row0, factor)
        best = np.inf
        bi, bj = pi - reach, pj - reach
        first = True
        for dj in range(-reach, reach + 1):
            for di in range(-reach, reach + 1):
                i, j = pi + di, pj + dj
                v = field[j, i] if 0 <= i < w and 0 <= j < h else np.inf
                if first or v < best:
                    best, bi, bj = v, i, j
                    first = False
        dist[q] = best * cell_m
        pcell[q, 0] = bi
        pcell[q, 1] = bj
    return dist, pcell


@numba.njit(cache=True, nogil=True)
def descend(
    field: NDArray[np.float64], free: NDArray[np.bool_], goal_i: int, goal_j: int
) -> NDArray[np.int64]:
    """Planning cells (K, 2) ``(i, j)`` from ``(goal_i, goal_j)`` down the field to its zero
    (goal first): each step to the free neighbour (no corner cutting) with the smallest
    ``field + step cost`` among those with a smaller field value."""
    h, w = field.shape
    drs = (-1, 1, 0, 0, -1, -1, 1, 1)
    dcs = (0, 0, -1, 1, -1, 1, -1, 1)
    sqrt2 = math.sqrt(2.0)
    out = np.empty((h * w + 1, 2), dtype=np.int64)
    i, j = goal_i, goal_j
    out[0, 0], out[0, 1] = i, j
    n = 1
    for _ in range(h * w):
        cur = field[j, i]
        if cur == 0.0:
            break
        best_v, bi, bj = np.inf, i, j
        for k in range(8):
            dr, dc = drs[k], dcs[k]
            jj, ii = j + dr, i + dc
            if not (0 <= ii < w and 0 <= jj < h) or not free[jj, ii]:
                continue
            if k >= 4 and not (free[j + dr, i] and free[j, i + dc]):
                continue
            v = field[jj, ii] + (sqrt2 if k >= 4 else 1.0)
            if v < best_v and field[jj, ii] < cur:
                best_v, bi, bj = v, ii, jj
        if bi == i and bj == j:
            break
        i, j = bi, bj
        out[n, 0], out[n, 1] = i, j
        n += 1
    return out[:n]


@numba.njit(cache=True, nogil=True)
def max_step(path: NDArray[np.float64]) -> float:
    """Longest segment of a polyline (K >= 2, 2), NaN-propagating as numpy's ``max``."""
    m = -np.inf
    for q in range(path.shape[0] - 1):
        s = math.hypot(path[q + 1, 0] - path[q, 0], path[q + 1, 1] - path[q, 1])
        if s > m or s != s:
            m = s
            if s != s:
                break
    return m


@numba.njit(cache=True, nogil=True)
def densify(path: NDArray[np.float64], spacing: float) -> NDArray[np.float64]:
    """``path`` (K >= 2, 2) with ``ceil(segment / spacing)`` evenly spaced points per segment
    and its last point (``mrexplore.policies.base.densify_path``'s arithmetic)."""
    k = path.shape[0]
    steps = np.empty(k - 1, dtype=np.int64)
    total = 0
    for q in range(k - 1):
        s = math.hypot(path[q + 1, 0] - path[q, 0], path[q + 1, 1] - path[q, 1])
        steps[q] = max(int(np.ceil(s / spacing)), 1)
        total += steps[q]
    out = np.empty((total + 1, 2))
    o = 0
    for q in range(k - 1):
        n = steps[q]
        for m in range(n):
            frac = float(m) / float(n)
            out[o, 0] = path[q, 0] + (path[q + 1, 0] - path[q, 0]) * frac
            out[o, 1] = path[q, 1] + (path[q + 1, 1] - path[q, 1]) * frac
            o += 1
    out[o, 0], out[o, 1] = path[k - 1, 0], path[k - 1, 1]
    return out


@numba.njit(cache=True, nogil=True)
def nearest_index(path: NDArray[np.float64], x: float, y: float) -> int:
    """Index of the path point (K, 2) with the smallest squared distance to ``(x, y)`` (the
    first on ties)."""
    best = 0
    bd = np.inf
    for q in range(path.shape[0]):
        dx = path[q, 0] - x
        dy = path[q, 1] - y
        d = dx * dx + dy * dy
        if d < bd or (q == 0) or d != d:
            best, bd = q, d
            if d != d:
                break
    return best


@numba.njit(cache=True, nogil=True)
def waypoint(
    path: NDArray[np.float64],
    x: float,
    y: float,
    lookahead: float,
    free: NDArray[np.bool_],
    col0: float,
    row0: float,
    factor: int,
    use_free: bool,
) -> int:
    """The path follower's waypoint index on a dense ``path`` (K, 2) for a robot at ``(x, y)``.

    The first point ``lookahead`` cells or more beyond the point nearest the robot (the last
    point if none); with ``use_free``, pulled back to the farthest point whose straight segment
    from the robot, sampled every half cell past the first 1.5 cells, stays on traversable
    cells of the planning grid ``free`` (offset ``col0, row0``, ``factor`` fine cells per
    cell); the point after the nearest when no segment is clear.
    """
    n = path.shape[0]
    k = 0
    bd = np.inf
    for q in range(n):
        d = math.hypot(path[q, 0] - x, path[q, 1] - y)
        if d != d:
            k = q
            break
        if d < bd or q == 0:
            k, bd = q, d
    j = n - 1
    for q in range(k, n):
        if math.hypot(path[q, 0] - x, path[q, 1] - y) >= lookahead:
            j = q
            break
    if not use_free or j <= k:
        return j
    h, w = free.shape
    longest = -np.inf
    for q in range(k + 1, j + 1):
        s = math.hypot(path[q, 0] - x, path[q, 1] - y)
        if s > longest or s != s:
            longest = s
    steps = max(int(np.ceil(longest / 0.5)), 1)
    for q in range(j, k, -1):
        sx = path[q, 0] - x
        sy = path[q, 1] - y
        length = math.hypot(sx, sy)
        ok = True
        for s in range(1, steps + 1):
            t = float(s) / float(steps)
            if length * t < 1.5:
                continue
            i = _plan_cell(x + sx * t, col0, factor)
            jj = _plan_cell(y + sy * t, row0, factor)
            if not (0 <= i < w and 0 <= jj < h and free[jj, i]):
                ok = False
                break
        if ok:
            return q
    return k + 1
