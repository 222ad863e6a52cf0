"""What pins a merge's pose: cross support, lone pins and the agreeing walls' area."""

from __future__ import annotations

import numpy as np
import pytest

from mrexplore.grid import FREE, OCCUPIED, UNKNOWN
from mrexplore.merge.common import translation


def test_cross_support_is_zero_along_one_wall_and_large_at_a_corner() -> None:
    """A pose resting on one straight wall (even a long, bumpy, slanted one) leaves a slide along
    it free; a corner pins it."""
    import cv2

    from mrexplore.merge.pinning import cross_support

    wall = np.zeros((200, 200), np.uint8)
    cv2.line(wall, (20, 30), (180, 150), 1, 1)  # a slanted staircase wall
    wall[88:90, 100] = 1  # a bump
    one = wall.astype(bool)
    assert cross_support(one, one, np.eye(3)) < 3.0
    corner = one.copy()
    corner[150:190, 180] = True  # a second wall, across the first
    assert cross_support(corner, corner, np.eye(3)) > 20.0


def test_cross_support_on_a_window_equals_the_whole_map(
    office_pair: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    """cross_support filters only a window around b's landed walls: the tensor there is the
    whole map's (equal up to float32 rounding of the filters)."""
    import cv2

    from mrexplore.grid import make_transform
    from mrexplore.merge.pinning import cross_support

    def whole(wall_a: np.ndarray, wall_b: np.ndarray, T: np.ndarray) -> float:
        img = cv2.GaussianBlur(wall_a.astype(np.float32), (0, 0), 1.0)
        gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3)
        gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3)
        j = [cv2.GaussianBlur(p, (0, 0), 4.0) for p in (gx * gx, gy * gy, gx * gy)]
        rb, cb = np.nonzero(wall_b)
        c = np.rint(T[0, 0] * cb + T[0, 1] * rb + T[0, 2]).astype(np.int64)
        r = np.rint(T[1, 0] * cb + T[1, 1] * rb + T[1, 2]).astype(np.int64)
        h, w = wall_a.shape
        ok = (c >= 0) & (c < w) & (r >= 0) & (r < h)
        near = cv2.dilate(wall_a.view(np.uint8), np.ones((3, 3), np.uint8)).astype(bool)
        ok[ok] = near[r[ok], c[ok]]
        ang = 0.5 * np.arctan2(2.0 * j[2][r[ok], c[ok]], j[0][r[ok], c[ok]] - j[1][r[ok], c[ok]])
        u = np.stack([np.cos(ang), np.sin(ang)], axis=1).astype(np.float64)
        return float(np.linalg.eigvalsh(u.T @ u)[0]) if ok.any() else 0.0

    a, b, T_ab = office_pair
    wa, wb = a >= OCCUPIED, b >= OCCUPIED
    rng = np.random.default_rng(0)
    poses = [np.asarray(T_ab)] + [
        make_transform(rng.uniform(-3, 3), rng.uniform(-40, 200), rng.uniform(-40, 200))
        for _ in range(10)
    ]
    for T in poses:
        assert cross_support(wa, wb, T) == pytest.approx(whole(wa, wb, T), rel=1e-5, abs=1e-6)


def test_agreeing_area_is_the_smallest_rectangle_of_the_agreeing_walls() -> None:
    """Walls that agree both ways count (b's on a's walls or within a cell of them, and a's on
    b's); a wall of b over a's open floor does not."""
    from mrexplore.merge.common import MapCodes
    from mrexplore.merge.pinning import agreeing_area

    a = np.full((80, 80), FREE, dtype=np.int8)
    a[10, 10:41] = OCCUPIED  # an L of walls: 30 cells along row 10, 20 down column 40
    a[10:31, 40] = OCCUPIED
    a[:, 70:] = UNKNOWN
    same = agreeing_area(MapCodes(a), MapCodes(a), np.eye(3))
    assert same == pytest.approx(30 * 20)
    b = np.full((80, 80), FREE, dtype=np.int8)
    b[10:12, 10:41] = OCCUPIED  # the L's arm along row 10, two cells thick, and a wall of b
    b[40, 10:30] = OCCUPIED  # over a's open floor (row 40)
    arm = agreeing_area(MapCodes(a), MapCodes(b), np.eye(3))
    # the arm only, rows 10-12 (a's column 40 meets b's arm within a cell down to row 12)
    assert arm == pytest.approx(30 * 2)
    assert agreeing_area(MapCodes(a), MapCodes(b), translation(0.0, 25.0)) == 0.0


def test_agreeing_area_equals_opencvs_smallest_rectangle() -> None:
    """Random wall blobs, a map against itself: the area is OpenCV's ``minAreaRect``'s of the
    wall cells."""
    import cv2

    from mrexplore.merge.common import MapCodes
    from mrexplore.merge.pinning import agreeing_area

    rng = np.random.default_rng(3)
    for _ in range(30):
        grid = np.full((300, 300), FREE, dtype=np.int8)
        centre = rng.uniform(100, 200, size=2)
        spread = rng.uniform(2, 40, size=2)
        for _ in range(int(rng.integers(2, 12))):
            c, r = np.clip(np.rint(centre + rng.normal(size=2) * spread), 2, 296).astype(int)
            grid[r - 1 : r + 2, c - 1 : c + 2] = OCCUPIED  # 3 x 3 blocks: every cell reliable
        rows, cols = np.nonzero(grid == OCCUPIED)
        pts = np.stack([cols, rows], axis=1).astype(np.float32)
        (_, _), (w, h), _ = cv2.minAreaRect(pts)
        codes = MapCodes(grid)
        assert agreeing_area(codes, codes, np.eye(3)) == pytest.approx(w * h, rel=1e-4)


def test_lone_pin_support_leaves_out_one_small_thing() -> None:
    """Two long parallel walls (rack sides) pin a pose across them only; a post beside them pins
    it along. Left out, the post takes the pin with it; with two posts, either one still pins."""
    from mrexplore.merge.common import MapCodes
    from mrexplore.merge.pinning import cross_support, lone_pin_support
    from mrexplore.merge.repeats import Structures

    g = np.full((120, 300), FREE, dtype=np.int8)
    g[30:32, 10:290] = OCCUPIED
    g[80:82, 10:290] = OCCUPIED
    g[50:60, 100:110] = OCCUPIED  # a 0.5 m post (10 cells at 0.05 m)
    wall = g >= OCCUPIED
    assert cross_support(wall, wall, np.eye(3), precise=True) > 10.0
    lone = lone_pin_support(wall, wall, np.eye(3), Structures(MapCodes(g)), 30.0)
    assert lone is not None and lone[0] < 1.0
    g[50:60, 200:210] = OCCUPIED  # a second post
    wall = g >= OCCUPIED
    two = lone_pin_support(wall, wall, np.eye(3), Structures(MapCodes(g)), 30.0)
    assert two is not None and two[0] > 10.0


def test_pin_terms_shared_by_both_pin_tests_give_the_public_answers() -> None:
    """The merger computes a pose's support terms once for the cross-support and lone-pin
    tests (float32, and float64 near a threshold): the same numbers as the public functions."""
    from mrexplore.merge.common import MapCodes
    from mrexplore.merge.pinning import PinTerms, cross_support, lone_pin_support
    from mrexplore.merge.repeats import Structures

    g = np.full((120, 300), FREE, dtype=np.int8)
    g[30:32, 10:290] = OCCUPIED
    g[80:82, 10:290] = OCCUPIED
    g[50:60, 100:110] = OCCUPIED
    g[40:46, 220:260] = OCCUPIED
    wall = g >= OCCUPIED
    T = np.array([[1.0, 0.0, 1.0], [0.0, 1.0, -1.0], [0.0, 0.0, 1.0]])
    cells = np.nonzero(wall)
    structures = Structures(MapCodes(g))
    pins = PinTerms(wall, wall, T, cells)
    for precise in (False, True):
        assert pins.cross(precise) == cross_support(wall, wall, T, precise, cells)
        shared = pins.lone_pin(precise, structures, 30.0)
        alone = lone_pin_support(wall, wall, T, structures, 30.0, cells, precise=precise)
        assert shared == alone and shared is not None
    assert pins._terms(False) is pins._terms(False)  # computed once
