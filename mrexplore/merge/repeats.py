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
- :func:`outside_object`: when the agreement of a pose lies, in either map, on one structure
  seen only from outside (a rack, a shelf, a cabinet: the map knows little free space inside
  its convex hull) plus at most one small thing beside it. Racks are larger than the
  ``min_object_m2`` floor, and a rack with a post beside it is the warehouse's unit of repeat:
  three pairs of crops that share nothing were merged rack side on rack side
  (``object_hull_free``).

Their measured effects: ``docs/merging.md``; how they were chosen: ``docs/merging_history.md``
("Repeats: a copy the search never tried, and a match on one object" and "A rack seen from
outside, and the one post that pins a pose").
"""

from __future__ import annotations

import math
from typing import NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore.grid import Int8Grid, Transform
from mrexplore.merge.coarse import CoarseMatcher
from mrexplore.merge.common import (
    MapCodes,
    agreeing_cells,
    rectangle_area,
    rectangle_sides,
    rigid_inverse,
)

#: ``outside_object``'s sizes at the semantic merger's resolution: a thing whose longer side is
#: under ``OBJECT_CLUTTER_M`` (m) is small (a post, a box: the nav2 warehouse's H-shaped posts
#: are 0.95 m), and a structure is judged from its hull only when its smallest rectangle is at
#: least ``OBJECT_WIDTH_M`` (m) across (a straight wall's hull holds no floor either way).
OBJECT_CLUTTER_M = 1.5
OBJECT_WIDTH_M = 1.0


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
    return Structures(codes).labels


class Structures:
    """A map's :func:`wall_structures`, with each one's box, cells, size and inside."""

    def __init__(self, codes: MapCodes) -> None:
        self.codes = codes
        grown = cv2.dilate(codes.occupied, np.ones((3, 3), np.uint8))
        _, labels, boxes, _ = cv2.connectedComponentsWithStats(
            grown, connectivity=8, ltype=cv2.CV_32S
        )
        self.labels: NDArray[np.int32] = np.asarray(labels, dtype=np.int32)
        self._boxes = np.asarray(boxes, dtype=np.int64)  # (L, 5): x, y, w, h, area

    def points(self, k: int) -> NDArray[np.intp]:
        """(M, 2) (col, row) of every cell of structure ``k`` (dilated, as labelled)."""
        x, y, w, h = (int(v) for v in self._boxes[k, :4])
        rr, cc = np.nonzero(self.labels[y : y + h, x : x + w] == k)
        return np.stack([cc + x, rr + y], axis=1)

    def sides(self, k: int) -> tuple[float, float]:
        """(long, short) sides (cells) of structure ``k``'s smallest rectangle."""
        return rectangle_sides(self.points(k))

    def is_small(self, k: int, small_cells: float) -> bool:
        """Whether structure ``k``'s smallest rectangle is under ``small_cells`` long."""
        # a rectangle's box spans at most sqrt(2) times its longer side (box sides count cells,
        # rectangles run between cell centres): larger boxes are not small
        if int(self._boxes[k, 2:4].max()) - 1 > small_cells * math.sqrt(2.0):
            return False
        return self.sides(k)[0] < small_cells

    def hull_free(self, k: int) -> float:
        """Share of structure ``k``'s convex hull that the map knows as free."""
        x, y, w, h = (int(v) for v in self._boxes[k, :4])
        hull = cv2.convexHull((self.points(k) - (x, y)).astype(np.int32))
        inside = np.zeros((h, w), np.uint8)
        cv2.fillConvexPoly(inside, hull, 1)
        free = self.codes.free[y : y + h, x : x + w] & inside.view(np.bool_)
        return float(np.count_nonzero(free)) / max(int(np.count_nonzero(inside)), 1)


class _Agreement(NamedTuple):
    """One map's side of a pose's agreement, by wall structure."""

    structures: Structures
    cells: tuple[NDArray[np.intp], NDArray[np.intp]]  # the map's wall cells (rows, cols)
    cell_labels: NDArray[np.int32]  # (N,) the structure of each wall cell
    on: NDArray[np.bool_]  # (N,) which wall cells agree with the other map

    def counts(self) -> NDArray[np.intp]:
        """Agreeing wall cells per structure label."""
        return np.bincount(self.cell_labels[self.on])


#: a's and b's sides of a pose's agreement (``None``: none of that map's walls agree).
ByStructure = tuple["_Agreement | None", "_Agreement | None"]


def agreement_by_structure(
    a: MapCodes,
    b: MapCodes,
    T: Transform,
    tolerance: int = 1,
    structures_b: Structures | None = None,
    structures_a: Structures | None = None,
) -> ByStructure:
    """a's and b's agreement under ``T`` (b cells -> a cells; the verifier's agreement,
    :func:`~mrexplore.merge.common.agreeing_cells`) by structure, for
    :func:`one_object_area` and :func:`outside_object` to share (one labelling of each map;
    ``structures_a``, ``structures_b``: the maps' own, when the caller has them)."""
    out: list[_Agreement | None] = []
    for mine, other, to_other, known in (
        (a, b, rigid_inverse(T), structures_a),
        (b, a, T, structures_b),
    ):
        rows, cols = mine.wall_cells()
        on, _, _ = agreeing_cells((rows, cols), to_other, other.codes(tolerance))
        if not on.any():
            out.append(None)
            continue
        structures = known if known is not None else Structures(mine)
        out.append(_Agreement(structures, (rows, cols), structures.labels[rows, cols], on))
    return out[0], out[1]


def ruled_out_structure(
    a: MapCodes,
    b: MapCodes,
    T: Transform,
    slack: int,
    tolerance: int = 1,
    structures_b: Structures | None = None,
    structures_a: Structures | None = None,
) -> int:
    """The largest wall structure of either map that the other map rules out under ``T`` (b
    cells -> a cells): none of its wall cells lands on the other map's walls (nor on free space
    within ``tolerance`` of one), while half of them or more land on floor the other map has
    seen open all round (free cells with no wall and no unknown cell within ``tolerance +
    slack``). A thing one robot saw where the other saw open floor; one that a pose a few cells
    off grazes with its edge is not ruled out.

    Returns:
        How many of that structure's wall cells land on such floor (0 when no structure is
        ruled out).

    >>> import numpy as np
    >>> g = np.zeros((40, 40), dtype=np.int8)
    >>> g[0, :] = g[-1, :] = g[:, 0] = g[:, -1] = 100  # a room
    >>> h = g.copy()
    >>> h[18:22, 18:22] = 100  # the same room with a box on its floor
    >>> ruled_out_structure(MapCodes(g), MapCodes(h), np.eye(3), slack=2)
    16
    >>> ruled_out_structure(MapCodes(h), MapCodes(h), np.eye(3), slack=2)
    0
    """
    k = 2 * (tolerance + slack) + 1
    most = 0
    for mine, other, to_other, known in (
        (a, b, rigid_inverse(T), structures_a),
        (b, a, T, structures_b),
    ):
        rows, cols = mine.wall_cells()
        if rows.size == 0:
            continue
        on, c, r = agreeing_cells((rows, cols), to_other, other.codes(tolerance))
        seen_open = cv2.erode(other.free.view(np.uint8), np.ones((k, k), np.uint8))
        h, w = seen_open.shape
        inside = (c >= 0) & (c < w) & (r >= 0) & (r < h)
        open_ = np.zeros(rows.size, dtype=bool)
        open_[inside] = seen_open[r[inside], c[inside]] > 0
        structures = known if known is not None else Structures(mine)
        labels = structures.labels[rows, cols]
        n = int(labels.max()) + 1
        agreeing = np.bincount(labels[on], minlength=n)
        ruled = np.bincount(labels[open_], minlength=n)
        ruled[(agreeing > 0) | (2 * ruled < np.bincount(labels, minlength=n))] = 0
        most = max(most, int(ruled.max()))
    return most


def one_object_area(
    a: MapCodes,
    b: MapCodes,
    T: Transform,
    share: float = 0.95,
    tolerance: int = 1,
    by_structure: ByStructure | None = None,
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
    if by_structure is None:
        by_structure = agreement_by_structure(a, b, T, tolerance)
    for agreement in by_structure:
        if agreement is None:
            return None
        counts = agreement.counts()
        k = int(np.argmax(counts))
        if counts[k] < share * np.count_nonzero(agreement.on):
            return None
        rows, cols = agreement.cells
        sel = agreement.cell_labels == k
        areas.append(rectangle_area(np.stack([cols[sel], rows[sel]], axis=1)))
    return max(areas)


def outside_object(
    a: MapCodes,
    b: MapCodes,
    T: Transform,
    hull_free: float,
    clutter_cells: float,
    min_width_cells: float,
    share: float = 0.95,
    tolerance: int = 1,
    by_structure: ByStructure | None = None,
) -> bool:
    """Whether, in either map, at least ``share`` of the agreeing wall cells under ``T`` (b
    cells -> a cells) lie on one structure seen from outside plus at most one small structure.

    Structures are :func:`wall_structures`. One is *seen from outside* when its smallest
    rectangle (:func:`~mrexplore.merge.common.rectangle_sides`, all its occupied cells) is at
    least ``min_width_cells`` across and the map's free cells fill less than ``hull_free`` of
    its convex hull: a rack or a cabinet, whose inside no robot sees, where a room's walls
    enclose the floor the robot drove on. *Small*: the longer side under ``clutter_cells`` (a
    post, a box). Either map suffices, since being an object is a property of the place and the
    map that sees more of it tells (the other may see only a rack's two long sides, which do
    not close).

    >>> import numpy as np
    >>> g = np.zeros((80, 80), dtype=np.int8)
    >>> g[20:40, 10:70] = 100  # a 20 x 60 rack on open floor, its inside unknown
    >>> g[22:38, 12:68] = -1
    >>> codes = MapCodes(g)
    >>> outside_object(codes, codes, np.eye(3), 0.2, 30.0, 20.0)
    True
    >>> room = np.full((80, 80), -1, dtype=np.int8)  # the same outline seen from inside
    >>> room[20:40, 10:70] = 100
    >>> room[21:39, 11:69] = 0
    >>> outside_object(MapCodes(room), MapCodes(room), np.eye(3), 0.2, 30.0, 20.0)
    False
    """
    if by_structure is None:
        by_structure = agreement_by_structure(a, b, T, tolerance)
    for agreement in by_structure:
        if agreement is None:
            return False
        counts = agreement.counts()
        structures = agreement.structures
        main = small = 0  # 0: none yet (label 0 is no structure)
        # largest first: the main structure is the one carrying most agreement that is not
        # small, and the small thing beside it the small one carrying most
        for k in np.argsort(-counts, kind="stable"):
            k = int(k)
            if k == 0 or counts[k] == 0:
                continue
            if structures.is_small(k, clutter_cells):
                small = small or k
            elif not main:
                if structures.sides(k)[1] < min_width_cells or structures.hull_free(k) >= hull_free:
                    break  # a wall seen from inside, or a thin one: not this map
                main = k
            if main and small:
                break
        carried = int(counts[main]) + (int(counts[small]) if small else 0)
        if main and carried >= share * np.count_nonzero(agreement.on):
            return True
    return False
