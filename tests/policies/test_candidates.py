"""Candidate goals and their features on tiny hand-made views."""

from __future__ import annotations

import numpy as np
import pytest

from mrexplore.grid import FREE, OCCUPIED, UNKNOWN
from mrexplore.policies.candidates import (
    FAR,
    FEATURE_NAMES,
    GAIN_FEATURE_NAMES,
    GoalExecutor,
    candidate_features,
    gain_features,
    teammate_claims,
)
from mrexplore.policies.explorers import FrontierCandidates
from mrexplore.types import RobotView

COL = {n: i for i, n in enumerate(FEATURE_NAMES)}


def _view(m: np.ndarray, pose: tuple[float, float, float] = (10.0, 10.0, 0.0), **kw) -> RobotView:  # type: ignore[no-untyped-def]
    return RobotView(
        agent="robot_0", map=m, resolution_m=0.05, pose_cell=pose, robot_radius_m=0.15, **kw
    )


def _cands(n: int) -> FrontierCandidates:
    """``n`` frontiers 2 m apart along +col; the first has the longest path."""
    i = np.arange(n)
    return FrontierCandidates(
        targets=np.stack([20 + 40 * i, np.full(n, 10)], axis=1).astype(np.int64),
        size_m=0.5 + 0.1 * i,
        dist_m=np.asarray(1.0 + i, dtype=np.float64)[::-1].copy(),  # reversed: sorting matters
        goals=np.zeros((n, 2), dtype=np.int64),
    )


def test_rows_are_nearest_first_and_the_mask_marks_them() -> None:
    m = np.full((40, 300), FREE, dtype=np.int8)
    feats, mask, index = candidate_features(_cands(3), _view(m), k=5)
    assert mask.tolist() == [1, 1, 1, 0, 0]
    assert index.tolist() == [2, 1, 0, -1, -1]
    assert feats[:3, COL["path_m"]].tolist() == pytest.approx([0.1, 0.2, 0.3])
    assert feats[:3, COL["rank"]].tolist() == pytest.approx([0.0, 0.2, 0.4])
    assert not feats[3:].any()
    assert feats.dtype == np.float32 and (feats >= 0).all()
    # nobody known: teammate distances are FAR, merged 0
    assert feats[0, COL["mate_target_m"]] == FAR and feats[0, COL["merged"]] == 0


def test_no_candidate_leaves_only_wait() -> None:
    m = np.full((20, 20), FREE, dtype=np.int8)
    for cands in (None, _cands(0)):
        feats, mask, index = candidate_features(cands, _view(m), k=4)
        assert mask.tolist() == [1, 0, 0, 0] and index.tolist() == [-1] * 4
        assert not feats.any()


def test_current_target_is_kept_among_the_rows() -> None:
    m = np.full((40, 200), FREE, dtype=np.int8)
    cands = _cands(5)
    far = (int(cands.targets[0, 0]), int(cands.targets[0, 1]))  # the farthest by path
    feats, _mask, index = candidate_features(cands, _view(m), k=2, current_target=far)
    assert index.tolist() == [4, 0]
    assert feats[:, COL["is_current"]].tolist() == [0.0, 1.0]


def test_claims_and_teammates_shape_the_features() -> None:
    m = np.full((40, 200), FREE, dtype=np.int8)
    cands = _cands(2)  # targets (20, 10) and (60, 10)
    claims = np.array([[60.0, 10.0]])
    view = _view(m, merged=True, teammates={"robot_1": (60.0, 10.0)})
    feats, _, index = candidate_features(cands, view, k=2, claims=claims)
    row = {int(i): r for r, i in enumerate(index)}
    assert feats[row[1], COL["claim"]] == pytest.approx(1.0)  # on the claim: full discount
    assert feats[row[0], COL["claim"]] == pytest.approx(0.5)  # 2 m away with a 4 m range
    assert feats[row[1], COL["mate_pos_m"]] == pytest.approx(0.0)
    assert feats[row[0], COL["merged"]] == 1.0


def test_teammate_claims_need_a_merge_and_radio_range() -> None:
    m = np.zeros((5, 5), dtype=np.int8)
    shift = np.array([[1.0, 0, 5], [0, 1, 0], [0, 0, 1]])
    targets = {"robot_1": (1, 2)}
    assert teammate_claims(_view(m), targets) is None  # not merged
    out_of_range = _view(m, merged=True, transforms={"robot_1": shift})
    assert teammate_claims(out_of_range, targets) is None
    heard = _view(m, merged=True, transforms={"robot_1": shift}, in_range=frozenset({"robot_1"}))
    assert teammate_claims(heard, targets).tolist() == [[6.0, 2.0]]  # type: ignore[union-attr]


def test_executor_drives_to_the_committed_goal() -> None:
    # a free corridor with unknown space at its right end: one frontier
    m = np.full((30, 120), OCCUPIED, dtype=np.int8)
    m[5:25, 2:100] = FREE
    m[5:25, 100:118] = UNKNOWN
    view = _view(m, pose=(20.0, 15.0, 0.0))
    ex = GoalExecutor()
    ex.reset(np.random.default_rng(0))
    cands = ex.propose(view)
    assert cands is not None and len(cands) >= 1
    ex.commit(0, view)
    assert ex.path is not None and not ex.needs_decision
    assert ex.next_action(view) == 0  # FORWARD along +col
    ex.commit(-1, view)  # wait
    assert ex.path is None and ex.done


def test_gain_features_count_the_unknown_around_each_target() -> None:
    # 0.05 m cells: the near square is 41 x 41 cells, the range square (1 m here) the same;
    # a 2 m range gives 81 x 81.
    m = np.full((200, 300), FREE, dtype=np.int8)
    m[:, 150:] = UNKNOWN  # the right half never seen
    cands = FrontierCandidates(
        targets=np.array([[60, 100], [150, 100], [290, 5]], dtype=np.int64),
        size_m=np.ones(3),
        dist_m=np.array([1.0, 2.0, 3.0]),
        goals=np.zeros((3, 2), dtype=np.int64),
    )
    index = np.array([0, 1, 2, -1], dtype=np.int64)
    g = gain_features(_view(m), cands, index, sensor_range_m=2.0)
    assert g.shape == (4, len(GAIN_FEATURE_NAMES)) and g.dtype == np.float32
    assert g[0].tolist() == [0.0, 0.0]  # deep in the known part
    # on the boundary: the target's column and the 20 right of it are unknown
    assert g[1, 0] == pytest.approx(21 / 41)
    assert g[1, 1] == pytest.approx(41 / 81)
    # at the canvas corner (cols 270..299, rows 0..25 on the canvas, all unknown): the part
    # off the canvas counts as unknown too
    assert g[2, 0] == pytest.approx(1.0)
    assert g[3].tolist() == [0.0, 0.0]  # an empty row
    assert not gain_features(_view(m), None, index).any()
