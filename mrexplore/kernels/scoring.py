"""Compiled kernels of the map-accuracy evaluation (:class:`mrexplore.truth.MapScorer` and
:class:`mrexplore.truth.IncrementalScore`): evaluation against the truth only.
"""

from __future__ import annotations

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
    free on a wall or occupied with no wall within one cell (``near_wall``); held free cells are
    free claims on ``reachable`` cells (counted only when ``want_held``)."""
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
    return n, bad, held


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
    ``claims, contradicting claims, reachable free claims`` over the world (as
    :func:`claim_counts`): both are updated for the cells whose class changed.
    """
    for r in range(r0, r1):
        for c in range(c0, c1):
            k = sample[r, c]
            v = -1 if k < 0 else src[k]
            new = 0
            if v >= 0 and v <= free_hi:
                new = 1
            elif v >= occ_lo:
                new = 2
            old = cls[r, c]
            if new == old:
                continue
            if old == 1:
                counts[0] -= 1
                counts[1] -= walls[r, c]
                counts[2] -= reachable[r, c]
            elif old == 2:
                counts[0] -= 1
                counts[1] -= not near_wall[r, c]
            if new == 1:
                counts[0] += 1
                counts[1] += walls[r, c]
                counts[2] += reachable[r, c]
            elif new == 2:
                counts[0] += 1
                counts[1] += not near_wall[r, c]
            cls[r, c] = new
