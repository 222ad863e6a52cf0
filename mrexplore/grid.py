"""Occupancy-grid cell values, checks and 2-D homogeneous transforms: the one place for them.

Conventions (see README, "Conventions"):

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

from typing import Final, NamedTuple

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


def known_bbox(grid: Int8Grid, margin: int = 0) -> Box | None:
    """The box (half-open) of the known cells of ``grid``, grown by ``margin`` and clipped to
    the grid, or None when nothing is known.

    Uses row/column maxima of the int8 array (``UNKNOWN`` is the smallest value), which numpy
    reduces with SIMD: much cheaper than a boolean mask of a whole canvas.

    >>> g = np.full((4, 5), UNKNOWN, dtype=np.int8); g[1, 2] = FREE; g[2, 3] = OCCUPIED
    >>> known_bbox(g), known_bbox(g, margin=1)
    ((1, 3, 2, 4), (0, 4, 1, 5))
    """
    rows = np.flatnonzero(grid.max(axis=1) > UNKNOWN)
    if rows.size == 0:
        return None
    r0, r1 = int(rows[0]), int(rows[-1]) + 1
    cols = np.flatnonzero(grid[r0:r1].max(axis=0) > UNKNOWN)
    c0, c1 = int(cols[0]), int(cols[-1]) + 1
    h, w = grid.shape
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
    """

    version: int
    known_box: Box | None
    changed_box: Box | None


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


def invert_transform(T: Transform) -> Transform:
    """Inverse of a 3x3 homogeneous transform."""
    return np.asarray(np.linalg.inv(np.asarray(T, dtype=np.float64)), dtype=np.float64)


def apply_transform(
    T: Transform, points: NDArray[np.floating] | NDArray[np.integer]
) -> NDArray[np.float64]:
    """Map ``points`` of shape (N, 2) as ``(col, row)`` through ``T``; returns (N, 2) float64."""
    pts = np.asarray(points, dtype=np.float64).reshape(-1, 2)
    return pts @ np.asarray(T, dtype=np.float64)[:2, :2].T + np.asarray(T, dtype=np.float64)[:2, 2]
