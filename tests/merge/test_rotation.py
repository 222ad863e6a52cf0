"""Rotation candidates on large maps: the pooled walls of the segment spectrum."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrexplore.grid import OCCUPIED_THRESHOLD
from mrexplore.merge.rotation import hough_pool, pool_any, rotation_candidates
from mrexplore.studies.merge_cases import rotate_map


@pytest.mark.parametrize("f", [1, 2, 3, 5, 16])
def test_pool_any_marks_every_block_holding_a_wall(f: int) -> None:
    rng = np.random.default_rng(f)
    for _ in range(5):
        h, w = (int(x) for x in rng.integers(1, 3 * f + 30, 2))
        wall = rng.random((h, w)) < 0.02
        want = np.zeros((-(-h // f), -(-w // f)), dtype=bool)
        for r, c in zip(*np.nonzero(wall), strict=True):
            want[r // f, c // f] = True
        np.testing.assert_array_equal(pool_any(wall, f), want)


def test_hough_pool_halves_only_maps_past_the_bound() -> None:
    assert hough_pool((640, 640), (600, 600), 409_600) == 1  # at the bound: as before
    assert hough_pool((641, 640), (10, 10), 409_600) == 2  # the larger map decides
    assert hough_pool((10, 10), (3000, 3000), 409_600) == 2  # never coarser than 2 x 2
    assert hough_pool((5000, 5000), (1, 1), 0) == 1  # 0: never pooled


@pytest.mark.parametrize("pooled", [False, True])
@pytest.mark.parametrize(("turn_deg", "rel_deg"), [(23.0, 71.0), (-41.0, 12.5), (8.0, -133.0)])
def test_rotation_candidates_contain_the_truth_off_the_grid_axes(
    turn_deg: float, rel_deg: float, pooled: bool
) -> None:
    """The whole real map is turned first, so neither map has walls along the grid axes, and
    both are degraded like SLAM maps (ragged walls, speckle, a bend): the truth must still be
    within 1.5 degrees of a candidate. ``pooled``: the bound set so low that the segments come
    from walls pooled 2 x 2, as on a large map."""
    from mrexplore.studies.merge_cases import add_map_noise
    from mrexplore.world.map_io import read_map_yaml

    rng = np.random.default_rng(int(abs(turn_deg) * 10))
    envs = Path(__file__).resolve().parents[2] / "envs"
    full, _ = rotate_map(read_map_yaml(envs / "tb3_office.yaml").grid, np.radians(turn_deg))
    h, w = full.shape
    a = add_map_noise(full[h // 4 : 3 * h // 4, w // 4 : 3 * w // 4].copy(), rng)
    b, _ = rotate_map(
        add_map_noise(full[h // 3 : 5 * h // 6, w // 5 : 3 * w // 4].copy(), rng),
        np.radians(rel_deg),
    )
    wa, wb = a >= OCCUPIED_THRESHOLD, b >= OCCUPIED_THRESHOLD
    cap = max(wa.size, wb.size) - 1 if pooled else 0
    assert hough_pool(wa.shape, wb.shape, cap) == (2 if pooled else 1)
    cands = np.degrees(rotation_candidates(wa, wb, hough_max_cells=cap))
    # b = rotate(crop) by rel: the rotation mapping b into a is -rel
    err = np.abs((cands + rel_deg + 180.0) % 360.0 - 180.0)
    assert err.min() <= 1.5, (cands, -rel_deg)
