"""2-D transforms of mrexplore.grid: products, inverses and point maps in plain elementwise
arithmetic (no BLAS/LAPACK), so the same bits on every CPU and for every memory layout."""

from __future__ import annotations

import numpy as np
import pytest

from mrexplore.errors import GridError
from mrexplore.grid import (
    affine_inverse,
    apply_transform,
    chain,
    invert_transform,
    make_transform,
    map_points,
    rigid_inverse,
)


def _rigid(rng: np.random.Generator) -> np.ndarray:
    return make_transform(float(rng.uniform(-np.pi, np.pi)), *rng.uniform(-500, 500, 2))


def _scaled(rng: np.random.Generator) -> np.ndarray:
    """A rigid transform times a scale in [0.25, 4] (map <-> world with two resolutions), some
    with a different scale per axis and a shear (any affine)."""
    T = _rigid(rng)
    S = np.eye(3)
    S[0, 0] = S[1, 1] = rng.uniform(0.25, 4.0)
    if rng.random() < 0.5:
        S[1, 1] = rng.uniform(0.25, 4.0)
        S[0, 1] = rng.uniform(-0.5, 0.5)
    return chain(T, S)


def _transforms(n: int, seed: int) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [_rigid(rng) for _ in range(n)] + [_scaled(rng) for _ in range(n)]


def _layouts(A: np.ndarray) -> list[np.ndarray]:
    """The same values as C-ordered, Fortran-ordered and non-contiguous (strided) arrays."""
    big = np.zeros((2 * A.shape[0], 3 * A.shape[1]))
    big[::2, ::3] = A
    strided = big[::2, ::3]
    assert not strided.flags.c_contiguous and not strided.flags.f_contiguous
    return [np.ascontiguousarray(A), np.asfortranarray(A), strided]


def test_the_affine_inverse_times_t_is_the_identity() -> None:
    for T in _transforms(50, seed=0):
        Ti = affine_inverse(T)
        np.testing.assert_allclose(chain(Ti, T), np.eye(3), rtol=0, atol=1e-12)
        np.testing.assert_allclose(chain(T, Ti), np.eye(3), rtol=0, atol=1e-12)
        assert Ti[2].tolist() == [0.0, 0.0, 1.0]
        # the merger's name for it keeps its bits
        assert rigid_inverse(T).tobytes() == Ti.tobytes()


def test_invert_transform_agrees_with_linalg() -> None:
    for T in _transforms(50, seed=1):
        np.testing.assert_allclose(invert_transform(T), np.linalg.inv(T), rtol=0, atol=1e-12)


def test_invert_transform_refuses_what_it_cannot_invert() -> None:
    projective = np.eye(3)
    projective[2, 0] = 1e-3
    singular = np.array([[1.0, 2.0, 3.0], [2.0, 4.0, 5.0], [0.0, 0.0, 1.0]])
    broken = make_transform(0.3, float("nan"), 1.0)
    for T in (projective, singular, broken, np.eye(2)):
        with pytest.raises(GridError):
            invert_transform(T)


def test_chain_agrees_with_the_matrix_product() -> None:
    Ts = _transforms(30, seed=2)
    for A, B, C in zip(Ts[::3], Ts[1::3], Ts[2::3], strict=True):
        np.testing.assert_allclose(chain(A, B, C), A @ B @ C, rtol=1e-15, atol=1e-12)


def test_apply_transform_agrees_with_the_matrix_form() -> None:
    rng = np.random.default_rng(3)
    pts = rng.uniform(-1000, 1000, (500, 2))
    for T in _transforms(10, seed=4):
        np.testing.assert_allclose(
            apply_transform(T, pts), pts @ T[:2, :2].T + T[:2, 2], rtol=0, atol=1e-12
        )
    # integer points and a single (2,) point are taken as (N, 2) float64
    T = _transforms(1, seed=5)[0]
    ints = rng.integers(-50, 50, (7, 2))
    assert apply_transform(T, ints).tolist() == apply_transform(T, ints.astype(float)).tolist()
    assert apply_transform(T, np.array([3, 4])).shape == (1, 2)


def test_the_helpers_give_the_same_bits_for_every_memory_layout() -> None:
    rng = np.random.default_rng(6)
    pts = rng.uniform(-1000, 1000, (257, 2))  # odd length: SIMD loops and their scalar tails
    Ts = _transforms(5, seed=7)

    def answers(T: np.ndarray, U: np.ndarray, p: np.ndarray) -> tuple[bytes, ...]:
        return (
            chain(T, U).tobytes(),
            affine_inverse(T).tobytes(),
            invert_transform(T).tobytes(),
            apply_transform(T, p).tobytes(),
            np.stack(map_points(p, T), axis=1).tobytes(),
        )

    for T, U in zip(Ts, Ts[::-1], strict=True):
        want = answers(T, U, pts)
        for Tl, Ul, pl in zip(_layouts(T), _layouts(U), _layouts(pts), strict=True):
            assert answers(Tl, Ul, pl) == want


def test_merge_common_still_exports_the_helpers() -> None:
    from mrexplore.merge import common

    assert common.chain is chain
    assert common.rigid_inverse is rigid_inverse
    assert common.map_points is map_points


def test_map_changes_compare_with_their_cells() -> None:
    """``MapChange`` with listed cells compares (and hashes) as a value, arrays included."""
    from mrexplore.grid import MapChange

    box = (0, 2, 0, 3)
    a = MapChange(3, box, box, np.array([1, 4], dtype=np.int64))
    assert a == MapChange(3, box, box, np.array([1, 4], dtype=np.int64))
    assert a != MapChange(3, box, box, np.array([1, 5], dtype=np.int64))
    assert a != MapChange(3, box, box) and MapChange(3, box, box) == MapChange(3, box, box)
    assert a != MapChange(4, box, box, a.cells)
    assert len({a, MapChange(3, box, box, a.cells)}) == 1
