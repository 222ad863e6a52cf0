"""The compiled verifier count equals the numpy reference on real map pairs and random poses."""

from __future__ import annotations

import numpy as np
import pytest

from mrexplore import kernels
from mrexplore.kernels.merging import count_both_ways
from mrexplore.merge.common import Agreement, Verifier, translation


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


def test_compiled_shifted_count_equals_numpy_reference(
    office_pair: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    """The slide search's counts of many shifts of one pose, compiled against numpy; half-cell
    shifts put points on rounding ties (round half to even either way)."""
    from mrexplore.kernels.merging import count_shifted

    a, b, T_true = office_pair
    ver = Verifier(a, b)
    rng = np.random.default_rng(1)
    shifts = np.concatenate(
        [rng.uniform(-60, 60, (40, 2)), np.round(rng.uniform(-9, 9, (20, 2))) + 0.5]
    )
    from mrexplore.grid import map_points, rigid_inverse

    pb = np.stack(map_points(ver.points_b, T_true), axis=1)  # b's walls in a, as the slide has
    pa = np.stack(map_points(ver.points_a, rigid_inverse(T_true)), axis=1)
    for pts, codes in ((pb, ver.codes_a), (pa, ver.codes_b)):
        got = count_shifted(pts, shifts, codes)
        want = Verifier._count_many(pts, shifts, codes)
        np.testing.assert_array_equal(got[0], want[0])
        np.testing.assert_array_equal(got[1], want[1])
        assert got[0].sum() > 0 and got[1].sum() > 0


def test_many_poses_at_once_equal_one_at_a_time(
    office_pair: tuple[np.ndarray, np.ndarray, np.ndarray], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``Verifier.many`` (one kernel call for all poses) gives each pose's own agreement, a
    degenerate or non-finite pose included, with the kernels on and off."""
    a, b, T_true = office_pair
    rng = np.random.default_rng(2)
    ver = Verifier(a, b, slack=1)
    poses = [T_true, np.eye(3), np.zeros((3, 3)), np.full((3, 3), np.nan)] + [
        translation(*rng.uniform(-40, 40, 2)) @ T_true @ _rotation(rng.uniform(-0.3, 0.3))
        for _ in range(40)
    ]
    one_by_one = [ver(T) for T in poses]
    assert one_by_one[0].agree > 0 and one_by_one[2] == one_by_one[3] == Agreement(0, 0, 0.0)
    assert ver.many(np.stack(poses)) == one_by_one
    assert ver.many(np.zeros((0, 3, 3))) == []
    monkeypatch.setattr(kernels, "USE_NUMBA", False)
    assert ver.many(np.stack(poses)) == one_by_one


def test_structured_counts_equal_the_whole_map_reference(
    office_pair: tuple[np.ndarray, np.ndarray, np.ndarray], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``Verifier.structured`` (its counts from the kernel, its groups of contradictions found
    in the box around them) against the reference: numpy counts and groups labelled on the
    whole map, on poses from right to far off and group sizes from 1 to 40 cells."""
    import cv2

    from mrexplore.grid import rigid_inverse

    def runs(flat: np.ndarray, shape: tuple[int, int], min_run: int) -> int:
        if flat.size < min_run:
            return 0
        img = np.zeros(shape[0] * shape[1], dtype=np.uint8)
        img[flat] = 1
        _, _, stats, _ = cv2.connectedComponentsWithStats(img.reshape(shape), connectivity=8)
        areas = stats[1:, cv2.CC_STAT_AREA]
        return int(areas[areas >= min_run].sum())

    def reference(ver: Verifier, T: np.ndarray, min_run: int) -> Agreement:
        Ti = rigid_inverse(T)
        ab, db, nb = Verifier._count(ver.points_b, T, ver.codes_a)
        aa, da, _ = Verifier._count(ver.points_a, Ti, ver.codes_b)
        on_a = Verifier._contradictions(ver.points_b, T, ver.codes_a)
        on_b = Verifier._contradictions(ver.points_a, Ti, ver.codes_b)
        held = runs(on_a, ver.codes_a.shape, min_run) + runs(on_b, ver.codes_b.shape, min_run)
        return Agreement(ab + aa, min(db + da, held), nb / ver.points_b.shape[0])

    a, b, T_true = office_pair
    rng = np.random.default_rng(4)
    poses = [T_true] + [
        translation(*rng.uniform(-s, s, 2)) @ T_true @ _rotation(rng.uniform(-0.1, 0.1))
        for s in (1, 3, 10, 40)
        for _ in range(6)
    ]
    seen_runs = set()
    for use in (True, False):
        monkeypatch.setattr(kernels, "USE_NUMBA", use)
        for slack in (0, 2):
            ver = Verifier(a, b, slack=slack)
            for T in poses:
                for min_run in (1, 5, 40):
                    got = ver.structured(T, min_run)
                    assert got == reference(ver, T, min_run)
                    seen_runs.add(got.disagree > 0)
    assert seen_runs == {True, False}  # some poses had groups counted, some none
