"""World families: the split by world seed, determinism, identical copies, reachability, specs."""

from __future__ import annotations

import itertools
from collections.abc import Callable

import cv2
import numpy as np
import pytest

from mrexplore.errors import WorldError
from mrexplore.world import World, load_world
from mrexplore.world.family import (
    FAMILIES,
    FAMILY_GENERATORS,
    MAX_LONG_M,
    MAX_SHORT_M,
    PART_SIZE,
    PARTS,
    family_seed,
    family_seeds,
    family_spec,
    family_world,
    parse_family_spec,
    radial,
)
from mrexplore.world.generators import unreachable_free_cells

SEEDS = range(24)  # enough draws to meet every layout of paper_like
Gen = Callable[..., World]


def _canonical(world: World, copy: dict) -> np.ndarray:
    """A copy's cells turned back to the template's orientation."""
    c, r, w, h = copy["box"]
    assert c >= 0 and r >= 0 and c + w <= world.shape[1] and r + h <= world.shape[0]
    return np.rot90(world.walls[r : r + h, c : c + w], -(copy["rotation_deg"] // 90)).copy()


# --- the split -------------------------------------------------------------------------------


@pytest.mark.parametrize("family", FAMILIES)
def test_parts_are_disjoint_and_fixed(family: str) -> None:
    seeds = {part: family_seeds(family, part, 50) for part in PARTS}
    assert seeds["tune"][:3] == [0, 1, 2] and seeds["test"][:3] == [100_000, 100_001, 100_002]
    assert seeds["test2"][:2] == [200_000, 200_001]
    assert seeds["test5"][:2] == [500_000, 500_001]
    assert seeds["test10"][0] == 1_000_000 and seeds["test99"][0] == 9_900_000
    assert len(set().union(*seeds.values())) == 50 * len(PARTS)
    # the parts cannot meet at any index, in the order they are opened
    for before, after in itertools.pairwise(PARTS):
        assert family_seed(before, PART_SIZE - 1) < family_seed(after, 0)


def test_family_world_is_its_seed_alone() -> None:
    w = family_world("paper_like", "test", 7)
    again = FAMILY_GENERATORS["paper_like"](np.random.default_rng(100_007))
    np.testing.assert_array_equal(w.walls, again.walls)
    assert w.name == "paper_like/test/0007" and w.meta["seed"] == 100_007
    tune = family_world("paper_like", "tune", 7)
    assert tune.shape != w.shape or not np.array_equal(tune.walls, w.walls)


# --- determinism -----------------------------------------------------------------------------


@pytest.mark.parametrize("gen", FAMILY_GENERATORS.values(), ids=FAMILY_GENERATORS.keys())
def test_same_seed_same_grid(gen: Gen) -> None:
    for seed in (0, 5, 11):
        a, b = gen(np.random.default_rng(seed)), gen(np.random.default_rng(seed))
        np.testing.assert_array_equal(a.walls, b.walls)
        assert a.meta == b.meta
    c = gen(np.random.default_rng(12))
    assert c.shape != a.shape or not np.array_equal(c.walls, a.walls)


# --- the copies, reachability, size ----------------------------------------------------------


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("gen", FAMILY_GENERATORS.values(), ids=FAMILY_GENERATORS.keys())
def test_copies_identical_cell_for_cell(gen: Gen, seed: int) -> None:
    world = gen(np.random.default_rng(seed), noise=False)
    assert len(world.meta["copies"]) >= (3 if world.meta["generator"] == "office_row" else 2)
    assert world.meta["twin_rooms"] == [c["box"] for c in world.meta["copies"]]
    # copies turned by quarter turns are cell for cell the same (a radial floor's other wings
    # are drawn turned to the nearest cell: test_radial_floor_is_the_same_under_its_turn)
    copies = [c for c in world.meta["copies"] if isinstance(c["rotation_deg"], int)]
    assert copies
    t = 3  # wall cells at 0.05 m
    ref = _canonical(world, copies[0])
    if world.meta["doors_differ"]:
        ref[:t] = True  # copies differ in their door wall only: close it in the comparison
    for copy in copies[1:]:
        other = _canonical(world, copy)
        if world.meta["doors_differ"]:
            other[:t] = True
        np.testing.assert_array_equal(other, ref)
    # in different places, never overlapping (neighbours may share a wall)
    boxes = [(c + t, r + t, w - 2 * t, h - 2 * t) for c, r, w, h in (x["box"] for x in copies)]
    for i, (ca, ra, wa, ha) in enumerate(boxes):
        for cb, rb, wb, hb in boxes[i + 1 :]:
            assert ca + wa <= cb or cb + wb <= ca or ra + ha <= rb or rb + hb <= ra
    # furnished: something stands inside, most of it is free
    inner = ref[t:-t, t:-t]
    assert 0.0 < inner.mean() < 0.6


@pytest.mark.parametrize("seed", SEEDS)
@pytest.mark.parametrize("gen", FAMILY_GENERATORS.values(), ids=FAMILY_GENERATORS.keys())
def test_every_free_cell_reachable_and_size_modest(gen: Gen, seed: int) -> None:
    world = gen(np.random.default_rng(seed))  # noise as drawn
    bad = unreachable_free_cells(world.walls, world.resolution_m, world.meta["start_cell"])
    assert not bad.any(), f"{int(bad.sum())} free cells unreachable"
    long_m, short_m = max(world.size_m), min(world.size_m)
    assert long_m <= MAX_LONG_M + 1e-9 and short_m <= MAX_SHORT_M + 1e-9
    assert world.walls[0].all() and world.walls[-1].all()
    assert world.walls[:, 0].all() and world.walls[:, -1].all()


@pytest.mark.parametrize("gen", FAMILY_GENERATORS.values(), ids=FAMILY_GENERATORS.keys())
def test_noise_changes_a_few_cells_not_the_layout(gen: Gen) -> None:
    for seed in range(6):
        noisy = gen(np.random.default_rng(seed), noise=True)
        clean = gen(np.random.default_rng(seed), noise=False)
        assert noisy.shape == clean.shape and clean.meta["noise"] is None
        changed = int((noisy.walls != clean.walls).sum())
        assert noisy.meta["noise"] is not None
        assert 0 < changed <= noisy.meta["noise"]["speckles"] + noisy.meta["noise"]["bumps"]
        assert changed < 0.01 * clean.free.sum()


def _square_round(walls: np.ndarray, centre: tuple[int, int]) -> np.ndarray:
    """``walls`` padded with wall into a square of odd side whose centre cell is ``centre``
    (col, row)."""
    c, r = centre
    h, w = walls.shape
    half = max(c, r, w - 1 - c, h - 1 - r)
    out = np.ones((2 * half + 1, 2 * half + 1), dtype=np.bool_)
    out[half - r : half - r + h, half - c : half - c + w] = walls
    return out


@pytest.mark.parametrize("seed", range(16))
def test_radial_floor_is_the_same_under_its_turn(seed: int) -> None:
    world = radial(np.random.default_rng(seed), noise=False)
    n = world.meta["wings"]
    c, r, w, h = world.meta["corridor_box"]  # the hall's inscribed square, about its centre
    sq = _square_round(world.walls, (c + w // 2, r + h // 2)).astype(np.uint8)
    side = sq.shape[0]
    mid = (side - 1) / 2
    turned = cv2.warpAffine(
        sq,
        cv2.getRotationMatrix2D((mid, mid), 360.0 / n, 1.0),
        (side, side),
        flags=cv2.INTER_NEAREST,
        borderValue=1,
    )
    # outside the hall (where clutter may stand): the same floor, cell for cell with 2 or 4
    # wings, all but the turned walls' edge cells otherwise
    ys, xs = np.ogrid[:side, :side]
    away = (xs - mid) ** 2 + (ys - mid) ** 2 > (2 * max(w, h)) ** 2
    free = (sq == 0) & away
    differ = ((turned != sq) & away).sum() / free.sum()
    if n in (2, 4):
        assert differ == 0.0
    else:
        assert differ < 0.03
    # every wing holds the same rooms: copies k * m + j of wing k, turned by 360 k / n more
    copies = world.meta["copies"]
    m = len(copies) // n
    assert len(copies) == n * m and m >= 1
    for k in range(n):
        for j in range(m):
            got = copies[k * m + j]["rotation_deg"]
            want = (copies[j]["rotation_deg"] + 360.0 * k / n) % 360.0
            assert got == pytest.approx(want, abs=1e-3) or abs(got - want) == pytest.approx(360.0)


def test_radial_draws_every_number_of_wings() -> None:
    wings = {family_world("radial", "tune", k).meta["wings"] for k in range(40)}
    assert wings == {2, 3, 4, 5, 6}


def test_paper_like_varies_widely() -> None:
    worlds = [family_world("paper_like", "tune", k) for k in range(40)]
    layouts = {w.meta["layout"] for w in worlds}
    assert {"corridor_one_side", "corridor_both_sides", "hall", "two_wings", "open_plan"} <= layouts
    turns = {
        (c["rotation_deg"] - w.meta["copies"][0]["rotation_deg"]) % 360
        for w in worlds
        for c in w.meta["copies"]
    }
    assert {0, 90, 180, 270} <= turns
    assert {len(w.meta["copies"]) for w in worlds} == {2, 3, 4}
    assert any(w.meta["doors_differ"] for w in worlds) and any(w.meta["clutter"] for w in worlds)
    widths = [w.meta["repeated_size_m"][0] for w in worlds if w.meta["repeated_size_m"]]
    assert min(widths) < 5.0 and max(widths) > 9.0 and min(widths) >= 3.0 - 0.05
    assert max(widths) <= 12.0 + 0.05


# --- specs -----------------------------------------------------------------------------------


def test_family_specs_load() -> None:
    spec = family_spec("office_row", "tune", 3)
    assert spec == "family:office_row/tune/3" and parse_family_spec(spec) == (
        "office_row",
        "tune",
        3,
    )
    w = load_world(spec)
    np.testing.assert_array_equal(w.walls, family_world("office_row", "tune", 3).walls)
    assert w.name == "office_row/tune/0003"


def test_random_family_specs_draw_from_the_rng() -> None:
    a = load_world("random:paper_like?noise=false", rng=np.random.default_rng(4))
    b = load_world("random:paper_like?noise=false", rng=np.random.default_rng(4))
    np.testing.assert_array_equal(a.walls, b.walls)
    assert a.meta["noise"] is None


@pytest.mark.parametrize(
    ("spec", "words"),
    [
        ("family:nope/test/1", "unknown family 'nope'"),  # bad family, lists the families
        ("family:paper_like/dev/1", "unknown part 'dev'"),  # bad part
        ("family:paper_like/test/x", "index must be a whole number"),  # not a number
        ("family:paper_like/test/-1", "index must be a whole number"),  # negative
        ("family:paper_like/test/100000", "below 100000"),  # beyond the part
        ("family:paper_like/test", "expected 'family:<family>/<part>/<index>'"),  # too short
        ("family:paper_like/test/1/2", "expected 'family:<family>/<part>/<index>'"),  # too long
        ("random:paper_like?noise=3", "noise"),  # a bad option
        ("random:paper_like?width_m=3", "width_m"),  # an option it does not take
    ],
)
def test_bad_specs_are_refused_at_the_door(spec: str, words: str) -> None:
    with pytest.raises(WorldError, match=words):
        load_world(spec, rng=np.random.default_rng(0))


@pytest.mark.parametrize(
    ("call", "words"),
    [
        (lambda: family_seeds("nope", "tune", 3), "unknown family"),
        (lambda: family_seeds("paper_like", "train", 3), "unknown part"),
        (lambda: family_seeds("paper_like", "tune", -1), "number of worlds"),
        (lambda: family_world("paper_like", "tune", PART_SIZE), "world index"),
        (lambda: family_spec("paper_like", "tune", 1.5), "integer"),
    ],
)
def test_bad_arguments_name_the_problem(call: Callable[[], object], words: str) -> None:
    with pytest.raises(WorldError, match=words):
        call()
