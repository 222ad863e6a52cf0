"""The seed paper's method: Eq. (5), Eq. (4) trusted points, Algorithm 2 correlation."""

from __future__ import annotations

import numpy as np
import pytest

from mrexplore.errors import ConfigError
from mrexplore.grid import FREE, OCCUPIED, UNKNOWN
from mrexplore.merge import merge_maps, window_size
from mrexplore.merge.paper import correlation_matrix, trusted_points, unknown_share


@pytest.mark.parametrize(
    ("corridor_m", "res_m", "alpha", "expected"),
    [
        (3.0, 0.05, 0, 60),  # the paper's example: 3 m corridor at 0.05 m/cell
        (3.0, 0.05, -10, 50),  # lower end of the paper's alpha range
        (3.0, 0.05, 10, 70),  # upper end
        (1.0, 0.05, 0, 20),  # the real-robot experiment's narrow corridor (~20 px)
        (2.0, 0.1, 1, 21),
    ],
)
def test_window_size_eq5(corridor_m: float, res_m: float, alpha: int, expected: int) -> None:
    assert window_size(corridor_m, res_m, alpha) == expected


@pytest.mark.parametrize(
    ("corridor_m", "res_m"), [(0.0, 0.05), (3.0, 0.0), (-1.0, 0.05), (0.05, 0.05)]
)
def test_window_size_rejects_bad_values(corridor_m: float, res_m: float) -> None:
    with pytest.raises(ConfigError):
        window_size(corridor_m, res_m)


def test_trusted_point_rule_on_hand_made_windows() -> None:
    g = np.full((30, 30), FREE, dtype=np.int8)
    g[:, 20:] = UNKNOWN  # right third unknown
    pts = np.array(
        [
            [5.0, 15.0],  # 5x5 window fully known -> share 0, trusted
            [18.0, 15.0],  # window cols 16..20: one of five columns unknown -> 0.2, trusted
            [19.0, 15.0],  # cols 17..21: two of five unknown -> 0.4, not trusted
            [25.0, 15.0],  # all unknown -> 1.0, not trusted
            [0.0, 0.0],  # corner: cells outside the map count as unknown: 16 of 25 -> 0.64
        ]
    )
    share = unknown_share(g, pts, 5)
    np.testing.assert_allclose(share, [0.0, 0.2, 0.4, 1.0, 16 / 25])
    assert trusted_points(g, pts, 5, max_unknown=0.3).tolist() == [True, True, False, False, False]


def test_correlation_matrix_equals_brute_force() -> None:
    rng = np.random.default_rng(3)
    X = rng.normal(size=(7, 50))
    Y = rng.normal(size=(5, 50))
    Y[2] = 2.0 * X[4] + 1.0  # perfectly correlated pair
    Y[3] = 0.0  # constant row: defined as 0
    C = correlation_matrix(X, Y)
    brute = np.zeros((7, 5))
    for i in range(7):
        for j in range(5):
            if Y[j].std() > 0:
                brute[i, j] = np.corrcoef(X[i], Y[j])[0, 1]
    np.testing.assert_allclose(C, brute, atol=1e-12)
    assert np.unravel_index(np.argmax(C), C.shape) == (4, 2)


def _rooms(h: int = 120, w: int = 160) -> np.ndarray:
    m = np.full((h, w), FREE, dtype=np.int8)
    m[[0, 1, -1, -2], :] = OCCUPIED
    m[:, [0, 1, -1, -2]] = OCCUPIED
    m[60:62, :100] = OCCUPIED
    m[20:45, 70:72] = OCCUPIED
    m[85:90, 30:55] = OCCUPIED
    m[95:118, 120:122] = OCCUPIED
    m[30:34, 120:140] = OCCUPIED
    return m


def test_paper_recovers_a_pure_translation() -> None:
    full = _rooms()
    a = full[:, :120].copy()
    b = full[:, 30:].copy()  # b's cell (c, r) is a's (c + 30, r)
    res = merge_maps(a, b, method="paper", detector="harris", window=31)
    assert res.matched, res.reason
    assert res.transform is not None
    np.testing.assert_allclose(res.transform[:2, 2], [30.0, 0.0], atol=1.0)
    np.testing.assert_allclose(res.transform[:2, :2], np.eye(2))  # translation only
    assert res.merged is not None and res.merged.shape == full.shape


@pytest.mark.parametrize("detector", ["harris", "shi-tomasi", "fast", "sift", "orb"])
def test_paper_every_detector_gives_a_valid_result(detector: str) -> None:
    full = _rooms()
    res = merge_maps(full[:, :120], full[:, 30:], method="paper", detector=detector, window=31)
    assert res.method == "paper" and res.detector == detector
    assert 0.0 <= res.score <= 1.0
    assert res.matched == (res.transform is not None)
    if not res.matched:
        assert res.reason


def test_paper_refuses_when_nothing_is_trusted() -> None:
    g = np.full((80, 80), UNKNOWN, dtype=np.int8)
    g[38:42, 10:70] = FREE  # a thin strip: every window is mostly unknown
    g[37, 10:70] = OCCUPIED
    res = merge_maps(g, g, method="paper")
    assert not res.matched and "trusted" in res.reason
