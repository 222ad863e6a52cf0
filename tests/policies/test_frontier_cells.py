"""Frontier extraction on tiny hand-made grids."""

from __future__ import annotations

import numpy as np
import pytest

from mrexplore.errors import GridError
from mrexplore.grid import FREE, OCCUPIED, UNKNOWN
from mrexplore.policies.frontier_cells import find_frontiers, frontier_mask, known_bbox


def _room(h: int = 12, w: int = 14) -> np.ndarray:
    """A free room walled on all sides (rows 2..9, cols 2..11), inside an unknown canvas."""
    g = np.full((h, w), UNKNOWN, dtype=np.int8)
    g[2:10, 2:12] = OCCUPIED
    g[3:9, 3:11] = FREE
    return g


def _open_right() -> np.ndarray:
    g = _room()
    g[3:9, 11] = UNKNOWN  # the right wall was never seen: the room continues into unknown space
    return g


def _two_gaps() -> np.ndarray:
    g = _room()
    g[3:6, 11] = UNKNOWN  # two holes in the right wall, separated by wall cells at rows 6..7
    g[8, 11] = UNKNOWN
    g[6:8, 11] = OCCUPIED
    g[2, 5:9] = UNKNOWN  # and one in the bottom wall
    return g


def _occupied_only() -> np.ndarray:
    g = np.full((5, 5), OCCUPIED, dtype=np.int8)
    g[2, 2] = FREE  # a free cell surrounded by walls: no unknown next to it
    return g


def _diagonal_unknown() -> np.ndarray:
    g = np.full((5, 5), FREE, dtype=np.int8)
    g[0:2, 0:2] = OCCUPIED
    g[0, 0] = UNKNOWN  # unknown touches free cells only diagonally -> (1,1) is occupied; none
    return g


@pytest.mark.parametrize(
    ("grid", "min_size", "expected_sizes"),
    [
        (_open_right(), 1, [6]),  # one unknown side: one frontier along it, 6 cells tall
        (
            _two_gaps(),
            1,
            [4, 3, 1],
        ),  # three separated gaps: bottom (4), right-low (3), right-high (1)
        (_two_gaps(), 2, [4, 3]),  # min size drops the single-cell gap
        (_room(), 1, []),  # a fully known room: nothing to explore
        (_occupied_only(), 1, []),  # free next to occupied only is not a frontier
        (_diagonal_unknown(), 1, []),  # unknown only diagonally adjacent to free: not 4-adjacent
        (np.full((4, 4), UNKNOWN, dtype=np.int8), 1, []),  # nothing known at all
        (
            np.full((4, 4), FREE, dtype=np.int8),
            1,
            [],
        ),  # everything free: the canvas edge is no frontier
    ],
)
def test_frontier_sizes(grid: np.ndarray, min_size: int, expected_sizes: list[int]) -> None:
    fronts = find_frontiers(grid, min_size_cells=min_size)
    assert [f.size for f in fronts] == expected_sizes
    mask = frontier_mask(grid)
    for f in fronts:
        assert f.cells.shape == (f.size, 2)
        # Every cell is a frontier cell, and the target is one of the cells.
        assert mask[f.cells[:, 1], f.cells[:, 0]].all()
        assert any((f.cells == np.array(f.target)).all(axis=1))
    if min_size == 1:
        assert int(mask.sum()) == sum(expected_sizes)


def test_frontier_geometry_open_side() -> None:
    f = find_frontiers(_open_right(), min_size_cells=1)[0]
    assert set(f.cells[:, 0].tolist()) == {10}  # the last free column, next to the unknown one
    assert sorted(f.cells[:, 1].tolist()) == [3, 4, 5, 6, 7, 8]
    assert f.centroid == pytest.approx((10.0, 5.5))
    assert f.target[0] == 10 and f.target[1] in (5, 6)  # the cells closest to the centroid


def test_frontier_cells_free_and_next_to_unknown() -> None:
    rng = np.random.default_rng(3)
    g = rng.choice(np.array([UNKNOWN, FREE, OCCUPIED], dtype=np.int8), size=(30, 40))
    mask = frontier_mask(g)
    # Reference with explicit neighbours (outside the grid counts as not unknown).
    unk = np.pad(g == UNKNOWN, 1)
    near = unk[:-2, 1:-1] | unk[2:, 1:-1] | unk[1:-1, :-2] | unk[1:-1, 2:]
    assert np.array_equal(mask, (g == FREE) & near)


def test_known_bbox() -> None:
    g = _room()
    assert known_bbox(g) == (2, 10, 2, 12)
    assert known_bbox(g, margin=5) == (0, 12, 0, 14)
    assert known_bbox(np.full((3, 3), UNKNOWN, dtype=np.int8)) is None


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros((3, 3), dtype=np.float32),  # float map
        np.zeros((3,), dtype=np.int8),  # 1-D
        [[0, 0], [0, 0]],  # not an array
    ],
)
def test_bad_map_raises(bad: object) -> None:
    with pytest.raises(GridError):
        find_frontiers(bad)  # type: ignore[arg-type]


def test_bad_min_size_raises() -> None:
    with pytest.raises(GridError, match="min_size_cells"):
        find_frontiers(_room(), min_size_cells=0)
