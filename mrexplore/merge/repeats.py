"""What repeats: a map's own repeats, and evidence that rests on one object, whose copies a map
need not show.

- :func:`repeat_shifts`: the translations under which a map's walls fall on its own walls. A
  warehouse's rack rows, a row of identical offices: when a map shows one thing twice, the pose
  that lays the other map on one copy has a rival that lays it on the other, and the coarse
  search, which keeps the few best peaks of each rotation, may never have tried that rival (a
  warehouse pair was merged 268 cells off, one rack period, with the truth not among its
  hypotheses). The semantic merger moves its best pose by each map's repeats and judges the
  moved poses as rivals (``repeat_rivals``).
- :func:`one_object_area`: when the agreement of a pose lies on one connected wall structure
  in each map, the size of that structure. A rack seen whole by both robots matches perfectly
  at every copy of it, and the other copies may lie where neither map has looked: two crops of
  a warehouse that share nothing were merged rack on rack with 1,333 agreeing wall cells and
  none against (``min_object_m2``).

Measured in ``docs/merging.md`` item 21.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore.grid import Int8Grid, Transform
from mrexplore.merge.coarse import CoarseMatcher
from mrexplore.merge.common import MapCodes, agreeing_cells, rectangle_area, rigid_inverse


def repeat_shifts(
    grid: Int8Grid, scale: int, k: int, min_cells: float
) -> list[tuple[float, float]]:
    """The ``k`` translations ``(dc, dr)`` (cells, to about ``scale``) under which the map's
    pooled walls agree best with its own, best first, each at least ``min_cells`` long.

    The coarse matcher's ratio score of the map against itself (its autocorrelation): the zero
    shift always wins, and the next peaks are the repeats. A shift and its opposite both
    appear; both are kept (a copy may lie on either side).

    >>> import numpy as np
    >>> g = np.zeros((40, 120), dtype=np.int8)
    >>> for c in (12, 52, 92):  # three identical posts, 40 cells apart, on open floor
    ...     g[16:24, c : c + 8] = 100
    >>> sorted(repeat_shifts(g, 4, 4, 16.0))
    [(-80.0, 0.0), (-40.0, 0.0), (40.0, 0.0), (80.0, 0.0)]
    """
    matcher = CoarseMatcher(grid, scale, grid.shape, w_free=0.0, ratio_power=2.0)
    # The pooled score's one-block tolerance makes each peak a plateau of ties (3 x 3 blocks):
    # one shift per plateau, the mean of its tied members, so that a repeat comes out where it
    # is and not at the plateau's corner; none near the zero shift.
    apart = 3 * scale
    groups: list[tuple[float, list[tuple[float, float]]]] = [(math.inf, [(0.0, 0.0)])]
    for dc, dr, score in matcher.peaks(None, 9 * (k + 1)):
        home = next(
            (g for g in groups if math.hypot(dc - g[1][0][0], dr - g[1][0][1]) < apart), None
        )
        if home is None:
            groups.append((score, [(dc, dr)]))
        elif score == home[0]:
            home[1].append((dc, dr))
    shifts = [
        (sum(c for c, _ in members) / len(members), sum(r for _, r in members) / len(members))
        for _, members in groups[1:]
    ]
    return [(dc, dr) for dc, dr in shifts if math.hypot(dc, dr) >= min_cells][:k]


def wall_structures(codes: MapCodes) -> NDArray[np.int32]:
    """Labels (H, W) int32 of a map's connected wall structures: occupied cells, 8-connected
    after a 3 x 3 dilation, so that a wall broken by one missing cell stays one structure
    (0 = no structure)."""
    grown = cv2.dilate(codes.occupied, np.ones((3, 3), np.uint8))
    _, labels = cv2.connectedComponents(grown, connectivity=8, ltype=cv2.CV_32S)
    return np.asarray(labels, dtype=np.int32)


def one_object_area(
    a: MapCodes, b: MapCodes, T: Transform, share: float = 0.95, tolerance: int = 1
) -> float | None:
    """When at least ``share`` of each map's agreeing wall cells under ``T`` (b cells -> a
    cells; the verifier's agreement, :func:`~mrexplore.merge.common.agreeing_cells`) lie on
    one connected wall structure of that map (:func:`wall_structures`): the larger of the two
    structures' smallest rectangles, cells^2 (exact, :func:`rectangle_area`). ``None`` when the
    agreement spreads over several structures in either map, or nothing agrees.

    >>> import numpy as np
    >>> g = np.zeros((60, 60), dtype=np.int8)
    >>> g[20:30, 20:40] = 100  # a 10 x 20 rack on open floor
    >>> codes = MapCodes(g)
    >>> one_object_area(codes, codes, np.eye(3))
    171.0
    >>> g[5, 5:55] = 100  # and a long wall: the agreement spreads over two structures
    >>> one_object_area(MapCodes(g), MapCodes(g), np.eye(3)) is None
    True
    """
    areas = []
    for mine, other, to_other in ((a, b, rigid_inverse(T)), (b, a, T)):
        rows, cols = mine.wall_cells()
        on, _, _ = agreeing_cells((rows, cols), to_other, other.codes(tolerance))
        n_on = int(np.count_nonzero(on))
        if n_on == 0:
            return None
        labels = wall_structures(mine)[rows, cols]
        counts = np.bincount(labels[on])
        k = int(np.argmax(counts))
        if counts[k] < share * n_on:
            return None
        sel = labels == k
        areas.append(rectangle_area(np.stack([cols[sel], rows[sel]], axis=1)))
    return max(areas)
