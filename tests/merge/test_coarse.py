"""The coarse translation search's building blocks against plain numpy references."""

from __future__ import annotations

import numpy as np
import pytest

from mrexplore.grid import FREE_THRESHOLD, OCCUPIED_THRESHOLD
from mrexplore.merge.coarse import _correlation, _pool, _spectrum


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


@pytest.mark.parametrize("s", [1, 2, 3, 4, 7, 16, 17, 32])
def test_pool_is_block_any_wall_and_all_free(s: int) -> None:
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
