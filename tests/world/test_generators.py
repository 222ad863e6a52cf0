"""Generators: determinism, identical twin rooms, an otherwise unambiguous floor, reachability."""

from __future__ import annotations

import math
from collections.abc import Callable

import cv2
import numpy as np
import pytest

from mrexplore.errors import WorldError
from mrexplore.world import GENERATORS, World, symmetric_office, twin_wings

ROBOT_R_M = 0.15

# (generator, width_m, height_m, resolution_m)
CASES = [
    (symmetric_office, 20.0, 16.0, 0.05),  # the default world's size
    (symmetric_office, 10.0, 8.0, 0.05),  # small, for fast tests
    (symmetric_office, 8.0, 8.0, 0.05),  # near the smallest floor that holds three rooms
    (symmetric_office, 15.0, 25.0, 0.05),  # tall: deep rooms
    (symmetric_office, 25.0, 25.0, 0.1),  # Explore-Bench-like coarse grid
    (twin_wings, 20.0, 20.0, 0.05),  # the shipped second layout
    (twin_wings, 15.0, 15.0, 0.05),  # smallest typical size
    (twin_wings, 25.0, 20.0, 0.1),  # coarse
]
SEEDS = [0, 1, 2, 3, 4]


def _ids(case: tuple) -> str:
    return f"{case[0].__name__}-{case[1]:g}x{case[2]:g}@{case[3]:g}"


def _make(case: tuple, seed: int) -> World:
    gen, w, h, res = case
    return gen(np.random.default_rng(seed), width_m=w, height_m=h, resolution_m=res)


def _crop(walls: np.ndarray, box: tuple[int, int, int, int]) -> np.ndarray:
    c, r, w, h = box
    assert c >= 0 and r >= 0 and c + w <= walls.shape[1] and r + h <= walls.shape[0]
    return walls[r : r + h, c : c + w]


def _disk(radius: float) -> np.ndarray:
    k = math.ceil(radius)
    yy, xx = np.mgrid[-k : k + 1, -k : k + 1]
    return (xx * xx + yy * yy <= radius * radius).astype(np.uint8)


def _unreached(world: World, start: tuple[int, int]) -> np.ndarray:
    """Independent check (erosion/dilation, not the generator's distance transform): free cells
    that a disc of ROBOT_R_M starting at ``start`` (col, row) can neither stand on nor touch
    (corners allowed: a cell within sqrt(2) * r + 1 cell of a reachable centre counts)."""
    r = round(ROBOT_R_M / world.resolution_m, 6)  # 0.15 / 0.05 is 2.9999999999999996
    free = world.free.astype(np.uint8)
    # the disc (cells whose centres are within r) must lie on free cells
    centres = cv2.erode(free, _disk(r), borderValue=0)
    assert centres[start[1], start[0]], "the corridor centre must be a valid robot position"
    _, labels = cv2.connectedComponents(centres, connectivity=8)
    comp = (labels == labels[start[1], start[0]]).astype(np.uint8)
    touched = cv2.dilate(comp, _disk(math.sqrt(2.0) * r + 1.0)) > 0
    return world.free & ~touched


def _corridor_centre(world: World) -> tuple[int, int]:
    c, r, w, h = world.meta["corridor_box"]
    return (c + w // 2, r + h // 2)


# --- determinism -----------------------------------------------------------------------------


@pytest.mark.parametrize("case", CASES, ids=_ids)
def test_same_seed_same_world_and_different_seeds_differ(case: tuple) -> None:
    a, b, c = _make(case, 7), _make(case, 7), _make(case, 8)
    np.testing.assert_array_equal(a.walls, b.walls)
    assert a.meta["twin_rooms"] == b.meta["twin_rooms"]
    assert a.shape != c.shape or not np.array_equal(a.walls, c.walls)


def test_size_and_resolution_are_honoured() -> None:
    w = symmetric_office(np.random.default_rng(0), width_m=20.0, height_m=16.0, resolution_m=0.05)
    assert w.shape == (320, 400) and w.resolution_m == 0.05 and w.size_m == pytest.approx((20, 16))
    assert w.walls[0].all() and w.walls[-1].all() and w.walls[:, 0].all() and w.walls[:, -1].all()


# --- the twins -------------------------------------------------------------------------------


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("case", CASES, ids=_ids)
def test_twin_rooms_identical_elsewhere_different(case: tuple, seed: int) -> None:
    world = _make(case, seed)
    box_a, box_b = world.meta["twin_rooms"]
    rot = world.meta["twin_rotation_deg"]
    assert rot == (180 if case[0] is twin_wings else 0)
    room_a, room_b = _crop(world.walls, box_a), _crop(world.walls, box_b)
    # cell for cell identical (after the stated rotation)
    np.testing.assert_array_equal(room_b, np.rot90(room_a, rot // 90))
    # at different places, not overlapping
    ca, ra, wa, ha = box_a
    cb, rb, wb, hb = box_b
    assert ca + wa <= cb or cb + wb <= ca or ra + ha <= rb or rb + hb <= ra
    # real furnished rooms: walls all round except a door >= 0.9 m, furniture inside
    t = 2 if world.resolution_m > 0.05 else 3
    rim = room_a.copy()
    rim[t:-t, t:-t] = True
    assert (~rim).sum() >= math.ceil(0.9 / world.resolution_m - 1e-9) * t  # the door hole
    interior = room_a[t:-t, t:-t]
    assert 0 < interior.mean() < 0.5  # some furniture, mostly free
    # no other room looks like a twin
    for box in world.meta["rooms"]:
        if box in (box_a, box_b):
            continue
        other = _crop(world.walls, box)
        for k in range(4):
            cand = np.rot90(other, k)
            assert cand.shape != room_a.shape or not np.array_equal(cand, room_a)


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("case", CASES, ids=_ids)
def test_floor_is_not_symmetric_under_the_twin_transform(case: tuple, seed: int) -> None:
    """Moving the floor so twin A lands on twin B must not map the floor onto itself."""
    world = _make(case, seed)
    (ca, ra, wa, ha), (cb, rb, wb, hb) = world.meta["twin_rooms"]
    walls = world.walls
    if world.meta["twin_rotation_deg"] == 180:
        # point (c, r) of A maps to (ca + cb + wa - 1 - c, ra + rb + ha - 1 - r)
        moved = np.rot90(walls, 2)
        dc = ca + cb + wa - 1 - (walls.shape[1] - 1)
        dr = ra + rb + ha - 1 - (walls.shape[0] - 1)
    else:
        moved, dc, dr = walls, cb - ca, rb - ra
    H, W = walls.shape
    # overlap of walls[r, c] with moved[r - dr, c - dc]
    r0, r1 = max(0, dr), min(H, H + dr)
    c0, c1 = max(0, dc), min(W, W + dc)
    here = walls[r0:r1, c0:c1]
    there = moved[r0 - dr : r1 - dr, c0 - dc : c1 - dc]
    np.testing.assert_array_equal(
        _crop(walls, (cb, rb, wb, hb)), _crop(moved, (cb - dc, rb - dr, wb, hb))
    )
    disagree = float((here != there).mean())
    assert disagree > 0.02, f"floor nearly maps onto itself ({disagree:.3%} of the overlap differs)"


# --- reachability and sizes ------------------------------------------------------------------


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("case", CASES, ids=_ids)
def test_every_free_cell_reachable_by_the_robot(case: tuple, seed: int) -> None:
    world = _make(case, seed)
    bad = _unreached(world, _corridor_centre(world))
    assert not bad.any(), (
        f"{int(bad.sum())} free cells unreachable, e.g. (row, col) {np.argwhere(bad)[0]}"
    )


@pytest.mark.parametrize("case", CASES, ids=_ids)
def test_corridor_width_measured_on_the_grid(case: tuple) -> None:
    world = _make(case, 3)
    boxes = world.meta.get("corridor_boxes", [world.meta["corridor_box"]])
    for c, r, w, h in boxes[:2]:  # horizontal corridors: measure vertical free runs
        mid = r + h // 2
        free = world.free[:, c : c + w]
        # length of the free run through row ``mid`` in each column, vectorised with cumsums
        walls_below = np.maximum.accumulate(np.where(~free, np.arange(free.shape[0])[:, None], -1))
        walls_above = np.minimum.accumulate(
            np.where(~free, np.arange(free.shape[0])[:, None], free.shape[0])[::-1]
        )[::-1]
        runs = walls_above[mid] - walls_below[mid] - 1
        # most columns are not doors: the most common run is the corridor width
        width_cells = np.bincount(runs).argmax()
        assert 2.5 - 1e-9 <= width_cells * world.resolution_m <= 3.0 + 1e-9
        assert width_cells * world.resolution_m == pytest.approx(h * world.resolution_m)


def test_corridor_and_door_options() -> None:
    rng = np.random.default_rng(0)
    w = symmetric_office(rng, width_m=12, height_m=10, corridor_width_m=2.5, door_width_m=0.9)
    assert w.meta["corridor_width_m"] == pytest.approx(2.5)
    w2 = symmetric_office(np.random.default_rng(0), width_m=12, height_m=10, furniture=False)
    box = w2.meta["twin_rooms"][0]
    assert not _crop(w2.walls, box)[3:-3, 3:-3].any()  # empty rooms without furniture


# --- bad options -----------------------------------------------------------------------------


@pytest.mark.parametrize("gen", [symmetric_office, twin_wings])
@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"width_m": -5.0}, "width_m"),  # negative
        ({"height_m": 0.0}, "height_m"),  # zero
        ({"width_m": float("nan")}, "width_m"),  # NaN
        ({"width_m": 4.0}, "width_m"),  # too small to hold the rooms
        ({"height_m": 5.0}, "height_m"),  # too small for two room rows and a corridor
        ({"resolution_m": -0.05}, "resolution_m"),  # negative resolution
        ({"resolution_m": 1.0}, "resolution_m"),  # coarser than a door
        ({"corridor_width_m": 4.0}, "corridor_width_m"),  # outside 2.5-3.0 m
        ({"door_width_m": 0.5}, "door_width_m"),  # a robot could not pass
        ({"robot_radius_m": 0.6}, "robot_radius_m"),  # robot wider than the doors
        ({"wall_cells": 0}, "wall_cells"),  # no walls
        ({"width": 20.0}, "unknown generator option"),  # typo of width_m
        ({"rooms_per_side": 1}, "rooms_per_side"),  # too few rooms for two twins
        ({"furniture": "maybe"}, "furniture must be True or False"),  # not a bool
    ],
)
def test_bad_options_raise_world_error_naming_them(
    gen: Callable[..., World], kwargs: dict, words: str
) -> None:
    with pytest.raises(WorldError, match=words):
        gen(np.random.default_rng(0), **kwargs)


def test_registry_of_generators() -> None:
    assert {"symmetric_office": symmetric_office, "twin_wings": twin_wings} == GENERATORS
