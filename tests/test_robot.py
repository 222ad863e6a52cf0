"""Robot motion: walls stop robots, no squeezing through diagonal gaps, turns wrap; start poses."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mrexplore.errors import ConfigError, WorldError
from mrexplore.robot import (
    Action,
    Motion,
    RobotConfig,
    configuration_space,
    sample_start_poses,
    wrap_angle,
    wrap_angle_scalar,
)
from mrexplore.world.world import World


def corridor_world() -> World:
    """20 x 12 cells of 0.1 m, bordered, with a one-cell-thick wall at col 12."""
    walls = np.zeros((12, 20), dtype=bool)
    walls[[0, -1], :] = True
    walls[:, [0, -1]] = True
    walls[:, 12] = True
    return World(walls=walls, resolution_m=0.1, name="corridor")


def xy_of_cell(world: World, col: float, row: float) -> tuple[float, float]:
    p = world.xy_of(np.array([[col, row]]))[0]
    return float(p[0]), float(p[1])


def test_defaults_document_the_step() -> None:
    cfg = RobotConfig()
    assert cfg.step_m == pytest.approx(0.125)
    assert math.degrees(cfg.turn_rad) == pytest.approx(22.5)


@pytest.mark.parametrize(
    "kwargs",
    [
        {"radius_m": 0.0},  # no body
        {"speed_mps": -1.0},  # backwards speed
        {"turn_rate_rps": float("nan")},  # NaN
        {"dt_s": 0.0},  # frozen time
    ],
)
def test_config_is_validated(kwargs: dict[str, float]) -> None:
    with pytest.raises(ConfigError):
        RobotConfig(**kwargs)


def test_driving_at_a_one_cell_wall_stops_before_it() -> None:
    world = corridor_world()
    motion = Motion(world, RobotConfig(radius_m=0.1))
    pose = np.array([[*xy_of_cell(world, 3, 6), 0.0]])
    collided_once = False
    for _ in range(20):
        pose, collided = motion.step(pose, np.array([Action.FORWARD]))
        collided_once |= bool(collided[0])
    assert collided_once
    col = world.cell_of(pose[:, :2])[0, 0]
    # radius 1 cell: the centre may not be on col 11 (next to the wall): it ends on col 10.
    assert 9.5 <= col < 10.5
    assert not motion.cspace[6, round(col)]
    # and never beyond the wall
    assert col < 12


def test_cannot_squeeze_through_a_diagonal_gap() -> None:
    # Two blocked C-space cells touching at a corner; moving diagonally between them must stop.
    walls = np.zeros((9, 9), dtype=bool)
    walls[4, 5] = True
    walls[5, 4] = True
    world = World(walls=walls, resolution_m=0.1)
    # a tiny radius: C-space = the walls themselves (kernel of one cell)
    motion = Motion(world, RobotConfig(radius_m=0.01, speed_mps=0.4, dt_s=0.25))
    start = np.array([[*xy_of_cell(world, 4, 4), math.pi / 4]])
    pose, collided = motion.step(start, np.array([Action.FORWARD]))
    assert bool(collided[0])
    cell = np.floor(world.cell_of(pose[:, :2])[0] + 0.5)
    assert tuple(cell) == (4.0, 4.0)  # still in the start cell, not past the gap


def test_turns_wrap_and_stay_does_nothing() -> None:
    world = corridor_world()
    motion = Motion(world)
    pose = np.array([[*xy_of_cell(world, 5, 5), math.pi - 0.1]])
    left, col = motion.step(pose, np.array([Action.TURN_LEFT]))
    assert not col[0]
    assert -math.pi < left[0, 2] <= math.pi
    assert left[0, 2] == pytest.approx(wrap_angle(math.pi - 0.1 + math.pi / 8))
    right, _ = motion.step(
        np.array([[*xy_of_cell(world, 5, 5), -math.pi + 0.1]]), np.array([Action.TURN_RIGHT])
    )
    assert right[0, 2] == pytest.approx(math.pi + 0.1 - math.pi / 8)
    still, _ = motion.step(pose, np.array([Action.STAY]))
    assert np.array_equal(still, pose)
    # 16 left turns make a full circle
    p = pose.copy()
    for _ in range(16):
        p, _ = motion.step(p, np.array([Action.TURN_LEFT]))
    assert p[0, 2] == pytest.approx(pose[0, 2])
    assert wrap_angle(-math.pi) == pytest.approx(math.pi)


def test_step_is_vectorised_over_robots() -> None:
    world = corridor_world()
    motion = Motion(world, RobotConfig(radius_m=0.1))
    poses = np.array(
        [
            [*xy_of_cell(world, 3, 6), 0.0],
            [*xy_of_cell(world, 3, 3), math.pi / 2],
            [*xy_of_cell(world, 5, 5), 0.0],
        ]
    )
    new, col = motion.step(poses, np.array([Action.FORWARD, Action.FORWARD, Action.STAY]))
    assert new[0, 0] == pytest.approx(poses[0, 0] + 0.125)
    assert new[1, 1] == pytest.approx(poses[1, 1] + 0.125)
    assert np.array_equal(new[2], poses[2])
    assert not col.any()
    with pytest.raises(ConfigError):
        motion.step(poses, np.array([0, 1]))
    with pytest.raises(ConfigError):
        motion.step(poses, np.array([0, 1, 7]))


def test_configuration_space_dilates_by_the_radius() -> None:
    walls = np.zeros((11, 11), dtype=bool)
    walls[5, 5] = True
    cs = configuration_space(walls, 2.0)
    assert cs[5, 3] and cs[5, 7] and cs[3, 5] and cs[7, 5]
    assert not cs[3, 3]  # diagonal distance 2.83 > 2
    assert cs[0, :].all() and cs[:, 0].all()  # the outside counts as wall


def test_start_poses_are_free_and_robot_0_does_not_depend_on_n() -> None:
    world = corridor_world()
    radius = 0.1
    one = sample_start_poses(world, 1, np.random.default_rng(3), radius)
    three = sample_start_poses(world, 3, np.random.default_rng(3), radius, min_separation_m=0.3)
    assert np.array_equal(one[0], three[0])
    assert (three[:, 2] == 0.0).all()
    motion = Motion(world, RobotConfig(radius_m=radius))
    assert motion.is_free(three[:, :2]).all()
    d = np.hypot(*(three[:, None, :2] - three[None, :, :2]).transpose(2, 0, 1))
    assert (d[np.triu_indices(3, 1)] >= 0.3).all()
    # the largest component only: the left part (cols 1..11) is bigger than the right one
    cols = world.cell_of(three[:, :2])[:, 0]
    assert (cols < 12).all()
    unaligned = sample_start_poses(world, 4, np.random.default_rng(3), radius, aligned=False)
    assert np.array_equal(unaligned[0, :2], one[0, :2])
    assert ((unaligned[:, 2] > -math.pi) & (unaligned[:, 2] <= math.pi)).all()
    assert np.ptp(unaligned[:, 2]) > 0


def test_start_poses_errors() -> None:
    world = corridor_world()
    with pytest.raises(WorldError):
        sample_start_poses(world, 2, np.random.default_rng(0), 0.1, min_separation_m=100.0)
    with pytest.raises(ConfigError):
        sample_start_poses(world, 0, np.random.default_rng(0), 0.1)


def test_wrap_angle_scalar_equals_the_numpy_wrap() -> None:
    # Bit for bit, on random angles and the edges: +-pi and their neighbours, multiples of
    # 2 pi, signed zeros, tiny and huge values, infinities and NaN.
    rng = np.random.default_rng(12)
    edges = [math.pi, -math.pi, 0.0, -0.0, 5e-324, -5e-324, 1e-300, 1e300, -1e300]
    edges += [np.nextafter(v, d) for v in (math.pi, -math.pi) for d in (-10.0, 10.0)]
    edges += [k * math.pi for k in range(-40, 41)]
    edges += [k * 2.0 * math.pi + e for k in range(-20, 21) for e in (0.0, 1e-15, -1e-15)]
    edges += [math.pi + k * math.pi / 8 for k in range(-64, 65)]
    edges += [math.inf, -math.inf, math.nan]
    values = np.concatenate(
        [
            np.array(edges, dtype=np.float64),
            rng.uniform(-4 * math.pi, 4 * math.pi, 5000),
            rng.normal(0.0, 1e3, 2000),
        ]
    )
    with np.errstate(invalid="ignore"):
        expected = wrap_angle(values)
    got = np.array([wrap_angle_scalar(float(v)) for v in values])
    assert got.tobytes() == expected.tobytes()
