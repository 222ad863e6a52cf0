"""``MapCompositor``: the pixels of map merging. It follows each robot's own-frame map as it
changes and composes each robot's fused map from its own map and its teammates' maps warped
into its frame; :class:`~mrexplore.merge.MapMergeTracker` decides which transforms to use.

- Change detection: from the owner's :class:`~mrexplore.grid.MapChange` (version, known box,
  changed box), or, without one, by comparing the known box with a snapshot of the last one.
- Patches: a teammate's map, cropped to its known box, warped (nearest neighbour) into the
  robot's canvas and cached; when the teammate's map changed by one version inside a box, only
  the image of that box is re-warped.
- Fusion: "occupied beats free beats unknown" (the cell-wise maximum of -1 < 0 < 100, so a wall
  seen by anyone stays a wall), recomputed only in the boxes that changed since the last call.

Cost on steps without a merge attempt (2 robots, 1500 x 1500 canvases, ~400 x 400 known):
about 0.1 ms per map to find its known box (none with a ``MapChange``) and one ~0.1 ms warp per
changed teammate.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.errors import GridError
from mrexplore.grid import UNKNOWN, Int8Grid, MapChange, Transform, chain, invert_transform
from mrexplore.merge.common import known_bbox, translation, warp_into
from mrexplore.types import Box

# The compiled recomposition of listed cells (None without numba); used while kernels.enabled().
_merging = kernels.load("merging")


@dataclass
class _Patch:
    """Teammate j's map warped into robot i's canvas, restricted to a window.

    ``changed``: the region of i's canvas (r0, r1, c0, c1) rewritten by the last incremental
    update, or None after a full rebuild; ``changed_cells``: the flat cells of i's canvas in it
    whose value that update changed (int64, read-only), None after a full rebuild.
    """

    r0: int
    c0: int
    data: Int8Grid
    version: int  # j's map version it was made from
    T: Transform  # T_ij it was made with
    T_inv: Transform  # its inverse (cached: used every step)
    changed: Box | None = None
    serial: int = 0  # which patch this is (a replaced transform makes a new one)
    changed_cells: NDArray[np.int64] | None = None


def _clip(box: Box, shape: tuple[int, int]) -> Box | None:
    r0, r1, c0, c1 = max(0, box[0]), min(shape[0], box[1]), max(0, box[2]), min(shape[1], box[3])
    return (r0, r1, c0, c1) if r1 > r0 and c1 > c0 else None


def _union(a: Box, b: Box) -> Box:
    return (min(a[0], b[0]), max(a[1], b[1]), min(a[2], b[2]), max(a[3], b[3]))


def _load_cells_kernels() -> None:
    """Load :func:`_recompose_cells`' compiled loops now, with the argument types of the env's
    use (read-only maps and cell lists): their first load from numba's cache (~12 ms) otherwise
    fell in the step that applies a first merge."""
    if _merging is None or not kernels.enabled():
        return
    grid = np.zeros((1, 1), dtype=np.int8)
    grid.flags.writeable = False
    cells = np.zeros(1, dtype=np.int64)
    cells.flags.writeable = False
    _recompose_cells(
        np.zeros((1, 1), dtype=np.int8),
        grid,
        cells,
        [_Patch(0, 0, grid.copy(), 0, np.eye(3), np.eye(3))],
    )


def _recompose_cells(
    buf: Int8Grid, own: Int8Grid, cells: NDArray[np.int64], patches: Iterable[_Patch]
) -> NDArray[np.int64]:
    """Recompose the fused buffer at the flat ``cells`` of ``own`` (the cell-wise maximum of
    ``own`` and of the ``patches`` covering each); returns those of them whose value changed,
    in the order given. A scan changes tens of cells: compiled loops over them (numpy's
    per-call overhead on arrays this small cost as much as recomposing their box)."""
    if _merging is None or not kernels.enabled():
        rows, cols = np.divmod(cells, own.shape[1])
        value = own[rows, cols]
        for p in patches:
            h, w = p.data.shape
            pr, pc = rows - p.r0, cols - p.c0
            inside = (pr >= 0) & (pr < h) & (pc >= 0) & (pc < w)
            value[inside] = np.maximum(value[inside], p.data[pr[inside], pc[inside]])
        moved = value != buf[rows, cols]
        buf[rows[moved], cols[moved]] = value[moved]
        return cells[moved]
    value = _merging.cells_of(own, cells)
    for p in patches:
        _merging.max_at_cells(value, cells, own.shape[1], p.data, p.r0, p.c0)
    return np.asarray(_merging.settle_cells(buf, cells, value))


def _map_box(T: Transform, box: Box) -> Box:
    """Cells (r0, r1, c0, c1) covering the image of ``box`` under T, one cell of slack.

    Plain Python on the four corners: called every step, where numpy's per-call overhead on
    4 x 2 arrays would cost more than the arithmetic.
    """
    r0, r1, c0, c1 = box
    a, b, tx = float(T[0, 0]), float(T[0, 1]), float(T[0, 2])
    c, d, ty = float(T[1, 0]), float(T[1, 1]), float(T[1, 2])
    xs = [a * x + b * y + tx for x, y in ((c0, r0), (c1 - 1, r0), (c0, r1 - 1), (c1 - 1, r1 - 1))]
    ys = [c * x + d * y + ty for x, y in ((c0, r0), (c1 - 1, r0), (c0, r1 - 1), (c1 - 1, r1 - 1))]
    return (
        math.floor(min(ys)) - 1,
        math.ceil(max(ys)) + 2,
        math.floor(min(xs)) - 1,
        math.ceil(max(xs)) + 2,
    )


class MapCompositor:
    """The maps of ``n`` robots as they change, and each robot's fused map (see the module doc).

    >>> import numpy as np
    >>> comp = MapCompositor(2)
    >>> m = np.full((50, 50), -1, dtype=np.int8); m[10:20, 10:20] = 0
    >>> comp.observe(0, m); comp.observe(1, m)
    >>> comp.version(0), comp.bbox(0), comp.known_cells(0)
    (1, (10, 20, 10, 20), 100)
    >>> comp.fused(0, {1: np.eye(3)}, lambda i, j: True).shape
    (50, 50)
    """

    def __init__(self, n: int) -> None:
        self.n = int(n)
        self.reset()
        if self.n > 1:
            _load_cells_kernels()

    def reset(self) -> None:
        """Forget every map, patch and composition (a new episode)."""
        self._maps: list[Int8Grid | None] = [None] * self.n
        self._bbox: list[Box | None] = [None] * self.n
        self._snap: list[Int8Grid | None] = [None] * self.n  # copy of the known box, change test
        self._version = [0] * self.n
        self._patches: dict[tuple[int, int], _Patch] = {}
        # what changed in each robot's map at its last version: a box in its cells, None = all
        self._delta: list[Box | None] = [None] * self.n
        # the cells of that box that changed, when the map's owner listed them
        self._delta_cells: list[NDArray[np.int64] | None] = [None] * self.n
        self._fused: list[Int8Grid | None] = [None] * self.n
        self._fused_key: list[tuple[Any, ...] | None] = [None] * self.n
        # per robot: the fusion buffer and the versions it reflects (own, {j: patch version})
        self._fbuf: list[Int8Grid | None] = [None] * self.n
        self._fbuf_ver: list[tuple[int, dict[int, tuple[int, int]]] | None] = [None] * self.n
        self._next_serial = 1
        # per robot: compositions of the fused map so far, and the box the last one rewrote
        # (None: all of it), for readers that follow the fused map incrementally
        self._fcount = [0] * self.n
        self._fchanged: list[Box | None] = [None] * self.n
        # ... and the flat cells the last one changed (None: not listed), listed only once a
        # reader has asked for them (the compare costs a copy of each recomposed box)
        self._fcells: list[NDArray[np.int64] | None] = [None] * self.n
        self._list_cells = [False] * self.n
        # per robot: a box holding every known cell of the last composition
        self._fknown: list[Box] = [(0, 0, 0, 0)] * self.n
        # per robot: the MapChange.version last observed (None: observed without one)
        self._seen_version: list[int | None] = [None] * self.n

    def version(self, i: int) -> int:
        """A counter that grows whenever robot i's map content changes (0 before any map)."""
        return self._version[i]

    def has_map(self, i: int) -> bool:
        """Has robot i's map been observed (since the last reset)?"""
        return self._maps[i] is not None

    def bbox(self, i: int) -> Box | None:
        """Robot i's known box (half-open, its cells), None while all is unknown."""
        return self._bbox[i]

    def forget_pair(self, i: int, j: int) -> None:
        """Drop every cached patch involving robot i or j (their transform changed)."""
        self._patches = {k: p for k, p in self._patches.items() if i not in k and j not in k}

    def observe(self, i: int, m: Int8Grid, change: MapChange | None = None) -> None:
        """Take robot i's current map (int8, its own canvas), with what its owner knows of its
        changes (``change``, describing this very array) or without (the known box is scanned).
        """
        if change is None:
            self._observe_scan(i, m)
        else:
            self._observe_change(i, m, change)

    def _observe_change(self, i: int, m: Int8Grid, change: MapChange) -> None:
        """:meth:`_observe_scan` from the owner's :class:`MapChange`: no canvas scan, no snapshot.

        Consecutive owner versions give the changed box; anything else (the first map, a skipped
        version, a new canvas) is taken as "everything changed", as :meth:`observe` does.
        """
        prev, seen = self._maps[i], self._seen_version[i]
        self._maps[i] = m
        same_canvas = prev is not None and prev.shape == m.shape and seen is not None
        if same_canvas and change.version == seen:
            return  # nothing changed
        consecutive = same_canvas and seen is not None and change.version == seen + 1
        self._seen_version[i] = change.version
        self._bbox[i] = change.known_box
        self._snap[i] = None  # only the scanning path needs it
        self._delta[i] = change.changed_box if consecutive else None
        self._delta_cells[i] = change.cells if consecutive else None
        self._version[i] += 1

    def _observe_scan(self, i: int, m: Int8Grid) -> None:
        """Record robot i's map; bump its version and note the changed box when it changed.

        Cost: the known box (two SIMD max-reductions) and one comparison of the known box with
        the previous snapshot, which also yields the (usually small) box of changed cells.
        """
        self._seen_version[i] = None
        bb = known_bbox(m)
        prev, old_bb, snap = self._maps[i], self._bbox[i], self._snap[i]
        self._maps[i] = m
        delta: Box | None = None
        if prev is None or prev.shape != m.shape or snap is None or old_bb is None or bb is None:
            if prev is not None and bb is None and old_bb is None:
                return  # still all unknown: nothing changed
        elif (
            bb[0] <= old_bb[0] and bb[1] >= old_bb[1] and bb[2] <= old_bb[2] and bb[3] >= old_bb[3]
        ):
            # the known box kept or grew: compare with the old snapshot placed in the new box
            cur = m[bb[0] : bb[1], bb[2] : bb[3]]
            if bb == old_bb:
                diff = cur != snap
            else:
                before = np.full(cur.shape, UNKNOWN, dtype=np.int8)
                before[
                    old_bb[0] - bb[0] : old_bb[1] - bb[0], old_bb[2] - bb[2] : old_bb[3] - bb[2]
                ] = snap
                diff = cur != before
            rows = np.flatnonzero(diff.any(axis=1))
            if rows.size == 0:
                return  # same content
            cols = np.flatnonzero(diff[rows[0] : rows[-1] + 1].any(axis=0))
            delta = (
                bb[0] + int(rows[0]),
                bb[0] + int(rows[-1]) + 1,
                bb[2] + int(cols[0]),
                bb[2] + int(cols[-1]) + 1,
            )
        self._bbox[i] = bb
        self._snap[i] = None if bb is None else m[bb[0] : bb[1], bb[2] : bb[3]].copy()
        self._delta[i] = delta
        self._delta_cells[i] = None
        self._version[i] += 1

    def crop(self, i: int) -> tuple[Int8Grid, tuple[int, int]] | None:
        """Robot i's map cropped to its known box (a view) and the crop's (col, row) in the
        canvas, or None before anything is known."""
        bb, m = self._bbox[i], self._maps[i]
        if bb is None or m is None:
            return None
        return m[bb[0] : bb[1], bb[2] : bb[3]], (bb[2], bb[0])

    def known_cells(self, i: int) -> int:
        """Known cells of robot i's map (counted in its known box; only on merge steps)."""
        crop = self.crop(i)
        return 0 if crop is None else int(np.count_nonzero(crop[0] != UNKNOWN))

    def fused(
        self, i: int, mates: dict[int, Transform], linked: Callable[[int, int], bool]
    ) -> Int8Grid:
        """Robot i's fused map: int8, same shape and frame as its own map, with the maps of
        ``mates`` (teammate j -> T_ij, j's cells to i's) fused in over links that are up
        (``linked(i, j)``; a teammate out of range contributes the last map received from it).

        Composed incrementally: only the boxes that changed since the last call (in i's map or
        in a teammate's warped patch) are recomputed in an internal buffer; the result is a
        read-only view of that buffer, the same object until a map or transform changes. Like
        an own map's ``to_int8()`` it reflects the next composition: copy it to keep it.
        """
        own = self._maps[i]
        if own is None:
            raise GridError("MapCompositor.fused: observe the map first")
        patches = {
            j: p for j in sorted(mates) if (p := self._patch(i, j, mates[j], linked)) is not None
        }
        # patch serials, not ids: a dropped patch's id can be reused by its replacement
        key = (
            self._version[i],
            id(own),
            tuple((j, p.serial, p.version) for j, p in patches.items()),
        )
        cached = self._fused[i]
        if cached is not None and self._fused_key[i] == key:
            return cached
        buf, ver = self._fbuf[i], self._fbuf_ver[i]
        regions: list[Box] | None = []
        # per region, the cells of it that changed when they are known (the own map's, listed by
        # its owner; a patch's, found by its update): those regions are recomposed cell by cell
        region_cells: list[NDArray[np.int64] | None] = []
        if buf is None or ver is None or buf.shape != own.shape or set(ver[1]) != set(patches):
            regions = None
        else:
            if ver[0] != self._version[i]:
                d = self._delta[i]
                if ver[0] + 1 != self._version[i] or d is None:
                    regions = None
                elif regions is not None:
                    regions.append(d)
                    region_cells.append(self._delta_cells[i])
            for j, p in patches.items():
                serial, version = ver[1][j]
                if serial != p.serial:
                    # a new patch (the pair's transform was replaced): its old image is in the
                    # buffer, so compose afresh
                    regions = None
                if regions is None or version == p.version:
                    continue
                if version + 1 != p.version or p.changed is None:
                    regions = None
                else:
                    regions.append(p.changed)
                    region_cells.append(p.changed_cells)
        changed: Box | None = None
        moved: list[NDArray[np.int64]] | None = [] if self._list_cells[i] else None
        if regions is None:  # rebuild the buffer
            buf = own.copy()
            for p in patches.values():
                h, w = p.data.shape
                win = buf[p.r0 : p.r0 + h, p.c0 : p.c0 + w]
                np.maximum(win, p.data, out=win)
        else:
            assert buf is not None
            for box, cells in zip(regions, region_cells, strict=True):
                cl = _clip(box, own.shape)
                if cl is None:
                    continue
                r0, r1, c0, c1 = cl
                changed = cl if changed is None else _union(changed, cl)
                if cells is not None:
                    # only these cells of the box changed in their map: the rest of the box
                    # would be recomposed to the values it holds
                    listed = _recompose_cells(buf, own, cells, patches.values())
                    if moved is not None:
                        moved.append(listed)
                    continue
                before = None if moved is None else buf[r0:r1, c0:c1].copy()
                buf[r0:r1, c0:c1] = own[r0:r1, c0:c1]
                for p in patches.values():
                    h, w = p.data.shape
                    sub = _clip((r0 - p.r0, r1 - p.r0, c0 - p.c0, c1 - p.c0), (h, w))
                    if sub is None:
                        continue
                    a0, a1, b0, b1 = sub
                    win = buf[p.r0 + a0 : p.r0 + a1, p.c0 + b0 : p.c0 + b1]
                    np.maximum(win, p.data[a0:a1, b0:b1], out=win)
                if moved is not None and before is not None:
                    # the cells this region's composition changed (an overlap recomposed by a
                    # later region gets the same values: each region's own compare lists it once)
                    flat = np.flatnonzero(before != buf[r0:r1, c0:c1])
                    rows, cols = np.divmod(flat, c1 - c0)
                    moved.append((rows + r0) * own.shape[1] + (cols + c0))
        self._fbuf[i] = buf
        self._fbuf_ver[i] = (
            self._version[i],
            {j: (p.serial, p.version) for j, p in patches.items()},
        )
        self._fcount[i] += 1
        self._fchanged[i] = None if regions is None else (changed or (0, 0, 0, 0))
        self._fcells[i] = (
            None
            if regions is None or moved is None
            else (np.concatenate(moved) if moved else np.zeros(0, dtype=np.int64))
        )
        self._fknown[i] = self._known_box(i, own.shape, patches.values())
        # A read-only view of the buffer, a new view object whenever the content changed (as
        # the own maps' ``to_int8``): a fresh copy cost a memset of the canvas per changed step.
        out = buf.view()
        out.flags.writeable = False
        self._fused[i], self._fused_key[i] = out, key
        return out

    def _known_box(self, i: int, shape: tuple[int, int], patches: Iterable[_Patch]) -> Box:
        """A box holding every known cell of robot i's composition: its own known box and the
        windows of the ``patches`` fused in, clipped to ``shape``; ``(0, 0, 0, 0)`` when empty."""
        box = self._bbox[i]
        for p in patches:
            h, w = p.data.shape
            win = _clip((p.r0, p.r0 + h, p.c0, p.c0 + w), shape)
            if win is not None:
                box = win if box is None else _union(box, win)
        return (0, 0, 0, 0) if box is None else box

    def fused_known_box(self, i: int) -> Box:
        """A half-open box of robot i's last fused map (:meth:`fused`) holding every cell that is
        not unknown: its own known box and the windows of the teammates' patches (no scan;
        possibly larger than the tightest box); ``(0, 0, 0, 0)`` before any composition."""
        return self._fknown[i]

    def fused_change(self, i: int) -> tuple[int, Box | None]:
        """``(composition count, box)`` of robot i's fused map: the count grows by one with
        every :meth:`fused` that recomposed it, and ``box`` (half-open, i's cells; empty when
        nothing changed, None when rebuilt whole) bounds what that composition rewrote. A reader
        that saw count k - 1 need only look at the box to follow count k."""
        return self._fcount[i], self._fchanged[i]

    def fused_changed_cells(self, i: int) -> NDArray[np.int64] | None:
        """The flat cells of robot i's fused map whose value the last composition counted by
        :meth:`fused_change` changed (int64, inside its box; a cell may repeat), or None when
        that composition rebuilt the map whole or did not list them: the cells are listed from
        the first composition after a reader first asked (readers that never ask pay nothing)."""
        self._list_cells[i] = True
        return self._fcells[i]

    def _patch(
        self, i: int, j: int, T: Transform, linked: Callable[[int, int], bool]
    ) -> _Patch | None:
        """j's map warped into i's canvas (cached); stale copy when the link is down.

        When j's map changed by one version inside a box, only the image of that box is
        re-warped (from a crop of j's map covering its preimage); otherwise the patch is rebuilt
        from j's known box.
        """
        old = self._patches.get((i, j))
        if not linked(i, j) or (old is not None and old.version == self._version[j]):
            return old
        own, mj = self._maps[i], self._maps[j]
        if own is None or mj is None:
            return old
        d = self._delta[j]
        if (
            old is not None
            and d is not None
            and old.version + 1 == self._version[j]
            and np.array_equal(old.T, T)
        ):
            h, w = old.data.shape
            dst = _clip(_map_box(T, d), own.shape)
            win = (old.r0, old.r0 + h, old.c0, old.c0 + w)
            if dst is None or (
                dst[0] >= win[0] and dst[1] <= win[1] and dst[2] >= win[2] and dst[3] <= win[3]
            ):
                if dst is not None:
                    # source crop = preimage of the destination box: every destination cell
                    # finds its nearest source cell inside it (or outside j's map = unknown)
                    src = _clip(_map_box(old.T_inv, dst), mj.shape)
                    if src is not None:
                        s0, s1, t0, t1 = src
                        piece = warp_into(
                            mj[s0:s1, t0:t1],
                            chain(T, translation(t0, s0)),  # no BLAS: same bits on any CPU
                            (dst[1] - dst[0], dst[3] - dst[2]),
                            dst_origin=(dst[2], dst[0]),
                        )
                    else:
                        piece = np.full((dst[1] - dst[0], dst[3] - dst[2]), UNKNOWN, np.int8)
                    window = old.data[
                        dst[0] - old.r0 : dst[1] - old.r0, dst[2] - old.c0 : dst[3] - old.c0
                    ]
                    rows, cols = np.divmod(np.flatnonzero(piece != window), piece.shape[1])
                    cells = (rows + dst[0]) * own.shape[1] + (cols + dst[2])
                    window[...] = piece
                else:
                    cells = np.zeros(0, dtype=np.int64)
                cells.flags.writeable = False
                old.version = self._version[j]
                old.changed = dst if dst is not None else (0, 0, 0, 0)
                old.changed_cells = cells
                return old
        cj = self.crop(j)
        if cj is None:
            return old
        b, (cb, rb) = cj
        T_crop = chain(T, translation(cb, rb))  # cropped j cells -> i cells (chain: no BLAS)
        box = _clip(_map_box(T_crop, (0, b.shape[0], 0, b.shape[1])), own.shape)
        if box is None:
            return old  # j's known part falls outside i's canvas
        r0, r1, c0, c1 = box
        data = warp_into(b, T_crop, (r1 - r0, c1 - c0), dst_origin=(c0, r0))
        p = _Patch(
            r0, c0, data, self._version[j], T.copy(), invert_transform(T), None, self._next_serial
        )
        self._next_serial += 1
        self._patches[(i, j)] = p
        return p
