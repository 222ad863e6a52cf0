"""The merger's CPU-independent arithmetic: transform products and inverses without
BLAS, the exact integer blur of the rotation spectrum, rounded rotation candidates."""

from __future__ import annotations

import math

import numpy as np

from mrexplore.grid import make_transform
from mrexplore.merge.common import chain, map_points, rigid_inverse, translation
from mrexplore.merge.rotation import (
    CANDIDATE_DECIMALS,
    _integer_gaussian,
    rotation_candidates,
    wall_normals,
)


def _random_transforms(n: int, seed: int = 0) -> list[np.ndarray]:
    rng = np.random.default_rng(seed)
    return [
        make_transform(float(rng.uniform(-np.pi, np.pi)), *rng.uniform(-500, 500, 2))
        for _ in range(n)
    ]


def test_chain_equals_the_matrix_product() -> None:
    Ts = _random_transforms(30)
    for A, B, C in zip(Ts[::3], Ts[1::3], Ts[2::3], strict=True):
        np.testing.assert_allclose(chain(A, B, C), A @ B @ C, rtol=0, atol=1e-9)
        assert chain(A).tolist() == A.tolist()


def test_chain_of_3x3_has_the_bits_of_the_elementwise_formula() -> None:
    # chain's Python-float path for 3 x 3 against the numpy formula it replaced, on
    # transforms of many magnitudes, with -0.0, inf and NaN entries
    def reference(*Ts: np.ndarray) -> np.ndarray:
        out = np.asarray(Ts[0], dtype=np.float64)
        for B in Ts[1:]:
            out = out[:, 0:1] * B[0:1, :] + out[:, 1:2] * B[1:2, :] + out[:, 2:3] * B[2:3, :]
        return out

    rng = np.random.default_rng(7)
    specials = [-0.0, 0.0, np.inf, -np.inf, np.nan, 1e-300, 1e300]
    for k in range(3000):
        Ts = [
            rng.normal(size=(3, 3)) * 10 ** rng.uniform(-4, 5, (3, 3))
            for _ in range(int(rng.integers(2, 5)))
        ]
        if k % 5 == 0:
            Ts[0][2] = [0.0, 0.0, 1.0]
        if k % 11 == 0:
            Ts[-1][int(rng.integers(3)), int(rng.integers(3))] = specials[k % len(specials)]
        with np.errstate(all="ignore"):
            assert chain(*Ts).tobytes() == reference(*Ts).tobytes()


def test_chain_each_has_the_bits_of_chain() -> None:
    # stacks against one, one against stacks and stacks against stacks (broadcast, as the
    # consistency polish's grid of shifts x turns is made), with -0.0, inf and NaN entries
    from mrexplore.grid import chain_each

    rng = np.random.default_rng(8)
    specials = [-0.0, 0.0, np.inf, -np.inf, np.nan, 1e-300, 1e300]
    A = rng.normal(size=(40, 3, 3)) * 10 ** rng.uniform(-4, 5, (40, 3, 3))
    B = rng.normal(size=(40, 3, 3)) * 10 ** rng.uniform(-4, 5, (40, 3, 3))
    for k in range(0, 40, 3):
        A[k, k % 3, (k // 3) % 3] = specials[k % len(specials)]
    C = np.stack(_random_transforms(5, seed=3))
    with np.errstate(all="ignore"):
        for k in range(40):
            assert chain_each(A, B)[k].tobytes() == chain(A[k], B[k]).tobytes()
            assert chain_each(A, B[0])[k].tobytes() == chain(A[k], B[0]).tobytes()
            assert chain_each(A[0], B)[k].tobytes() == chain(A[0], B[k]).tobytes()
        grid = chain_each(A[None], C[:, None])
        assert grid.shape == (5, 40, 3, 3)
        for t in range(5):
            for k in range(40):
                assert grid[t, k].tobytes() == chain(A[k], C[t]).tobytes()


def test_rigid_inverse_inverts() -> None:
    for T in _random_transforms(20, seed=1):
        np.testing.assert_allclose(chain(T, rigid_inverse(T)), np.eye(3), rtol=0, atol=1e-12)
        np.testing.assert_allclose(rigid_inverse(T), np.linalg.inv(T), rtol=0, atol=1e-9)


def test_map_points_equals_the_matrix_form() -> None:
    T = _random_transforms(1, seed=2)[0]
    pts = np.random.default_rng(3).uniform(0, 300, (100, 2))
    x, y = map_points(pts, T)
    np.testing.assert_allclose(np.stack([x, y], 1), pts @ T[:2, :2].T + T[:2, 2], atol=1e-9)


def test_translations_compose_exactly() -> None:
    T = _random_transforms(1, seed=4)[0]
    assert chain(translation(3, -7), T)[:2, :2].tolist() == T[:2, :2].tolist()


def test_the_blurred_gradients_are_exact_integers() -> None:
    k = _integer_gaussian(2.5)
    assert k.shape[1] == 1 and np.all(k == np.rint(k)) and abs(k.sum() - 1024) <= 2
    wall = np.zeros((60, 60), dtype=bool)
    wall[10:50, 20] = wall[30, 5:55] = True
    deg, mag = wall_normals(wall)
    assert deg.dtype == np.float64 and mag.size == deg.size > 0
    # directions are rounded to a grid far coarser than the last-bit noise of arctan2
    np.testing.assert_array_equal(deg, np.round(deg, 6))


def test_rotation_candidates_lie_on_their_grid() -> None:
    wall = np.zeros((80, 80), dtype=bool)
    wall[10:70, 15] = wall[10:70, 60] = wall[12, 15:61] = True
    rot = np.zeros_like(wall)
    rot[10:70, 20] = rot[10:70, 65] = rot[40, 20:66] = True
    for t in rotation_candidates(wall, rot):
        d = math.degrees(t)
        assert -180.0 < d <= 180.0
        assert abs(d * 10**CANDIDATE_DECIMALS - round(d * 10**CANDIDATE_DECIMALS)) < 1e-6


def test_cross_support_fast_and_precise_agree() -> None:
    from mrexplore.merge.pinning import cross_support

    wall = np.zeros((90, 90), dtype=bool)
    wall[10:80, 10] = wall[10, 10:80] = wall[10:80, 79] = True  # a room corner and a far wall
    T = np.eye(3)  # the identity: every wall lands on itself
    fast = cross_support(wall, wall, T)
    precise = cross_support(wall, wall, T, precise=True)
    assert precise > 10.0  # a corner pins the pose
    assert abs(fast - precise) < 1e-3  # float32 is far inside the guard band of one cell
