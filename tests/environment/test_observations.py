"""Observation images: what is ahead of the robot, in map-frame and heading-up views."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mrexplore.environment.observations import ObservationBuilder
from mrexplore.grid import FREE, OCCUPIED, UNKNOWN
from mrexplore.types import RobotView


def _view(theta: float) -> RobotView:
    """A robot at (100, 100) in a known free square with one wall 30 cells to its +col side."""
    m = np.full((200, 200), UNKNOWN, dtype=np.int8)
    m[40:160, 40:160] = FREE
    m[60:140, 130:134] = OCCUPIED  # the wall, at +col of the robot
    return RobotView("robot_0", m, 0.05, (100.0, 100.0, theta), 0.15)


def _wall_centroid(obs: np.ndarray) -> tuple[float, float]:
    rows, cols = np.nonzero(obs[5] > 64)  # fine view, occupied share
    return float(cols.mean()), float(rows.mean())


@pytest.mark.parametrize(
    ("heading_up", "theta", "expect"),
    [
        (False, 0.0, "+col"),  # map frame: the wall stays at +col whatever the heading
        (False, 2.0, "+col"),
        (True, 0.0, "+row"),  # heading up, facing the wall: it is ahead, at +row
        (True, math.pi / 2, "+col"),  # already facing +row: nothing turns, the wall stays right
        (True, -math.pi / 2, "-col"),  # facing -row: the view turns half round, the wall to -col
        (True, math.pi, "-row"),  # facing away from the wall: it is behind
    ],
)
def test_the_wall_appears_where_it_is(heading_up: bool, theta: float, expect: str) -> None:
    b = ObservationBuilder(0.05, 12.8, 6.4, 64, heading_up=heading_up)
    obs = b.build(_view(theta), np.zeros((0, 2)))
    assert obs.shape == (8, 64, 64) and obs.dtype == np.uint8
    cx, cy = _wall_centroid(obs)
    dx, dy = cx - 31.5, cy - 31.5
    axis = {"+col": dx, "-col": -dx, "+row": dy, "-row": -dy}[expect]
    assert axis > 10 and abs(dx if expect.endswith("row") else dy) < 4, (cx, cy)


def test_heading_up_keeps_the_robot_marker_fixed() -> None:
    b = ObservationBuilder(0.05, 12.8, 6.4, 64, heading_up=True)
    markers = {b.build(_view(t), np.zeros((0, 2)))[6].tobytes() for t in (0.0, 1.0, -2.5)}
    assert len(markers) == 1


@pytest.mark.parametrize(
    ("resolution_m", "global_m", "local_m", "size"),
    [
        (0.05, 25.6, 6.4, 64),  # the defaults: factors 4 (every second cell) and 2
        (0.1, 25.6, 6.4, 64),  # Explore-Bench's resolution: factors 2 and 1
        (0.05, 25.6, 6.4, 48),  # no integer factor: the OpenCV path
        (0.05, 4.0, 1.0, 32),  # a fine view smaller than the image: nearest neighbour, OpenCV
    ],
)
def test_compiled_shares_equal_the_opencv_path(
    resolution_m: float, global_m: float, local_m: float, size: int
) -> None:
    """The one-pass compiled shares give OpenCV's inRange + INTER_AREA values exactly, for
    windows inside the map, across its border and outside it, in noisy maps with every value."""
    from mrexplore.environment.observations import _shares, _window

    rng = np.random.default_rng(1)
    m = rng.choice(
        np.array([UNKNOWN, FREE, 10, 25, 26, 50, 64, 65, OCCUPIED], dtype=np.int8), (700, 650)
    )
    m[rng.random(m.shape) < 0.5] = UNKNOWN
    # the same map known only inside a box (read only there when the box is given)
    inner = np.full_like(m, UNKNOWN)
    inner[201:437, 117:390] = m[201:437, 117:390]
    whole = np.array([0, 700, 0, 650], dtype=np.int64)
    cases = [
        (m, whole),
        (inner, whole),
        (inner, np.array([201, 437, 117, 390], dtype=np.int64)),
        (inner, np.array([199, 440, 116, 391], dtype=np.int64)),
        # the known box on the map's edges, and past them (read only inside the map)
        (m, np.array([0, 700, 0, 650], dtype=np.int64) + np.array([-9, 9, -9, 9])),
        (np.full_like(m, UNKNOWN), np.zeros(4, dtype=np.int64)),  # nothing known
    ]
    b = ObservationBuilder(resolution_m, global_m, local_m, size)
    for side in (b.global_cells, b.local_cells, 3 * b.global_cells // 2, 3 * b.local_cells // 2):
        n = size if side in (b.global_cells, b.local_cells) else 3 * size // 2
        for centre in [
            (325.0, 350.0),
            (10.4, 690.6),
            (640.5, 2.5),
            (-300.0, 200.0),
            (3.5, 4.5),
            (118.5, 436.5),
            (395.0, 190.0),
        ]:
            for grid, known in cases:
                free = np.zeros((n, n), np.uint8)
                occ = np.zeros((n, n), np.uint8)
                b._shares_into(grid, centre, side, free, occ, known)
                ref = _shares(_window(grid, centre, side), n)
                np.testing.assert_array_equal(free, ref[0])
                np.testing.assert_array_equal(occ, ref[1])


def test_compiled_shares_on_small_maps_equal_the_opencv_path() -> None:
    """Maps a few cells wide, smaller than the window and than one block: the blocks that cross
    both side edges at once are summed as OpenCV's path does."""
    from mrexplore.environment.observations import _shares, _window

    rng = np.random.default_rng(3)
    values = np.array([UNKNOWN, FREE, 25, 50, 65, OCCUPIED], dtype=np.int8)
    b = ObservationBuilder(0.05, 12.8, 3.2, 32)
    for _ in range(60):
        h, w = (int(v) for v in rng.integers(1, 12, 2))
        grid = rng.choice(values, (h, w))
        for side in (b.global_cells, b.local_cells):
            centre = (float(rng.uniform(-side, w + side)), float(rng.uniform(-side, h + side)))
            free = np.zeros((32, 32), np.uint8)
            occ = np.zeros((32, 32), np.uint8)
            b._shares_into(grid, centre, side, free, occ, np.array([0, h, 0, w], np.int64))
            ref = _shares(_window(grid, centre, side), 32)
            np.testing.assert_array_equal(free, ref[0])
            np.testing.assert_array_equal(occ, ref[1])


def test_few_dots_mark_what_the_numpy_path_marks() -> None:
    # up to _FEW_DOTS points (teammates) are marked in plain Python; the same points repeated
    # past that count take the numpy path and must mark the same pixels
    from mrexplore.environment.observations import _FEW_DOTS

    rng = np.random.default_rng(5)
    b = ObservationBuilder(0.05, 25.6, 6.4, 64)
    for k in range(200):
        n = int(rng.integers(1, _FEW_DOTS + 1))
        cells = rng.uniform(100.0, 700.0, (n, 2))
        if k % 3 == 0:
            cells = np.round(cells * 8.0) / 8.0  # on pixel boundaries
        centre = (float(rng.uniform(300, 500)), float(rng.uniform(300, 500)))
        phi = 0.0 if k % 2 else float(rng.uniform(-np.pi, np.pi))
        radius = int(k % 4 == 0) * 2
        few = np.zeros((64, 64), np.uint8)
        many = np.zeros((64, 64), np.uint8)
        b._dots(few, [tuple(c) for c in cells], centre, 64 / 512, phi, radius)
        b._dots(many, np.tile(cells, (_FEW_DOTS + 1, 1)), centre, 64 / 512, phi, radius)
        np.testing.assert_array_equal(few, many)
        assert few.any() or not ((np.abs(cells - centre) < 250).all())


def test_compiled_trail_equals_the_numpy_drawing() -> None:
    from mrexplore.kernels import views

    rng = np.random.default_rng(2)
    b = ObservationBuilder(0.05, 25.6, 6.4, 64)
    cells = rng.uniform(-100.0, 900.0, (3000, 2))
    cells[:50] = np.round(cells[:50] * 8.0) / 8.0  # on pixel boundaries
    for centre in [(400.0, 400.0), (412.5, 398.75), (0.0, 0.0)]:
        a = np.zeros((64, 64), np.uint8)
        ref = np.zeros((64, 64), np.uint8)
        views.trail_dots(a, cells, centre[0], centre[1], 64 / 512)
        b._dots(ref, cells, centre, 64 / 512, 0.0, radius=0)
        np.testing.assert_array_equal(a, ref)


def test_compiled_turned_trail_equals_the_numpy_drawing() -> None:
    """Heading-up views: the trail turned with the view, pixel for pixel as numpy draws it,
    cells on pixel boundaries too."""
    import math

    from mrexplore.kernels import views

    rng = np.random.default_rng(4)
    b = ObservationBuilder(0.05, 25.6, 6.4, 64)
    cells = rng.uniform(-100.0, 900.0, (3000, 2))
    cells[:50] = np.round(cells[:50] * 8.0) / 8.0
    for phi in (math.pi / 2, -math.pi / 2, math.pi, 0.3, -2.9, 1e-9):
        for centre in [(400.0, 400.0), (412.5, 398.75), (0.0, 0.0)]:
            a = np.zeros((64, 64), np.uint8)
            ref = np.zeros((64, 64), np.uint8)
            views.turned_trail_dots(
                a, cells, centre[0], centre[1], 64 / 512, math.cos(phi), math.sin(phi)
            )
            b._dots(ref, cells, centre, 64 / 512, phi, radius=0)
            np.testing.assert_array_equal(a, ref)
            assert ref.any()
