"""Occupancy-grid cell values, checks and 2-D homogeneous transforms: the one place for them.

Conventions (``docs/guide/environment.md``, "Conventions"):

* Public maps are ``int8`` arrays in the ROS ``nav_msgs/OccupancyGrid`` convention:
  ``UNKNOWN = -1``, ``FREE = 0``, ``OCCUPIED = 100``; values in between are occupancy
  probabilities in percent.
* Arrays are indexed ``grid[row, col]``; row 0 is the *bottom* of the map (lowest y), exactly as
  ``OccupancyGrid.data``. Image files have row 0 at the top; :mod:`mrexplore.world.map_io` is the
  only place that flips.
* A point on a grid is ``(col, row) = (x, y)`` in cells; the centre of cell ``(c, r)`` is at the
  integer point ``(c, r)``.
* A transform between two grids is a 3x3 float64 homogeneous matrix acting on ``(col, row, 1)``;
  ``T_ab`` maps cells of grid *b* into grid *a*.
* A box of cells is ``(row0, row1, col0, col1)``, half-open (``grid[row0:row1, col0:col1]``):
  :data:`mrexplore.types.Box`, the one convention of the package.
"""

from __future__ import annotations

from typing import Any, Final, NamedTuple

import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import GridError
from mrexplore.types import Box

UNKNOWN: Final[int] = -1
FREE: Final[int] = 0
OCCUPIED: Final[int] = 100

#: A cell whose occupancy (percent) is at least this is treated as a wall by readers of int8 maps.
OCCUPIED_THRESHOLD: Final[int] = 65
#: A known cell whose occupancy (percent) is at most this is treated as free.
FREE_THRESHOLD: Final[int] = 25

Int8Grid = NDArray[np.int8]
Transform = NDArray[np.float64]


def known_bbox(grid: Int8Grid, margin: int = 0, within: Box | None = None) -> Box | None:
    """The box (half-open) of the known cells of ``grid``, grown by ``margin`` and clipped to
    the grid, or None when nothing is known. ``within``: a box known to hold every known cell
    (a :class:`~mrexplore.types.RobotView`'s ``known_box``): only it is scanned, with the same
    answer.

    Uses row/column maxima of the int8 array (``UNKNOWN`` is the smallest value), which numpy
    reduces with SIMD: much cheaper than a boolean mask of a whole canvas.

    >>> g = np.full((4, 5), UNKNOWN, dtype=np.int8); g[1, 2] = FREE; g[2, 3] = OCCUPIED
    >>> known_bbox(g), known_bbox(g, margin=1), known_bbox(g, within=(1, 4, 2, 5))
    ((1, 3, 2, 4), (0, 4, 1, 5), (1, 3, 2, 4))
    """
    h, w = grid.shape
    top, left = 0, 0
    if within is not None:
        top, left = max(0, within[0]), max(0, within[2])
        grid = grid[top : max(top, within[1]), left : max(left, within[3])]
    rows = np.flatnonzero(grid.max(axis=1, initial=UNKNOWN) > UNKNOWN)
    if rows.size == 0:
        return None
    r0, r1 = int(rows[0]), int(rows[-1]) + 1
    cols = np.flatnonzero(grid[r0:r1].max(axis=0) > UNKNOWN)
    c0, c1 = int(cols[0]) + left, int(cols[-1]) + 1 + left
    r0, r1 = r0 + top, r1 + top
    return (max(0, r0 - margin), min(h, r1 + margin), max(0, c0 - margin), min(w, c1 + margin))


class MapChange(NamedTuple):
    """What the owner of an int8 map already knows about its changes, so that a reader (the
    merge tracker) need not scan the canvas to find them. Boxes are ``(row0, row1, col0, col1)``,
    half-open, in the map's cells.

    Attributes:
        version: grows by one with every update that changed at least one int8 cell.
        known_box: the box of the cells that are not unknown, None while all are unknown.
        changed_box: the box of the cells the update that made ``version`` changed (None at
            version 0).
        cells: the flat indices (int64, read-only) of the cells inside ``changed_box`` that
            did change, when the owner listed them (else None: the box tells).
    """

    version: int
    known_box: Box | None
    changed_box: Box | None
    cells: NDArray[np.int64] | None = None

    def __eq__(self, other: object) -> bool:
        # a tuple's == would compare the cell arrays element-wise (an ambiguous truth value)
        if not isinstance(other, MapChange):
            return NotImplemented
        a, b = self.cells, other.cells
        same = a is b or (a is not None and b is not None and np.array_equal(a, b))
        return self[:3] == other[:3] and same

    def __ne__(self, other: object) -> bool:
        # tuple's own != would be used otherwise, with the same element-wise compare
        eq = self.__eq__(other)
        return eq if eq is NotImplemented else not eq

    def __hash__(self) -> int:
        return hash(self[:3])


def validate_grid(grid: object, name: str = "grid") -> Int8Grid:
    """Return ``grid`` as a 2-D int8 occupancy array, or raise :class:`GridError` naming why.

    Accepts int8 arrays and integer arrays whose values are all in ``{-1} U [0, 100]``; refuses
    floats (NaN would hide there), booleans, non-2-D arrays and empty arrays.
    """
    if not isinstance(grid, np.ndarray):
        raise GridError(f"{name} must be a numpy array, got {type(grid).__name__}")
    if grid.ndim != 2:
        raise GridError(f"{name} must be 2-D (rows, cols), got shape {grid.shape}")
    if grid.size == 0:
        raise GridError(f"{name} is empty (shape {grid.shape})")
    if grid.dtype == np.int8 or (np.issubdtype(grid.dtype, np.integer) and grid.dtype != np.bool_):
        arr = grid
    else:
        raise GridError(
            f"{name} must be an int8 occupancy grid (-1 unknown, 0 free, 100 occupied), "
            f"got dtype {grid.dtype}"
        )
    bad = (arr < UNKNOWN) | (arr > OCCUPIED)
    if bad.any():
        r, c = np.argwhere(bad)[0]
        raise GridError(
            f"{name} has a value {int(arr[r, c])} at (row {r}, col {c}) outside -1..100"
        )
    return arr.astype(np.int8, copy=False)


def check_int8_map(grid: object, name: str = "grid") -> Int8Grid:
    """Cheap per-step check: ``grid`` is a non-empty 2-D int8 array, else :class:`GridError`.

    Unlike :func:`validate_grid` it does not scan the values: every-step callers (the merge
    tracker, the fusion stage) hand over whole canvases, and the full check runs inside
    :func:`mrexplore.merge.merge_maps` when a merge is attempted.
    """
    if (
        not isinstance(grid, np.ndarray)
        or grid.dtype != np.int8
        or grid.ndim != 2
        or grid.size == 0
    ):
        raise GridError(
            f"{name} must be a non-empty 2-D int8 array (-1/0/100), got "
            f"{getattr(grid, 'dtype', type(grid).__name__)} {getattr(grid, 'shape', '')}"
        )
    return grid


def known_mask(grid: Int8Grid) -> NDArray[np.bool_]:
    """Cells with any information (not ``UNKNOWN``)."""
    return grid != UNKNOWN


def free_mask(grid: Int8Grid) -> NDArray[np.bool_]:
    """Known cells with occupancy at most :data:`FREE_THRESHOLD` percent."""
    return (grid >= FREE) & (grid <= FREE_THRESHOLD)


def occupied_mask(grid: Int8Grid) -> NDArray[np.bool_]:
    """Cells with occupancy at least :data:`OCCUPIED_THRESHOLD` percent."""
    return grid >= OCCUPIED_THRESHOLD


def make_transform(theta_rad: float, tx: float, ty: float) -> Transform:
    """Rigid 2-D transform: rotate by ``theta_rad`` (counter-clockwise in (col, row)), then shift.

    Returns a 3x3 float64 matrix acting on column vectors ``(col, row, 1)``.
    """
    c, s = float(np.cos(theta_rad)), float(np.sin(theta_rad))
    return np.array([[c, -s, tx], [s, c, ty], [0.0, 0.0, 1.0]], dtype=np.float64)


def transform_angle(T: Transform) -> float:
    """Rotation angle of a (near) rigid transform, radians in (-pi, pi]."""
    return float(np.arctan2(T[1, 0], T[0, 0]))


# Transforms feed the merger, whose ICP amplifies a difference in the last bit into a different
# pose on a poor hypothesis (traced: 1e-16 -> 1.6 cells in four ICP calls), and the evaluation.
# numpy's ``@`` and ``linalg.inv`` call BLAS/LAPACK, whose kernels (and their fused multiply-adds)
# depend on the CPU; the helpers below use plain elementwise IEEE operations in a fixed order, the
# same bits on every CPU and for every memory layout of their inputs.


def chain(*transforms: Transform) -> Transform:
    """The product ``T1 @ T2 @ ...`` of 3x3 transforms (left to right), the same bits on every
    CPU (unlike ``@``, which calls BLAS).

    >>> chain(make_transform(0.0, 1, 2), make_transform(0.0, 3, 4))[:2, 2].tolist()
    [4.0, 6.0]
    """
    out = np.asarray(transforms[0], dtype=np.float64)
    mats = [np.asarray(T, dtype=np.float64) for T in transforms[1:]]
    if mats and out.shape == (3, 3) and all(B.shape == (3, 3) for B in mats):
        # Python floats: the same IEEE operations in the same order as the numpy path below
        # (CPython never fuses a multiply and an add), at a third of its cost on 3 x 3
        a = out.tolist()
        for B in mats:
            b0, b1, b2 = B.tolist()
            a = [[r[0] * b0[j] + r[1] * b1[j] + r[2] * b2[j] for j in range(3)] for r in a]
        return np.array(a)
    for B in mats:
        # (a0 b0 + a1 b1) + a2 b2 per entry: separate multiplies and adds, no fused rounding
        out = out[:, 0:1] * B[0:1, :] + out[:, 1:2] * B[1:2, :] + out[:, 2:3] * B[2:3, :]
    return out


def chain_each(A: NDArray[np.float64], B: NDArray[np.float64]) -> NDArray[np.float64]:
    """The products ``A[k] @ B[k]`` (K, 3, 3) of stacks of 3x3 transforms (either may be one
    3x3, used for every k): :func:`chain`'s IEEE operations in its order, the same bits.

    >>> shifts = np.stack([make_transform(0.0, d, 0) for d in (1, 2)])
    >>> chain_each(shifts, make_transform(0.0, 3, 4))[:, :2, 2].tolist()
    [[4.0, 4.0], [5.0, 4.0]]
    """
    A = np.asarray(A, dtype=np.float64)
    B = np.asarray(B, dtype=np.float64)
    # out[k, i, j] = (A[k, i, 0] B[k, 0, j] + A[k, i, 1] B[k, 1, j]) + A[k, i, 2] B[k, 2, j]
    a = [A[..., :, m, None] for m in range(3)]
    b = [B[..., m, None, :] for m in range(3)]
    return np.asarray(a[0] * b[0] + a[1] * b[1] + a[2] * b[2])


def affine_inverse(T: Transform) -> Transform:
    """The inverse (3x3 float64) of a 2-D affine 3x3 transform (last row ``0 0 1``: rotation,
    scale, shear and shift, e.g. a map -> world transform with its resolutions), by the closed
    form with the determinant of its 2x2 part in a fixed order: the same bits on every CPU
    (unlike ``np.linalg.inv``, which calls LAPACK). The last row is not read; no checks (see
    :func:`invert_transform`).

    >>> T = np.array([[2.0, 0.0, 4.0], [0.0, 0.5, 1.0], [0.0, 0.0, 1.0]])
    >>> Ti = affine_inverse(T)
    >>> Ti[:2, 2].tolist(), chain(T, Ti).tolist() == np.eye(3).tolist()
    ([-2.0, -2.0], True)
    """
    T = np.asarray(T, dtype=np.float64)
    a, b, c, d = float(T[0, 0]), float(T[0, 1]), float(T[1, 0]), float(T[1, 1])
    det = a * d - b * c
    ia, ib, ic, id_ = d / det, -b / det, -c / det, a / det
    tx, ty = float(T[0, 2]), float(T[1, 2])
    return np.array(
        [[ia, ib, -(ia * tx + ib * ty)], [ic, id_, -(ic * tx + id_ * ty)], [0.0, 0.0, 1.0]]
    )


def rigid_inverse(T: Transform) -> Transform:
    """The inverse of a rigid (or any affine) 3x3 transform: :func:`affine_inverse`, the name the
    merger uses (the closed form, not the transpose, so its poses keep their bits).

    >>> rigid_inverse(make_transform(0.0, 2, -1))[:2, 2].tolist()
    [-2.0, 1.0]
    """
    return affine_inverse(T)


def map_points(pts: NDArray[np.float64], T: Transform) -> tuple[NDArray[Any], NDArray[Any]]:
    """Columns and rows (N,) of the points ``pts`` (N, 2) ``(col, row)`` mapped by ``T``, in
    elementwise IEEE operations (the same bits on every CPU, unlike ``pts @ R.T``)."""
    x, y = pts[:, 0], pts[:, 1]
    return (
        x * float(T[0, 0]) + y * float(T[0, 1]) + float(T[0, 2]),
        x * float(T[1, 0]) + y * float(T[1, 1]) + float(T[1, 2]),
    )


def invert_transform(T: Transform) -> Transform:
    """Inverse (3x3 float64) of a 2-D affine 3x3 transform: last row exactly ``0 0 1``, any
    non-singular 2x2 part (rigid, or scaled like a map -> world transform). The closed form of
    :func:`affine_inverse`, the same bits on every CPU.

    Raises :class:`GridError` when ``T`` is not 3x3, not affine, not finite or singular.
    """
    A = np.asarray(T, dtype=np.float64)
    if A.shape != (3, 3) or A[2].tolist() != [0.0, 0.0, 1.0]:
        raise GridError(f"not a 2-D affine 3x3 transform (last row 0 0 1): {A.tolist()}")
    det = float(A[0, 0]) * float(A[1, 1]) - float(A[0, 1]) * float(A[1, 0])
    if not (np.isfinite(A).all() and det != 0.0):
        raise GridError(f"a singular or non-finite transform has no inverse: {A.tolist()}")
    return affine_inverse(A)


def apply_transform(
    T: Transform, points: NDArray[np.floating] | NDArray[np.integer]
) -> NDArray[np.float64]:
    """Map ``points`` of shape (N, 2) as ``(col, row)`` through ``T``; returns (N, 2) float64.

    Elementwise ``x r00 + y r01 + t0`` in a fixed order (:func:`map_points`), not a matrix
    product: the same bits on every CPU.
    """
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return np.stack(map_points(pts, np.asarray(T, dtype=np.float64)), axis=1)
