"""map_server I/O: round trips, map_server semantics (negate, thresholds, modes), bad input."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from mrexplore.errors import MapFileError, MapFileNotFoundError, WorldError
from mrexplore.grid import FREE, OCCUPIED, UNKNOWN
from mrexplore.world import (
    World,
    list_worlds,
    load_world,
    read_map_yaml,
    world_from_file,
    world_to_file,
    write_map_yaml,
)


def _write_pair(tmp: Path, pixels: np.ndarray, yaml_text: str, name: str = "m.pgm") -> Path:
    """A hand-made map: ``pixels`` (image order, row 0 = top) and a YAML naming ``name``."""
    ok, buf = cv2.imencode(Path(name).suffix, pixels)
    assert ok
    (tmp / name).write_bytes(buf.tobytes())
    path = tmp / "m.yaml"
    path.write_text(yaml_text.replace("IMAGE", name), encoding="utf-8")
    return path


BASE = "image: IMAGE\nresolution: 0.05\norigin: [1.5, -2.0, 0.0]\n"


# --- round trips ----------------------------------------------------------------------------


@pytest.mark.parametrize("name", list_worlds())
def test_every_shipped_world_round_trips(name: str, tmp_path: Path) -> None:
    src = load_world(name)
    occ = read_map_yaml(Path(src.meta["source"]))
    out = write_map_yaml(tmp_path / f"{name}.yaml", occ.grid, occ.resolution_m, occ.origin_m)
    back = read_map_yaml(out)
    # tb3_office/depot are trinary already (map_saver output), so the grid must be identical.
    np.testing.assert_array_equal(back.grid, occ.grid)
    assert back.resolution_m == occ.resolution_m
    assert back.origin_m == occ.origin_m


@settings(
    max_examples=40, deadline=None, suppress_health_check=[HealthCheck.function_scoped_fixture]
)
@given(
    grid=arrays(
        np.int8,
        st.tuples(st.integers(1, 24), st.integers(1, 24)),
        elements=st.sampled_from([UNKNOWN, FREE, OCCUPIED]),
    ),
    resolution=st.floats(0.001, 2.0, allow_nan=False),
    origin=st.tuples(*[st.floats(-1e4, 1e4, allow_nan=False)] * 3),
    fmt=st.sampled_from(["pgm", "png"]),
)
def test_random_trinary_grids_round_trip_exactly(
    tmp_path: Path,
    grid: np.ndarray,
    resolution: float,
    origin: tuple[float, float, float],
    fmt: str,
) -> None:
    path = write_map_yaml(tmp_path / "r.yaml", grid, resolution, origin, image_format=fmt)
    back = read_map_yaml(path)
    np.testing.assert_array_equal(back.grid, grid)
    assert back.resolution_m == resolution
    assert back.origin_m == origin


def test_rows_are_flipped_only_in_files(tmp_path: Path) -> None:
    # One wall cell at row 0 (lowest y) must be the *bottom* row of the image.
    grid = np.zeros((3, 4), np.int8)
    grid[0, 1] = OCCUPIED
    path = write_map_yaml(tmp_path / "f.yaml", grid, 0.1)
    img = cv2.imread(str(path.with_suffix(".pgm")), cv2.IMREAD_UNCHANGED)
    assert img is not None
    assert img[2, 1] == 0 and img[0, 1] == 254
    assert read_map_yaml(path).grid[0, 1] == OCCUPIED


def test_world_round_trip_keeps_walls_and_twin_boxes(tmp_path: Path) -> None:
    world = load_world("small_office")
    back = world_from_file(world_to_file(world, tmp_path / "w.yaml"))
    np.testing.assert_array_equal(back.walls, world.walls)
    assert back.meta["twin_rooms"] == world.meta["twin_rooms"]
    assert back.resolution_m == world.resolution_m


def test_writer_is_byte_deterministic(tmp_path: Path) -> None:
    world = load_world("small_office")
    a = world_to_file(world, tmp_path / "a" / "w.yaml")
    b = world_to_file(world, tmp_path / "b" / "w.yaml")
    assert a.read_bytes() == b.read_bytes()
    assert a.with_suffix(".pgm").read_bytes() == b.with_suffix(".pgm").read_bytes()


# --- map_server semantics --------------------------------------------------------------------

# One image row of pixel values; p = (255 - v) / 255.
PIXELS = np.array([[0, 50, 100, 128, 200, 205, 230, 254, 255]], np.uint8)


@pytest.mark.parametrize(
    ("extra", "expected"),
    [
        # thresholds .65 / .196: p = 1, .80, .61, .50, .22, .196 (50/255 > .196), .10, 0, 0
        ("", [100, 100, -1, -1, -1, -1, 0, 0, 0]),
        # negate: p = v / 255, so black is free and white occupied; p(50) = .19608 is not < .196
        ("negate: 1\n", [0, -1, -1, -1, 100, 100, 100, 100, 100]),
        # tight thresholds: only pure black occupied (p > .99), only p < .01 free
        ("occupied_thresh: 0.99\nfree_thresh: 0.01\n", [100, -1, -1, -1, -1, -1, -1, 0, 0]),
        # p equal to occupied_thresh is not occupied (strict >): p(50) = 205/255 = 0.8039...
        (f"occupied_thresh: {205 / 255!r}\n", [100, -1, -1, -1, -1, -1, 0, 0, 0]),
        # scale: between thresholds 99 * (p - free) / (occ - free), truncated
        (
            "mode: scale\nfree_thresh: 0.2\noccupied_thresh: 0.8\n",
            # p(100) = .608 -> 67.3, p(128) = .498 -> 49.2, p(200) = .216 -> 2.6, p(205) < .2 free
            [100, 100, 67, 49, 2, 0, 0, 0, 0],
        ),
        # raw: the pixel is the value; outside 0..100 is unknown
        ("mode: raw\n", [0, 50, 100, -1, -1, -1, -1, -1, -1]),
    ],
)
def test_map_server_pixel_rule(tmp_path: Path, extra: str, expected: list[int]) -> None:
    path = _write_pair(tmp_path, PIXELS, BASE + extra)
    got = read_map_yaml(path).grid
    assert got.tolist() == [expected]


def test_scale_mode_value_between_thresholds(tmp_path: Path) -> None:
    # v = 205 -> p = 0.19608; with free 0.1, occ 0.9: 99 * 0.09608 / 0.8 = 11.89 -> 11
    path = _write_pair(
        tmp_path,
        np.array([[205]], np.uint8),
        BASE + "mode: scale\nfree_thresh: 0.1\noccupied_thresh: 0.9\n",
    )
    assert read_map_yaml(path).grid.tolist() == [[11]]


def test_colour_image_is_mean_of_channels(tmp_path: Path) -> None:
    # BGR (0, 0, 255) has mean 85 -> p = 0.667 > 0.65 -> occupied; (254, 254, 254) -> free
    img = np.array([[[0, 0, 255], [254, 254, 254], [205, 205, 205]]], np.uint8)
    path = _write_pair(tmp_path, img, BASE, name="c.png")
    assert read_map_yaml(path).grid.tolist() == [[100, 0, -1]]


def test_world_from_file_unknown_is_wall_and_border_added(tmp_path: Path) -> None:
    # free cells touch the image edge -> a 1-cell wall border, origin moved by one cell
    img = np.array([[254, 254, 205], [254, 0, 254]], np.uint8)
    path = _write_pair(tmp_path, img, BASE)
    w = world_from_file(path)
    assert w.shape == (4, 5)
    assert w.walls[0].all() and w.walls[-1].all() and w.walls[:, 0].all() and w.walls[:, -1].all()
    # bottom inner row = image row 1 = [free, wall, free]; top = [free, free, unknown -> wall]
    assert w.walls[1, 1:4].tolist() == [False, True, False]
    assert w.walls[2, 1:4].tolist() == [False, False, True]
    assert w.origin_m == pytest.approx((1.5 - 0.05, -2.0 - 0.05))


def test_world_from_file_no_border_when_edges_are_walls(tmp_path: Path) -> None:
    img = np.full((4, 4), 0, np.uint8)
    img[1:3, 1:3] = 254
    w = world_from_file(_write_pair(tmp_path, img, BASE))
    assert w.shape == (4, 4) and w.origin_m == (1.5, -2.0) and int(w.free.sum()) == 4


# --- bad input -------------------------------------------------------------------------------


@pytest.mark.parametrize(
    ("yaml_text", "error", "words"),
    [
        # YAML without image
        ("resolution: 0.05\n", MapFileError, "'image'"),
        # YAML without resolution
        ("image: IMAGE\n", MapFileError, "'resolution'"),
        # negative resolution
        ("image: IMAGE\nresolution: -0.05\n", MapFileError, "positive"),
        # zero resolution
        ("image: IMAGE\nresolution: 0\n", MapFileError, "positive"),
        # non-numeric resolution
        ("image: IMAGE\nresolution: fine\n", MapFileError, "number"),
        # free above occupied
        (BASE + "free_thresh: 0.7\noccupied_thresh: 0.3\n", MapFileError, "thresh"),
        # threshold outside [0, 1]
        (BASE + "occupied_thresh: 1.5\n", MapFileError, "thresh"),
        # unknown mode
        (BASE + "mode: fuzzy\n", MapFileError, "'mode'"),
        # origin with two numbers
        ("image: IMAGE\nresolution: 0.05\norigin: [0, 0]\n", MapFileError, "'origin'"),
        # not a mapping at all
        ("- just\n- a list\n", MapFileError, "mapping"),
        # image that does not exist
        (
            "image: nothere.pgm\nresolution: 0.05\norigin: [0, 0, 0]\n",
            MapFileNotFoundError,
            "nothere",
        ),
        # no origin: map_server requires it (it used to default to 0 silently)
        ("image: IMAGE\nresolution: 0.05\n", MapFileError, "missing required key 'origin'"),
    ],
)
def test_bad_yaml_raises_named_error(
    tmp_path: Path, yaml_text: str, error: type[Exception], words: str
) -> None:
    path = _write_pair(tmp_path, np.full((3, 3), 254, np.uint8), yaml_text)
    with pytest.raises(error, match=words):
        read_map_yaml(path)


def test_missing_yaml(tmp_path: Path) -> None:
    with pytest.raises(MapFileNotFoundError, match=r"nope\.yaml"):
        read_map_yaml(tmp_path / "nope.yaml")
    with pytest.raises(FileNotFoundError):  # also the builtin, for callers who know only that
        world_from_file(tmp_path / "nope.yaml")


def test_unreadable_image(tmp_path: Path) -> None:
    (tmp_path / "m.pgm").write_bytes(b"this is not an image \x00\x01\x02" * 10)
    (tmp_path / "m.yaml").write_text(BASE.replace("IMAGE", "m.pgm"), encoding="utf-8")
    with pytest.raises(MapFileError, match="cannot decode image"):
        read_map_yaml(tmp_path / "m.yaml")


def test_empty_image_file(tmp_path: Path) -> None:
    (tmp_path / "m.pgm").write_bytes(b"")
    (tmp_path / "m.yaml").write_text(BASE.replace("IMAGE", "m.pgm"), encoding="utf-8")
    with pytest.raises(MapFileError, match="cannot decode image"):
        read_map_yaml(tmp_path / "m.yaml")


def test_world_with_no_free_cell(tmp_path: Path) -> None:
    path = _write_pair(tmp_path, np.full((5, 5), 205, np.uint8), BASE)  # all unknown
    with pytest.raises(WorldError, match="no free cell"):
        world_from_file(path)


@pytest.mark.parametrize(
    ("kwargs", "words"),
    [
        ({"resolution_m": -1.0}, "resolution_m"),  # negative resolution
        ({"resolution_m": float("nan")}, "resolution_m"),  # NaN resolution
        ({"resolution_m": 0.05, "image_format": "jpg"}, "image_format"),  # lossy format refused
        ({"resolution_m": 0.05, "origin_m": (0.0, float("inf"))}, "origin_m"),  # infinite origin
    ],
)
def test_writer_rejects_bad_values(tmp_path: Path, kwargs: dict, words: str) -> None:
    with pytest.raises(MapFileError, match=words):
        write_map_yaml(tmp_path / "x.yaml", np.zeros((2, 2), np.int8), **kwargs)


def test_world_to_file_of_generated_world(tmp_path: Path) -> None:
    walls = np.ones((5, 6), bool)
    walls[1:4, 1:5] = False
    path = world_to_file(World(walls, 0.1, (2.0, 3.0), "tiny"), tmp_path / "t.yaml")
    occ = read_map_yaml(path)
    assert occ.grid.tolist() == np.where(walls, OCCUPIED, FREE).tolist()
    assert occ.origin_m == (2.0, 3.0, 0.0)
