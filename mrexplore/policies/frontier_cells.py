"""Frontier extraction on int8 occupancy grids: known-free cells next to unknown ones.

A *frontier cell* is a known-free cell (:func:`mrexplore.grid.free_mask`) with at least one
4-neighbour that is unknown. Frontier cells are grouped into *frontiers* by 8-connectivity
(``cv2.connectedComponentsWithStats``), as explore_lite and Yamauchi's frontier exploration do.

Everything is vectorised: the grid is cropped to the bounding box of its known cells (a robot's
canvas is ~1500 x 1500 cells of which a few hundred square are known), so the cost follows the
explored area, not the canvas.
"""

from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.errors import GridError
from mrexplore.grid import Int8Grid, free_mask, known_bbox, known_mask

_planning = kernels.load("planning")

__all__ = [
    "Frontier",
    "find_frontiers",
    "frontier_mask",
    "frontier_near",
    "known_bbox",
    "window_frontier_mask",
]

#: 4-connectivity cross: a frontier cell needs an unknown cell up, down, left or right.
_CROSS = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=np.uint8)


@dataclass(frozen=True, eq=False)
class Frontier:
    """One frontier: an 8-connected cluster of frontier cells.

    Attributes:
        cells: int64 (N, 2), the frontier cells as ``(col, row)`` in the map's cells.
        size: number of cells N (multiply by the resolution for a length in metres).
        centroid: ``(col, row)`` float mean of the cells (may lie off the frontier).
        target: ``(col, row)`` int: the frontier cell closest to the centroid (a cell that is
            actually on the frontier, known free, hence a sensible place to drive towards).
    """

    cells: NDArray[np.int64]
    size: int
    centroid: tuple[float, float]
    target: tuple[int, int]


def _check_map(map_int8: object) -> Int8Grid:
    """Cheap structural check (no full value scan: this runs every step on 2M-cell canvases)."""
    if not isinstance(map_int8, np.ndarray) or map_int8.ndim != 2 or map_int8.size == 0:
        shape = getattr(map_int8, "shape", None)
        raise GridError(
            f"map must be a non-empty 2-D int8 numpy array, got {type(map_int8).__name__} {shape}"
        )
    if map_int8.dtype != np.int8:
        raise GridError(
            f"map must be an int8 occupancy grid (-1/0/100), got dtype {map_int8.dtype}"
        )
    return map_int8


def window_frontier_mask(grid: Int8Grid) -> NDArray[np.bool_]:
    """Frontier mask of a window of a grid (a crop); cells outside the window count as *not*
    unknown."""
    unknown = (~known_mask(grid)).view(np.uint8)
    # Dilating "unknown" with a cross marks every cell that has an unknown 4-neighbour (or is
    # unknown). OpenCV's default dilate border never adds values, so the canvas edge is not a
    # frontier by itself.
    near_unknown = cv2.dilate(unknown, _CROSS).view(np.bool_)
    return free_mask(grid) & near_unknown


def frontier_mask(map_int8: Int8Grid) -> NDArray[np.bool_]:
    """bool (H, W): known-free cells with an unknown 4-neighbour.

    Args:
        map_int8: int8 (H, W) occupancy grid (``mrexplore.grid`` convention).

    Returns:
        bool (H, W), same shape as the input. All False when nothing (or everything) is known.
    """
    grid = _check_map(map_int8)
    out = np.zeros(grid.shape, dtype=bool)
    box = known_bbox(grid, margin=1)
    if box is None:
        return out
    r0, r1, c0, c1 = box
    out[r0:r1, c0:c1] = window_frontier_mask(grid[r0:r1, c0:c1])
    return out


def find_frontiers(map_int8: Int8Grid, min_size_cells: int = 8) -> list[Frontier]:
    """Cluster the frontier cells of ``map_int8`` into frontiers (8-connectivity).

    Args:
        map_int8: int8 (H, W) occupancy grid.
        min_size_cells: frontiers with fewer cells are dropped (sensor speckle between diverging
            lidar beams leaves tiny unknown holes inside explored space; 8 cells = 0.4 m at
            0.05 m/cell, close to explore_lite's ``min_frontier_size`` of 0.5 m).

    Returns:
        The frontiers, largest first (ties by position, so the order is deterministic).
    """
    grid = _check_map(map_int8)
    if min_size_cells < 1:
        raise GridError(f"min_size_cells must be >= 1, got {min_size_cells}")
    if _planning is not None and kernels.enabled():
        return _compiled_frontiers(grid, min_size_cells)
    box = known_bbox(grid, margin=1)
    if box is None:
        return []
    r0, r1, c0, c1 = box
    mask = window_frontier_mask(grid[r0:r1, c0:c1])
    n, labels, stats, centroids = cv2.connectedComponentsWithStats(
        mask.view(np.uint8), connectivity=8, ltype=cv2.CV_32S
    )
    if n <= 1:
        return []
    sizes = stats[:, cv2.CC_STAT_AREA]
    keep = np.zeros(n, dtype=bool)
    keep[1:] = sizes[1:] >= min_size_cells
    if not keep.any():
        return []
    rows, cols = np.nonzero(keep[labels])
    lab = labels[rows, cols]
    # Group cells by label once (stable sort keeps raster order inside a frontier).
    order = np.argsort(lab, kind="stable")
    rows, cols, lab = rows[order], cols[order], lab[order]
    # Distance of every cell to its own frontier's centroid; the first cell of each group after
    # sorting by (label, distance) is the target.
    d2 = (cols - centroids[lab, 0]) ** 2 + (rows - centroids[lab, 1]) ** 2
    by_dist = np.lexsort((d2, lab))
    labels_kept = np.flatnonzero(keep)
    starts = np.searchsorted(lab, labels_kept)
    ends = np.searchsorted(lab, labels_kept, side="right")
    first_by_dist = np.searchsorted(lab[by_dist], labels_kept)
    target_idx = by_dist[first_by_dist]

    frontiers = []
    for k, label in enumerate(labels_kept):
        s, e = starts[k], ends[k]
        cells = np.stack([cols[s:e] + c0, rows[s:e] + r0], axis=1).astype(np.int64)
        t = target_idx[k]
        frontiers.append(
            Frontier(
                cells=cells,
                size=int(sizes[label]),
                centroid=(float(centroids[label, 0] + c0), float(centroids[label, 1] + r0)),
                target=(int(cols[t] + c0), int(rows[t] + r0)),
            )
        )
    frontiers.sort(key=lambda f: (-f.size, f.target[1], f.target[0]))
    return frontiers


def _compiled_frontiers(grid: Int8Grid, min_size_cells: int) -> list[Frontier]:
    """:func:`find_frontiers` by one compiled pass (the same frontiers, cells and targets)."""
    assert _planning is not None
    cells, starts, window, centroids, targets = _planning.frontier_clusters(grid, min_size_cells)
    c0, r0 = int(window[0]), int(window[1])
    frontiers = []
    for k in range(starts.size - 1):
        s, e = int(starts[k]), int(starts[k + 1])
        t = cells[targets[k]]
        frontiers.append(
            Frontier(
                cells=cells[s:e],
                size=e - s,
                centroid=(float(centroids[k, 0] + c0), float(centroids[k, 1] + r0)),
                target=(int(t[0]), int(t[1])),
            )
        )
    frontiers.sort(key=lambda f: (-f.size, f.target[1], f.target[0]))
    return frontiers


def frontier_near(grid: Int8Grid, cell: tuple[int, int], radius: int = 2) -> bool:
    """Whether a frontier cell lies within ``radius`` cells (a square) of ``cell`` ``(col, row)``
    of ``grid`` (int8 (H, W)); cells beyond the grid are not unknown."""
    c, r = cell
    h, w = grid.shape
    if _planning is not None and kernels.enabled() and 0 <= c < w and 0 <= r < h:
        return bool(_planning.frontier_near(grid, c, r, radius))
    r0, r1 = max(r - radius - 1, 0), min(r + radius + 2, h)
    c0, c1 = max(c - radius - 1, 0), min(c + radius + 2, w)
    win = window_frontier_mask(grid[r0:r1, c0:c1])
    rr0, cc0 = max(r - radius - r0, 0), max(c - radius - c0, 0)
    return bool(win[rr0 : r + radius + 1 - r0, cc0 : c + radius + 1 - c0].any())
