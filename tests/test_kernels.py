"""The compiled kernels (mrexplore.kernels) against the numpy path and the one-ray reference.

The numba path and the numpy path evaluate the same float64 formulas, so they must agree bit for
bit: ranges, hits, observed cells, maps, motion, and whole simulator rollouts. The first test
compiles the kernels (or loads them from numba's on-disk cache): a few seconds once.
"""

from __future__ import annotations

import math
from collections.abc import Iterator

import numpy as np
import pytest

from mrexplore import kernels, mapping, sensors
from mrexplore.kernels import sensing
from mrexplore.mapping import OccupancyMap
from mrexplore.robot import Action, Motion, RobotConfig
from mrexplore.sensors import Lidar, LidarConfig, cast_ray_reference
from mrexplore.sim import SimConfig, Simulation
from mrexplore.world.world import World
from tests.test_sensors import random_origins, random_world


@pytest.fixture(scope="module", autouse=True)
def compiled() -> None:
    """Compile (or load) the kernels once, before any test of this module."""
    assert kernels.HAVE_NUMBA
    kernels.warm_up()


@pytest.fixture
def numpy_path(monkeypatch: pytest.MonkeyPatch) -> Iterator[None]:
    """Let a test switch paths with ``set_path`` (restored afterwards); the numpy map path in
    float64, which the kernel reproduces bit for bit."""
    monkeypatch.setattr(kernels, "USE_NUMBA", True)
    monkeypatch.setattr(mapping, "NUMPY_TRAVERSE_DTYPE", np.float64)
    yield


def set_path(use_numba: bool) -> None:
    """Select the compiled kernels (True) or the numpy path (only inside ``numpy_path``)."""
    kernels.USE_NUMBA = use_numba


def test_corner_eps_is_shared() -> None:
    assert sensing.CORNER_EPS == sensors.CORNER_EPS
    assert sensing.END_NUDGE_CELLS == mapping._END_NUDGE_CELLS


def test_cast_equals_numpy_and_reference_on_random_worlds(numpy_path: None) -> None:
    # Random worlds with one-cell walls and diagonal staircases; float32 numpy positions (the
    # default) and float64: the compiled cast equals both bit for bit, and the reference to
    # 1e-4 cells.
    rng = np.random.default_rng(2024)
    for it in range(12):
        walls = random_world(rng)
        max_range = float(rng.uniform(3.0, 60.0))
        lidar = Lidar(LidarConfig(n_beams=120, max_range_m=max_range, noise_std_m=0.05))
        lidar.dtype = np.float64 if it % 2 else np.float32
        origins = random_origins(rng, walls, 3)
        if it % 3 == 0:  # exact cell centres and corners: the boundary cases
            origins = np.round(origins * 2.0) / 2.0
        headings = rng.uniform(-math.pi, math.pi, size=3)
        set_path(True)
        a = lidar.cast(walls, origins, headings, 1.0, want_visible=True)
        a_noisy = lidar.cast(walls, origins, headings, 1.0, rng=np.random.default_rng(it))
        set_path(False)
        b = lidar.cast(walls, origins, headings, 1.0, want_visible=True)
        b_noisy = lidar.cast(walls, origins, headings, 1.0, rng=np.random.default_rng(it))
        assert np.array_equal(a.ranges_m, b.ranges_m)
        assert np.array_equal(a.hit, b.hit)
        assert np.array_equal(a_noisy.ranges_m, b_noisy.ranges_m)  # same draws, same clip
        assert a.visible_flat is not None and b.visible_flat is not None
        for va, vb in zip(a.visible_flat, b.visible_flat, strict=True):
            assert set(va.tolist()) == set(vb.tolist())
        for i in range(3):
            for k, ang in enumerate(lidar.angles):
                if walls[math.floor(origins[i, 1] + 0.5), math.floor(origins[i, 0] + 0.5)]:
                    continue
                ref, ref_hit = cast_ray_reference(
                    walls,
                    (float(origins[i, 0]), float(origins[i, 1])),
                    headings[i] + ang,
                    max_range,
                )
                assert bool(a.hit[i, k]) == ref_hit
                assert float(a.ranges_m[i, k]) == pytest.approx(ref, abs=1e-4)


@pytest.mark.parametrize(
    ("angle_deg", "walls_rc", "expected"),
    [
        (45.0, [(2, 3), (3, 2)], math.sqrt(2) / 2),  # staircase corner: must not leak
        (-135.0, [(1, 2), (2, 1)], math.sqrt(2) / 2),  # the same, towards -col -row
        (45.0, [(3, 3)], math.sqrt(2) / 2),  # only the diagonal cell: entered at its corner
        (0.0, [(2, 4)], 1.5),  # straight along a row, one-cell wall
        (90.0, [], 2.5),  # straight up to the border of a 5x5 grid
    ],
)
def test_kernel_corner_rule(
    angle_deg: float, walls_rc: list[tuple[int, int]], expected: float
) -> None:
    walls = np.zeros((5, 5), dtype=bool)
    for r, c in walls_rc:
        walls[r, c] = True
    lidar = Lidar(LidarConfig(n_beams=1, fov_rad=0.1, max_range_m=20.0, noise_std_m=0.0))
    scan = lidar.cast(walls, np.array([[2.0, 2.0]]), np.array([math.radians(angle_deg)]), 1.0)
    assert bool(scan.hit[0, 0])
    assert scan.ranges_m[0, 0] == pytest.approx(expected, abs=1e-5)


def test_cast_observe_marks_match_numpy_and_count_new_cells(numpy_path: None) -> None:
    rng = np.random.default_rng(8)
    walls = random_world(rng)
    h, w = walls.shape
    reach = rng.random((h, w)) < 0.7
    lidar = Lidar(LidarConfig(n_beams=180, max_range_m=15.0, noise_std_m=0.02))
    grid = lidar.prepare(walls)
    steps = [random_origins(rng, walls, 2) for _ in range(6)]
    results = {}
    for use in (True, False):
        set_path(use)
        obs = np.zeros((2, h, w), dtype=bool)
        team = np.zeros((h, w), dtype=bool)
        draw = np.random.default_rng(1)
        newly_all, cov_all, ranges = [], 0, []
        for origins in steps:
            scan, newly, cov = lidar.cast_observe(
                grid, origins, np.zeros(2), 0.5, draw, obs, reach, team
            )
            newly_all.append(newly)
            cov_all += cov
            ranges.append(scan.ranges_m)
        results[use] = (obs.copy(), team.copy(), np.array(newly_all), cov_all, np.array(ranges))
    a, b = results[True], results[False]
    assert np.array_equal(a[0], b[0])  # observed masks identical
    assert np.array_equal(a[1], b[1])
    assert np.array_equal(a[2], b[2])  # newly observed counts
    assert a[3] == b[3]
    assert np.array_equal(a[4], b[4])
    # counts add up: newly per robot = observed cells; coverage increment = team & reach
    assert (a[2].sum(axis=0) == a[0].reshape(2, -1).sum(axis=1)).all()
    assert a[3] == int((a[1] & reach).sum())
    assert np.array_equal(a[1], a[0].any(axis=0))


def test_map_update_equals_numpy_on_the_same_scans(numpy_path: None) -> None:
    # A robot wandering a random world: each scan is integrated by both paths into their own
    # map; log-odds, int8 view and bbox must stay identical (incl. undecided cells, clamping,
    # beams cut at the canvas edge, and headings on multiples of 22.5 deg).
    rng = np.random.default_rng(31)
    walls = random_world(rng)
    lidar = Lidar(LidarConfig(n_beams=90, max_range_m=4.0, noise_std_m=0.05))
    res = 0.1
    shape, origin = (111, 121), (55, 60)  # small enough that some beams are cut at its edge
    ma = OccupancyMap(shape, res, origin, l_min=-2.0, l_max=2.5)
    mb = OccupancyMap(shape, res, origin, l_min=-2.0, l_max=2.5)
    o0 = None
    for k in range(40):
        o = random_origins(rng, walls, 1)
        hd = rng.uniform(-math.pi, math.pi, size=1)
        if k % 4 == 0:
            o = np.round(o * 2.0) / 2.0
            hd = np.round(hd / (math.pi / 8)) * (math.pi / 8)
        scan = lidar.cast(walls, o, hd, res, rng=rng)
        if o0 is None:
            o0 = o[0]
        pose = ((o[0, 0] - o0[0]) * res, (o[0, 1] - o0[1]) * res, float(hd[0]))
        set_path(True)
        ma.update(pose, scan.angles, scan.ranges_m[0], scan.hit[0])
        set_path(False)
        mb.update(pose, scan.angles, scan.ranges_m[0], scan.hit[0])
        assert np.array_equal(ma.logodds, mb.logodds)
        assert np.array_equal(ma.to_int8(), mb.to_int8())
        assert ma.known_bbox() == mb.known_bbox()
    mid = (ma.to_int8() > 0) & (ma.to_int8() < 100)
    assert mid.any()  # undecided cells were exercised


def test_map_update_stamps_wrap(monkeypatch: pytest.MonkeyPatch) -> None:
    # Past the uint16 stamp range the stamps are cleared: cells still change once per scan.
    monkeypatch.setattr(mapping, "_STAMP_WRAP", 3)
    m = OccupancyMap((11, 11), 0.1, (5, 5), l_min=-50.0, l_max=50.0)
    for _ in range(7):
        m.update(
            (0.0, 0.0, 0.0), np.array([0.0, 0.0]), np.array([0.35, 0.35]), np.array([True, True])
        )
    assert m.logodds[5, 9] == pytest.approx(7 * m.l_occ)
    assert m.logodds[5, 7] == pytest.approx(7 * m.l_free)


def test_motion_equals_numpy(numpy_path: None) -> None:
    walls = random_world(np.random.default_rng(4))
    world = World(walls=walls, resolution_m=0.05)
    motion = Motion(world, RobotConfig(radius_m=0.06))
    rng = np.random.default_rng(5)
    free = np.argwhere(~motion.cspace)
    for _ in range(30):
        cells = free[rng.integers(len(free), size=6)][:, ::-1].astype(np.float64)
        poses = np.column_stack(
            [world.xy_of(cells + rng.uniform(-0.5, 0.5, (6, 2))), rng.uniform(-math.pi, math.pi, 6)]
        )
        acts = rng.integers(0, 4, size=6)
        set_path(True)
        pa, ca = motion.step(poses, acts)
        set_path(False)
        pb, cb = motion.step(poses, acts)
        assert np.array_equal(pa, pb)
        assert np.array_equal(ca, cb)


def office() -> World:
    walls = np.zeros((30, 40), dtype=bool)
    walls[[0, -1], :] = True
    walls[:, [0, -1]] = True
    walls[:, 20] = True
    walls[12:18, 20] = False
    walls[5:8, 5:9] = True
    return World(walls=walls, resolution_m=0.1, name="office")


def test_simulation_rollout_equals_numpy(numpy_path: None) -> None:
    cfg = SimConfig(
        robot=RobotConfig(radius_m=0.15),
        lidar=LidarConfig(n_beams=90, max_range_m=3.0, noise_std_m=0.01),
        aligned_headings=False,
        odom_noise_trans=0.05,
        odom_noise_rot=0.05,
    )
    sims = []
    for use in (True, False):
        set_path(use)
        sim = Simulation(office(), 2, cfg)
        rng = np.random.default_rng(3)
        sim.reset(rng)
        act_rng = np.random.default_rng(4)
        for _ in range(60):
            act = np.where(act_rng.random(2) < 0.6, Action.FORWARD, act_rng.integers(1, 4, 2))
            sim.step(act, rng)
        sims.append(sim)
    a, b = sims
    assert np.array_equal(a.true_poses, b.true_poses)
    assert np.array_equal(a.est_poses, b.est_poses)
    assert np.array_equal(a.observed, b.observed)
    assert a.coverage() == b.coverage()
    for ma, mb in zip(a.maps, b.maps, strict=True):
        assert np.array_equal(ma.logodds, mb.logodds)
        assert np.array_equal(ma.to_int8(), mb.to_int8())
        assert ma.known_bbox() == mb.known_bbox()


@pytest.mark.parametrize("use_numba", [True, False])
def test_map_change_matches_a_canvas_comparison(numpy_path: None, use_numba: bool) -> None:
    """``OccupancyMap.change()`` (kept by the update, no canvas scan) equals what comparing the
    int8 canvas before and after each scan finds: the known box, the changed box, and a
    version that grows exactly when a cell changed."""
    from mrexplore.merge.common import known_bbox

    set_path(use_numba)
    cfg = SimConfig(
        lidar=LidarConfig(n_beams=90, max_range_m=3.0, noise_std_m=0.02),
        aligned_headings=False,
    )
    sim = Simulation(office(), 2, cfg)
    rng = np.random.default_rng(5)
    sim.reset(rng)
    act_rng = np.random.default_rng(6)
    before = [m.to_int8().copy() for m in sim.maps]
    versions = [m.version for m in sim.maps]
    for _ in range(80):
        # a third of the steps stand still: rescans that may change nothing
        act = np.where(act_rng.random(2) < 0.4, Action.FORWARD, act_rng.integers(1, 4, 2))
        sim.step(act, rng)
        for i, m in enumerate(sim.maps):
            now = m.to_int8()
            ch = m.change()
            assert ch.known_box == known_bbox(now)
            diff = now != before[i]
            if diff.any():
                rows, cols = np.nonzero(diff)
                box = (rows.min(), rows.max() + 1, cols.min(), cols.max() + 1)
                assert ch.version == versions[i] + 1
                assert ch.changed_box == tuple(int(v) for v in box)
            else:
                assert ch.version == versions[i]
            versions[i] = ch.version
            before[i] = now.copy()


@pytest.mark.parametrize("use_numba", [True, False])
def test_an_update_lists_the_cells_it_changed(
    numpy_path: None, monkeypatch: pytest.MonkeyPatch, use_numba: bool
) -> None:
    """``changed_cells`` are exactly the cells whose int8 value the update that made the
    version changed (both paths); past ``CHANGED_CELLS_LISTED`` only the box tells."""
    set_path(use_numba)
    rng = np.random.default_rng(4)
    m = mapping.OccupancyMap((201, 201), 0.05, (100, 100))
    assert m.changed_cells() is None
    ang = np.linspace(-np.pi, np.pi, 90, endpoint=False)
    x = y = 0.0
    for k in range(12):
        before = m.to_int8().copy()
        ranges = rng.uniform(0.2, 2.5, ang.size)
        m.update((x, y, 0.1 * k), ang, ranges, rng.random(ang.size) < 0.8)
        moved = np.flatnonzero(m.to_int8().reshape(-1) != before.reshape(-1))
        cells = m.changed_cells()
        assert cells is not None and np.array_equal(np.sort(cells), moved)
        x += 0.07
    monkeypatch.setattr(mapping, "CHANGED_CELLS_LISTED", 5)
    small = mapping.OccupancyMap((201, 201), 0.05, (100, 100))
    small.update((0.0, 0.0, 0.0), ang, np.full(ang.size, 2.0), np.ones(ang.size, dtype=bool))
    assert small.changed_cells() is None and small.change().changed_box is not None
