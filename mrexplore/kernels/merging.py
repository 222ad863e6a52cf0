"""Compiled kernels of the merger: the verifier's count of how the wall cells of one map land
on the other under a pose, and the wall ICP refinement.

Why compiled: the verifier runs for every hypothesis of every merge (dozens per merge) on up to
20,000 points per map; in numpy each call cost two matrix products, a 3x3 inverse, six
temporary arrays and two ``bincount`` (a fifth of a merge's time, mostly per-call overhead).

Rounding: a point lands on the cell ``rint(x)`` (round half to even, as ``np.rint``), computed as
``x * T[0, 0] + y * T[0, 1] + T[0, 2]`` in float64 without fused multiply-add, so the counts are
the same on every CPU.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = [
    "cells_of",
    "count_both_ways",
    "count_poses",
    "count_shifted",
    "grow_labels",
    "level_add",
    "level_batches",
    "level_find",
    "level_stamp",
    "max_at_cells",
    "pool_blocks",
    "ratio_scores",
    "settle_cells",
    "wall_icp",
]


@numba.njit(cache=True, nogil=True, inline="always")
def _count(
    pts: NDArray[np.float64],
    m00: float,
    m01: float,
    m02: float,
    m10: float,
    m11: float,
    m12: float,
    codes: NDArray[np.uint8],
) -> tuple[int, int, int]:
    """(agree, disagree, landed) of ``pts`` (N, 2) (col, row) moved by the 2x3 affine ``m``
    onto ``codes`` (H, W): code 3 (wall) or 2 (free near a wall) agrees, 1 (free) disagrees,
    0 (unknown) or outside does not count."""
    h, w = codes.shape
    agree = 0
    disagree = 0
    for k in range(pts.shape[0]):
        x = pts[k, 0]
        y = pts[k, 1]
        c = np.rint(x * m00 + y * m01 + m02)
        r = np.rint(x * m10 + y * m11 + m12)
        if c < 0 or c >= w or r < 0 or r >= h:
            continue
        code = codes[int(r), int(c)]
        if code >= 2:
            agree += 1
        elif code == 1:
            disagree += 1
    return agree, disagree, agree + disagree


@numba.njit(cache=True, nogil=True, inline="always")
def _both_ways(
    points_b: NDArray[np.float64],
    points_a: NDArray[np.float64],
    T: NDArray[np.float64],
    codes_a: NDArray[np.uint8],
    codes_b: NDArray[np.uint8],
) -> tuple[int, int, int, int, int]:
    """:func:`count_both_ways`' counts (one place for the arithmetic of both kernels)."""
    a, b, tx = T[0, 0], T[0, 1], T[0, 2]
    c, d, ty = T[1, 0], T[1, 1], T[1, 2]
    det = a * d - b * c
    ia, ib, ic, id_ = d / det, -b / det, -c / det, a / det
    itx = -(ia * tx + ib * ty)
    ity = -(ic * tx + id_ * ty)
    ab, db, nb = _count(points_b, a, b, tx, c, d, ty, codes_a)
    aa, da, _ = _count(points_a, ia, ib, itx, ic, id_, ity, codes_b)
    return ab, db, nb, aa, da


@numba.njit(cache=True, nogil=True)
def count_both_ways(
    points_b: NDArray[np.float64],
    points_a: NDArray[np.float64],
    T: NDArray[np.float64],
    codes_a: NDArray[np.uint8],
    codes_b: NDArray[np.uint8],
) -> tuple[int, int, int, int, int]:
    """Counts of b's wall points moved by ``T`` (3x3 affine, b cells -> a cells) on a's codes and
    of a's wall points moved by its inverse on b's codes: ``(agree_b, disagree_b, landed_b,
    agree_a, disagree_a)``. ``T``'s 2x2 part must be invertible (the caller checks)."""
    return _both_ways(points_b, points_a, T, codes_a, codes_b)


@numba.njit(cache=True, nogil=True)
def count_poses(
    points_b: NDArray[np.float64],
    points_a: NDArray[np.float64],
    Ts: NDArray[np.float64],
    codes_a: NDArray[np.uint8],
    codes_b: NDArray[np.uint8],
) -> NDArray[np.int64]:
    """:func:`count_both_ways` of each of the K poses ``Ts`` (K, 3, 3), in one call: (K, 5)
    ``(agree_b, disagree_b, landed_b, agree_a, disagree_a)`` per pose, the same counts. Every
    pose's 2x2 part must be invertible (the caller checks)."""
    out = np.zeros((Ts.shape[0], 5), dtype=np.int64)
    for k in range(Ts.shape[0]):
        ab, db, nb, aa, da = _both_ways(points_b, points_a, Ts[k], codes_a, codes_b)
        out[k, 0] = ab
        out[k, 1] = db
        out[k, 2] = nb
        out[k, 3] = aa
        out[k, 4] = da
    return out


@numba.njit(cache=True, nogil=True)
def count_shifted(
    base: NDArray[np.float64], offsets: NDArray[np.float64], codes: NDArray[np.uint8]
) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
    """Agree / disagree counts (K,) of the points ``base`` (N, 2) ``(col, row)`` moved by each
    of the K ``offsets`` (K, 2) on ``codes`` (H, W): the numpy reference
    :meth:`mrexplore.merge.common.Verifier._count_many` (one rounded sum per coordinate, the
    same bits) without its K x N temporaries."""
    h, w = codes.shape
    k_n = offsets.shape[0]
    agree = np.zeros(k_n, dtype=np.int64)
    disagree = np.zeros(k_n, dtype=np.int64)
    for k in range(k_n):
        ox = offsets[k, 0]
        oy = offsets[k, 1]
        n_agree = 0
        n_disagree = 0
        for n in range(base.shape[0]):
            c = np.rint(base[n, 0] + ox)
            r = np.rint(base[n, 1] + oy)
            if c < 0 or c >= w or r < 0 or r >= h:
                continue
            code = codes[int(r), int(c)]
            if code >= 2:
                n_agree += 1
            elif code == 1:
                n_disagree += 1
        agree[k] = n_agree
        disagree[k] = n_disagree
    return agree, disagree


@numba.njit(cache=True, nogil=True)
def wall_icp(
    T: NDArray[np.float64],
    pb: NDArray[np.float64],
    labels: NDArray[np.int32],
    lut: NDArray[np.float64],
    w: int,
    h: int,
    iters: int,
    max_dist: float,
) -> NDArray[np.float64]:
    """Point-to-line ICP of the points ``pb`` (N, 2) ``(col, row)`` onto the wall cells of a map
    whose distance-transform labels are ``labels`` (H*W, flat) and label -> cell table ``lut``
    (L, 2): the same formulas, in the same order, as
    :meth:`mrexplore.merge.icp.WallICP.reference` (numpy), which the tests hold it to.
    Returns the refined 3x3 ``T`` (a new array)."""
    T = T.copy()
    n_pts = pb.shape[0]
    md2 = max_dist * max_dist
    ux = np.empty(n_pts)
    uy = np.empty(n_pts)
    nx = np.empty(n_pts)
    ny = np.empty(n_pts)
    dd = np.empty(n_pts)
    for _ in range(iters):
        n_keep = 0
        n_ok = 0
        for k in range(n_pts):
            qx = T[0, 0] * pb[k, 0] + T[0, 1] * pb[k, 1] + T[0, 2]
            qy = T[1, 0] * pb[k, 0] + T[1, 1] * pb[k, 1] + T[1, 2]
            c = int(np.rint(qx))
            r = int(np.rint(qy))
            if c < 0 or c >= w or r < 0 or r >= h:
                continue
            lab = labels[r * w + c]
            ex = qx - lut[lab, 0]
            ey = qy - lut[lab, 1]
            d2 = ex * ex + ey * ey
            if d2 > md2:
                continue
            n_keep += 1
            d = math.sqrt(d2)
            if d > 1e-6:
                ux[n_ok] = qx
                uy[n_ok] = qy
                nx[n_ok] = ex / d
                ny[n_ok] = ey / d
                dd[n_ok] = d
                n_ok += 1
        if n_keep < 10 or n_ok < 10:
            return T
        cx = 0.0
        cy = 0.0
        for k in range(n_ok):
            cx += ux[k]
            cy += uy[k]
        cx /= n_ok
        cy /= n_ok
        A = np.zeros((3, 3))
        bvec = np.zeros(3)
        for k in range(n_ok):
            j0 = nx[k]
            j1 = ny[k]
            j2 = ny[k] * (ux[k] - cx) - nx[k] * (uy[k] - cy)
            A[0, 0] += j0 * j0
            A[0, 1] += j0 * j1
            A[0, 2] += j0 * j2
            A[1, 1] += j1 * j1
            A[1, 2] += j1 * j2
            A[2, 2] += j2 * j2
            bvec[0] -= j0 * dd[k]
            bvec[1] -= j1 * dd[k]
            bvec[2] -= j2 * dd[k]
        A[1, 0] = A[0, 1]
        A[2, 0] = A[0, 2]
        A[2, 1] = A[1, 2]
        for i in range(3):
            A[i, i] += 1e-6
        # 3x3 solve by Cramer's rule (numba's np.linalg needs scipy; A is symmetric positive
        # definite thanks to the 1e-6 ridge)
        det = (
            A[0, 0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1])
            - A[0, 1] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
            + A[0, 2] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0])
        )
        dtx = (
            bvec[0] * (A[1, 1] * A[2, 2] - A[1, 2] * A[2, 1])
            - A[0, 1] * (bvec[1] * A[2, 2] - A[1, 2] * bvec[2])
            + A[0, 2] * (bvec[1] * A[2, 1] - A[1, 1] * bvec[2])
        ) / det
        dty = (
            A[0, 0] * (bvec[1] * A[2, 2] - A[1, 2] * bvec[2])
            - bvec[0] * (A[1, 0] * A[2, 2] - A[1, 2] * A[2, 0])
            + A[0, 2] * (A[1, 0] * bvec[2] - bvec[1] * A[2, 0])
        ) / det
        dth = (
            A[0, 0] * (A[1, 1] * bvec[2] - bvec[1] * A[2, 1])
            - A[0, 1] * (A[1, 0] * bvec[2] - bvec[1] * A[2, 0])
            + bvec[0] * (A[1, 0] * A[2, 1] - A[1, 1] * A[2, 0])
        ) / det
        co = math.cos(dth)
        si = math.sin(dth)
        # T <- step @ T, step = translation(cx + dtx, cy + dty) @ R(dth) @ translation(-cx, -cy)
        # (written out: numba's matrix product needs scipy's BLAS)
        s02 = cx + dtx - (co * cx - si * cy)
        s12 = cy + dty - (si * cx + co * cy)
        T_new = np.empty((3, 3))
        for j in range(3):
            T_new[0, j] = co * T[0, j] - si * T[1, j] + s02 * T[2, j]
            T_new[1, j] = si * T[0, j] + co * T[1, j] + s12 * T[2, j]
            T_new[2, j] = T[2, j]
        T = T_new
        if abs(dtx) + abs(dty) < 0.05 and abs(dth) < 5e-4:
            break
    return T


@numba.njit(cache=True, nogil=True)
def pool_blocks(
    cells: NDArray[np.uint8], s: int, occupied: int, free_max: int
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """Wall and free block maps (ceil(H / s), ceil(W / s)) float32 0/1 of ``cells`` (H, W), an
    int8 occupancy map as its uint8 view (unknown -1 is 255): a block is a wall when any of its
    cells is in ``[occupied, 127]``, free when all s x s of its cells are in ``[0, free_max]``
    (a block cut by the map's edge is not). What :func:`mrexplore.merge.coarse._pool` computes
    with OpenCV (padding, two ``inRange``, two ``INTER_AREA`` resizes), in one pass.

    Row by row into per-column tallies, then folded into blocks every ``s`` rows: the per-row
    loop has no division and compiles to vector code (per-block loops ran 2x slower)."""
    h, w = cells.shape
    n_r, n_c = -(-h // s), -(-w // s)
    wall = np.zeros((n_r, n_c), dtype=np.float32)
    free = np.zeros((n_r, n_c), dtype=np.float32)
    col_wall = np.zeros(w, dtype=np.uint8)
    col_free = np.zeros(w, dtype=np.int32)
    full = s * s
    for bi in range(n_r):
        col_wall[:] = 0
        col_free[:] = 0
        for i in range(bi * s, min(bi * s + s, h)):
            row = cells[i]
            for j in range(w):
                v = row[j]
                col_wall[j] |= np.uint8((v >= occupied) & (v <= 127))
                col_free[j] += np.int32(v <= free_max)
        for bj in range(n_c):
            any_wall = 0
            n_free = 0
            for j in range(bj * s, min(bj * s + s, w)):
                any_wall |= col_wall[j]
                n_free += col_free[j]
            wall[bi, bj] = 1.0 if any_wall else 0.0
            free[bi, bj] = 1.0 if n_free == full else 0.0
    return wall, free


@numba.njit(cache=True, nogil=True)
def ratio_scores(agree: NDArray[np.float64], dis: NDArray[np.float64]) -> NDArray[np.float32]:
    """The coarse ratio score with power 2 of :meth:`mrexplore.merge.coarse.CoarseMatcher.peaks`
    from its two raw correlations (H, W): ``ag = max(rint(agree), 0)``, ``ds = max(rint(dis),
    0)``, ``S = ag * (ag / (ds + ag + 2))^2`` rounded to 6 decimals as ``np.round`` does
    (times 1e6, ``rint``, divided by 1e6), as float32. The same IEEE operations in the same
    order as the numpy path (numpy squares for the power 2), in one pass instead of nine."""
    n_r, n_c = agree.shape
    out = np.empty((n_r, n_c), dtype=np.float32)
    for i in range(n_r):
        for j in range(n_c):
            ag = np.rint(agree[i, j])
            if not (ag > 0.0 or ag != ag):  # np.maximum(x, 0.0): +0.0 for -0.0, NaN kept
                ag = 0.0
            ds = np.rint(dis[i, j])
            if not (ds > 0.0 or ds != ds):
                ds = 0.0
            q = ag / ((ds + ag) + 2.0)
            v = ag * (q * q)
            out[i, j] = np.float32(np.rint(v * 1e6) / 1e6)
    return out


# --- the places' level sweep (mrexplore.merge.places.segment_places) as one union-find: the
# components of {clearance >= level} for a falling ladder of levels are nested, so each level
# only adds its new cells to the sets of the one above, instead of labelling the whole map
# again (one connectedComponentsWithStats per level). A set's root is its first cell in raster
# order; OpenCV numbers 8-connected components in the order of their first 2 x 2 block (its
# block-based scan; every foreground cell of a block is one component), kept per root.


@numba.njit(cache=True, nogil=True)
def level_batches(
    clearance: NDArray[np.float32], levels: NDArray[np.float32]
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int32]]:
    """The cells of ``clearance`` (H, W) grouped by the first of the falling ``levels`` (L,)
    they reach (``clearance >= level`` in float32, as numpy compares a float32 map with a
    Python float): ``(order, starts, first)``, the raster indices of level ``l``'s new cells
    ``order[starts[l]:starts[l + 1]]`` and each cell's first level (L: none). ``levels`` must
    fall strictly (the first level a cell reaches is then found by bisection)."""
    h, w = clearance.shape
    n_levels = levels.shape[0]
    first = np.full(h * w, n_levels, dtype=np.int32)
    counts = np.zeros(n_levels + 1, dtype=np.int64)
    lowest = levels[n_levels - 1] if n_levels else np.float32(np.inf)
    for r in range(h):
        for c in range(w):
            v = clearance[r, c]
            if not v >= lowest:
                continue  # under every level (about half the cells: walls, unknown, edges)
            # the first level v reaches: a bisection of the falling ladder
            lo, hi = 0, n_levels - 1
            while lo < hi:
                mid = (lo + hi) // 2
                if v >= levels[mid]:
                    hi = mid
                else:
                    lo = mid + 1
            first[r * w + c] = lo
            counts[lo + 1] += 1
    starts = np.cumsum(counts)
    order = np.empty(starts[n_levels], dtype=np.int64)
    fill = starts[:n_levels].copy()
    for x in range(h * w):
        li = first[x]
        if li < n_levels:
            order[fill[li]] = x
            fill[li] += 1
    return order, starts, first


@numba.njit(cache=True, nogil=True, inline="always")
def _root(parent: NDArray[np.int64], x: int) -> int:
    while parent[x] != x:
        parent[x] = parent[parent[x]]  # path halving
        x = parent[x]
    return x


@numba.njit(cache=True, nogil=True)
def level_add(
    li: int,
    order: NDArray[np.int64],
    starts: NDArray[np.int64],
    first: NDArray[np.int32],
    w: int,
    parent: NDArray[np.int64],
    block: NDArray[np.int64],
    roots: NDArray[np.int64],
    n_roots: int,
) -> tuple[int, NDArray[np.int64]]:
    """Add level ``li``'s cells to the union-find ``parent`` (H * W; a set's root is its
    smallest raster index, ``block[root]`` its first 2 x 2 block), joining 8-neighbours already
    in; ``roots[:n_roots]``: the roots before. Returns the new root count (``roots`` updated)
    and the roots in the order OpenCV numbers their components."""
    h = first.shape[0] // w
    half_w = (w + 1) // 2
    for t in range(starts[li], starts[li + 1]):
        x = order[t]
        parent[x] = x
        r = x // w
        block[x] = (r >> 1) * half_w + ((x - r * w) >> 1)  # x >= 0: a shift is a halving
        roots[n_roots] = x
        n_roots += 1
    for t in range(starts[li], starts[li + 1]):
        x = order[t]
        r = x // w
        c = x - r * w
        rx = _root(parent, x)  # x's root, kept up to date through its unions below
        for dr in range(-1, 2):
            rr = r + dr
            if rr < 0 or rr >= h:
                continue
            for dc in range(-1, 2):
                cc = c + dc
                if cc < 0 or cc >= w or (dr == 0 and dc == 0):
                    continue
                y = rr * w + cc
                if first[y] > li:
                    continue
                b = _root(parent, y)
                if b == rx:
                    continue
                a = rx
                if b < a:
                    a, b = b, a
                parent[b] = a
                block[a] = min(block[a], block[b])
                rx = a
    k = 0
    for t in range(n_roots):
        x = roots[t]
        if parent[x] == x:
            roots[k] = x
            k += 1
    keys = np.empty(k, dtype=np.int64)
    for t in range(k):
        keys[t] = block[roots[t]]
    return k, roots[:k][np.argsort(keys)]


@numba.njit(cache=True, nogil=True)
def level_find(parent: NDArray[np.int64], cells: NDArray[np.int64]) -> NDArray[np.int64]:
    """The name (root) of the component of each cell (raster indices, already added)."""
    out = np.empty(cells.shape[0], dtype=np.int64)
    for k in range(cells.shape[0]):
        out[k] = _root(parent, cells[k])
    return out


@numba.njit(cache=True, nogil=True)
def level_stamp(
    first: NDArray[np.int32], li: int, start: int, markers: NDArray[np.int32], label: int
) -> None:
    """Write ``label`` into ``markers`` (H, W) where it is 0 on the component of level ``li``
    holding the cell ``start`` (8-connected cells whose first level is <= ``li``)."""
    h, w = markers.shape
    seen = np.zeros(h * w, dtype=np.bool_)
    stack = np.empty(h * w, dtype=np.int64)
    stack[0] = start
    seen[start] = True
    top = 1
    while top > 0:
        top -= 1
        x = stack[top]
        r = x // w
        c = x - r * w
        if markers[r, c] == 0:
            markers[r, c] = label
        for dr in range(-1, 2):
            rr = r + dr
            if rr < 0 or rr >= h:
                continue
            for dc in range(-1, 2):
                cc = c + dc
                if cc < 0 or cc >= w:
                    continue
                y = rr * w + cc
                if not seen[y] and first[y] <= li:
                    seen[y] = True
                    stack[top] = y
                    top += 1


@numba.njit(cache=True, nogil=True)
def grow_labels(markers: NDArray[np.int32], free: NDArray[np.uint8]) -> NDArray[np.int32]:
    """:func:`mrexplore.merge.places._grow` without a dilation of the whole map per round: the
    same rounds (a free unlabelled cell takes the largest label of its 3 x 3 window as it was
    before the round), but each round looks only at the cells beside those labelled in the
    last one (a cell beside an older label was taken in an earlier round)."""
    h, w = markers.shape
    labels = markers.copy()
    n = h * w
    front = np.empty(n, dtype=np.int64)
    nxt = np.empty(n, dtype=np.int64)
    queued = np.zeros(n, dtype=np.bool_)
    n_front = 0
    for r in range(h):
        for c in range(w):
            if labels[r, c] > 0:
                front[n_front] = r * w + c
                n_front += 1
    while n_front > 0:
        n_next = 0
        for t in range(n_front):
            x = front[t]
            r = x // w
            c = x - r * w
            for rr in range(max(r - 1, 0), min(r + 2, h)):
                for cc in range(max(c - 1, 0), min(c + 2, w)):
                    y = rr * w + cc
                    if free[rr, cc] > 0 and labels[rr, cc] == 0 and not queued[y]:
                        queued[y] = True
                        nxt[n_next] = y
                        n_next += 1
        vals = np.empty(n_next, dtype=np.int32)
        for t in range(n_next):  # every value from the labels before the round
            y = nxt[t]
            r = y // w
            c = y - r * w
            best = 0
            for rr in range(max(r - 1, 0), min(r + 2, h)):
                for cc in range(max(c - 1, 0), min(c + 2, w)):
                    best = max(best, labels[rr, cc])
            vals[t] = best
        for t in range(n_next):
            y = nxt[t]
            r = y // w
            labels[r, y - r * w] = vals[t]
        front, nxt = nxt, front
        n_front = n_next
    return labels


@numba.njit(cache=True, nogil=True)
def cells_of(grid: NDArray[np.int8], cells: NDArray[np.int64]) -> NDArray[np.int8]:
    """The values of ``grid`` (H, W) at the flat ``cells``."""
    w = grid.shape[1]
    out = np.empty(cells.shape[0], dtype=np.int8)
    for k in range(cells.shape[0]):
        r = cells[k] // w
        out[k] = grid[r, cells[k] - r * w]
    return out


@numba.njit(cache=True, nogil=True)
def max_at_cells(
    value: NDArray[np.int8],
    cells: NDArray[np.int64],
    w: int,
    patch: NDArray[np.int8],
    r0: int,
    c0: int,
) -> None:
    """``value[k] = max(value[k], patch[r - r0, c - c0])`` for the flat ``cells`` (of a map
    ``w`` cells wide) at ``(r, c)`` that ``patch``, placed with its cell (0, 0) at ``(r0, c0)``,
    covers."""
    h, pw = patch.shape
    for k in range(cells.shape[0]):
        r = cells[k] // w
        pr, pc = r - r0, cells[k] - r * w - c0
        if pr >= 0 and pr < h and pc >= 0 and pc < pw:
            value[k] = max(value[k], patch[pr, pc])


@numba.njit(cache=True, nogil=True)
def settle_cells(
    buf: NDArray[np.int8], cells: NDArray[np.int64], value: NDArray[np.int8]
) -> NDArray[np.int64]:
    """Write ``value`` into ``buf`` (H, W) at the flat ``cells``; returns the cells whose value
    changed, in order."""
    w = buf.shape[1]
    out = np.empty(cells.shape[0], dtype=np.int64)
    n = 0
    for k in range(cells.shape[0]):
        r = cells[k] // w
        c = cells[k] - r * w
        if buf[r, c] != value[k]:
            buf[r, c] = value[k]
            out[n] = cells[k]
            n += 1
    return out[:n]
