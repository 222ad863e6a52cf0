"""MapCompositor: change detection, crops, and fused maps (occupied beats free beats unknown)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from mrexplore.grid import OCCUPIED, UNKNOWN, MapChange, known_bbox
from mrexplore.merge.common import translation
from mrexplore.merge.compositor import MapCompositor


def _map() -> np.ndarray:
    m = np.full((40, 50), UNKNOWN, dtype=np.int8)
    m[10:20, 5:15] = 0
    return m


def test_version_and_known_box_follow_changes() -> None:
    comp = MapCompositor(1)
    m = _map()
    comp.observe(0, m)
    assert comp.version(0) == 1 and comp.bbox(0) == (10, 20, 5, 15)
    comp.observe(0, m)  # same content: no new version
    assert comp.version(0) == 1
    m[12, 16] = OCCUPIED  # grows the known box
    comp.observe(0, m)
    assert comp.version(0) == 2 and comp.bbox(0) == (10, 20, 5, 17)
    crop, (col, row) = comp.crop(0)  # type: ignore[misc]
    assert (col, row) == (5, 10) and crop.shape == (10, 12)
    assert comp.known_cells(0) == 101


def test_fused_map_is_the_cellwise_max_through_the_transform_and_the_links() -> None:
    comp = MapCompositor(2)
    a, b = _map(), np.full((40, 50), UNKNOWN, dtype=np.int8)
    b[10:20, 5:15] = OCCUPIED  # b's cells land 20 columns right of where they are in b
    comp.observe(0, a)
    comp.observe(1, b)
    T = translation(20, 0)
    fused = comp.fused(0, {1: T}, lambda i, j: True)
    assert (fused[10:20, 25:35] == OCCUPIED).all() and (fused[10:20, 5:15] == 0).all()
    assert not fused.flags.writeable
    # the link goes down: b's change does not travel, the last patch received stays
    b[30:35, 5:15] = OCCUPIED
    comp.observe(1, b)
    stale = comp.fused(0, {1: T}, lambda i, j: False)
    assert (stale[30:35, 25:35] == UNKNOWN).all() and (stale[10:20, 25:35] == OCCUPIED).all()
    linked = comp.fused(0, {1: T}, lambda i, j: True)
    assert (linked[30:35, 25:35] == OCCUPIED).all()
    # a new transform for the pair: forget its patches, the fused map follows the new one
    comp.forget_pair(0, 1)
    moved = comp.fused(0, {1: translation(30, 0)}, lambda i, j: True)
    assert (moved[10:20, 35:45] == OCCUPIED).all() and (moved[10:20, 25:35] != OCCUPIED).all()


def _holds(box: tuple[int, int, int, int], m: np.ndarray) -> bool:
    """Does ``box`` (half-open) hold every known cell of ``m``?"""
    tight = known_bbox(m)
    if tight is None:
        return True
    return box[0] <= tight[0] and box[1] >= tight[1] and box[2] <= tight[2] and box[3] >= tight[3]


def test_fused_known_box_holds_every_known_cell_as_the_maps_grow() -> None:
    comp = MapCompositor(2)
    assert comp.fused_known_box(0) == (0, 0, 0, 0)  # before any composition
    a, b = _map(), np.full((40, 50), UNKNOWN, dtype=np.int8)
    b[2:6, 3:8] = OCCUPIED
    comp.observe(0, a)
    comp.observe(1, b)
    T = translation(30, 25)  # b's cells land up and right of a's known box
    fused = comp.fused(0, {1: T}, lambda i, j: True)
    box = comp.fused_known_box(0)
    assert _holds(box, fused) and not _holds(comp.bbox(0), fused)  # type: ignore[arg-type]
    b[6:9, 3:12] = 0  # b grows: the incremental composition's box follows
    comp.observe(1, b)
    fused = comp.fused(0, {1: T}, lambda i, j: True)
    assert _holds(comp.fused_known_box(0), fused)
    assert (fused[31:34, 33:42] == 0).all()


def test_fused_changed_cells_are_the_cells_a_composition_changed() -> None:
    """After each incremental composition, ``fused_changed_cells`` holds exactly the cells whose
    value changed (as a set); a rebuild lists none (None)."""
    rng = np.random.default_rng(2)
    comp = MapCompositor(2)
    a, b = _map(), np.full((40, 50), UNKNOWN, dtype=np.int8)
    b[2:6, 3:8] = OCCUPIED
    comp.observe(0, a)
    comp.observe(1, b)
    T = translation(12, 9)
    before = comp.fused(0, {1: T}, lambda i, j: True).copy()
    assert comp.fused_changed_cells(0) is None  # the first composition is a rebuild
    listed = 0
    for k in range(8):
        m = (a, b)[k % 2]
        r, c = int(rng.integers(0, 30)), int(rng.integers(0, 40))
        m[r : r + 4, c : c + 6] = rng.choice(np.array([0, 50, OCCUPIED], dtype=np.int8))
        comp.observe(k % 2, m)
        now = comp.fused(0, {1: T}, lambda i, j: True)
        cells = comp.fused_changed_cells(0)
        if cells is None:  # rebuilt whole (a patch outgrew its window): the box says so too
            assert comp.fused_change(0)[1] is None
        else:
            listed += 1
            assert set(cells.tolist()) == set(np.flatnonzero(now != before).tolist())
        before = now.copy()
    assert listed >= 4


def test_changed_cells_are_listed_only_once_a_reader_asks() -> None:
    comp = MapCompositor(2)
    a, b = _map(), np.full((40, 50), UNKNOWN, dtype=np.int8)
    comp.observe(0, a)
    comp.observe(1, b)
    comp.fused(0, {1: translation(5, 5)}, lambda i, j: True)
    a[25:28, 5:9] = 0
    comp.observe(0, a)
    comp.fused(0, {1: translation(5, 5)}, lambda i, j: True)
    assert comp.fused_change(0)[1] is not None  # an incremental composition ...
    assert comp.fused_changed_cells(0) is None  # ... whose cells nobody had asked for
    a[30:32, 5:9] = 0
    comp.observe(0, a)
    comp.fused(0, {1: translation(5, 5)}, lambda i, j: True)
    cells = comp.fused_changed_cells(0)
    assert cells is not None and len(cells) == 8


def test_listed_own_cells_compose_as_the_changed_box(monkeypatch: pytest.MonkeyPatch) -> None:
    """A map change that lists its cells (``MapChange.cells``) is recomposed cell by cell, and
    so are the cells a teammate's patch update changed: the same fused maps as composed whole,
    and the same changed cells (as sets) as from the own map's changed box."""
    import mrexplore.merge.compositor as compositor

    calls = []
    recompose = compositor._recompose_cells

    def counted(*args: Any) -> Any:
        calls.append(1)
        return recompose(*args)

    monkeypatch.setattr(compositor, "_recompose_cells", counted)
    rng = np.random.default_rng(4)
    values = np.array([UNKNOWN, 0, 30, 70, OCCUPIED], dtype=np.int8)
    maps = [_map() for _ in range(3)]
    mates = {1: translation(12, 9), 2: translation(-6, 3)}
    listed, boxed = MapCompositor(3), MapCompositor(3)
    versions = [0, 0, 0]

    def tell(i: int, before: np.ndarray | None) -> None:
        m = maps[i]
        if before is not None:
            cells = np.flatnonzero(m != before)
            if cells.size == 0:
                return
            rows, cols = np.divmod(cells, m.shape[1])
            box = (int(rows.min()), int(rows.max()) + 1, int(cols.min()), int(cols.max()) + 1)
        else:
            cells, box = None, None
        versions[i] += 1
        for comp, with_cells in ((listed, True), (boxed, False)):
            change = MapChange(versions[i], known_bbox(m), box, cells if with_cells else None)
            comp.observe(i, m, change)

    for i in range(3):
        tell(i, None)
    for comp in (listed, boxed):
        comp.fused(0, mates, lambda i, j: True)
        comp.fused_changed_cells(0)  # a reader asks: the next compositions list their cells
    for k in range(40):
        i = 0 if k % 3 else int(rng.integers(1, 3))  # mostly the own map
        before = maps[i].copy()
        r, c = int(rng.integers(0, 36)), int(rng.integers(0, 44))
        maps[i][r : r + 4, c : c + 6] = rng.choice(values, (4, 6) if k % 2 else (1, 1))
        tell(i, before)
        a = listed.fused(0, mates, lambda i, j: True)
        b = boxed.fused(0, mates, lambda i, j: True)
        np.testing.assert_array_equal(a, b)
        fresh = MapCompositor(3)  # composed whole: the reference
        for j in range(3):
            fresh.observe(j, maps[j])
        np.testing.assert_array_equal(a, fresh.fused(0, mates, lambda i, j: True))
        assert listed.fused_change(0) == boxed.fused_change(0)
        ca, cb = listed.fused_changed_cells(0), boxed.fused_changed_cells(0)
        assert (ca is None) == (cb is None)
        if ca is not None and cb is not None:
            assert set(ca.tolist()) == set(cb.tolist())
    # the own map's changes cell by cell in one compositor, the teammates' in both
    assert len(calls) >= 20 + 2 * 10
