"""Planner: inflation, coarse grid, distance field, path extraction."""

from __future__ import annotations

import heapq
import math

import numpy as np
import pytest

from mrexplore.errors import ConfigError, GridError
from mrexplore.grid import FREE, OCCUPIED, UNKNOWN
from mrexplore.policies.planning import (
    PlanningGrid,
    distance_field,
    distance_field_scan,
    inflate_obstacles,
)

RES = 0.05
RADIUS = 0.15


def _dijkstra(free: np.ndarray, src: tuple[int, int]) -> np.ndarray:
    """Reference: heap Dijkstra, 8-connected, sqrt 2 diagonals, no corner cutting."""
    h, w = free.shape
    d = np.full((h, w), np.inf)
    d[src[1], src[0]] = 0.0
    pq = [(0.0, src[0], src[1])]
    while pq:
        dd, i, j = heapq.heappop(pq)
        if dd > d[j, i]:
            continue
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                jj, ii = j + dr, i + dc
                if (dr, dc) == (0, 0) or not (0 <= ii < w and 0 <= jj < h) or not free[jj, ii]:
                    continue
                if dr and dc and not (free[j + dr, i] and free[j, i + dc]):
                    continue
                nd = dd + (math.sqrt(2.0) if dr and dc else 1.0)
                if nd < d[jj, ii] - 1e-12:
                    d[jj, ii] = nd
                    heapq.heappush(pq, (nd, ii, jj))
    return d


@pytest.mark.parametrize("method", ["dijkstra", "scan"])
@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_distance_field_matches_reference(seed: int, method: str) -> None:
    rng = np.random.default_rng(seed)
    free = rng.random((25, 31)) > 0.3
    free[8, :27] = False  # two long walls: paths must snake
    free[16, 4:] = False
    free[0, 0] = True
    got = distance_field(free, np.array([[0, 0]]), method=method)
    ref = _dijkstra(free, (0, 0))
    assert np.array_equal(np.isinf(got), np.isinf(ref))
    fin = np.isfinite(ref)
    # Integer step costs 10000 / 14142: diagonals are sqrt 2 to 2e-5 relative.
    np.testing.assert_allclose(got[fin], ref[fin], rtol=1e-4, atol=1e-6)


def test_numba_and_numpy_fields_agree_exactly() -> None:
    """Both methods use the same integer step costs, so they must give the same numbers."""
    rng = np.random.default_rng(11)
    free = rng.random((70, 90)) > 0.25
    sources = np.array([[5, 5], [80, 60]])
    a = distance_field(free, sources, method="dijkstra")
    b = distance_field_scan(free, sources)
    assert np.array_equal(a, b)


def test_distance_field_bad_method() -> None:
    with pytest.raises(ConfigError):
        distance_field(np.ones((3, 3), dtype=bool), np.array([[0, 0]]), method="bfs")


@pytest.mark.parametrize("method", ["dijkstra", "scan"])
def test_distance_field_no_corner_cutting(method: str) -> None:
    free = np.array([[1, 0], [0, 1]], dtype=bool)
    d = distance_field(free, np.array([[0, 0]]), method=method)
    assert np.isinf(d[1, 1])  # diagonal between two blocked cells is not allowed


def test_distance_field_blocked_source() -> None:
    free = np.ones((3, 3), dtype=bool)
    free[1, 1] = False
    assert np.isinf(distance_field(free, np.array([[1, 1]]))).all()


def _two_rooms(gap_cells: int) -> np.ndarray:
    """Two free rooms split by a wall at col 30 with a door of ``gap_cells`` cells at rows 18.."""
    g = np.full((40, 60), FREE, dtype=np.int8)
    g[0, :] = g[-1, :] = OCCUPIED
    g[:, 0] = g[:, -1] = OCCUPIED
    g[:, 30] = OCCUPIED
    if gap_cells:
        g[18 : 18 + gap_cells, 30] = FREE
    return g


def test_path_goes_around_wall_through_door() -> None:
    g = _two_rooms(gap_cells=16)  # a 0.8 m door
    grid = PlanningGrid.build(g, RES, RADIUS, (10.0, 5.0), factor=2)
    goal = grid.nearest_free((50.0, 5.0))
    assert goal is not None
    path = grid.path_to(goal)
    assert path is not None
    # It crosses the wall column only inside the door, and keeps clear of inflated cells.
    blocked = inflate_obstacles(g, RADIUS, RES)
    cols, rows = np.rint(path[:, 0]).astype(int), np.rint(path[:, 1]).astype(int)
    assert not blocked[rows, cols].any()
    at_wall = np.abs(path[:, 0] - 30) < 1.5
    assert at_wall.any() and ((path[at_wall, 1] >= 18) & (path[at_wall, 1] < 34)).all()
    # Path length is about the field value (descent follows the field exactly).
    steps = np.hypot(*np.diff(path, axis=0).T).sum() / grid.factor
    assert steps == pytest.approx(grid.field[goal[1], goal[0]], rel=1e-3)


@pytest.mark.parametrize(
    ("gap_cells", "reachable"),
    [
        (0, False),  # no door
        (1, False),  # a one-cell (5 cm) gap: far narrower than the 0.3 m robot
        (4, False),  # 0.2 m: still narrower than the robot
        (16, True),  # 0.8 m door
    ],
)
def test_narrow_gap(gap_cells: int, reachable: bool) -> None:
    grid = PlanningGrid.build(_two_rooms(gap_cells), RES, RADIUS, (10.0, 20.0), factor=2)
    goal = grid.nearest_free((50.0, 20.0))
    assert goal is not None
    assert np.isfinite(grid.field[goal[1], goal[0]]) == reachable
    assert (grid.path_to(goal) is not None) == reachable


def test_start_inside_inflation_uses_nearest_free_cell() -> None:
    g = _two_rooms(gap_cells=16)
    # Hugging the left outer wall: 1 cell from it, inside the 3.5-cell inflation.
    grid = PlanningGrid.build(g, RES, RADIUS, (1.0, 20.0), factor=2)
    assert grid.start is not None
    assert grid.free[grid.start[1], grid.start[0]]
    assert grid.field[grid.start[1], grid.start[0]] == 0.0
    centre = grid.to_fine(np.array([grid.start]))[0]
    assert 3.0 <= centre[0] <= 7.0 and abs(centre[1] - 20.0) <= 2.0  # the closest free spot
    goal = grid.nearest_free((15.0, 20.0))
    assert goal is not None and grid.path_to(goal) is not None


def test_unknown_blocks_unless_optimistic() -> None:
    g = _two_rooms(gap_cells=16)
    g[:, 25:36] = UNKNOWN  # the door region was never seen
    pessimistic = PlanningGrid.build(g, RES, RADIUS, (10.0, 20.0), factor=2)
    optimistic = PlanningGrid.build(g, RES, RADIUS, (10.0, 20.0), factor=2, unknown_is_free=True)
    for grid, reachable in ((pessimistic, False), (optimistic, True)):
        goal = grid.nearest_free((50.0, 20.0))
        assert goal is not None
        assert np.isfinite(grid.field[goal[1], goal[0]]) == reachable


def test_crop_offsets_large_canvas() -> None:
    """The planner works on the known crop of a big canvas and answers in canvas cells."""
    canvas = np.full((600, 700), UNKNOWN, dtype=np.int8)
    canvas[300:340, 400:460] = _two_rooms(gap_cells=16)
    grid = PlanningGrid.build(canvas, RES, RADIUS, (410.0, 305.0), factor=2)
    assert grid.shape[0] < 60 and grid.shape[1] < 80  # cropped, not 300 x 350
    goal = grid.nearest_free((450.0, 305.0))
    assert goal is not None
    path = grid.path_to(goal)
    assert path is not None
    assert np.hypot(*(path[0] - (410.0, 305.0))) < 2.0
    assert np.hypot(*(path[-1] - (450.0, 305.0))) < 2.0


def test_inflation_radius() -> None:
    g = np.full((15, 15), FREE, dtype=np.int8)
    g[7, 7] = OCCUPIED
    b = inflate_obstacles(g, RADIUS, RES)
    # 0.15 m / 0.05 m + half a cell = 3.5 cells: (7, 10) blocked, (7, 11) free,
    # (10, 9) free (sqrt 13 > 3.5).
    assert b[7, 10] and not b[7, 11] and not b[10, 9] and b[9, 9]


@pytest.mark.parametrize(
    "kwargs",
    [
        {"factor": 0},  # no planning cells
    ],
)
def test_bad_options(kwargs: dict[str, int]) -> None:
    with pytest.raises(ConfigError):
        PlanningGrid.build(_two_rooms(16), RES, RADIUS, (10.0, 5.0), **kwargs)  # type: ignore[arg-type]


def test_bad_map() -> None:
    with pytest.raises(GridError):
        PlanningGrid.build(np.zeros((5, 5)), RES, RADIUS, (1.0, 1.0))  # type: ignore[arg-type]
    with pytest.raises(ConfigError):
        inflate_obstacles(_two_rooms(16), -0.1, RES)


def test_zero_clearance_inflation_is_the_simulators_collision_rule() -> None:
    """``clearance_cells=0`` blocks exactly the cells the simulator forbids to a robot centre."""
    from mrexplore.robot import configuration_space

    rng = np.random.default_rng(3)
    g = np.where(rng.random((40, 50)) < 0.03, OCCUPIED, FREE).astype(np.int8)
    blocked = inflate_obstacles(g, RADIUS, RES, clearance_cells=0.0)
    truth = configuration_space(g == OCCUPIED, RADIUS / RES)
    inner = (slice(4, -4), slice(4, -4))  # the simulator also walls the canvas border
    assert np.array_equal(blocked[inner], truth[inner])
    with pytest.raises(ConfigError):
        inflate_obstacles(g, RADIUS, RES, clearance_cells=-1.0)


def test_passable_path_joins_the_robot_to_where_it_came_from() -> None:
    """A robot standing in a gap its map shows too narrow: only its trail links it back."""
    g = _two_rooms(gap_cells=5)  # too narrow for the inflated robot
    trail = np.array([[10.0, 20.0], [20.0, 20.0], [30.0, 20.0]])
    without = PlanningGrid.build(g, RES, RADIUS, (30.0, 20.0), factor=1)
    with_trail = PlanningGrid.build(g, RES, RADIUS, (30.0, 20.0), factor=1, passable_path=trail)
    goal = with_trail.nearest_free((10.0, 20.0))
    assert goal is not None
    assert np.isfinite(with_trail.field[goal[1], goal[0]])
    path = with_trail.path_to(goal)
    assert path is not None
    assert without.start is not None and without.start != (30, 20)
