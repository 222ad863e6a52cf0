"""Own-frame occupancy maps: the inverse sensor model, the incremental int8 view, and full scans
of a closed room mapped exactly in the robot's own frame."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mrexplore.errors import ConfigError, GridError
from mrexplore.grid import FREE, OCCUPIED, UNKNOWN, apply_transform
from mrexplore.mapping import OccupancyMap
from mrexplore.robot import Action, RobotConfig
from mrexplore.sensors import LidarConfig
from mrexplore.sim import SimConfig, Simulation
from mrexplore.world.world import World


def one_beam(m: OccupancyMap, angle: float, range_m: float, hit: bool = True) -> None:
    m.update((0.0, 0.0, 0.0), np.array([angle]), np.array([range_m]), np.array([hit]))


def test_one_beam_free_then_occupied() -> None:
    m = OccupancyMap((11, 11), 0.1, (5, 5))
    one_beam(m, 0.0, 0.35)  # 3.5 cells from the centre of (5, 5): the boundary of col 9
    row = m.to_int8()[5]
    assert row.tolist() == [UNKNOWN] * 5 + [FREE] * 4 + [OCCUPIED] + [UNKNOWN]
    assert m.logodds[5, 6] == pytest.approx(m.l_free)
    assert m.logodds[5, 9] == pytest.approx(m.l_occ)
    assert m.known_bbox() == (5, 6, 5, 10)  # half-open


def test_no_hit_marks_free_up_to_the_range() -> None:
    m = OccupancyMap((11, 11), 0.1, (5, 5))
    one_beam(m, math.pi / 2, 0.3, hit=False)
    col = m.to_int8()[:, 5]
    assert col.tolist() == [UNKNOWN] * 5 + [FREE] * 4 + [UNKNOWN] * 2
    assert (m.to_int8() != OCCUPIED).all()


def test_each_cell_once_per_scan_and_occupied_wins() -> None:
    m = OccupancyMap((11, 11), 0.1, (5, 5))
    # Three beams along +col: two pass through col 7, one ends there with a hit.
    m.update(
        (0.0, 0.0, 0.0),
        np.array([0.0, 0.0, 0.0]),
        np.array([0.45, 0.45, 0.15]),
        np.array([False, False, True]),
    )
    # 1.5 cells from the centre of col 5 is the boundary of col 7: the third beam's wall cell.
    assert m.logodds[5, 7] == pytest.approx(m.l_occ)
    assert m.logodds[5, 8] == pytest.approx(m.l_free)  # free once, not twice
    assert m.logodds[5, 5] == pytest.approx(m.l_free)


def test_logodds_are_clamped_and_int8_is_incremental() -> None:
    m = OccupancyMap((11, 11), 0.1, (5, 5), l_min=-2.0, l_max=2.0)
    view = m.to_int8()
    assert not view.flags.writeable
    for _ in range(10):
        one_beam(m, 0.0, 0.35)
    assert m.logodds.min() == pytest.approx(-2.0)
    assert m.logodds.max() == pytest.approx(2.0)
    assert view[5, 9] == OCCUPIED  # the view follows the updates
    # a hit outweighs two passes; three leave the cell undecided, four make it free
    m2 = OccupancyMap((11, 11), 0.1, (5, 5))
    one_beam(m2, 0.0, 0.15)  # the wall cell (5, 7)
    seen = []
    for _ in range(4):
        one_beam(m2, 0.0, 0.45, hit=False)
        seen.append(int(m2.to_int8()[5, 7]))
    assert seen[:2] == [OCCUPIED, OCCUPIED] and 25 < seen[2] < 65 and seen[3] == FREE


@pytest.mark.parametrize("l_occ, after", [(1.4, "undecided"), (2.6, "wall"), (None, "wall")])
def test_a_wall_hit_once_then_passed_once(l_occ: float | None, after: str) -> None:
    """A grazing beam passes through a wall cell another scan hit: a hit worth one pass (1.4,
    the former default) leaves it undecided (+0.2), a hit worth more than two passes (the
    default 3.6; the env's ``map_l_occ``) keeps it a wall."""
    m = OccupancyMap((11, 11), 0.1, (5, 5), **({} if l_occ is None else {"l_occ": l_occ}))
    one_beam(m, 0.0, 0.15)  # the wall cell (5, 7)
    one_beam(m, 0.0, 0.45, hit=False)  # a later beam passes through it
    v = int(m.to_int8()[5, 7])
    assert (v == OCCUPIED) if after == "wall" else (25 < v < 65)


def test_pose_in_own_frame_and_cell_of() -> None:
    m = OccupancyMap((21, 21), 0.1, (10, 10))
    assert m.cell_of(0.2, -0.3) == pytest.approx((12.0, 7.0))
    # robot at (0.2, -0.3) m facing +y: a beam straight ahead hits 2 cells away
    m.update((0.2, -0.3, math.pi / 2), np.array([0.0]), np.array([0.15]), np.array([True]))
    assert m.to_int8()[9, 12] == OCCUPIED
    assert m.to_int8()[8, 12] == FREE and m.to_int8()[7, 12] == FREE


def test_beams_leaving_the_canvas_are_cut() -> None:
    m = OccupancyMap((9, 9), 0.1, (4, 4))
    one_beam(m, 0.0, 5.0)
    g = m.to_int8()
    assert (g != OCCUPIED).all()  # the hit lies outside: not recorded
    assert g[4, 7] == FREE and g[4, 8] == UNKNOWN  # the one-cell ring stays unknown


@pytest.mark.parametrize(
    ("kwargs", "error"),
    [
        ({"shape": (0, 5), "resolution_m": 0.1, "origin_cell": (0, 0)}, ConfigError),  # empty
        ({"shape": (5, 5), "resolution_m": 0.0, "origin_cell": (2, 2)}, ConfigError),  # res 0
        ({"shape": (5, 5), "resolution_m": 0.1, "origin_cell": (9, 2)}, ConfigError),  # outside
        ({"shape": (5, 5), "resolution_m": 0.1, "origin_cell": (2, 2), "l_free": 0.5}, ConfigError),
    ],
)
def test_constructor_is_validated(kwargs: dict[str, object], error: type[Exception]) -> None:
    with pytest.raises(error):
        OccupancyMap(**kwargs)  # type: ignore[arg-type]


def test_update_is_validated() -> None:
    m = OccupancyMap((11, 11), 0.1, (5, 5))
    with pytest.raises(GridError, match="same length"):
        m.update((0, 0, 0), np.zeros(2), np.zeros(3), np.zeros(2, bool))
    with pytest.raises(GridError, match="non-negative"):
        m.update((0, 0, 0), np.zeros(1), np.array([-1.0]), np.zeros(1, bool))
    with pytest.raises(GridError, match="outside"):
        m.update((5.0, 0, 0), np.zeros(1), np.zeros(1), np.zeros(1, bool))


# ---------------------------------------------------------------------- whole-room scans
def room_world() -> World:
    """A closed room (interior rows 5..18, cols 6..29) with a one-cell wall ring, in a larger
    free area that the robot cannot see."""
    walls = np.zeros((26, 40), dtype=bool)
    walls[4, 5:31] = True
    walls[19, 5:31] = True
    walls[4:20, 5] = True
    walls[4:20, 30] = True
    return World(walls=walls, resolution_m=0.05, name="room")


INTERIOR = (slice(5, 19), slice(6, 30))


def run_still(world: World, starts: np.ndarray, steps: int = 2) -> Simulation:
    cfg = SimConfig(
        robot=RobotConfig(radius_m=0.1),
        lidar=LidarConfig(n_beams=360, max_range_m=4.0, noise_std_m=0.0),
    )
    sim = Simulation(world, len(starts), cfg)
    sim.reset(np.random.default_rng(0), starts=starts)
    for _ in range(steps):
        sim.step(np.full(len(starts), Action.STAY), np.random.default_rng(1))
    return sim


def map_in_world(sim: Simulation, i: int) -> np.ndarray:
    """Robot i's int8 map resampled into world cells through the true transform (nearest)."""
    h, w = sim.world.shape
    rows, cols = np.mgrid[0:h, 0:w]
    T_map_from_world = np.asarray(np.linalg.inv(sim.world_from_map(i)), dtype=np.float64)
    pts = apply_transform(T_map_from_world, np.stack([cols.ravel(), rows.ravel()], 1))
    mc = np.floor(pts + 0.5).astype(int)
    return sim.maps[i].to_int8()[mc[:, 1], mc[:, 0]].reshape(h, w)


def test_still_robot_maps_exactly_its_room_in_its_own_frame() -> None:
    world = room_world()
    start = world.xy_of(np.array([[17.0, 11.0]]))[0]
    sim = run_still(world, np.array([[start[0], start[1], 0.0]]))
    m = sim.maps[0]
    g = m.to_int8()
    # own frame: the start is the canvas origin cell, and it is free
    assert g[m.origin_cell[1], m.origin_cell[0]] == FREE
    seen = map_in_world(sim, 0)
    interior = np.zeros(world.shape, dtype=bool)
    interior[INTERIOR] = True
    assert (seen[interior] == FREE).all()
    # the inner faces of the walls (4-adjacent to the interior, corners excluded) are occupied
    faces = np.zeros(world.shape, dtype=bool)
    faces[4, 6:30] = faces[19, 6:30] = True
    faces[5:19, 5] = faces[5:19, 30] = True
    assert (seen[faces] == OCCUPIED).all()
    # nothing outside the room (walls included) is known, and no free cell is called a wall
    room = interior | world.walls
    assert (seen[~room] == UNKNOWN).all()
    assert not ((seen == OCCUPIED) & ~world.walls).any()
    # and the canvas holds nothing else: as many known cells as the room shows
    assert np.count_nonzero(g != UNKNOWN) == np.count_nonzero(seen != UNKNOWN)


def test_rotated_start_maps_the_same_walls_under_the_true_transform() -> None:
    world = room_world()
    a = world.xy_of(np.array([[12.0, 10.0]]))[0]
    b = world.xy_of(np.array([[24.0, 13.0]]))[0]
    sim = run_still(world, np.array([[a[0], a[1], 0.0], [b[0], b[1], math.radians(30.0)]]))
    ga, gb = sim.maps[0].to_int8(), sim.maps[1].to_int8()
    occ_b = np.argwhere(gb == OCCUPIED)[:, ::-1].astype(float)  # (col, row)
    assert len(occ_b) > 50
    T_ab = sim.true_transform(0, 1)
    pa = np.floor(apply_transform(T_ab, occ_b) + 0.5).astype(int)
    occ_a = ga == OCCUPIED
    near = np.zeros(len(pa), dtype=bool)
    for dr in (-1, 0, 1):
        for dc in (-1, 0, 1):
            near |= occ_a[pa[:, 1] + dr, pa[:, 0] + dc]
    assert near.mean() > 0.95
    # b's own map is rotated: its occupied cells do not line up with a's without the transform
    assert np.abs(math.degrees(math.atan2(T_ab[1, 0], T_ab[0, 0])) - 30.0) < 1e-9


def test_cached_beam_directions_are_numpys() -> None:
    # The per-map cache of beam directions returns what numpy computes now, per heading bits
    # (0.0 and -0.0 apart) and per beam angles; old headings fall out after 16 others.
    m = OccupancyMap((21, 21), 0.05, (10, 10))
    ang = np.linspace(-math.pi, math.pi, 37)
    headings = [0.0, -0.0, math.pi / 8, -math.pi, math.pi, 1e-300] + [k * 0.1 for k in range(20)]
    for th in headings + headings[::-1]:
        dx, dy = m.beam_directions(th, ang)
        assert dx.tobytes() == np.cos(th + ang).tobytes()
        assert dy.tobytes() == np.sin(th + ang).tobytes()
    assert len(m._dir_cache) == 16
    first = m.beam_directions(0.3, ang)
    assert m.beam_directions(0.3, ang) is first  # a hit
    other = ang + 1e-3
    dx, _ = m.beam_directions(0.3, other)  # new angles: recomputed
    assert dx.tobytes() == np.cos(0.3 + other).tobytes()
    assert len(m._dir_cache) == 1
