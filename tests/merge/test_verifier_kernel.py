"""The compiled verifier count equals the numpy reference on real map pairs and random poses."""

from __future__ import annotations

import numpy as np

from mrexplore.kernels.merging import count_both_ways
from mrexplore.merge.common import Verifier, translation


def _rotation(theta: float) -> np.ndarray:
    c, s = np.cos(theta), np.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_compiled_count_equals_numpy_reference(
    office_pair: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    a, b, T_true = office_pair
    rng = np.random.default_rng(0)
    ver = Verifier(a, b)
    poses = [T_true, np.eye(3)] + [
        translation(*rng.uniform(-40, 40, 2)) @ T_true @ _rotation(rng.uniform(-0.3, 0.3))
        for _ in range(50)
    ]
    for T in poses:
        got = count_both_ways(ver.points_b, ver.points_a, T, ver.codes_a, ver.codes_b)
        ab, db, nb = Verifier._count(ver.points_b, T, ver.codes_a)
        aa, da, _ = Verifier._count(ver.points_a, np.linalg.inv(T), ver.codes_b)
        assert got == (ab, db, nb, aa, da)
