"""The compiled places (level sweep by one union-find, growth by fronts) equal the OpenCV/numpy
path (``kernels.USE_NUMBA = False``) label for label, on maps of the merge bench's families and
on random maps; and the merger's answers with the place test are the same either way."""

from __future__ import annotations

import numpy as np
import pytest

from mrexplore import kernels
from mrexplore.grid import FREE, OCCUPIED, UNKNOWN
from mrexplore.merge import merge_maps, places
from mrexplore.merge.places import Places, segment_places
from mrexplore.studies.merge_bench import make_cases

pytestmark = pytest.mark.skipif(not kernels.HAVE_NUMBA, reason="numba not installed")


def _both(grid: np.ndarray, monkeypatch: pytest.MonkeyPatch) -> tuple[Places, Places]:
    out = []
    for use in (False, True):
        monkeypatch.setattr(kernels, "USE_NUMBA", use)
        out.append(segment_places(grid))
    return out[0], out[1]


def _same(ref: Places, got: Places) -> None:
    assert got.count == ref.count
    assert got.labels.dtype == ref.labels.dtype and np.array_equal(got.labels, ref.labels)
    assert np.array_equal(got.peaks, ref.peaks)


@pytest.mark.parametrize("family", ["symmetric", "real", "noisy", "aliased"])
def test_places_equal_on_bench_maps(family: str, monkeypatch: pytest.MonkeyPatch) -> None:
    for case in make_cases(family, 2, 0):
        for grid in (case.a, case.b):
            _same(*_both(grid, monkeypatch))


def test_places_equal_on_random_maps(monkeypatch: pytest.MonkeyPatch) -> None:
    """Blobs of free space with walls, clutter and unknown holes: many components per level,
    components whose first cell and first 2 x 2 block disagree on their order."""
    import cv2

    rng = np.random.default_rng(7)
    for _ in range(20):
        h, w = (int(v) for v in rng.integers(40, 160, 2))
        m = np.full((h, w), UNKNOWN, np.int8)
        for _ in range(int(rng.integers(3, 12))):
            c, r = int(rng.integers(0, w)), int(rng.integers(0, h))
            ax = (int(rng.integers(3, 30)), int(rng.integers(3, 30)))
            cv2.ellipse(m, (c, r), ax, float(rng.uniform(0, 180)), 0, 360, FREE, -1)
        m[rng.random((h, w)) < 0.02] = OCCUPIED
        m[rng.random((h, w)) < 0.01] = UNKNOWN
        _same(*_both(m, monkeypatch))


def test_level_batches_find_the_first_level_each_cell_reaches() -> None:
    """Each cell's first level (the ladder searched by bisection) is the first level of the
    falling ladder it reaches, in float32, also for values equal to a level, between levels and
    under or over them all; and the cells are listed level by level in raster order."""
    from mrexplore.kernels import merging

    rng = np.random.default_rng(3)
    levels = (12.5 * 0.85 ** np.arange(16)).astype(np.float32)
    values = np.concatenate(
        [levels, np.nextafter(levels, np.float32(0)), rng.uniform(0, 14, 400), [0.0, 99.0]]
    ).astype(np.float32)
    clearance = rng.permutation(values)[: 21 * 20].reshape(21, 20)
    order, starts, first = merging.level_batches(clearance, levels)
    reached = clearance.ravel()[:, None] >= levels[None, :]
    expect = np.where(reached.any(axis=1), reached.argmax(axis=1), len(levels))
    assert np.array_equal(first, expect)
    for li in range(len(levels)):
        assert np.array_equal(order[starts[li] : starts[li + 1]], np.flatnonzero(expect == li))


@pytest.mark.expensive
def test_merges_with_the_place_test_are_the_same(monkeypatch: pytest.MonkeyPatch) -> None:
    """Only the places switched (the rest of the merger compiled on both sides: its numpy ICP
    differs in the last bits)."""
    compiled = places._merging
    for family in ("symmetric", "real", "aliased"):
        for case in make_cases(family, 2, 0):
            res = []
            for kernel_module in (None, compiled):
                monkeypatch.setattr(places, "_merging", kernel_module)
                res.append(merge_maps(case.a, case.b, method="semantic", place_test=True))
            off, on = res
            assert on.matched == off.matched and on.reason == off.reason
            assert (on.transform is None) == (off.transform is None)
            if on.transform is not None:
                assert np.array_equal(on.transform, off.transform)
            assert on.info.get("beyond_place_cells") == off.info.get("beyond_place_cells")
