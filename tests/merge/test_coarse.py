"""The coarse translation search's building blocks against plain numpy references."""

from __future__ import annotations

import numpy as np
import pytest

from mrexplore import kernels
from mrexplore.grid import FREE_THRESHOLD, OCCUPIED_THRESHOLD
from mrexplore.merge.coarse import CoarseMatcher, _correlation, _pool, _spectrum


def _pool_reference(grid: np.ndarray, s: int) -> tuple[np.ndarray, np.ndarray]:
    """Block any-wall / all-free by a loop over blocks (cells past the edge: neither)."""
    h, w = grid.shape
    H, W = -(-h // s), -(-w // s)
    wall = np.zeros((H, W), dtype=np.float32)
    free = np.zeros((H, W), dtype=np.float32)
    for r in range(H):
        for c in range(W):
            block = grid[r * s : r * s + s, c * s : c * s + s]
            wall[r, c] = (block >= OCCUPIED_THRESHOLD).any()
            full = block.shape == (s, s)
            free[r, c] = full and bool(((block >= 0) & (block <= FREE_THRESHOLD)).all())
    return wall, free


@pytest.mark.parametrize("compiled", [True, False])
@pytest.mark.parametrize("s", [1, 2, 3, 4, 7, 16, 17, 32])
def test_pool_is_block_any_wall_and_all_free(
    s: int, compiled: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Both paths: the compiled one pass and OpenCV's padding, ``inRange`` and resizes."""
    if compiled and not kernels.HAVE_NUMBA:
        pytest.skip("numba is not installed")
    monkeypatch.setattr(kernels, "USE_NUMBA", compiled)
    rng = np.random.default_rng(s)
    values = np.array([-1, 0, FREE_THRESHOLD, FREE_THRESHOLD + 1, OCCUPIED_THRESHOLD - 1,
                       OCCUPIED_THRESHOLD, 100], dtype=np.int8)  # fmt: skip
    for k in range(6):
        h, w = (int(x) for x in rng.integers(1, 4 * s + 40, 2))
        grid = rng.choice(values, (h, w)).astype(np.int8)
        if k == 1:  # one unknown cell among free ones: that block is no longer all free
            grid[:] = 0
            grid[rng.integers(h), rng.integers(w)] = -1
        if k == 2:  # one wall cell among unknown ones: that block holds a wall
            grid[:] = -1
            grid[rng.integers(h), rng.integers(w)] = 100
        got, want = _pool(grid, s), _pool_reference(grid, s)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])


@pytest.mark.parametrize("shape", [(45, 60), (45, 75), (64, 81)])  # odd and even sides
def test_correlation_is_the_circular_cross_correlation(shape: tuple[int, int]) -> None:
    """sum_x a(x + t) b(x) over the padded canvas, summed over pairs (numpy's FFT as reference)."""
    rng = np.random.default_rng(0)
    a1, a2 = rng.random((30, 41)), rng.random((30, 41))
    b1, b2 = rng.random((20, 33)), rng.random((20, 33))
    got = _correlation(
        (_spectrum(a1, shape), _spectrum(b1, shape)), (_spectrum(a2, shape), _spectrum(b2, shape))
    )

    def ref(a: np.ndarray, b: np.ndarray) -> np.ndarray:
        fa, fb = np.fft.rfft2(a, shape), np.fft.rfft2(b, shape)
        return np.fft.irfft2(fa * np.conj(fb), shape)

    np.testing.assert_allclose(got, ref(a1, b1) + ref(a2, b2), atol=1e-9)
    # one translation by hand: t = (2, 3) puts b's (r, c) on a's (r + 2, c + 3)
    pa = np.zeros(shape)
    pa[:30, :41] = a1
    pb = np.zeros(shape)
    pb[:20, :33] = b1
    assert got[2, 3] - ref(a2, b2)[2, 3] == pytest.approx(
        float((np.roll(pa, (-2, -3), (0, 1)) * pb).sum())
    )


def _office_pair(seed: int) -> tuple[np.ndarray, np.ndarray]:
    from mrexplore.studies.merge_cases import real_map_case
    from mrexplore.world import symmetric_office

    rng = np.random.default_rng(seed)
    world = symmetric_office(rng, width_m=16.0, height_m=16.0)
    full = np.where(world.walls, 100, 0).astype(np.int8)
    case = real_map_case(full, rng, crop=(200, 200), name="office")
    return case.a, case.b


@pytest.mark.skipif(not kernels.HAVE_NUMBA, reason="numba is not installed")
@pytest.mark.parametrize("seed", [0, 1, 2])
def test_compiled_coarse_peaks_equal_the_numpy_path(
    seed: int, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The compiled pooling and ratio score give the same peaks, scores bit for bit, as the
    OpenCV and numpy path, on rotated crops of an office floor and on b turned by 0-3 quarter
    turns (blocks cut by the edges, sides not a multiple of the block)."""
    from mrexplore.kernels.merging import ratio_scores

    a, b = _office_pair(seed)
    for quarter in range(4):
        bq = np.ascontiguousarray(np.rot90(b, quarter))
        for scale in (3, 4):
            got, want = [], []
            for use, out in ((True, got), (False, want)):
                monkeypatch.setattr(kernels, "USE_NUMBA", use)
                matcher = CoarseMatcher(a, scale, bq.shape, 0.2, 1.0, 2.0)
                out.append(matcher.peaks(bq, 12))
            assert got == want and len(got[0]) == 12
    # the score itself, on raw correlations with FFT noise, negative noise and ties of -0.0
    rng = np.random.default_rng(seed)
    ag = rng.integers(0, 400, (50, 60)) + rng.normal(0, 1e-9, (50, 60))
    ds = rng.integers(0, 400, (50, 60)) + rng.normal(0, 1e-9, (50, 60))
    ag[:5] = -1e-12
    ds[5:10] = -0.0
    want = np.maximum(np.rint(ds), 0.0)
    a0 = np.maximum(np.rint(ag), 0.0)
    want += a0
    want += 2.0
    np.divide(a0, want, out=want)
    np.power(want, 2.0, out=want)
    np.multiply(a0, want, out=want)
    want = np.round(want, 6).astype(np.float32)
    assert ratio_scores(ag, ds).tobytes() == want.tobytes()


def test_peaks_of_the_map_itself_reuse_its_spectra() -> None:
    """``peaks(None, k)`` (a's repeats, from a's own spectra) gives exactly the peaks of
    ``peaks(a, k)``; the linear score has no such shortcut and says so."""
    rng = np.random.default_rng(3)
    a = np.where(rng.random((90, 130)) < 0.1, 100, 0).astype(np.int8)
    a[:, 100:] = -1
    m = CoarseMatcher(a, 4, a.shape, w_free=0.0, ratio_power=2.0)
    assert m.peaks(None, 20) == m.peaks(a, 20)
    with pytest.raises(ValueError, match="ratio score"):
        CoarseMatcher(a, 4, a.shape, w_free=0.2).peaks(None, 5)
