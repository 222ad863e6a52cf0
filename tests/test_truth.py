"""Ground truth: frame transforms, reachable space, coverage, transform errors."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mrexplore.errors import GridError
from mrexplore.grid import apply_transform, make_transform
from mrexplore.truth import (
    IncrementalScore,
    MapScorer,
    T_world_from_map,
    coverage,
    map_contradiction,
    map_in_world,
    nearest_sampling,
    reachable_cspace,
    reachable_free,
    transform_error,
    true_transform,
)
from mrexplore.world.world import World


def two_rooms() -> World:
    """Two 8x8 rooms (0.1 m cells) side by side, separated by a wall with no door."""
    walls = np.ones((10, 20), dtype=bool)
    walls[1:9, 1:9] = False
    walls[1:9, 11:19] = False
    return World(walls=walls, resolution_m=0.1, origin_m=(1.0, -2.0))


@pytest.mark.parametrize(
    ("start", "map_cell", "world_cell"),
    [
        # heading 0, start at the centre of world cell (3, 4): map origin (50, 60) -> (3, 4)
        ((1.35, -1.55, 0.0), (50, 60), (3.0, 4.0)),
        # one map cell along +col is one world cell along +col
        ((1.35, -1.55, 0.0), (51, 60), (4.0, 4.0)),
        # heading 90 deg: map +col is world +row
        ((1.35, -1.55, math.pi / 2), (52, 60), (3.0, 6.0)),
        # heading 180 deg: map +row is world -row
        ((1.35, -1.55, math.pi), (50, 61), (3.0, 3.0)),
    ],
)
def test_T_world_from_map(
    start: tuple[float, float, float], map_cell: tuple[int, int], world_cell: tuple[float, float]
) -> None:
    world = two_rooms()
    T = T_world_from_map(start, (50, 60), world.resolution_m, world)
    p = apply_transform(T, np.array([map_cell], dtype=float))[0]
    assert p == pytest.approx(world_cell, abs=1e-9)


def test_true_transform_composes_and_inverts() -> None:
    world = two_rooms()
    sa, sb, sc = (1.35, -1.55, 0.3), (1.75, -1.25, -2.0), (2.25, -1.35, 1.1)
    oa, ob, oc = (40, 40), (41, 39), (30, 50)
    res = world.resolution_m
    t_ab = true_transform(sa, oa, sb, ob, world, res)
    t_bc = true_transform(sb, ob, sc, oc, world, res)
    t_ac = true_transform(sa, oa, sc, oc, world, res)
    assert np.allclose(t_ab @ t_bc, t_ac)
    assert np.allclose(true_transform(sb, ob, sa, oa, world, res), np.linalg.inv(t_ab))
    # b's origin cell lands where b's start is in a's frame
    p = apply_transform(t_ab, np.array([ob], dtype=float))[0]
    dx, dy = sb[0] - sa[0], sb[1] - sa[1]
    c, s = math.cos(-sa[2]), math.sin(-sa[2])
    expect = (oa[0] + (c * dx - s * dy) / res, oa[1] + (s * dx + c * dy) / res)
    assert p == pytest.approx(expect)


def test_reachable_is_the_room_of_the_starts() -> None:
    world = two_rooms()
    left = reachable_free(world, 0.1, np.array([[4, 4]]))
    assert left[1:9, 1:9].all()  # the whole left room, walls' neighbours included
    assert not left[:, 10:].any()
    both = reachable_free(world, 0.1, np.array([[4, 4], [14, 4]]))
    assert both.sum() == 2 * 64
    assert not (both & world.walls).any()
    cs = reachable_cspace(world, 0.1, np.array([[4, 4]]))
    assert cs.sum() == 6 * 6  # centres keep one cell from the walls
    with pytest.raises(GridError):
        reachable_free(world, 0.1, np.array([[40, 4]]))


def test_coverage() -> None:
    reach = np.zeros((4, 4), dtype=bool)
    reach[:2] = True
    seen = np.zeros((4, 4), dtype=bool)
    seen[0] = True
    seen[3] = True  # not reachable: does not count
    assert coverage(seen, reach) == pytest.approx(0.5)
    assert coverage(seen, np.zeros_like(reach)) == 0.0
    with pytest.raises(GridError):
        coverage(seen, reach[:3])


def test_transform_error() -> None:
    T = make_transform(0.2, 5.0, -3.0)
    pts = np.array([[0.0, 0.0], [10.0, 4.0]])
    assert transform_error(T, T, pts) == pytest.approx((0.0, 0.0))
    shifted = make_transform(0.2, 7.0, -3.0)
    assert transform_error(shifted, T, pts) == pytest.approx((2.0, 0.0))
    rotated = make_transform(0.2 + math.radians(10.0), 5.0, -3.0)
    assert transform_error(rotated, T, pts)[1] == pytest.approx(10.0)


# ---------------------------------------------------------------------------- map accuracy


def test_map_in_world_places_cells_and_leaves_the_rest_unknown() -> None:
    m = np.full((6, 6), -1, dtype=np.int8)
    m[1, 2] = 0
    m[4, 4] = 100
    T = make_transform(0.0, 3.0, 1.0)  # map (c, r) -> world (c + 3, r + 1)
    w = map_in_world(m, T, (8, 10))
    assert w.shape == (8, 10) and w.dtype == np.int8
    assert w[2, 5] == 0 and w[5, 7] == 100
    assert np.count_nonzero(w != -1) == 2
    # a quarter turn: map +col becomes world +row
    Tr = make_transform(math.pi / 2, 7.0, 0.0)
    wr = map_in_world(m, Tr, (8, 10))
    c, r = apply_transform(Tr, np.array([[2.0, 1.0]]))[0]
    assert wr[round(r), round(c)] == 0


def test_contradiction_counts_free_on_walls_and_walls_far_from_walls() -> None:
    walls = np.zeros((7, 7), dtype=bool)
    walls[:, 3] = True  # one wall column
    scorer = MapScorer(walls)
    m = np.full((7, 7), -1, dtype=np.int8)
    assert math.isnan(scorer.contradiction(m))  # no claim
    m[:, 3] = 100  # correct walls
    m[:, 1] = 0  # correct free space
    m[0, 4] = 100  # a wall one cell off: within tolerance
    m[3, 5] = 50  # neither free nor occupied: not a claim
    assert scorer.contradiction(m) == 0.0
    m[6, 3] = 0  # a free claim on a true wall
    m[2, 5] = 100  # a wall claim with no true wall within 1 cell
    claims = 7 + 6 + 1 + 1 + 1
    assert scorer.contradiction(m) == pytest.approx(2 / claims)
    assert map_contradiction(m, np.eye(3), walls) == pytest.approx(2 / claims)


def test_held_free_counts_reachable_claims_that_do_not_contradict_the_truth() -> None:
    walls = np.zeros((5, 5), dtype=bool)
    reachable = np.zeros((5, 5), dtype=bool)
    reachable[1:4, 1:4] = True
    m = np.full((5, 5), -1, dtype=np.int8)
    m[0:3, 0:3] = 0
    assert MapScorer(walls, reachable).held_free(m) == 4
    # a wall drawn a cell onto the floor beside a true wall is held; one on open floor is not
    walls[4, :] = True
    m[3, 1] = 100  # beside the wall of row 4
    m[1, 1] = 100  # two cells from it: contradicts the truth
    assert MapScorer(walls, reachable).held_free(m) == 4 - 1 + 1
    with pytest.raises(GridError):
        MapScorer(walls).held_free(m)
    with pytest.raises(GridError):
        MapScorer(walls, reachable[:4])


def test_a_correct_map_agrees_and_a_misplaced_one_contradicts() -> None:
    from mrexplore.sim import Simulation
    from mrexplore.world import load_world

    world = load_world("small_office")
    sim = Simulation(world, 1)
    rng = np.random.default_rng(0)
    sim.reset(rng)
    for k in range(40):
        sim.step(np.array([1 if k < 16 else 0]), rng)  # turn, then drive
    m = sim.maps[0].to_int8()
    T = sim.world_from_map(0)
    good = map_contradiction(m, T, world.walls)
    bad = map_contradiction(m, make_transform(0.0, 12.0, 7.0) @ T, world.walls)
    assert good < 0.02
    assert bad > 0.1


def test_scores_in_one_pass_equal_the_two_methods() -> None:
    rng = np.random.default_rng(4)
    walls = rng.random((60, 50)) < 0.2
    reach = rng.random((60, 50)) < 0.6
    scorer = MapScorer(walls, reach)
    for p_known in (0.0, 0.3, 1.0):
        m = rng.choice(np.array([-1, 0, 10, 25, 26, 50, 64, 65, 100], dtype=np.int8), (60, 50))
        m[rng.random(m.shape) >= p_known] = -1
        share, held = scorer.scores(m, held=True)
        ref = scorer.contradiction(m)
        assert share == ref or (np.isnan(share) and np.isnan(ref))
        assert held == scorer.held_free(m)
        assert scorer.scores(m)[1] is None


@pytest.mark.parametrize("theta", [0.0, 0.37, 2.9, -1.2])
def test_rescoring_the_changed_cells_equals_rescoring_the_whole_world(theta: float) -> None:
    """``update_cells`` finds every world cell that samples a changed map cell, under a turned
    and shifted transform: the same classes and counts as re-scoring the whole world."""
    rng = np.random.default_rng(3)
    walls = rng.random((70, 80)) < 0.2
    scorer = MapScorer(walls, reachable=rng.random((70, 80)) < 0.7)
    T = make_transform(theta, 31.3, 17.6)
    sample = nearest_sampling(T, (90, 110), walls.shape)
    if sample is None:
        pytest.skip("OpenCV's sampling could not be pinned down here")
    values = np.array([-1, 0, 10, 50, 80, 100], dtype=np.int8)
    m = rng.choice(values, size=(90, 110))
    by_cells, whole = IncrementalScore(scorer, T, sample), IncrementalScore(scorer, T, sample)
    by_cells.update(m, None)
    whole.update(m, None)
    for _ in range(6):
        changed = rng.choice(m.size, size=150, replace=False)
        m.reshape(-1)[changed] = rng.choice(values, size=changed.size)
        got = by_cells.update_cells(m, changed)
        assert got == pytest.approx(whole.update(m, None), nan_ok=True)
        assert np.array_equal(by_cells.cls, whole.cls)
        assert np.array_equal(by_cells.counts, whole.counts)


def test_rescoring_changed_cells_needs_a_rigid_transform() -> None:
    walls = np.zeros((20, 20), dtype=bool)
    T = np.diag([2.0, 2.0, 1.0])  # a map at half the world's resolution
    sample = nearest_sampling(T, (10, 10), walls.shape)
    assert sample is not None
    inc = IncrementalScore(MapScorer(walls), T, sample)
    with pytest.raises(GridError, match="rigid"):
        inc.update_cells(np.zeros((10, 10), dtype=np.int8), np.array([3]))
