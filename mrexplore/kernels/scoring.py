"""Compiled kernels of the map-accuracy evaluation (:class:`mrexplore.truth.MapScorer` and
:class:`mrexplore.truth.IncrementalScore`): evaluation against the truth only.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray


@numba.njit(cache=True, nogil=True)
def claim_counts(
    in_world: NDArray[np.int8],
    walls: NDArray[np.bool_],
    near_wall: NDArray[np.bool_],
    reachable: NDArray[np.bool_],
    free_hi: int,
    occ_lo: int,
    want_held: bool,
) -> tuple[int, int, int]:
    """One pass of :class:`mrexplore.truth.MapScorer` over a map warped into the world (all
    (H, W)): ``(claims, contradicting claims, held free cells)``. A claim is a free cell
    (``0 <= v <= free_hi``) or an occupied one (``v >= occ_lo``); it contradicts the truth when
    free on a wall or occupied with no wall within one cell (``near_wall``); held cells are the
    claims on ``reachable`` cells that do not contradict it (counted only when ``want_held``)."""
    h, w = in_world.shape
    n = 0
    bad = 0
    held = 0
    for r in range(h):
        for c in range(w):
            v = in_world[r, c]
            if v >= 0 and v <= free_hi:
                n += 1
                if walls[r, c]:
                    bad += 1
                if want_held and reachable[r, c]:
                    held += 1
            elif v >= occ_lo:
                n += 1
                if not near_wall[r, c]:
                    bad += 1
                elif want_held and reachable[r, c]:
                    held += 1
    return n, bad, held


@numba.njit(cache=True, nogil=True, inline="always")
def _claim(v: int, free_hi: int, occ_lo: int) -> int:
    """A map value's class: 0 no claim (unknown or undecided), 1 free, 2 occupied."""
    if v >= 0 and v <= free_hi:
        return 1
    if v >= occ_lo:
        return 2
    return 0


@numba.njit(cache=True, nogil=True, inline="always")
def _claim_counts(cls: int, wall: bool, near_wall: bool, reachable: bool) -> tuple[int, int, int]:
    """What one world cell of class ``cls`` adds to ``claims, contradicting claims, held
    cells`` (:func:`claim_counts`)."""
    if cls == 1:
        return 1, int(wall), int(reachable)
    if cls == 2:
        return 1, int(not near_wall), int(reachable and near_wall)
    return 0, 0, 0


@numba.njit(cache=True, nogil=True, inline="always")
def _count_change(
    old: int, new: int, wall: bool, near_wall: bool, reachable: bool
) -> tuple[int, int, int]:
    """How a world cell going from class ``old`` to ``new`` changes the running counts."""
    a0, a1, a2 = _claim_counts(old, wall, near_wall, reachable)
    b0, b1, b2 = _claim_counts(new, wall, near_wall, reachable)
    return b0 - a0, b1 - a1, b2 - a2


@numba.njit(cache=True, nogil=True)
def score_region(
    src: NDArray[np.int8],
    sample: NDArray[np.int32],
    cls: NDArray[np.uint8],
    walls: NDArray[np.bool_],
    near_wall: NDArray[np.bool_],
    reachable: NDArray[np.bool_],
    r0: int,
    r1: int,
    c0: int,
    c1: int,
    free_hi: int,
    occ_lo: int,
    counts: NDArray[np.int64],
) -> None:
    """Re-score the world cells ``[r0, r1) x [c0, c1)`` of a map sampled into the world.

    ``sample[r, c]``: the flat index into ``src`` (the map, flat int8) that world cell (r, c)
    takes (nearest neighbour), -1 outside the map. ``cls`` (H, W) uint8 holds each world cell's
    class as last scored (0 no claim, 1 free, 2 occupied); ``counts`` int64 (3,) the running
    ``claims, contradicting claims, held cells`` over the world (as :func:`claim_counts`): both
    are updated for the cells whose class changed.
    """
    for r in range(r0, r1):
        for c in range(c0, c1):
            # arrays indexed here, not in a helper (a helper's array arguments cost ~6x)
            k = sample[r, c]
            new = _claim(-1 if k < 0 else src[k], free_hi, occ_lo)
            if new != cls[r, c]:
                d0, d1, d2 = _count_change(
                    cls[r, c], new, walls[r, c], near_wall[r, c], reachable[r, c]
                )
                counts[0] += d0
                counts[1] += d1
                counts[2] += d2
                cls[r, c] = new


@numba.njit(cache=True, nogil=True)
def score_cells(
    src: NDArray[np.int8],
    map_w: int,
    sample: NDArray[np.int32],
    cls: NDArray[np.uint8],
    walls: NDArray[np.bool_],
    near_wall: NDArray[np.bool_],
    reachable: NDArray[np.bool_],
    t: NDArray[np.float64],
    map_cells: NDArray[np.int64],
    free_hi: int,
    occ_lo: int,
    counts: NDArray[np.int64],
) -> None:
    """Re-score the world cells that sample the map cells ``map_cells`` (flat indices into
    ``src``, a map ``map_w`` cells wide), as :func:`score_region` would: the same ``cls`` and
    ``counts`` as re-scoring any region holding them, since no other world cell's source
    changed.

    ``t`` float64 (6,): ``a, b, tx, c, d, ty`` of the rigid map-to-world transform ``sample``
    was made with (world cells, same resolution). A world cell samples the map cell nearest
    its preimage, so it lies within ~1.5 cells of the map cell's image: the 5 x 5 world cells
    around that image whose ``sample`` is the map cell are all of them.
    """
    h, w = sample.shape
    a, b, tx, c, d, ty = t[0], t[1], t[2], t[3], t[4], t[5]
    for m in map_cells:
        row = m // map_w
        col = m - row * map_w
        ci = math.floor(a * col + b * row + tx + 0.5)
        ri = math.floor(c * col + d * row + ty + 0.5)
        new = _claim(src[m], free_hi, occ_lo)
        for r in range(max(0, ri - 2), min(h, ri + 3)):
            for cc in range(max(0, ci - 2), min(w, ci + 3)):
                if sample[r, cc] == m and new != cls[r, cc]:
                    d0, d1, d2 = _count_change(
                        cls[r, cc], new, walls[r, cc], near_wall[r, cc], reachable[r, cc]
                    )
                    counts[0] += d0
                    counts[1] += d1
                    counts[2] += d2
                    cls[r, cc] = new


@numba.njit(cache=True, nogil=True)
def sampled_displacements(
    grid: NDArray[np.int8],
    r0: int,
    r1: int,
    c0: int,
    c1: int,
    max_points: int,
    t_est: NDArray[np.float64],
    t_true: NDArray[np.float64],
    ox: float,
    oy: float,
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """Per sampled known cell of ``grid[r0:r1, c0:c1]``: how far ``t_est`` puts it from where
    ``t_true`` does (cells), and its distance from ``(ox, oy)`` (cells).

    The sample is :func:`mrexplore.truth.known_cells`' (row-major, every k-th known cell,
    ``k = max(1, n // max_points)``), and each figure is computed with the same IEEE operations
    as :func:`mrexplore.truth.transform_error` and :meth:`mrexplore.sim.Simulation.
    drift_allowance` (``x r00 + y r01 + t0``, then ``sqrt(dx dx + dy dy)``), so the means
    numpy takes of the two (M,) float64 arrays are theirs bit for bit, without the (N, 2)
    intermediate arrays.
    """
    n = 0
    for r in range(r0, r1):
        for c in range(c0, c1):
            if grid[r, c] != -1:
                n += 1
    step = max(1, n // max_points)
    m = (n + step - 1) // step
    disp = np.empty(m, dtype=np.float64)
    rad = np.empty(m, dtype=np.float64)
    a0, a1, a2 = t_est[0, 0], t_est[0, 1], t_est[0, 2]
    b0, b1, b2 = t_est[1, 0], t_est[1, 1], t_est[1, 2]
    p0, p1, p2 = t_true[0, 0], t_true[0, 1], t_true[0, 2]
    q0, q1, q2 = t_true[1, 0], t_true[1, 1], t_true[1, 2]
    idx = 0
    k = 0
    for r in range(r0, r1):
        for c in range(c0, c1):
            if grid[r, c] == -1:
                continue
            if idx % step == 0:
                x = float(c)
                y = float(r)
                dx = (x * a0 + y * a1 + a2) - (x * p0 + y * p1 + p2)
                dy = (x * b0 + y * b1 + b2) - (x * q0 + y * q1 + q2)
                disp[k] = np.sqrt(dx * dx + dy * dy)
                ex = x - ox
                ey = y - oy
                rad[k] = np.sqrt(ex * ex + ey * ey)
                k += 1
            idx += 1
    return disp, rad
