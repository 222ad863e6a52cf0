"""Places: a map's free space cut into rooms, halls and corridors at its narrow passages, and
whether a merge's evidence reaches beyond one of them.

Two maps that each hold one copy of a repeated room agree perfectly under the pose that lays
one copy on the other; no figure computed on that room alone tells the copies apart. What
does is agreement *outside* the room: another room, the corridor's ends, things in the
corridor. :func:`beyond_places` asks for it, beyond the :data:`PLACES_LEFT_OUT` places that
hold most of the agreement (a repeated unit is often a room and the corridor stretch in front
of its door).

**Places.** A place is a region of known free space joined to the rest by passages narrower
than :data:`PASSAGE_RATIO` of its own clearance (the largest distance from its floor to the
nearest wall or unknown cell): a door into a room, a room's opening into a corridor. Small
pockets whose openings are about as wide as they are (the floor between a table and a wall)
stay part of the place around them. Every size is relative to the place's own clearance, so
rooms, halls and corridors are found at any scale, and no area or length decides.

**The cut** (:func:`segment_places`) is a persistence clustering of the distance transform
(a topographic flooding from the widest floor down): sweeping the clearance level ``t`` down a
geometric ladder, the components of ``{clearance >= t}`` are born at their peaks and meet at
their passages; when two meet at level ``t``, the lower one stays a place of its own if ``t <
PASSAGE_RATIO * its peak`` and is absorbed otherwise. Each place's core (its component just
before it met a place it stays apart from) then grows through the free space to the walls.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.grid import FREE, FREE_THRESHOLD, Int8Grid, Transform
from mrexplore.merge.common import MapCodes, agreeing_cells, rigid_inverse
from mrexplore.merge.pinning import cross_support

# The compiled level sweep (None without numba); used while mrexplore.kernels.enabled().
_merging = kernels.load("merging")

__all__ = [
    "PASSAGE_RATIO",
    "PLACES_LEFT_OUT",
    "Places",
    "beyond_places",
    "outside_cells",
    "segment_places",
]

#: A passage narrower than this share of a place's clearance separates it (a door of 0.9 m
#: into a 4 m wide room: 0.9 / 4 = 0.22; the floor between a table and a wall, entered along
#: its length: ~1). A shape ratio, not a size.
PASSAGE_RATIO = 0.5

#: How many places, those holding most of the agreement, the evidence must reach beyond: a
#: repeated unit is often two places in a map (a room and the corridor stretch in front of its
#: door, a room its furniture cuts in two), so the agreement outside the two that hold most of
#: it must pin the pose by itself. Chosen on the tuning part of the world families: with one,
#: a row of identical offices was merged wrongly (docs/merging.md).
PLACES_LEFT_OUT = 2

#: The clearance levels of the sweep shrink by this factor from one to the next: the level
#: where two places meet is known to this precision (a ratio, so any map size takes the
#: same number of steps per doubling of clearance).
_LEVEL_FACTOR = 0.85

#: The lowest level of the sweep (cells): below it the distance transform is the pixel
#: staircase of the walls, not the shape of the floor.
_LOWEST_LEVEL_CELLS = 1.0


@dataclass(frozen=True)
class Places:
    """A map's places.

    Attributes:
        labels: (H, W) int32, the place of each known free cell (1..n), 0 elsewhere.
        count: the number of places n.
        peaks: (n + 1,) float32, each place's clearance (cells; index 0 unused).
    """

    labels: NDArray[np.int32]
    count: int
    peaks: NDArray[np.float32]


def _free(grid: Int8Grid) -> NDArray[np.uint8]:
    return ((grid >= FREE) & (grid <= FREE_THRESHOLD)).view(np.uint8)


def _first_pixel(labels: NDArray[np.int32], top: int, k: int) -> tuple[int, int]:
    """A pixel of component ``k`` (connectedComponents numbers them in raster order of their
    first pixel, so its first row is ``top`` and the pixel is the first ``k`` there)."""
    cols = np.flatnonzero(labels[top] == k)
    return top, int(cols[0])


class _Sweep:
    """The components of ``{clearance >= level}`` down the ladder, each named by an int, listed
    per level in OpenCV's order (the order decides the places' labels)."""

    def level(self, li: int, level: float) -> list[int]:
        raise NotImplementedError

    def names_of(self, pixels: list[tuple[int, int]]) -> list[int]:
        raise NotImplementedError

    def first_pixel(self, name: int) -> tuple[int, int]:
        raise NotImplementedError

    def stamp(self, markers: NDArray[np.int32], li: int, name: int, label: int) -> None:
        """``label`` where ``markers`` is 0 on component ``name`` of level ``li``."""
        raise NotImplementedError


class _LabelSweep(_Sweep):
    """Every level labelled afresh by OpenCV (names: its labels); the numpy path."""

    def __init__(self, clearance: NDArray[Any]) -> None:
        self.clearance = clearance
        self.comps: list[NDArray[np.int32]] = []
        self.tops: NDArray[Any] = np.zeros(0, np.int32)

    def level(self, li: int, level: float) -> list[int]:
        mask = (self.clearance >= level).view(np.uint8)
        n, comp, stats, _ = cv2.connectedComponentsWithStats(mask, connectivity=8)
        self.comps.append(comp.astype(np.int32, copy=False))
        self.tops = stats[:, cv2.CC_STAT_TOP]
        return list(range(1, n))

    def names_of(self, pixels: list[tuple[int, int]]) -> list[int]:
        comp = self.comps[-1]
        return [int(comp[r, c]) for r, c in pixels]

    def first_pixel(self, name: int) -> tuple[int, int]:
        return _first_pixel(self.comps[-1], int(self.tops[name]), name)

    def stamp(self, markers: NDArray[np.int32], li: int, name: int, label: int) -> None:
        markers[(self.comps[li] == name) & (markers == 0)] = label


class _UnionSweep(_Sweep):
    """The compiled sweep: each level adds its cells to one union-find (names: the roots, first
    cells in raster order); the same components in the same order, without labelling the map
    per level."""

    def __init__(self, clearance: NDArray[Any], levels: list[float]) -> None:
        assert _merging is not None
        self.k = _merging
        # float32 levels: numpy compares a float32 map with a Python float in float32
        self.order, self.starts, self.first = _merging.level_batches(
            clearance, np.array(levels, dtype=np.float32)
        )
        self.w = clearance.shape[1]
        self.parent = np.zeros(clearance.size, np.int64)
        self.block = np.zeros(clearance.size, np.int64)
        self.roots = np.zeros(clearance.size, np.int64)
        self.n_roots = 0

    def level(self, li: int, level: float) -> list[int]:
        self.n_roots, names = self.k.level_add(
            li,
            self.order,
            self.starts,
            self.first,
            self.w,
            self.parent,
            self.block,
            self.roots,
            self.n_roots,
        )
        return [int(x) for x in names]

    def names_of(self, pixels: list[tuple[int, int]]) -> list[int]:
        cells = np.array([r * self.w + c for r, c in pixels], dtype=np.int64)
        return [int(x) for x in self.k.level_find(self.parent, cells)]

    def first_pixel(self, name: int) -> tuple[int, int]:
        r, c = divmod(name, self.w)
        return r, c

    def stamp(self, markers: NDArray[np.int32], li: int, name: int, label: int) -> None:
        self.k.level_stamp(self.first, li, name, markers, label)


def segment_places(grid: Int8Grid) -> Places:
    """Cut a map's known free space into places (see the module docstring).

    Args:
        grid: (H, W) int8 occupancy map (``-1`` unknown, ``0`` free, ``100`` occupied).

    Returns:
        :class:`Places`: every known free cell labelled with its place.
    """
    free = _free(grid)
    h, w = free.shape
    clearance = cv2.distanceTransform(free, cv2.DIST_L2, 5)
    top = float(clearance.max()) if clearance.size else 0.0
    if top < _LOWEST_LEVEL_CELLS:
        labels = np.zeros((h, w), np.int32)
        return Places(labels, 0, np.zeros(1, np.float32))
    levels: list[float] = []
    t = top
    while t >= _LOWEST_LEVEL_CELLS:
        levels.append(t)
        t *= _LEVEL_FACTOR
    # per place: a seed pixel, its peak, its core (the (level, component) it had just before it
    # met a place it stays apart from; None while it has met none: the core follows its
    # component down) and the place it was absorbed into (itself while it was not)
    seeds: list[tuple[int, int]] = []
    peaks: list[float] = []
    cores: list[tuple[int, int] | None] = []
    last: list[tuple[int, int]] = []
    owner: list[int] = []
    previous = top / _LEVEL_FACTOR
    compiled = _merging is not None and kernels.enabled()
    sweep: _Sweep = _UnionSweep(clearance, levels) if compiled else _LabelSweep(clearance)
    for li, level in enumerate(levels):
        names = sweep.level(li, level)  # the components' names in OpenCV's (raster) order
        groups: dict[int, list[int]] = {}
        alive = [p for p in range(len(seeds)) if owner[p] == p]
        for p, name in zip(alive, sweep.names_of([seeds[p] for p in alive]), strict=True):
            groups.setdefault(name, []).append(p)
        for k in names:
            if k not in groups:  # born between the previous level and this one
                seeds.append(sweep.first_pixel(k))
                peaks.append(previous)
                cores.append(None)
                last.append((li, k))
                owner.append(len(owner))
                groups[k] = [len(seeds) - 1]
        for k, members in groups.items():
            if len(members) > 1:
                members.sort(key=lambda p: -peaks[p])
                for p in members[1:]:
                    if cores[p] is None and level >= PASSAGE_RATIO * peaks[p]:
                        owner[p] = members[0]  # a wide opening: part of the place it meets
                apart = [p for p in members if owner[p] == p]
                if len(apart) > 1:
                    for p in apart:  # met a place it stays apart from: its core is set
                        if cores[p] is None:
                            cores[p] = last[p]
            for p in members:
                if owner[p] == p and cores[p] is None:
                    last[p] = (li, k)
        previous = level
    kept = [p for p in range(len(seeds)) if owner[p] == p]
    markers = np.zeros((h, w), np.int32)
    out_peaks = np.zeros(len(kept) + 1, np.float32)
    for label, p in enumerate(kept, start=1):
        li, k = cores[p] or last[p]
        sweep.stamp(markers, li, k, label)
        out_peaks[label] = peaks[p]
    return Places(_grow(markers, free), len(kept), out_peaks)


def _grow(markers: NDArray[np.int32], free: NDArray[np.uint8]) -> NDArray[np.int32]:
    """The cores grown through the free cells, one cell a round, until no free cell they can
    reach is left (where two meet, the larger label takes the cell: the boundary between two
    places is one cell either way)."""
    if _merging is not None and kernels.enabled():
        return _merging.grow_labels(markers, free)
    labels = markers.astype(np.float32)
    open_ = (free > 0) & (markers == 0)
    kernel = np.ones((3, 3), np.uint8)
    while True:
        grown = cv2.dilate(labels, kernel)
        take = open_ & (grown > 0)
        if not take.any():
            break
        labels[take] = grown[take]
        open_ &= ~take
    return labels.astype(np.int32)


def outside_cells(
    cells: tuple[NDArray[np.intp], NDArray[np.intp]],
    agree: NDArray[np.bool_],
    places: Places,
    skip: int = PLACES_LEFT_OUT,
    reach: int = 2,
) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """The agreeing wall cells that bound none of the ``skip`` places bounded by most of them.

    Args:
        cells: (rows, cols) of a map's wall cells.
        agree: (N,) bool, which of them agree under the pose.
        places: the map's places.
        skip: how many places are left out, the most agreeing first.
        reach: a wall cell bounds the places whose floor lies within this many cells (a
            square window): a wall between a room and a corridor bounds both.

    Returns:
        (rows, cols) of the agreeing cells outside those places. A wall no floor lies beside
        (inside a thick wall) is not outside.
    """
    rows, cols = cells[0][agree], cells[1][agree]
    if rows.size == 0 or places.count == 0:
        return rows[:0], cols[:0]
    k = np.ones((2 * reach + 1, 2 * reach + 1), np.uint8)
    # the place each agreeing wall cell bounds, by the nearest label within reach (max wins)
    near = cv2.dilate(places.labels.astype(np.float32), k)[rows, cols].astype(np.int64)
    out = near > 0
    counts = np.bincount(near, minlength=places.count + 1)
    counts[0] = 0
    for _ in range(skip):
        main = int(np.argmax(counts))
        if counts[main] == 0:
            break
        counts[main] = 0
        out &= cv2.dilate((places.labels == main).view(np.uint8), k)[rows, cols] == 0
    return rows[out], cols[out]


def beyond_places(
    grid_a: Int8Grid,
    grid_b: Int8Grid,
    codes_a: MapCodes,
    codes_b: MapCodes,
    T: Transform,
    skip: int = PLACES_LEFT_OUT,
) -> tuple[float, float]:
    """How firmly the agreement beyond the places holding most of it pins a pose, in each map.

    In each map, the wall cells that agree under ``T`` (b cells -> a cells; the verifier's
    agreement, a cell's tolerance) are split into those bounding the ``skip`` places most of
    them bound and the rest (:func:`outside_cells`); the rest's
    :func:`~mrexplore.merge.pinning.cross_support` says whether it pins the pose by itself.
    A repeated room laid on its twin agrees inside the room only, and the corridor seen
    through its door is straight: ~0 in both maps.

    Args:
        grid_a, grid_b: (H, W) int8 maps (the merger's crops).
        codes_a, codes_b: their verifier codes.
        T: (3, 3) pose, b's cells -> a's.

    Returns:
        ``(support_a, support_b)``: wall cells (the smaller eigenvalue of the normals'
        tensor), float64 on any CPU.
    """
    T_inv = rigid_inverse(T)
    supports = []
    for grid, codes, other, pose in (
        (grid_a, codes_a, codes_b, T_inv),
        (grid_b, codes_b, codes_a, T),
    ):
        cells = codes.wall_cells()
        agree, _, _ = agreeing_cells(cells, pose, other.codes(1))
        out = outside_cells(cells, agree, segment_places(grid), skip)
        if out[0].size == 0:
            supports.append(0.0)
            continue
        # the normals are the other map's, where the outside walls land on it
        supports.append(cross_support(other.wall, codes.wall, pose, precise=True, cells_b=out))
    return supports[0], supports[1]
