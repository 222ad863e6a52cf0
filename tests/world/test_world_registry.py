"""Registry: shipped names, paths, ``random:`` specs and their errors."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrexplore.errors import MapFileNotFoundError, WorldError
from mrexplore.world import World, list_worlds, load_world, symmetric_office, world_to_file

SHIPPED = {
    "symmetric_office",
    "twin_wings",
    "small_office",
    "symmetric_office_coarse",
    "tb3_office",
    "depot",
}


def test_list_worlds_has_the_shipped_worlds() -> None:
    assert set(list_worlds()) >= SHIPPED
    assert list_worlds() == sorted(list_worlds())


@pytest.mark.parametrize("name", sorted(SHIPPED))
def test_every_shipped_world_loads(name: str) -> None:
    world = load_world(name)
    assert world.name == name
    assert world.free.any() and world.walls.dtype == np.bool_
    # robots cannot leave: the outer ring of cells is wall
    w = world.walls
    assert w[0].all() and w[-1].all() and w[:, 0].all() and w[:, -1].all()


@pytest.mark.parametrize(
    ("name", "shape", "res"),
    [
        ("symmetric_office", (320, 400), 0.05),  # 20 x 16 m, the default world
        ("small_office", (160, 200), 0.05),  # 10 x 8 m
        ("symmetric_office_coarse", (250, 250), 0.1),  # Explore-Bench's grid settings
        ("tb3_office", (384, 384), 0.05),  # real map, no free cell on its edge
        ("depot", (309, 606), 0.05),  # real map, free on its edge -> 1-cell border added
    ],
)
def test_shipped_sizes(name: str, shape: tuple[int, int], res: float) -> None:
    world = load_world(name)
    assert world.shape == shape and world.resolution_m == res


@pytest.mark.parametrize("name", ["symmetric_office", "small_office", "twin_wings"])
def test_shipped_generated_worlds_keep_identical_twins(name: str) -> None:
    world = load_world(name)
    (ca, ra, wa, ha), (cb, rb, wb, hb) = world.meta["twin_rooms"]
    room_a = world.walls[ra : ra + ha, ca : ca + wa]
    room_b = world.walls[rb : rb + hb, cb : cb + wb]
    np.testing.assert_array_equal(room_b, np.rot90(room_a, world.meta["twin_rotation_deg"] // 90))


def test_shipped_world_is_reproducible_from_its_seed() -> None:
    shipped = load_world("small_office")
    fresh = symmetric_office(np.random.default_rng(shipped.meta["seed"]), **shipped.meta["options"])
    np.testing.assert_array_equal(fresh.walls, shipped.walls)


def test_world_spec_is_returned_as_is() -> None:
    world = load_world("small_office")
    assert load_world(world) is world


def test_path_specs(tmp_path: Path) -> None:
    src = load_world("small_office")
    path = world_to_file(src, tmp_path / "mine.yaml")
    for spec in (path, str(path)):  # a Path and a str path
        world = load_world(spec)
        np.testing.assert_array_equal(world.walls, src.walls)
        assert world.name == "mine"


def test_missing_path_spec(tmp_path: Path) -> None:
    with pytest.raises(MapFileNotFoundError):
        load_world(str(tmp_path / "absent.yaml"))


@pytest.mark.parametrize(
    ("spec", "shape"),
    [
        ("random:symmetric_office", (320, 400)),  # defaults: 20 x 16 m at 0.05
        ("random:symmetric_office?width_m=10&height_m=8", (160, 200)),  # options from the query
        ("random:twin_wings?width_m=16&height_m=15&resolution_m=0.1", (150, 160)),  # coarse wings
    ],
)
def test_random_specs(spec: str, shape: tuple[int, int]) -> None:
    a = load_world(spec, rng=np.random.default_rng(5))
    b = load_world(spec, rng=np.random.default_rng(5))
    assert isinstance(a, World) and a.shape == shape
    np.testing.assert_array_equal(a.walls, b.walls)  # drawn from the rng only


@pytest.mark.parametrize(
    ("spec", "rng", "words"),
    [
        ("no_such_world", None, "symmetric_office"),  # unknown name: lists the shipped ones
        ("random:symmetric_office", None, "rng"),  # random without a Generator
        ("random:maze", np.random.default_rng(0), "unknown generator 'maze'"),  # bad generator
        ("random:symmetric_office?width=10", np.random.default_rng(0), "width"),  # option typo
        (
            "random:symmetric_office?width_m=abc",
            np.random.default_rng(0),
            "width_m",
        ),  # not a number
        ("random:symmetric_office?width_m=3", np.random.default_rng(0), "width_m"),  # too small
    ],
)
def test_bad_specs(spec: str, rng: np.random.Generator | None, words: str) -> None:
    with pytest.raises(WorldError, match=words):
        load_world(spec, rng=rng)


def test_bad_spec_type() -> None:
    with pytest.raises(WorldError, match="World, a name or a path"):
        load_world(42)  # type: ignore[arg-type]
