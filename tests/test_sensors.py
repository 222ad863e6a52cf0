"""Lidar: the vectorised cast against the one-ray reference, and the geometry cases that break
naive ray casters (one-cell walls, diagonal corners, the grid border)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mrexplore.errors import ConfigError, GridError
from mrexplore.sensors import Lidar, LidarConfig, cast_ray_reference
from mrexplore.traversal import traverse


def random_world(rng: np.random.Generator) -> np.ndarray:
    """Random wall blobs, one-cell-thick walls and diagonal staircases (cells touching only at
    corners), on a grid of random size without a border (the grid edge must stop beams)."""
    h, w = (int(v) for v in rng.integers(12, 48, size=2))
    walls = rng.random((h, w)) < 0.03
    for _ in range(3):  # blobs
        r0, c0 = int(rng.integers(0, h)), int(rng.integers(0, w))
        walls[r0 : r0 + int(rng.integers(1, 5)), c0 : c0 + int(rng.integers(1, 5))] = True
    r = int(rng.integers(0, h))
    walls[r, : w // 2] = True  # one-cell-thick horizontal wall
    c = int(rng.integers(0, w))
    walls[h // 2 :, c] = True  # one-cell-thick vertical wall
    r0, c0 = int(rng.integers(0, h)), int(rng.integers(0, w))
    for k in range(min(h, w)):  # staircase, 45 deg
        if 0 <= r0 + k < h and 0 <= c0 + k < w:
            walls[r0 + k, c0 + k] = True
    for k in range(min(h, w)):  # staircase, -45 deg
        if 0 <= r0 - k < h and 0 <= c0 + k < w:
            walls[r0 - k, c0 + k] = True
    return walls


def random_origins(rng: np.random.Generator, walls: np.ndarray, n: int) -> np.ndarray:
    free = np.argwhere(~walls)
    cells = free[rng.integers(len(free), size=n)][:, ::-1].astype(np.float64)  # (col, row)
    return cells + rng.uniform(-0.499, 0.499, size=(n, 2))


def test_cast_matches_reference_on_random_worlds() -> None:
    rng = np.random.default_rng(1234)
    n_rays = 0
    for _ in range(25):
        walls = random_world(rng)
        max_range_m = float(rng.uniform(3.0, 60.0))
        lidar = Lidar(LidarConfig(n_beams=90, max_range_m=max_range_m, noise_std_m=0.0))
        origins = random_origins(rng, walls, 4)
        headings = rng.uniform(-math.pi, math.pi, size=4)
        scan = lidar.cast(walls, origins, headings, resolution_m=1.0)
        for i in range(4):
            for b, a in enumerate(lidar.angles):
                ref, ref_hit = cast_ray_reference(
                    walls, tuple(origins[i]), headings[i] + a, max_range_m
                )
                assert scan.hit[i, b] == ref_hit
                assert scan.ranges_m[i, b] == pytest.approx(ref, abs=1e-4)
                n_rays += 1
    assert n_rays == 25 * 4 * 90


def test_cast_matches_reference_at_coarse_resolution_and_grid_aligned_beams() -> None:
    # Beams along the axes (0, 90, 180, 270 deg) and origins at exact cell centres: the
    # parallel-ray and exact-boundary code paths.
    rng = np.random.default_rng(7)
    walls = random_world(rng)
    lidar = Lidar(LidarConfig(n_beams=8, max_range_m=3.0, noise_std_m=0.0))
    free = np.argwhere(~walls)[:20, ::-1].astype(np.float64)
    scan = lidar.cast(walls, free, np.zeros(len(free)), resolution_m=0.1)
    for i, o in enumerate(free):
        for b, a in enumerate(lidar.angles):
            ref, ref_hit = cast_ray_reference(walls, tuple(o), a, 30.0)
            assert scan.hit[i, b] == ref_hit
            assert scan.ranges_m[i, b] == pytest.approx(ref * 0.1, abs=1e-5)


def test_no_ray_passes_a_wall() -> None:
    """Dense points along each beam, up to just before its range, all lie in free cells."""
    rng = np.random.default_rng(99)
    for _ in range(10):
        walls = random_world(rng)
        h, w = walls.shape
        lidar = Lidar(LidarConfig(n_beams=180, max_range_m=80.0, noise_std_m=0.0))
        origins = random_origins(rng, walls, 3)
        headings = rng.uniform(-math.pi, math.pi, size=3)
        scan = lidar.cast(walls, origins, headings, resolution_m=1.0)
        assert scan.hit.all()  # the grid edge stops every beam
        s = np.linspace(0.0, 1.0, 400)
        for i in range(3):
            ang = headings[i] + lidar.angles
            d = np.stack([np.cos(ang), np.sin(ang)], axis=1)
            t = (scan.ranges_m[i].astype(np.float64) - 2e-3)[:, None] * s[None, :]
            pts = origins[i][None, None, :] + t[:, :, None] * d[:, None, :]
            cells = np.floor(pts + 0.5).astype(int)
            assert (cells[..., 0] >= 0).all() and (cells[..., 0] < w).all()
            assert (cells[..., 1] >= 0).all() and (cells[..., 1] < h).all()
            assert not walls[cells[..., 1], cells[..., 0]].any()


@pytest.mark.parametrize(
    ("angle_deg", "walls_rc", "expected"),
    [
        # 45 deg from cell (2, 2) through the corner between walls (3, 2) and (2, 3): the corner
        # is at distance sqrt(2)/2 from the centre; the beam must stop there.
        (45.0, [(2, 3), (3, 2)], math.sqrt(2) / 2),
        # 135 deg: the mirrored staircase (row 3 col 2) and (row 2 col 1).
        (135.0, [(3, 2), (2, 1)], math.sqrt(2) / 2),
        # -45 deg: walls (row 1, col 2) and (row 2, col 3).
        (-45.0, [(1, 2), (2, 3)], math.sqrt(2) / 2),
        # 45 deg with only the diagonal cell (3, 3) walled: the beam enters it through its corner.
        (45.0, [(3, 3)], math.sqrt(2) / 2),
        # 45 deg with a wall touching the corner from one side only: the corner rule stops it.
        (45.0, [(3, 2)], math.sqrt(2) / 2),
        # 45 deg, nothing near: the grid border (row/col 5 are outside a 5x5 grid) at corner (5, 5).
        (45.0, [], math.sqrt(2) * 2.5),
    ],
)
def test_diagonal_corners_stop_the_beam(
    angle_deg: float, walls_rc: list[tuple[int, int]], expected: float
) -> None:
    walls = np.zeros((5, 5), dtype=bool)
    for r, c in walls_rc:
        walls[r, c] = True
    lidar = Lidar(LidarConfig(n_beams=1, fov_rad=0.1, max_range_m=20.0, noise_std_m=0.0))
    scan = lidar.cast(walls, np.array([[2.0, 2.0]]), np.array([math.radians(angle_deg)]), 1.0)
    assert bool(scan.hit[0, 0])
    assert scan.ranges_m[0, 0] == pytest.approx(expected, abs=1e-4)
    ref, ref_hit = cast_ray_reference(walls, (2.0, 2.0), math.radians(angle_deg), 20.0)
    assert ref_hit and ref == pytest.approx(expected, abs=1e-4)


@pytest.mark.parametrize(
    ("heading_deg", "expected_cells"),
    [
        (0.0, 7.5),  # +col: from the centre of col 3 to the right edge of a 11-wide grid
        (90.0, 3.5),  # +row: from the centre of row 2 to the top edge of a 6-high grid
        (180.0, 3.5),  # -col
        (-90.0, 2.5),  # -row
    ],
)
def test_beams_stop_at_the_grid_border(heading_deg: float, expected_cells: float) -> None:
    walls = np.zeros((6, 11), dtype=bool)
    lidar = Lidar(LidarConfig(n_beams=1, fov_rad=0.01, max_range_m=100.0, noise_std_m=0.0))
    scan = lidar.cast(walls, np.array([[3.0, 2.0]]), np.array([math.radians(heading_deg)]), 0.5)
    assert bool(scan.hit[0, 0])
    assert scan.ranges_m[0, 0] == pytest.approx(expected_cells * 0.5, abs=1e-5)


def test_max_range_and_no_hit() -> None:
    walls = np.zeros((3, 40), dtype=bool)
    walls[:, 30] = True
    lidar = Lidar(LidarConfig(n_beams=1, fov_rad=0.01, max_range_m=1.0, noise_std_m=0.0))
    scan = lidar.cast(walls, np.array([[2.0, 1.0]]), np.array([0.0]), 0.05)
    assert not scan.hit[0, 0]  # the wall is 27.5 cells = 1.375 m away
    assert scan.ranges_m[0, 0] == pytest.approx(1.0)


def test_noise_only_on_hits_and_clipped() -> None:
    walls = np.zeros((20, 20), dtype=bool)
    walls[:, 19] = True
    cfg = LidarConfig(n_beams=2, fov_rad=math.pi, max_range_m=0.5, noise_std_m=0.3)
    lidar = Lidar(cfg)
    # Heading 90 deg: beam 0 (-90 deg relative) points along +col at the wall 1.5 cells away
    # (0.15 m: a hit); beam 1 points along -col at the border 17.5 cells away (1.75 m: no hit).
    origins = np.array([[17.0, 10.0]])
    clean = lidar.cast(walls, origins, np.array([math.pi / 2]), 0.1)
    noisy = [
        lidar.cast(walls, origins, np.array([math.pi / 2]), 0.1, rng=np.random.default_rng(s))
        for s in range(20)
    ]
    for b in range(2):
        vals = np.array([n.ranges_m[0, b] for n in noisy])
        if clean.hit[0, b]:
            assert (vals >= 0.0).all() and (vals <= cfg.max_range_m).all()
            assert np.ptp(vals) > 0.0
        else:
            assert (vals == clean.ranges_m[0, b]).all()
    assert clean.hit.any()


def test_visible_cells_are_free_before_the_hit_plus_the_hit_cell() -> None:
    walls = np.zeros((7, 12), dtype=bool)
    walls[:, 8] = True
    lidar = Lidar(LidarConfig(n_beams=1, fov_rad=0.01, max_range_m=100.0, noise_std_m=0.0))
    scan = lidar.cast(walls, np.array([[2.0, 3.0]]), np.array([0.0]), 1.0, want_visible=True)
    assert scan.visible_flat is not None
    cells = {(int(i) % 12, int(i) // 12) for i in scan.visible_flat[0]}
    assert cells == {(c, 3) for c in range(2, 9)}


def test_visible_cells_match_the_traversal_of_a_full_scan() -> None:
    rng = np.random.default_rng(5)
    walls = random_world(rng)
    h, w = walls.shape
    lidar = Lidar(LidarConfig(n_beams=360, max_range_m=30.0, noise_std_m=0.0))
    origins = random_origins(rng, walls, 2)
    scan = lidar.cast(walls, origins, np.zeros(2), 1.0, want_visible=True)
    assert scan.visible_flat is not None
    for i in range(2):
        vis = np.zeros(h * w, dtype=bool)
        vis[scan.visible_flat[i]] = True
        vis2 = vis.reshape(h, w)
        # every wall cell seen is one the beams hit; the robot's own cell is seen
        oc = np.floor(origins[i] + 0.5).astype(int)
        assert vis2[oc[1], oc[0]]
        ang = lidar.angles
        ends = origins[i] + (scan.ranges_m[i, :, None] + 1e-3) * np.stack(
            [np.cos(ang), np.sin(ang)], 1
        )
        ec = np.floor(ends + 0.5).astype(int)
        inside = (ec[:, 0] >= 0) & (ec[:, 0] < w) & (ec[:, 1] >= 0) & (ec[:, 1] < h)
        assert vis2[ec[inside, 1], ec[inside, 0]].all()
        seen_walls = vis2 & walls
        hit_cells = np.zeros_like(walls)
        hit_cells[ec[inside, 1], ec[inside, 0]] = True
        # walls seen only at hit cells (corner rule may add the cell beside a corner)
        near = np.zeros_like(walls)
        for dr in (-1, 0, 1):
            for dc in (-1, 0, 1):
                near |= np.roll(np.roll(hit_cells, dr, 0), dc, 1)
        assert not (seen_walls & ~near).any()


def test_traversal_enters_each_crossed_cell_once_in_order() -> None:
    # A ray from (0.7, 0.8) (corner coords) at 30 deg: the cells entered at crossings with
    # t < 5 are exactly the cells a dense sampling of the segment visits (minus the start).
    o = np.array([[0.7, 0.8]])
    a = math.radians(30.0)
    d = np.array([[math.cos(a), math.sin(a)]])
    tr = traverse(o, d, 0, 8, row_stride=100, t_cap=10.0)
    entered = tr.selected(tr.count_before(np.array([5.0])))
    assert len(entered) == len(set(entered.tolist()))  # each cell once
    s = np.linspace(0.0, 5.0 - 1e-6, 20000)
    pts = o[0] + s[:, None] * d[0]
    dense = {int(r) * 100 + int(c) for c, r in np.floor(pts)}
    assert set(entered.tolist()) | {0} == dense
    # and in order of t within each family: the x-family cells step +1 column at a time
    x_cells = tr.idx[: int(tr.count_before(np.array([5.0]))[0]), 0]
    assert np.all(np.diff(x_cells % 100) == 1)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"n_beams": 0},  # no beam
        {"fov_rad": 0.0},  # empty field of view
        {"fov_rad": 7.0},  # more than a full circle
        {"max_range_m": -1.0},  # negative range
        {"noise_std_m": -0.1},  # negative noise
        {"max_range_m": float("nan")},  # NaN
    ],
)
def test_config_is_validated(kwargs: dict[str, float]) -> None:
    with pytest.raises(ConfigError):
        LidarConfig(**kwargs)  # type: ignore[arg-type]


def test_bad_inputs_raise_grid_error() -> None:
    lidar = Lidar(LidarConfig(n_beams=4))
    walls = np.zeros((5, 5), dtype=bool)
    with pytest.raises(GridError, match="inside"):
        lidar.cast(walls, np.array([[7.0, 1.0]]), np.array([0.0]), 0.05)
    with pytest.raises(GridError, match="bool"):
        lidar.cast(walls.astype(np.uint8), np.array([[1.0, 1.0]]), np.array([0.0]), 0.05)
    with pytest.raises(GridError, match="headings"):
        lidar.cast(walls, np.array([[1.0, 1.0]]), np.array([0.0, 1.0]), 0.05)


def test_beam_angles() -> None:
    full = Lidar(LidarConfig(n_beams=4)).angles
    assert np.allclose(full, [-math.pi, -math.pi / 2, 0.0, math.pi / 2])
    part = Lidar(LidarConfig(n_beams=3, fov_rad=math.pi)).angles
    assert np.allclose(part, [-math.pi / 2, 0.0, math.pi / 2])


def test_corners_of_is_check_origins_of_the_world_cells_bit_for_bit() -> None:
    from mrexplore.world import World

    rng = np.random.default_rng(3)
    lidar = Lidar(LidarConfig(n_beams=4))
    for origin, res in (((0.0, 0.0), 0.05), ((-3.7, 12.25), 0.05), ((0.1, -0.3), 0.1)):
        world = World(walls=np.zeros((40, 60), dtype=bool), resolution_m=res, origin_m=origin)
        grid = lidar.prepare(world.walls)
        # random poses, and poses on cell boundaries (where the snap decides the cell)
        cells = rng.uniform(-0.49, 39.4, size=(64, 2))
        cells[32:] = np.round(cells[32:] * 2.0) / 2.0 - 0.5 + rng.choice([0.0, 1e-12], (32, 2))
        cells = np.clip(cells, -0.5, 39.49)
        poses = np.concatenate([world.xy_of(cells), rng.uniform(-3, 3, (64, 1))], axis=1)
        want, _ = lidar.check_origins(grid, world.cell_of(poses[:, :2]), poses[:, 2])
        got = lidar.corners_of(grid, poses, world)
        assert got.tobytes() == want.tobytes()
    # the second exactly on the grid's top edge (row corner 40.0, as check_origins finds)
    for bad in ([6.5, 1.0], [1.15, 3.7], [float("nan"), 1.0], [1.0, float("inf")]):
        pose = np.array([[bad[0], bad[1], 0.0]])
        with pytest.raises(GridError, match="inside the 40x60 grid"):
            lidar.corners_of(grid, pose, world)
        with pytest.raises(GridError, match="inside the 40x60 grid"):
            lidar.check_origins(grid, world.cell_of(pose[:, :2]), pose[:, 2])
