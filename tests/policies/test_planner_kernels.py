"""The planner's compiled kernels give what its numpy/OpenCV path gives, bit for bit.

Every function is called twice on the same inputs, once with the kernels switched off
(``kernels.USE_NUMBA = False``: the numpy/OpenCV path) and once on; then a team rollout holds
the compiled planner's decisions to the numpy planner's, step by step.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from contextlib import contextmanager
from functools import partial
from typing import Any, TypeVar

import numpy as np
import pytest

import mrexplore
from mrexplore import kernels
from mrexplore.policies import make_team_policy
from mrexplore.policies.base import densify_path, follow_path, nearest_path_index
from mrexplore.policies.explorers import CoordinatedFrontierPolicy
from mrexplore.policies.frontier_cells import find_frontiers, frontier_near
from mrexplore.policies.planning import PlanningGrid, distance_field

pytestmark = pytest.mark.skipif(not kernels.HAVE_NUMBA, reason="the kernels need numba")

T = TypeVar("T")


@contextmanager
def _kernels(on: bool) -> Iterator[None]:
    saved = kernels.USE_NUMBA
    kernels.USE_NUMBA = on
    try:
        yield
    finally:
        kernels.USE_NUMBA = saved


def _both(fn: Callable[[], T]) -> tuple[T, T]:
    """``fn()`` on the numpy path, then on the compiled one."""
    with _kernels(False):
        ref = fn()
    with _kernels(True):
        new = fn()
    return ref, new


def _same(a: Any, b: Any) -> None:
    """Equal, arrays by dtype, shape and bytes (so -0.0, inf and NaN count)."""
    if isinstance(a, np.ndarray):
        assert isinstance(b, np.ndarray)
        assert a.dtype == b.dtype and a.shape == b.shape
        assert np.ascontiguousarray(a).tobytes() == np.ascontiguousarray(b).tobytes()
    elif isinstance(a, (list, tuple)):
        assert type(a) is type(b) and len(a) == len(b)
        for x, y in zip(a, b, strict=True):
            _same(x, y)
    else:
        assert type(a) is type(b) and (a == b or (a != a and b != b)), (a, b)


def _random_map(rng: np.random.Generator) -> np.ndarray:
    """An int8 map: a few rectangles of known cells (free, undecided, walls) with unknown holes
    and walls, on an unknown canvas; sometimes touching the canvas edges."""
    h, w = (int(v) for v in rng.integers(8, 90, size=2))
    m = np.full((h, w), -1, dtype=np.int8)
    values = np.array([0, 0, 0, 0, 5, 25, 26, 50, 64, 65, 100], dtype=np.int8)
    for _ in range(int(rng.integers(0, 5))):
        r0, c0 = int(rng.integers(0, h)), int(rng.integers(0, w))
        r1, c1 = r0 + int(rng.integers(1, h)), c0 + int(rng.integers(1, w))
        block = m[r0:r1, c0:c1]
        block[...] = rng.choice(values, size=block.shape, p=None)
        block[rng.random(block.shape) < 0.6] = 0
    m[rng.random(m.shape) < rng.uniform(0, 0.1)] = -1
    m[rng.random(m.shape) < rng.uniform(0, 0.05)] = 100
    return m


def test_frontiers_equal_the_opencv_path() -> None:
    rng = np.random.default_rng(0)
    for case in range(400):
        m = _random_map(rng)
        size = int(rng.integers(1, 12))
        if case % 3 == 0:
            m = m[1:-1, 2:]  # a non-contiguous crop, as the planner passes
        ref, new = _both(partial(find_frontiers, m, size))
        assert len(ref) == len(new)
        for f, g in zip(ref, new, strict=True):
            _same(f.cells, g.cells)
            assert (f.size, f.centroid, f.target) == (g.size, g.centroid, g.target)
        h, w = m.shape
        for _ in range(20):
            cell = (int(rng.integers(0, w)), int(rng.integers(0, h)))
            radius = int(rng.integers(0, 4))
            a, b = _both(partial(frontier_near, m, cell, radius))
            assert a == b


def test_planning_grid_equals_the_numpy_path() -> None:
    rng = np.random.default_rng(1)
    for _ in range(300):
        m = _random_map(rng)
        h, w = m.shape
        start = (float(rng.uniform(-2, w + 2)), float(rng.uniform(-2, h + 2)))
        kw = {
            "factor": int(rng.integers(1, 4)),
            "unknown_is_free": bool(rng.integers(2)),
            "clearance_cells": float(rng.choice([0.0, 0.5, 1.3])),
            "margin_m": float(rng.choice([0.0, 0.3])),
        }
        radius = float(rng.choice([0.0, 0.05, 0.15, 0.22]))

        ref, new = _both(partial(PlanningGrid.build, m, 0.05, radius, start, **kw))
        _same(ref.free, new.free)
        _same(ref.field, new.field)
        assert (ref.start, ref.col0, ref.row0) == (new.start, new.col0, new.row0)
        cells = np.stack([rng.integers(-3, w + 3, 30), rng.integers(-3, h + 3, 30)], axis=1)
        for reach in (0, 1, 2):
            a, b = _both(partial(new.approach, cells, reach))
            _same(a[0], b[0])
            _same(a[1], b[1])
        hh, ww = new.shape
        for _ in range(10):
            goal = (int(rng.integers(-1, ww + 1)), int(rng.integers(-1, hh + 1)))
            pa, pb = _both(partial(new.path_to, goal))
            if pa is None:
                assert pb is None
            else:
                _same(pa, pb)


def test_distance_fields_with_several_sources_equal_the_scans() -> None:
    rng = np.random.default_rng(2)
    for _ in range(200):
        h, w = (int(v) for v in rng.integers(1, 60, size=2))
        free = rng.random((h, w)) > rng.uniform(0, 0.5)
        src = np.stack([rng.integers(-1, w + 1, 3), rng.integers(-1, h + 1, 3)], axis=1)
        _same(
            distance_field(free, src, method="scan"), distance_field(free, src, method="dijkstra")
        )


def test_path_helpers_equal_the_numpy_path() -> None:
    rng = np.random.default_rng(3)
    for _ in range(500):
        k = int(rng.integers(1, 12))
        path = np.cumsum(rng.normal(0, rng.choice([0.3, 1.0, 4.0]), size=(k, 2)), axis=0) + 20
        if rng.integers(3) == 0:
            path = np.rint(path)  # planning-cell centres: axis-aligned and diagonal steps
        spacing = float(rng.choice([1.0, 0.5, 2.0]))
        a, b = _both(partial(densify_path, path, spacing))
        _same(a, b)
        dense = densify_path(path)
        pose = (float(rng.uniform(10, 40)), float(rng.uniform(10, 40)), float(rng.uniform(-4, 4)))
        i, j = _both(partial(nearest_path_index, dense, pose))
        assert i == j
        free = rng.random((30, 30)) > rng.uniform(0, 0.4)
        grid = PlanningGrid(free, -5, 3, 2, 0.05, np.zeros(free.shape), None)
        for args in (
            {"lookahead_cells": 6.0, "arrive_cells": 3.0},
            {"lookahead_cells": 1.0, "arrive_cells": 0.5, "blocked_ahead": True},
        ):
            a2, b2 = _both(partial(follow_path, dense, pose, grid=grid, **args))
            assert a2 == b2
            assert a2 == follow_path(dense, pose, clear=grid.clear, **args)


def _team_state(team: CoordinatedFrontierPolicy) -> list[Any]:
    out: list[Any] = []
    for name in sorted(team.robots):
        r = team.robots[name]
        out += [r.target, r.done, r.n_plans, list(r.blacklist)]
        out.append(None if r.path is None else r.path.tobytes())
    return out


@pytest.mark.expensive
def test_compiled_planner_drives_the_team_as_the_numpy_planner() -> None:
    """Two coordinated-frontier teams, one planning on the numpy path and one compiled, decide
    on the same views of one merging rollout: the same actions, targets and paths at every
    step (the env steps with the compiled team's actions)."""
    penv = mrexplore.parallel_env(world="symmetric_office", n_robots=2)
    penv.reset(seed=3)
    teams = {}
    for on in (False, True):
        team = make_team_policy("coordinated-frontier", penv.possible_agents)
        assert isinstance(team, CoordinatedFrontierPolicy)
        team.reset(np.random.default_rng(3))
        teams[on] = team
    merged_at = None
    for t in range(400):
        if not penv.agents:
            break
        views = {a: penv.robot_view(a) for a in penv.agents}
        with _kernels(False):
            ref = teams[False].act(views)
        with _kernels(True):
            new = teams[True].act(views)
        assert ref == new, t
        assert _team_state(teams[False]) == _team_state(teams[True]), t
        _, _, _, _, infos = penv.step(new)
        if merged_at is None and infos["robot_0"]["merged"]:
            merged_at = t
    assert merged_at is not None  # the rollout covers merged steps (fused maps, claims)
    assert sum(r.n_plans for r in teams[True].robots.values()) > 40
    penv.close()
