"""Compiled (numba) kernel of the merger's verifier: how the wall cells of one map land on the
other under a pose.

Why compiled: :class:`mrexplore.merge.common.Verifier` is called for every hypothesis of every
merge (dozens per merge), on up to 20,000 points per map; in numpy each call cost two matrix
products, a 3x3 inverse, six temporary arrays and two ``bincount`` (profiled: a fifth of a
merge's time, mostly per-call overhead). One pass over the points here does the same counting.

Rounding: a point lands on the cell ``rint(x)`` (round half to even, as ``np.rint``), computed as
``x * T[0, 0] + y * T[0, 1] + T[0, 2]`` in float64 without fused multiply-add, so the counts are
the same on every CPU.
"""

from __future__ import annotations

import numba
import numpy as np
from numpy.typing import NDArray

__all__ = ["count_both_ways"]


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
    a, b, tx = T[0, 0], T[0, 1], T[0, 2]
    c, d, ty = T[1, 0], T[1, 1], T[1, 2]
    det = a * d - b * c
    ia, ib, ic, id_ = d / det, -b / det, -c / det, a / det
    itx = -(ia * tx + ib * ty)
    ity = -(ic * tx + id_ * ty)
    ab, db, nb = _count(points_b, a, b, tx, c, d, ty, codes_a)
    aa, da, _ = _count(points_a, ia, ib, itx, ic, id_, ity, codes_b)
    return ab, db, nb, aa, da
