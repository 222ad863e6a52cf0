"""What pins a merge's pose: how the walls that agree under it hold it in place.

Two maps laid on each other by a pose agree on some wall cells. Whether those walls *pin* the
pose is a question of their directions and extent, not of their number:

- :func:`cross_support`: the smaller eigenvalue of ``sum n n^T`` over the agreeing walls'
  normals, in wall cells. One straight wall or a corridor gives ~0 however long: a slide along
  it fits as well. :func:`slide_direction` is the direction it is weakest along.
- :func:`lone_pin_support`: the same with one small thing of b left out: rack sides pinned
  along only by the post beside them match every aisle's post.
- :func:`agreeing_area`: the area of the smallest rectangle around the agreeing walls; one
  object, a rack or a pillar, fits every copy of it.

The semantic merger (:mod:`mrexplore.merge.semantic`) refuses a pose that fails them
(``min_cross_cells``, ``lone_pin_test``, ``min_wall_area_m2``); the measurements behind the
thresholds are in ``docs/merging.md``.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore.grid import Transform
from mrexplore.merge.common import MapCodes, agreeing_cells, rectangle_area, rigid_inverse
from mrexplore.merge.repeats import Structures

__all__ = [
    "CROSS_GUARD_CELLS",
    "PinTerms",
    "agreeing_area",
    "cross_support",
    "lone_pin_support",
    "slide_direction",
]

#: Within this many cells of ``min_cross_cells`` the cross support is recomputed in float64
#: before it decides: float32's CPU-dependent last bits move it by far less.
CROSS_GUARD_CELLS = 1.0

#: How far (cells) the structure tensor of :func:`cross_support` reaches: float Gaussian
#: kernels span 4 sigma each side (OpenCV), so blur 1 (4) + Sobel (1) + blur 4 (16), plus slack.
_TENSOR_REACH = 24


#: :func:`_support_terms`: the unit normals (N, 2) and the index (N,) of their b wall cells.
_Terms = tuple[NDArray[np.float64], NDArray[np.intp]]


def _support_tensor(
    wall_a: NDArray[np.bool_],
    wall_b: NDArray[np.bool_],
    T: Transform,
    precise: bool = False,
    cells_b: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None,
) -> NDArray[np.float64] | None:
    """``sum n n^T`` (2 x 2, (col, row) axes) of :func:`cross_support`, None without support."""
    return _tensor(_support_terms(wall_a, wall_b, T, precise, cells_b))


def _tensor(terms: _Terms | None) -> NDArray[np.float64] | None:
    """``sum n n^T`` (2 x 2) of the support terms, None without support."""
    return None if terms is None else np.asarray(terms[0].T @ terms[0], dtype=np.float64)


def _support_terms(
    wall_a: NDArray[np.bool_],
    wall_b: NDArray[np.bool_],
    T: Transform,
    precise: bool,
    cells_b: tuple[NDArray[np.intp], NDArray[np.intp]] | None,
) -> tuple[NDArray[np.float64], NDArray[np.intp]] | None:
    """The unit normals ``n`` (N, 2) of :func:`cross_support`'s sum and the index (N,) of the
    b wall cell each belongs to (in ``cells_b``' order); None without support."""
    rb, cb = np.nonzero(wall_b) if cells_b is None else cells_b
    index = np.arange(rb.size)
    T = np.asarray(T, dtype=np.float64)
    c = np.rint(T[0, 0] * cb + T[0, 1] * rb + T[0, 2]).astype(np.int64)
    r = np.rint(T[1, 0] * cb + T[1, 1] * rb + T[1, 2]).astype(np.int64)
    h, w = wall_a.shape
    inside = (c >= 0) & (c < w) & (r >= 0) & (r < h)
    c, r, index = c[inside], r[inside], index[inside]
    if c.size == 0:
        return None
    # The filters below reach 21 cells (blur 4 + Sobel 1 + blur 16): a window that far around
    # b's landed walls gives the same tensor there as the whole map, at a fraction of the cost.
    r0, c0 = max(int(r.min()) - _TENSOR_REACH, 0), max(int(c.min()) - _TENSOR_REACH, 0)
    r1, c1 = min(int(r.max()) + _TENSOR_REACH + 1, h), min(int(c.max()) + _TENSOR_REACH + 1, w)
    win = wall_a[r0:r1, c0:c1]
    r, c = r - r0, c - c0
    near = cv2.dilate(win.view(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
    on = near[r, c]
    c, r, index = c[on], r[on], index[on]
    if c.size == 0:
        return None
    dtype, depth = (np.float64, cv2.CV_64F) if precise else (np.float32, cv2.CV_32F)
    img = cv2.GaussianBlur(win.astype(dtype), (0, 0), 1.0)
    gx = cv2.Sobel(img, depth, 1, 0, ksize=3)
    gy = cv2.Sobel(img, depth, 0, 1, ksize=3)
    jxx = cv2.GaussianBlur(gx * gx, (0, 0), 4.0)
    jyy = cv2.GaussianBlur(gy * gy, (0, 0), 4.0)
    jxy = cv2.GaussianBlur(gx * gy, (0, 0), 4.0)
    ang = 0.5 * np.arctan2(2.0 * jxy[r, c], jxx[r, c] - jyy[r, c]).astype(np.float64)
    return np.stack([np.cos(ang), np.sin(ang)], axis=1), index


def lone_pin_support(
    wall_a: NDArray[np.bool_],
    wall_b: NDArray[np.bool_],
    T: Transform,
    structures_b: Structures,
    small_cells: float,
    cells_b: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None,
    top: int = 3,
    precise: bool = False,
) -> tuple[float, int] | None:
    """:func:`cross_support` with one small thing of b left out, the lowest over the
    ``top`` small things (:meth:`Structures.is_small` under ``small_cells``) carrying most of
    the support's cells, and that thing's cell count; None when no small thing agrees.

    Parallel rack sides pin a pose across them only; a post beside them may be all that pins
    it along, and a warehouse has a post by every aisle. ``precise``: as for
    :func:`cross_support` (float32 filters unless set)."""
    terms = _support_terms(wall_a, wall_b, T, precise, cells_b)
    return _lone_pin(terms, wall_b, structures_b, small_cells, cells_b, top)


def _lone_pin(
    terms: _Terms | None,
    wall_b: NDArray[np.bool_],
    structures_b: Structures,
    small_cells: float,
    cells_b: tuple[NDArray[np.intp], NDArray[np.intp]] | None,
    top: int = 3,
) -> tuple[float, int] | None:
    """:func:`lone_pin_support` from the pose's :func:`_support_terms`."""
    if terms is None:
        return None
    u, index = terms
    rb, cb = np.nonzero(wall_b) if cells_b is None else cells_b
    labels = structures_b.labels[rb[index], cb[index]]
    counts = np.bincount(labels)
    lowest: tuple[float, int] | None = None
    tried = 0
    for k in np.argsort(-counts, kind="stable"):
        k = int(k)
        if tried == top or counts[k] == 0:
            break
        if k == 0 or not structures_b.is_small(k, small_cells):
            continue
        tried += 1
        rest = u[labels != k]
        support = float(np.linalg.eigvalsh(rest.T @ rest)[0]) if rest.size else 0.0
        if lowest is None or support < lowest[0]:
            lowest = (support, int(counts[k]))
    return lowest


def cross_support(
    wall_a: NDArray[np.bool_],
    wall_b: NDArray[np.bool_],
    T: Transform,
    precise: bool = False,
    cells_b: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None,
) -> float:
    """How firmly a pose is pinned along its weakest direction, in wall cells: the smaller
    eigenvalue of ``sum n n^T`` over b's wall cells that land within a cell of a's walls under
    ``T`` (b cells -> a cells), ``n`` the unit normal of a's wall there.

    Normals come from a's structure tensor (gradients of the lightly blurred walls, their
    products averaged over 4 cells), which smooths the staircase and the bumps of lidar walls.
    One straight wall, or the two parallel walls of a corridor, gives ~0 whatever its length:
    the maps then agree equally well after a slide along it, and only wall bumps of a cell or
    two would decide where. A room corner gives the length of its shorter wall.

    In float32 (OpenCV's fast filters) unless ``precise``: float32's last bits differ between
    CPUs' SIMD paths, by far less than a thousandth of a cell here, so a caller comparing the
    answer with a threshold recomputes it with ``precise=True`` (float64) when it lies near.
    ``cells_b``: ``np.nonzero(wall_b)``, when the caller has it.
    """
    return _cross(_support_terms(wall_a, wall_b, T, precise, cells_b))


def _cross(terms: _Terms | None) -> float:
    """:func:`cross_support` from the pose's :func:`_support_terms`."""
    M = _tensor(terms)
    return 0.0 if M is None else float(np.linalg.eigvalsh(M)[0])


class PinTerms:
    """The support terms of one pose (b cells -> a cells), in float32 and in float64, each
    computed at most once: the cross-support and lone-pin tests of a merge read the same ones.

    Float32 (OpenCV's fast filters) differs between CPUs' SIMD paths in its last bits, far
    below a thousandth of a cell here; a caller comparing with a threshold recomputes with
    ``precise=True`` (float64) when the float32 answer lies within :data:`CROSS_GUARD_CELLS`.
    """

    def __init__(
        self,
        wall_a: NDArray[np.bool_],
        wall_b: NDArray[np.bool_],
        T: Transform,
        cells_b: tuple[NDArray[np.intp], NDArray[np.intp]],
    ) -> None:
        self._args = (wall_a, wall_b, T)
        self._cells_b = cells_b
        self._done: dict[bool, _Terms | None] = {}

    def _terms(self, precise: bool) -> _Terms | None:
        if precise not in self._done:
            self._done[precise] = _support_terms(*self._args, precise, self._cells_b)
        return self._done[precise]

    def cross(self, precise: bool) -> float:
        """:func:`cross_support` of the pose, wall cells."""
        return _cross(self._terms(precise))

    def lone_pin(
        self, precise: bool, structures_b: Structures, small_cells: float, top: int = 3
    ) -> tuple[float, int] | None:
        """:func:`lone_pin_support` of the pose: ``(support, cells of the thing left out)``."""
        wall_b = self._args[1]
        return _lone_pin(
            self._terms(precise), wall_b, structures_b, small_cells, self._cells_b, top
        )


def slide_direction(
    wall_a: NDArray[np.bool_],
    wall_b: NDArray[np.bool_],
    T: Transform,
    cells_b: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None,
) -> NDArray[np.float64] | None:
    """The unit direction (col, row) of a's cells along which the agreeing walls pin pose ``T``
    least (the eigenvector of :func:`cross_support`'s smallest eigenvalue, float64), None
    without agreeing walls. Its sign is fixed (first non-zero component positive)."""
    M = _support_tensor(wall_a, wall_b, T, True, cells_b)
    if M is None:
        return None
    # rounded: the tensor's last bits differ between CPUs' SIMD paths, the slide must not
    v = np.round(np.linalg.eigh(M)[1][:, 0], 9)
    if v[0] < 0 or (v[0] == 0 and v[1] < 0):
        v = -v
    return np.asarray(v / math.hypot(float(v[0]), float(v[1])), dtype=np.float64)


def agreeing_area(a: MapCodes, b: MapCodes, T: Transform, tolerance: int = 1) -> float:
    """How much of the maps the evidence of a pose covers, in cells^2 of a: the area of the
    smallest rectangle, at any angle, around the wall cells that agree under ``T`` (b cells ->
    a cells), the verifier's agreement both ways (:class:`~mrexplore.merge.common.Verifier`): b's
    reliable walls that land on a wall of a or on free space within ``tolerance`` cells of one,
    where they land, and a's walls that land so on b. 0 when fewer than three agree or all on
    one line.

    A rack or a pillar gives a square metre or a few however well it matches, and every copy
    of it matches as well; a room's or a corridor's walls cover it (exact on any CPU:
    :func:`~mrexplore.merge.common.rectangle_area`).
    """
    on_b, cb, rb = agreeing_cells(b.wall_cells(), T, a.codes(tolerance))
    on_a, _, _ = agreeing_cells(a.wall_cells(), rigid_inverse(T), b.codes(tolerance))
    ra, ca = a.wall_cells()
    return rectangle_area(
        np.concatenate(
            [np.stack([cb[on_b], rb[on_b]], axis=1), np.stack([ca[on_a], ra[on_a]], axis=1)]
        )
    )
