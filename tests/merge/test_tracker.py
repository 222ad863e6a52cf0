"""MapMergeTracker: merge over time, keep, never flip-flop, chain, respect links, fuse."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np
import pytest
from conftest import look_alike_canvases

import mrexplore.merge.semantic as semantic_module
import mrexplore.merge.tracker as tracker_module
from mrexplore.errors import ConfigError, GridError
from mrexplore.grid import OCCUPIED as OCC
from mrexplore.grid import UNKNOWN, chain, invert_transform, map_points
from mrexplore.merge import MapMergeTracker, MergeResult, TrackerOptions
from mrexplore.merge.common import (
    Agreement,
    MapCodes,
    MergeEvidence,
    Verifier,
    WeighedPose,
    known_bbox,
    translation,
)
from mrexplore.studies.merge_cases import rotate_map
from mrexplore.truth import merge_error
from mrexplore.types import Sighting


def _canvas(
    m: np.ndarray, shape: tuple[int, int] = (320, 340), at: tuple[int, int] = (40, 30)
) -> tuple[np.ndarray, np.ndarray]:
    """Place m in a bigger unknown canvas at (col, row) = at; returns (canvas, T canvas<-m)."""
    out = np.full(shape, UNKNOWN, dtype=np.int8)
    out[at[1] : at[1] + m.shape[0], at[0] : at[0] + m.shape[1]] = m
    return out, translation(*at)


def _in_crops(ca: np.ndarray, cb: np.ndarray, T: np.ndarray) -> np.ndarray:
    """``T`` (cb's canvas cells -> ca's) in the cells of their known boxes: what the tracker
    hands the merger, and what a scripted merger must answer in."""
    ra0, _, ca0, _ = known_bbox(ca)  # type: ignore[misc]
    rb0, _, cb0, _ = known_bbox(cb)  # type: ignore[misc]
    return translation(-ca0, -ra0) @ T @ translation(cb0, rb0)


def _constants(mp: pytest.MonkeyPatch, **values: object) -> None:
    """Set the tracker's rule constants (by their former option names) for this test."""
    for name, value in values.items():
        mp.setattr(tracker_module, tracker_module.DEMOTED_TRACKER_OPTIONS[name], value)


def _merged_after_rechecks(
    tr: MapMergeTracker, ca: np.ndarray, cb: np.ndarray, later: np.ndarray
) -> bool:
    """Merge at step 1 on ``(ca, cb)``, then feed ``(ca, later)`` for steps 2-10 (re-checks at
    the tracker's ``recheck_every``): is the pair still merged?"""
    tr.update([ca, cb], step=1)
    assert tr.merged(0)
    for step in range(2, 11):
        tr.update([ca, later], step=step)
    return tr.merged(0)


@pytest.fixture(scope="module")
def robots(
    office_pair: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    a, b, T_ab = office_pair
    ca, Ta = _canvas(a, at=(40, 30))
    cb, Tb = _canvas(b, shape=(360, 360), at=(20, 10))
    T_true = Ta @ T_ab @ invert_transform(Tb)  # robot 1 canvas cells -> robot 0 canvas cells
    return ca, cb, T_true


def test_merges_once_enough_is_known_and_keeps_the_transform(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    ca, cb, T_true = robots
    early = cb.copy()
    rows, _ = np.nonzero(early != UNKNOWN)
    early[rows.min() + 25 :, :] = UNKNOWN  # robot 1 has barely started: a thin strip only
    tr = MapMergeTracker(2, merge_every=5, recheck_every=20, confirmations=1)
    tr.update([ca, early], step=0)
    assert not tr.merged(0) and tr.transform(0, 1) is None
    tr.update([ca, cb], step=3)  # not a merge step: nothing tried
    assert not tr.merged(0)
    tr.update([ca, cb], step=5)
    assert tr.merged(0) and tr.merged(1) and tr.group(0) == {0, 1}
    T = tr.transform(0, 1)
    assert T is not None and merge_error(T, T_true, cb)[0] < 1.0
    T10 = tr.transform(1, 0)
    assert T10 is not None
    np.testing.assert_allclose(T10, invert_transform(T), atol=1e-9)
    first = T.copy()
    for step in range(6, 200):  # same maps for many steps, with re-checks: no flip-flop
        tr.update([ca, cb], step=step)
    np.testing.assert_array_equal(tr.transform(0, 1), first)
    res = tr.last_result(0, 1)
    assert isinstance(res, MergeResult) and res.matched


def test_fused_map_holds_both_robots_knowledge(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    ca, cb, T_true = robots
    tr = MapMergeTracker(2, merge_every=1, confirmations=1)
    tr.update([ca, cb], step=0)
    f0, f1 = tr.fused(0), tr.fused(1)
    assert f0.shape == ca.shape and f1.shape == cb.shape and f0.dtype == np.int8
    known0 = ca != UNKNOWN
    assert np.all(f0[known0] >= ca[known0])  # own knowledge kept (fusion only raises)
    assert np.count_nonzero(f0 != UNKNOWN) > np.count_nonzero(known0) * 1.2  # teammate added
    # a wall of robot 1, mapped through the true transform, is a wall in robot 0's fused map
    rows, cols = np.nonzero(cb >= 65)
    p = np.stack([cols, rows], axis=1) @ T_true[:2, :2].T + T_true[:2, 2]
    c, r = np.rint(p[:, 0]).astype(int), np.rint(p[:, 1]).astype(int)
    ok = (c >= 0) & (c < ca.shape[1]) & (r >= 0) & (r < ca.shape[0])
    assert np.mean(f0[r[ok], c[ok]] >= 65) > 0.9
    assert tr.fused(0) is f0  # cached until something changes
    with pytest.raises(ValueError):
        f0[0, 0] = 0  # read-only: callers copy before writing


def test_links_are_respected(robots: tuple[np.ndarray, np.ndarray, np.ndarray]) -> None:
    ca, cb, _ = robots
    tr = MapMergeTracker(2, merge_every=1, confirmations=1)
    off = np.zeros((2, 2), dtype=bool)
    for step in range(5):
        tr.update([ca, cb], step=step, links=off)
    assert not tr.merged(0) and tr.last_result(0, 1) is None  # never even tried
    np.testing.assert_array_equal(tr.fused(0), ca)
    on = ~off
    tr.update([ca, cb], step=5, links=on)
    assert tr.merged(0)
    before = tr.fused(0).copy()
    grown = cb.copy()
    grown[grown == UNKNOWN] = 0  # robot 1 learns a lot more ...
    tr.update([ca, grown], step=6, links=off)  # ... while out of range: robot 0 keeps the old copy
    np.testing.assert_array_equal(tr.fused(0), before)
    tr.update([ca, grown], step=7, links=on)
    assert np.count_nonzero(tr.fused(0) != UNKNOWN) > np.count_nonzero(before != UNKNOWN)


def test_transforms_chain_through_merged_pairs() -> None:
    from mrexplore.world.map_io import read_map_yaml

    full = read_map_yaml(Path(__file__).resolve().parents[2] / "envs" / "tb3_office.yaml").grid
    m0 = full[60:250, 150:340].copy()  # rows 60-249
    m1 = full[140:320, 180:370].copy()  # overlaps both
    m2, T_rot = rotate_map(full[252:332, 160:378], np.radians(-70.0))  # rows 252+: not m0's
    T_20_true = translation(160 - 150, 252 - 60) @ invert_transform(T_rot)  # m2 -> m0
    tr = MapMergeTracker(3, merge_every=1, confirmations=1)
    tr.update([m0, m1, m2], step=0)
    assert tr.group(0) == {0, 1, 2}
    assert tr.transform(1, 0) is not None and tr.transform(1, 2) is not None
    r02 = tr.last_result(0, 2)
    assert r02 is not None and not r02.matched  # 0-2 share no cell: refused directly ...
    T = tr.transform(0, 2)  # ... yet known through robot 1
    assert T is not None and merge_error(T, T_20_true, m2)[0] < 1.5


class _Scripted:
    """A merger returning scripted transforms with a claimed score (for the no-flip-flop rule)."""

    def __init__(self, transforms: list[np.ndarray]) -> None:
        self.transforms = transforms
        self.calls = 0

    def merge(self, a: np.ndarray, b: np.ndarray) -> MergeResult:
        T = self.transforms[min(self.calls, len(self.transforms) - 1)]
        self.calls += 1
        return MergeResult(matched=True, transform=T, score=0.99)


def test_recheck_replaces_only_a_clearly_better_transform(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    ca, cb, T_true = robots
    # The tracker crops maps to their known boxes; express the truth in cropped cells.
    T_crop = _in_crops(ca, cb, T_true)
    wrong = translation(40.0, 0.0) @ T_crop
    scripted = _Scripted([T_crop, wrong])
    tr = MapMergeTracker(2, merger=scripted, merge_every=1, recheck_every=2, confirmations=1)
    for step in range(10):
        tr.update([ca, cb], step=step)
    assert scripted.calls >= 3  # re-checks happened
    T = tr.transform(0, 1)
    assert T is not None and merge_error(T, T_true, cb)[0] < 1e-6  # the wrong one never won


def test_bad_configuration_and_input() -> None:
    with pytest.raises(ConfigError, match="n_robots"):
        MapMergeTracker(0)
    with pytest.raises(ConfigError, match="merge_every"):
        MapMergeTracker(2, merge_every=0)
    with pytest.raises(ConfigError, match="unknown option"):
        MapMergeTracker(2, min_scroe=0.5)  # typo caught at construction
    with pytest.raises(ConfigError, match="merger"):
        MapMergeTracker(2, merger="fft")
    with pytest.raises(ConfigError, match="only apply"):
        MapMergeTracker(2, merger=lambda a, b: MergeResult(False, None, 0.0), min_score=0.5)
    tr = MapMergeTracker(2)
    g = np.zeros((10, 10), dtype=np.int8)
    with pytest.raises(GridError, match="expected 2 maps"):
        tr.update([g], step=0)
    with pytest.raises(GridError, match="int8"):
        tr.update([g, g.astype(np.float32)], step=0)
    with pytest.raises(ConfigError, match="links"):
        tr.update([g, g], step=0, links=np.ones((3, 3), dtype=bool))
    tr.reset()
    with pytest.raises(GridError, match="update"):
        tr.fused(0)


def test_incremental_fusion_equals_fusion_from_scratch() -> None:
    """Maps edited in place step after step (small boxes, new areas): the incrementally
    composed fused maps equal a from-scratch warp + fusion at every step."""
    from mrexplore.grid import make_transform
    from mrexplore.merge.common import warp_into

    rng = np.random.default_rng(0)
    m0 = np.full((200, 220), UNKNOWN, dtype=np.int8)
    m1 = np.full((210, 200), UNKNOWN, dtype=np.int8)
    m0[60:120, 60:140] = 0
    m1[50:110, 70:150] = 0
    T = make_transform(0.6, 30.3, -20.7)
    never = MergeResult(matched=False, transform=None, score=0.0)
    tr = MapMergeTracker(2, merger=lambda a, b: never, merge_every=1, recheck_every=0)
    tr.update([m0, m1], step=0)
    tr._edges[(0, 1)] = T  # inject a transform: this test is about composition only
    tr._paths = None
    for step in range(1, 60):
        for m in (m0, m1):
            r, c = (int(x) for x in rng.integers(30, 170, 2))
            kind = step % 4
            if kind == 0:
                m[r : r + 5, c : c + 7] = OCC  # a new wall blob
            elif kind == 1:
                m[r : r + 3, c : c + 20] = 0  # a new free strip (may grow the known box)
            elif kind == 2:
                m[r, c] = OCC if m[r, c] != OCC else 0  # one cell flips
        tr.update([m0, m1], step=step)
        ref0 = np.maximum(m0, warp_into(m1, T, m0.shape))
        ref1 = np.maximum(m1, warp_into(m0, invert_transform(T), m1.shape))
        np.testing.assert_array_equal(tr.fused(0), ref0)
        np.testing.assert_array_equal(tr.fused(1), ref1)


class _Seq:
    """A merger answering with a scripted sequence of transforms (None = refuse; a tuple
    ``(T, consistent)`` = refuse with best pose T, consistent with the maps or not, as the
    semantic merger reports a refusal for uniqueness, pinning or shared area)."""

    def __init__(self, answers: list[np.ndarray | tuple[np.ndarray, bool] | None]) -> None:
        self.answers = answers
        self.calls = 0

    def merge(self, a: np.ndarray, b: np.ndarray) -> MergeResult:
        T = self.answers[min(self.calls, len(self.answers) - 1)]
        self.calls += 1
        if T is None:
            return MergeResult(matched=False, transform=None, score=0.5, reason="scripted refusal")
        if isinstance(T, tuple):
            ev = MergeEvidence(best=WeighedPose(T[0], Agreement(90, 10)), consistent=T[1])
            return MergeResult(False, None, 0.9, reason="scripted refusal", evidence=ev)
        return MergeResult(matched=True, transform=T, score=0.99)


def _growing_maps(k: int) -> list[np.ndarray]:
    """Two maps whose known boxes keep their lower-left corner (10, 10) and grow with k, so a
    transform in cropped cells stays the same transform in canvas cells."""
    maps = []
    for _ in range(2):
        m = np.full((120, 120), UNKNOWN, dtype=np.int8)
        m[10 : 40 + 5 * k, 10 : 40 + 5 * k] = 0
        maps.append(m)
    return maps


@pytest.mark.parametrize(
    ("answers", "merged_at"),
    [
        # two agreeing attempts on grown maps: accepted at the second
        ([translation(3.0, 0.0)], 1),
        # a refusal in between breaks the run: accepted only after two new agreeing attempts
        ([translation(3.0, 0.0), None, translation(3.0, 0.0)], 3),
        # the second attempt disagrees (10 cells away): it starts a new run
        ([translation(3.0, 0.0), translation(13.0, 0.0)], 2),
        # a refusal whose best pose is the pending one, consistent: the run goes on
        ([translation(3.0, 0.0), (translation(3.0, 0.0), True), translation(3.0, 0.0)], 2),
        # ... but not when that pose was inconsistent, or lies elsewhere
        ([translation(3.0, 0.0), (translation(3.0, 0.0), False), translation(3.0, 0.0)], 3),
        ([translation(3.0, 0.0), (translation(13.0, 0.0), True), translation(3.0, 0.0)], 3),
    ],
)
def test_a_transform_needs_agreeing_attempts_on_growing_maps(
    answers: list[np.ndarray | tuple[np.ndarray, bool] | None], merged_at: int
) -> None:
    seq = _Seq(answers)
    tr = MapMergeTracker(
        2, merger=seq, merge_every=1, recheck_every=0, confirmations=2, keep_run_on_refusal=True
    )
    tr.update(_growing_maps(0), step=0)
    tr.update(_growing_maps(0), step=1)  # nothing changed: no new evidence, no attempt
    assert seq.calls == 1 and not tr.merged(0)
    for k in range(1, 6):
        tr.update(_growing_maps(k), step=k + 1)
        if tr.merged(0):
            assert k == merged_at
            break
    assert tr.merged(0)


def test_every_refusal_breaks_the_run_when_asked() -> None:
    """``keep_run_on_refusal=False``: the rule before, a consistent refusal breaks the run."""
    T = translation(3.0, 0.0)
    seq = _Seq([T, (T, True), T])
    tr = MapMergeTracker(
        2, merger=seq, merge_every=1, recheck_every=0, confirmations=2, keep_run_on_refusal=False
    )
    for k in range(4):
        tr.update(_growing_maps(k), step=k)
        assert tr.merged(0) == (k == 3)


def test_the_attempt_observer_sees_every_applied_attempt() -> None:
    """``attempt_observer`` gets one record per attempt, in order: the merger's answer, the pose
    it accepted, the run's length after it and whether the pair is merged; a tracker pickles
    without it."""
    import pickle

    from mrexplore.merge.tracker import AttemptRecord

    T = translation(3.0, 0.0)
    seq = _Seq([T, None, T, T])
    tr = MapMergeTracker(2, merger=seq, merge_every=1, recheck_every=0, confirmations=2)
    seen: list[AttemptRecord] = []
    tr.attempt_observer = seen.append
    for k in range(4):
        tr.update(_growing_maps(k), step=k)
    assert [r.step for r in seen] == [0, 1, 2, 3]
    assert [r.T is not None for r in seen] == [True, False, True, True]
    assert [r.pending for r in seen] == [1, 0, 1, 0]
    assert [r.merged for r in seen] == [False, False, False, True]
    assert seen[1].result.reason == "scripted refusal" and (seen[0].i, seen[0].j) == (0, 1)
    assert pickle.loads(pickle.dumps(tr)).attempt_observer is None


@pytest.mark.parametrize(
    ("latency", "attempts", "rechecks"),
    # latency 0: attempts at steps 0, 1, 2 (merged by the third), re-checks at 4, 8, 12;
    # latency 2: attempts start at 0, 2, 4 (a pair is not tried while its attempt is under
    # way) and take effect at 2, 4, 6; the re-check of step 8 takes effect at 10, that of 12
    # would at 14, after the last step
    [(0, 3, 3), (2, 3, 1)],
)
def test_work_counts_the_applied_attempts_and_rechecks_and_their_cpu(
    latency: int, attempts: int, rechecks: int
) -> None:
    """``work`` counts what the tracker applied this episode, with the CPU the merger took;
    ``reset`` zeroes it."""
    from mrexplore.merge import MergeWork

    seq = _Seq([None, None, translation(3.0, 0.0)])
    tr = MapMergeTracker(
        2,
        merger=seq,
        merge_every=1,
        recheck_every=4,
        confirmations=1,
        merge_latency_steps=latency,
    )
    assert tr.work == MergeWork()
    for k in range(13):
        tr.update(_growing_maps(k), step=k)
    tr.wait_idle()
    assert (tr.work.attempts, tr.work.rechecks) == (attempts, rechecks)
    assert tr.work.cpu_s >= 0.0 and attempts + rechecks <= seq.calls
    tr.reset()
    assert tr.work == MergeWork()


class _PairLog:
    """A merger that refuses every pair and records which pairs it was asked about."""

    def __init__(self) -> None:
        self.pairs: list[tuple[int, int]] = []

    def merge(self, a: np.ndarray, b: np.ndarray) -> MergeResult:
        raise AssertionError("the tracker calls merge_pair when a merger has it")

    def merge_pair(
        self, i: int, j: int, a: np.ndarray, b: np.ndarray, oa: object, ob: object
    ) -> MergeResult:
        self.pairs.append((i, j))
        return MergeResult(matched=False, transform=None, score=0.5, reason="scripted refusal")


@pytest.mark.parametrize("rotating", [False, True])
@pytest.mark.parametrize("n", [2, 3, 4, 5, 8])
def test_rotating_partners_try_each_robot_once_a_round_and_every_pair_in_turn(
    monkeypatch: pytest.MonkeyPatch, n: int, rotating: bool
) -> None:
    """With ``ROTATING_PARTNERS`` a round tries each robot with one partner (n pairs, n / 2
    when the offset is half the team), every pair within n // 2 rounds; teams of two and three
    try every pair every round, as without it."""
    monkeypatch.setattr(tracker_module, "ROTATING_PARTNERS", rotating)
    log = _PairLog()
    tr = MapMergeTracker(n, merger=log, merge_every=1, confirmations=1)
    all_pairs = {(i, j) for i in range(n) for j in range(i + 1, n)}
    rounds = []
    for k in range(n // 2 * 2):
        before = len(log.pairs)
        tr.update(_growing_maps(k)[:1] * n, step=k)
        rounds.append(log.pairs[before:])
    if not rotating or n <= 3:
        assert all(set(r) == all_pairs and len(r) == len(all_pairs) for r in rounds)
        return
    for k, r in enumerate(rounds):
        offset = 1 + k % (n // 2)
        assert len(r) == len(set(r)) == (n // 2 if 2 * offset == n else n)
        assert all((j - i) % n in (offset, n - offset) for i, j in r)
    assert set().union(*rounds[: n // 2]) == all_pairs  # every pair had its turn
    assert rounds[: n // 2] == rounds[n // 2 :]  # and the rotation starts over


def test_no_attempt_when_told_not_to() -> None:
    seq = _Seq([translation(3.0, 0.0)])
    tr = MapMergeTracker(2, merger=seq, merge_every=1, confirmations=1)
    tr.update(_growing_maps(0), step=0, attempt=False)
    assert seq.calls == 0 and not tr.merged(0)
    tr.update(_growing_maps(1), step=1)
    assert seq.calls == 1 and tr.merged(0)
    with pytest.raises(ConfigError, match="merge_latency_steps"):
        MapMergeTracker(2, merge_latency_steps=-1)


def test_recheck_drops_a_transform_the_grown_maps_contradict(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
) -> None:
    ca, cb, T_true = robots
    T_crop = _in_crops(ca, cb, T_true)
    seq = _Seq([T_crop, None])
    tr = MapMergeTracker(2, merger=seq, merge_every=1, recheck_every=5, confirmations=1)
    # Robot 1's map now says something else where it overlaps robot 0's: its walls moved by
    # 15 cells (as if the kept transform had been a look-alike match). The re-check drops it.
    moved = np.full_like(cb, UNKNOWN)
    moved[:, 15:] = cb[:, :-15]
    assert not _merged_after_rechecks(tr, ca, cb, moved) and tr.transform(0, 1) is None
    # the drop is recorded: contradicted and dropped at the same re-check (nothing kept it)
    assert len(tr.drops) == 1
    drop = tr.drops[0]
    assert (drop.i, drop.j) == (0, 1) and drop.contradicted_step == drop.dropped_step > 0
    tr.reset()
    assert tr.drops == []


@pytest.mark.parametrize("noise_aware", [True, False])
def test_recheck_keeps_a_transform_the_maps_contradict_only_within_their_noise(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
    noise_aware: bool,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Speckles (two wall cells each, in open space) pull the raw index under ``drop_below``;
    the drop judges the noise-aware agreement, as acceptance does, and keeps the true
    transform. The raw judgement (slack 0, runs of 1) drops it."""
    ca, cb, T_true = robots
    from mrexplore.merge.common import Verifier

    T_crop = _in_crops(ca, cb, T_true)
    noisy = cb.copy()
    free = np.zeros(cb.shape, dtype=bool)
    free[::4, ::4] = True  # pairs 2 cells apart: every speckle is its own group
    free &= (cb == 0) & (np.roll(cb, -1, axis=1) == 0)
    walls = (cb >= 50).astype(np.uint8)
    near = cv2.dilate(walls, np.ones((9, 9), np.uint8)).astype(bool)  # 4 cells from a wall
    speckle = free & ~near
    noisy[speckle] = OCC
    noisy[np.roll(speckle, 1, axis=1)] = OCC
    raw = Verifier(ca, noisy)(T_true).score
    held = Verifier(ca, noisy, slack=2).structured(T_true, 5).score
    assert raw < 0.85 <= held  # the case the test is about
    if not noise_aware:
        _constants(
            monkeypatch, recheck_slack_cells=0, recheck_min_run_cells=1, relocate_tol_cells=0.0
        )
    tr = MapMergeTracker(2, merger=_Seq([T_crop]), merge_every=1, recheck_every=5, confirmations=1)
    assert _merged_after_rechecks(tr, ca, cb, noisy) is noise_aware


@pytest.mark.parametrize(("tol", "kept"), [(8.0, True), (5.0, False)])
def test_recheck_refits_a_contradicted_transform_the_merger_finds_again_nearby(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
    tol: float,
    kept: bool,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Robot 1's map moves 6 cells (as drift moves a map): the kept transform is contradicted,
    and the merger, run on the same maps, accepts the refitted one 6 cells away. Within
    ``relocate_tol_cells`` the pair stays merged with the new pose; beyond it, it is dropped."""
    ca, cb, T_true = robots
    from mrexplore.merge.common import Verifier

    # in crop cells the refitted pose of the moved map is the same matrix (its crop moved too)
    T_crop = _in_crops(ca, cb, T_true)
    moved = np.full_like(cb, UNKNOWN)
    moved[:, 6:] = cb[:, :-6]
    assert Verifier(ca, moved, slack=2).structured(T_true, 5).score < 0.85  # contradicted
    tr = MapMergeTracker(
        2,
        merger=_Seq([T_crop]),
        merge_every=1,
        recheck_every=5,
        confirmations=1,
    )
    _constants(monkeypatch, relocate_tol_cells=tol, drift_slack_cells=0)  # this rule alone
    assert _merged_after_rechecks(tr, ca, cb, moved) is kept
    if kept:
        T = tr.transform(0, 1)
        assert T is not None
        np.testing.assert_allclose(T, T_true @ translation(-6, 0), atol=1e-6)


def test_a_callable_merger_without_evidence_merges_and_drops(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A plain function that reports no :class:`MergeEvidence` (a user's own merger): it
    merges after two agreeing attempts (no best pose kept as a hypothesis, no rival
    remembered), and a refused re-check of a contradicted transform drops it (no refit:
    nothing says where the merger's best pose was)."""
    ca, cb, T_true = robots
    T_crop = _in_crops(ca, cb, T_true)
    answers = [T_crop, None, T_crop, T_crop]

    def merge(a: np.ndarray, b: np.ndarray) -> MergeResult:
        T = answers.pop(0) if answers else None
        if T is None:
            return MergeResult(False, None, 0.5, reason="scripted refusal")
        return MergeResult(True, T, 0.99, overlap_cells=500)

    tr = MapMergeTracker(
        2,
        merger=merge,
        merge_every=1,
        recheck_every=5,
        confirmations=2,
    )
    _constants(monkeypatch, retry_growth=0.0, drift_slack_cells=0)  # no drift kept here
    for step in range(3):  # accept, refuse (breaks the run), accept: one pending
        tr.update([ca, cb], step=step)
        assert not tr.merged(0)
        assert tr.hypotheses(0, 1) == []
    tr.update([ca, cb], step=3)
    assert tr.merged(0)
    moved = np.full_like(cb, UNKNOWN)
    moved[:, 6:] = cb[:, :-6]  # contradicts the kept transform; the merger now refuses
    for step in range(4, 11):
        tr.update([ca, moved], step=step)
    assert not tr.merged(0) and len(tr.drops) == 1


class _RefusesWithBest:
    """A first answer accepting ``T0``; then refusals that report a best pose, its noise-aware
    consistency and rivals, as the semantic merger's ``evidence`` does (crop cells)."""

    def __init__(
        self,
        T0: np.ndarray,
        best: np.ndarray,
        consistency: float,
        rivals: list[tuple[np.ndarray, float]],
    ) -> None:
        self.T0, self.best, self.consistency, self.rivals = T0, best, consistency, rivals
        self.calls = 0

    def merge(self, a: np.ndarray, b: np.ndarray) -> MergeResult:
        self.calls += 1
        if self.calls == 1:
            return MergeResult(matched=True, transform=self.T0, score=0.99)
        ev = MergeEvidence(
            best=WeighedPose(self.best, Agreement(80, 20)),  # raw index 0.80
            consistency=self.consistency,
            consistent=self.consistency >= 0.95,
            rivals=tuple(
                WeighedPose(R, Agreement(round(100 * s), 100 - round(100 * s)))
                for R, s in self.rivals
            ),
        )
        return MergeResult(
            matched=False, transform=None, score=0.8, reason="scripted refusal", evidence=ev
        )


@pytest.mark.parametrize(
    ("shift", "consistency", "rival", "refit", "kept"),
    [
        (6, 0.90, None, True, True),  # drift: the best pose is the kept place, 6 cells on
        (6, 0.90, (40, 0.70), True, True),  # a far pose explains clearly less: no rival
        (6, 0.90, (-4, 0.79), True, True),  # a near pose: the same place, refitted otherwise
        (6, 0.90, (40, 0.79), True, False),  # a far pose explains about as well: dropped
        (6, 0.80, None, True, False),  # the best pose itself is contradicted: dropped
        (14, 0.90, None, True, False),  # the best pose is another place: dropped
        (6, 0.90, None, False, False),  # refit_refused off: dropped, as before
    ],
)
def test_recheck_keeps_a_drifted_place_the_merger_ranks_first_but_refuses(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
    shift: int,
    consistency: float,
    rival: tuple[int, float] | None,
    refit: bool,
    kept: bool,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Drift bends the maps so that no rigid pose reaches the acceptance bar: the merger
    refuses, yet its best pose may still be the kept place. The pair stays merged, at that pose,
    only when it lies within ``relocate_tol_cells`` (10) of the kept one, agrees within the
    maps' noise at least ``drop_below`` (0.85) and beats every farther rival by the merger's
    margin (0.03 in raw index; the best's is 0.80)."""
    ca, cb, T_true = robots
    from mrexplore.merge.common import Verifier

    T_crop = _in_crops(ca, cb, T_true)
    moved = np.full_like(cb, UNKNOWN)
    moved[:, 6:] = cb[:, :-6]  # robot 1's map drifts 6 cells: the kept pose is contradicted
    assert Verifier(ca, moved, slack=2).structured(T_true, 5).score < 0.85
    # in crop cells (the moved map's crop moved with it) the best pose sits `shift` cells on
    best = T_crop @ translation(6 - shift, 0)
    rivals = [] if rival is None else [(T_crop @ translation(-rival[0], 0), rival[1])]
    merger = _RefusesWithBest(T_crop, best, consistency, rivals)
    tr = MapMergeTracker(
        2,
        merger=merger,
        merge_every=1,
        recheck_every=5,
        confirmations=1,
    )
    # this rule alone (a 6-cell drift is also kept by the next test's)
    _constants(monkeypatch, refit_refused=refit, drift_slack_cells=0)
    assert _merged_after_rechecks(tr, ca, cb, moved) is kept and merger.calls > 1
    if kept:
        T = tr.transform(0, 1)
        assert T is not None
        np.testing.assert_allclose(T, T_true @ translation(-shift, 0), atol=1e-6)


@pytest.mark.parametrize(
    ("shift", "slack", "kept"),
    [
        (6, 6, True),  # walls 6 cells off: within the drift slack, the place stands
        (6, 0, False),  # the rule off: dropped
        (15, 6, False),  # 15 cells: beyond it, dropped
    ],
)
def test_recheck_keeps_a_transform_contradicted_only_within_a_drifts_width(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
    shift: int,
    slack: int,
    kept: bool,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Robot 1's map slides ``shift`` cells (drift); the merger refuses every re-check without
    a pose. The kept transform stays while its walls lie within ``drift_slack_cells`` of the
    other map's, unchanged."""
    ca, cb, T_true = robots
    from mrexplore.merge.common import Verifier

    T_crop = _in_crops(ca, cb, T_true)
    moved = np.full_like(cb, UNKNOWN)
    moved[:, shift:] = cb[:, :-shift]
    assert Verifier(ca, moved, slack=2).structured(T_true, 5).score < 0.85  # contradicted
    tr = MapMergeTracker(
        2,
        merger=_Seq([T_crop, None]),
        merge_every=1,
        recheck_every=5,
        confirmations=1,
    )
    _constants(monkeypatch, drift_slack_cells=slack)
    assert _merged_after_rechecks(tr, ca, cb, moved) is kept
    if kept:
        np.testing.assert_allclose(tr.transform(0, 1), T_true, atol=1e-9)  # crop round trip


@pytest.mark.parametrize("sighted", [False, True])
def test_a_sighting_merges_look_alike_rooms_the_maps_alone_cannot_tell_apart(
    sighted: bool,
) -> None:
    """Robot 1's map is the left room of two identical ones that robot 0 knows, so alone
    every attempt is refused as ambiguous (and the tracker remembers the other room as a
    rival). A sighting (a guess of T_01 a few cells and degrees off) makes the pair due for
    an attempt at once, although the maps have not grown, and confines it to the guess's
    region, where the pose is unique: merged at the true place, the remembered rival
    outside the region no longer standing against it."""
    from mrexplore.merge.semantic import _turn_about

    canvas_a, canvas_b, T_true = look_alike_canvases()  # T_true: b's cells -> a's (left room)
    guess = chain(T_true, _turn_about(3.0, 85.0, 90.0), translation(5.0, -4.0))
    tr = MapMergeTracker(2, merge_every=1, confirmations=1, resolution_m=0.05)
    maps = [canvas_a, canvas_b]
    tr.update(maps, step=1)
    result = tr.last_result(0, 1)
    assert not tr.merged(0) and result is not None and result.reason.startswith("ambiguous")
    for step in range(2, 5):
        tr.update(maps, step=step, sightings={(0, 1): guess} if sighted else None)
    assert tr.merged(0) is sighted
    if sighted:
        T = tr.transform(0, 1)
        assert T is not None
        np.testing.assert_allclose(T[:2, 2], T_true[:2, 2], atol=1.0)


@pytest.mark.parametrize(("confirms", "slid"), [(True, False), (False, False), (True, True)])
def test_a_pose_a_sighting_guided_is_merged_without_a_second_attempt(
    confirms: bool, slid: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """With two confirmations asked, the first attempt guided by a sighting merges the pair
    when ``SIGHTING_CONFIRMS`` is on and the pose puts robot 1 where the sighting saw it (the
    sighting is the other measurement of the pose); off, or when the sighting saw robot 1 a
    few cells (beyond ``confirm_tol_cells``) from where the maps put it, the accepted pose
    only starts a run, and the same maps never extend it."""
    from mrexplore.merge.semantic import _turn_about
    from mrexplore.types import Sighting

    monkeypatch.setattr(tracker_module, "SIGHTING_CONFIRMS", confirms)
    canvas_a, canvas_b, T_true = look_alike_canvases()
    # exact where robot 1 was seen, turned by 3 degrees about it (off elsewhere) ...
    seen_at = (85.0, 90.0)
    guess = chain(T_true, _turn_about(3.0, *seen_at))
    if slid:  # ... or 5 cells off there too
        guess = chain(translation(4.0, -3.0), guess)
    tr = MapMergeTracker(2, merge_every=1, confirmations=2, resolution_m=0.05)
    maps = [canvas_a, canvas_b]
    tr.update(maps, step=1, sightings={(0, 1): Sighting(guess, seen_at)})
    merged = confirms and not slid
    assert tr.merged(0) is merged
    for step in range(2, 5):
        tr.update(maps, step=step)
    assert tr.merged(0) is merged
    if merged:
        T = tr.transform(0, 1)
        assert T is not None
        np.testing.assert_allclose(T[:2, 2], T_true[:2, 2], atol=1.0)


def test_hypotheses_hold_both_look_alike_rooms_until_the_pair_merges() -> None:
    """Refused as ambiguous between two identical rooms, the tracker offers both places as
    candidates (``hypotheses``, for a policy that goes to tell them apart), the inverses for the
    other robot; once merged (here by a sighting), none."""
    from mrexplore.merge.semantic import _turn_about

    canvas_a, canvas_b, T_true = look_alike_canvases()  # T_true: b's cells -> a's (left room)
    tr = MapMergeTracker(2, merge_every=1, confirmations=1, resolution_m=0.05)
    assert tr.hypotheses(0, 1) == []
    tr.update([canvas_a, canvas_b], step=1)
    assert not tr.merged(0)
    cands = tr.hypotheses(0, 1)
    shifts = sorted(round(float(T[0, 2]) - 40.0) for T in cands)
    assert len(cands) >= 2 and abs(shifts[0]) <= 2  # the true room ...
    assert any(abs(s - 129) <= 3 for s in shifts)  # ... and its twin, a room width away
    back = tr.hypotheses(1, 0)
    for T, B in zip(cands, back, strict=True):
        np.testing.assert_allclose(B, invert_transform(T), atol=1e-9)
    # asked again (every step): the same poses, in new arrays a caller may change
    again = tr.hypotheses(1, 0)
    assert [B.tolist() for B in again] == [B.tolist() for B in back]
    again[0][0, 2] += 100.0
    assert tr.hypotheses(1, 0)[0].tolist() == back[0].tolist()
    guess = chain(T_true, _turn_about(3.0, 85.0, 90.0), translation(5.0, -4.0))
    tr.update([canvas_a, canvas_b], step=2, sightings={(0, 1): guess})
    assert tr.merged(0) and tr.hypotheses(0, 1) == [] and tr.hypotheses(1, 0) == []


def test_tracker_fed_map_changes_equals_the_scanning_tracker() -> None:
    """Fed the maps' own change records (no canvas scans), the tracker keeps the same boxes,
    versions and fused maps as when it compares canvases itself."""
    from mrexplore.sim import Simulation
    from mrexplore.world import load_world

    world = load_world("small_office")
    sim = Simulation(world, 2)
    rng = np.random.default_rng(2)
    sim.reset(rng)
    T = sim.true_transform(0, 1)
    never = MergeResult(matched=False, transform=None, score=0.0)
    scan = MapMergeTracker(2, merger=lambda a, b: never)
    told = MapMergeTracker(2, merger=lambda a, b: never)
    act_rng = np.random.default_rng(3)
    for step in range(1, 60):
        act = np.where(act_rng.random(2) < 0.6, 0, act_rng.integers(1, 4, 2))
        sim.step(act, rng)
        maps = [m.to_int8() for m in sim.maps]
        scan.update(maps, step)
        told.update(maps, step, changes=[m.change() for m in sim.maps])
        if step == 20:  # merge both the same way, with the true transform (from now on,
            # fused maps: incremental patches from the changed boxes)
            for tr in (scan, told):
                tr._edges[(0, 1)] = T
                tr._paths = None
        for i in range(2):
            assert scan._px.bbox(i) == told._px.bbox(i)
            assert scan._px.version(i) == told._px.version(i)
            assert scan._px._delta[i] == told._px._delta[i]
            np.testing.assert_array_equal(scan.fused(i), told.fused(i))


def test_warp_into_equals_a_shifted_uint8_warp() -> None:
    """warp_into warps the int8 map as its uint8 view (unknown's -1 is 255): the same cells as
    the older shift to uint8 (unknown -> 0) and back, on whole maps and on crops (views)."""
    import cv2

    from mrexplore.grid import make_transform
    from mrexplore.merge.common import warp_into

    def shifted_warp(src, T, shape, origin):  # type: ignore[no-untyped-def]
        M = np.asarray(T, dtype=np.float64)[:2].copy()
        M[:, 2] -= origin
        out = cv2.warpAffine(
            (src.astype(np.int16) + 1).astype(np.uint8),
            M,
            (shape[1], shape[0]),
            flags=cv2.INTER_NEAREST,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=0,
        )
        return (out.astype(np.int16) - 1).astype(np.int8)

    rng = np.random.default_rng(6)
    whole = rng.choice(np.array([UNKNOWN, 0, 30, 64, OCC], dtype=np.int8), (90, 70))
    for k in range(30):
        T = make_transform(rng.uniform(-3.2, 3.2), rng.uniform(-40, 120), rng.uniform(-40, 120))
        if k % 3 == 0:
            T = make_transform(k * np.pi / 6, 30.0, 20.0)
        origin = (int(rng.integers(-20, 20)), int(rng.integers(-20, 20)))
        src = whole if k % 2 else whole[5:80, 3:61]
        np.testing.assert_array_equal(
            warp_into(src, T, (80, 100), dst_origin=origin),
            shifted_warp(src, T, (80, 100), origin),
        )


class _WithRivals:
    """A merger answering with scripted (transform or None, rivals) pairs, in crop cells."""

    def __init__(self, answers: list[tuple[np.ndarray | None, list[np.ndarray]]]) -> None:
        self.answers = answers
        self.calls = 0

    def merge(self, a: np.ndarray, b: np.ndarray) -> MergeResult:
        T, rivals = self.answers[min(self.calls, len(self.answers) - 1)]
        self.calls += 1
        ev = MergeEvidence(rivals=tuple(WeighedPose(R, Agreement(90, 10)) for R in rivals))
        if T is None:
            return MergeResult(False, None, 0.9, reason="scripted: ambiguous", evidence=ev)
        return MergeResult(True, T, 0.99, overlap_cells=500, evidence=ev)


@pytest.mark.parametrize(("memory", "merged"), [(8, False), (0, True)])
def test_a_remembered_rival_the_maps_still_support_blocks_a_look_alike(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
    memory: int,
    merged: bool,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """An attempt is refused as ambiguous between two poses; later attempts offer only the
    wrong one (the search no longer finds the other). The remembered rival, which the maps
    support better, keeps the pair apart; without the memory the wrong pose is accepted."""
    ca, cb, T_true = robots
    truth = _in_crops(ca, cb, T_true)
    wrong = translation(40.0, 0.0) @ truth
    merger = _WithRivals([(None, [truth]), (wrong, []), (wrong, []), (wrong, [])])
    tr = MapMergeTracker(2, merger=merger, merge_every=1, recheck_every=0, confirmations=2)
    _constants(monkeypatch, retry_growth=0.0, rival_memory=memory)
    for step in range(4):
        tr.update([ca, cb], step=step)
    assert tr.merged(0) is merged and merger.calls == (3 if merged else 4)


def test_a_remembered_rival_the_maps_rule_out_is_forgotten(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray], monkeypatch: pytest.MonkeyPatch
) -> None:
    """The other way round: the remembered rival is the wrong pose; the maps contradict it, so
    the true pose is accepted after its two agreeing attempts, and the rival is forgotten."""
    ca, cb, T_true = robots
    truth = _in_crops(ca, cb, T_true)
    wrong = translation(40.0, 0.0) @ truth
    merger = _WithRivals([(None, [wrong]), (truth, []), (truth, [])])
    tr = MapMergeTracker(2, merger=merger, merge_every=1, recheck_every=0)
    _constants(monkeypatch, retry_growth=0.0)
    for step in range(3):
        tr.update([ca, cb], step=step)
    assert tr.merged(0)
    assert merge_error(tr.transform(0, 1), T_true, cb)[0] < 0.5  # type: ignore[arg-type,index]
    assert not tr._rivals  # ruled out: nothing left to remember


@pytest.mark.parametrize(("cells", "merged"), [(100, False), (500, True)])
def test_a_pose_resting_on_too_little_wall_is_not_accepted(cells: int, merged: bool) -> None:
    """``min_accept_cells``: agreeing attempts whose pose rests on fewer wall cells than the
    floor count as refusals."""

    class _Thin(_Seq):
        def merge(self, a: np.ndarray, b: np.ndarray) -> MergeResult:
            self.calls += 1
            return MergeResult(True, translation(3.0, 0.0), 0.99, overlap_cells=cells)

    seq = _Thin([])
    tr = MapMergeTracker(2, merger=seq, merge_every=1, recheck_every=0, min_accept_cells=250)
    for k in range(4):
        tr.update(_growing_maps(k), step=k)
    assert seq.calls == (2 if merged else 4) and tr.merged(0) is merged


def test_a_remembered_rival_ruled_out_by_one_object_does_not_stand(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """The sandbox crop pair the merger accepts through the structure test (tests/merge/
    test_semantic.py): its half-turned rival, remembered by the tracker, must not break the
    run of agreeing attempts either; judged by the margin alone it would."""
    from mrexplore.grid import known_bbox
    from mrexplore.merge import merge_maps
    from mrexplore.studies.merge_cases import real_cases

    case = real_cases(15, 7)[14]
    # (one office of the real map: the place test would wait for a second place to agree)
    res = merge_maps(case.a, case.b, resolution_m=case.resolution_m, place_test=False)
    assert res.matched and res.transform is not None
    assert res.evidence is not None
    rival = res.evidence.rivals[0].transform
    box = known_bbox(case.b)
    assert box is not None
    tr = MapMergeTracker(2)
    verify = Verifier(MapCodes(case.a), MapCodes(case.b))
    args = (verify, ((0, 0), (0, 0)), res.transform, [rival], box)
    assert tr._standing(*args) == []
    # the run's own options reach the tracker's rival checks: without the structure test the
    # rival stands
    monkeypatch.setattr(semantic_module, "STRUCTURE_TEST", False)
    assert len(MapMergeTracker(2)._standing(*args)) == 1


def test_tracker_options_are_typed_validated_and_the_old_keywords_still_reach_them() -> None:
    """One default and one range each; the old keyword form routes into the same options;
    both forms at once, or a bad value, is a ConfigError naming the knob."""
    opts = TrackerOptions(confirmations=3, merge_every=5)
    tr = MapMergeTracker(2, options=opts)
    assert tr.options is opts
    old = MapMergeTracker(2, confirmations=3, merge_every=5)
    assert old.options == opts
    assert TrackerOptions(drop_below=1).drop_below == 1.0  # a float where a float is due
    with pytest.raises(ConfigError, match="MapMergeTracker: option drop_below must be in"):
        TrackerOptions(drop_below=1.5)
    with pytest.raises(ConfigError, match=r"\['confirmations'\] given both"):
        MapMergeTracker(2, options=opts, confirmations=2)
    with pytest.raises(ConfigError, match="must be a TrackerOptions"):
        MapMergeTracker(2, options={"confirmations": 2})  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="unknown option"):
        TrackerOptions.from_kwargs(confirmation=2)


def test_the_tracker_judges_rivals_with_the_runs_own_options() -> None:
    """A user's ``min_margin`` reaches the tracker's rival checks as well as the merger: one
    run holds one value of each setting (``FAR_CELLS`` and the rest are constants, one value
    for both); a former option is refused by name."""
    tr = MapMergeTracker(2, min_margin=0.11)
    assert tr._rival_rule.min_margin == 0.11
    with pytest.raises(ConfigError, match=r"far_cells \(now FAR_CELLS\) no longer an option"):
        MapMergeTracker(2, far_cells=7.5)
    with pytest.raises(ConfigError, match=r"rival_memory \(now RIVAL_MEMORY\)"):
        MapMergeTracker(2, rival_memory=0)
    assert MapMergeTracker(2)._rival_rule.min_margin == 0.03
    # a merger of another kind: the semantic defaults judge its rivals
    assert MapMergeTracker(2, merger="orb")._rival_rule.min_margin == 0.03


class _ScriptedWithBest:
    """A merger answering with scripted (accepted transform or None, best pose) pairs, in crop
    cells; the best pose is reported as the semantic merger's ``evidence.best``."""

    def __init__(self, answers: list[tuple[np.ndarray | None, np.ndarray]]) -> None:
        self.answers = answers
        self.calls = 0

    def merge(self, a: np.ndarray, b: np.ndarray) -> MergeResult:
        T, best = self.answers[min(self.calls, len(self.answers) - 1)]
        self.calls += 1
        ev = MergeEvidence(
            best=WeighedPose(best, Agreement(95, 5)), consistency=0.99, consistent=True
        )
        if T is None:
            return MergeResult(False, None, 0.9, reason="scripted: refused", evidence=ev)
        return MergeResult(True, T, 0.99, overlap_cells=500, evidence=ev)


@pytest.mark.parametrize(
    ("recheck", "on", "outcome"),
    [
        ("truth", True, "moved"),  # the merger accepts the true place: the pair moves there
        ("refused", True, "dropped"),  # it prefers the true place but refuses it: un-merged
        ("refused", False, "kept"),  # the rule off: the look-alike stays (drop_below 0)
        ("wrong", True, "kept"),  # the merger still prefers the kept place
    ],
)
def test_a_kept_pose_the_grown_maps_rank_below_another_place_gives_way(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
    recheck: str,
    on: bool,
    outcome: str,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A look-alike pose accepted while the maps were small is held to the standard of a
    rival: once the merger's best pose on the current maps is another place, consistent, that
    beats it by the merger's margins (here the maps contradict the kept pose) and that no
    other pose stands against, the pair moves to that place when the merger accepts it, and
    is un-merged otherwise. A kept pose merely contradicted is judged by ``drop_below`` (off
    here)."""
    ca, cb, T_true = robots
    truth = _in_crops(ca, cb, T_true)
    wrong = translation(40.0, 0.0) @ truth
    later = {"truth": (truth, truth), "refused": (None, truth), "wrong": (wrong, wrong)}
    merger = _ScriptedWithBest([(wrong, wrong), (wrong, wrong), later[recheck]])
    tr = MapMergeTracker(
        2, merger=merger.merge, merge_every=1, recheck_every=3, confirmations=2, drop_below=0.0
    )
    monkeypatch.setattr(tracker_module, "OUTRANKED_DROP", on)
    _constants(monkeypatch, retry_growth=0.0)
    for step in range(2):
        tr.update([ca, cb], step=step)
    assert tr.merged(0)
    kept = tr.transform(0, 1)
    assert kept is not None and merge_error(kept, T_true, cb)[0] > 30
    tr.update([ca, cb], step=3)  # the re-check
    now = tr.transform(0, 1)
    err = None if now is None else merge_error(now, T_true, cb)[0]
    if outcome == "moved":
        assert err is not None and err < 0.5 and [d.cause for d in tr.drops] == ["moved"]
    elif outcome == "dropped":
        assert err is None and [d.cause for d in tr.drops] == ["outranked"]
    else:
        assert err is not None and err > 30 and not tr.drops


def _sighted_at(T: np.ndarray, cb: np.ndarray) -> Sighting:
    """A sighting whose guess is ``T`` (canvas cells), robot 1 seen at its known box's centre."""
    r0, r1, c0, c1 = known_bbox(cb)  # type: ignore[misc]
    return Sighting(T, ((c0 + c1) / 2.0, (r0 + r1) / 2.0))


@pytest.mark.parametrize(
    ("seen", "on", "kept"),
    [
        ("truth", True, False),  # seen where the kept look-alike does not put it: dropped
        ("truth", False, True),  # the rule off: a merged pair's sightings are ignored
        ("turned", True, True),  # seen where the kept pose puts it, turned: maps bend, kept
        ("shifted", True, True),  # a metre off (the sighting's region is 2 m): kept
    ],
)
def test_a_sighting_binds_a_merged_pair(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
    seen: str,
    on: bool,
    kept: bool,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Robots that see each other measure where the other one is: a kept pose that puts the
    seen robot more than the sighting's region (``PRIOR_RADIUS_CELLS``) from there is a wrong
    place and is dropped; only the position at the sighting is judged, not the heading, which a
    kept rigid pose of bent maps differs from by the bending."""
    from mrexplore.merge.semantic import _turn_about

    ca, cb, T_true = robots
    wrong = translation(60.0, 0.0) @ T_true
    merger = _ScriptedWithBest([(_in_crops(ca, cb, wrong), _in_crops(ca, cb, wrong))])
    tr = MapMergeTracker(2, merger=merger.merge, merge_every=1, recheck_every=0, confirmations=1)
    monkeypatch.setattr(tracker_module, "SIGHTING_BINDS", on)
    tr.update([ca, cb], step=0)
    assert tr.merged(0)
    at = _sighted_at(T_true, cb).at_j
    guesses = {
        "truth": T_true,
        "turned": chain(wrong, _turn_about(15.0, at[0], at[1])),
        "shifted": chain(translation(20.0, 0.0), wrong),
    }
    # the scripted merger answers the look-alike again: no attempt moves the pair
    tr.update([ca, cb], step=1, sightings={(0, 1): Sighting(guesses[seen], at)})
    assert tr.merged(0) is kept
    assert [d.cause for d in tr.drops] == ([] if kept else ["sighting"])


@pytest.mark.parametrize(
    ("wrong_edge", "vouched", "dropped"),
    [
        (None, False, []),  # the chain puts robot 2 where it was seen: nothing goes
        ((1, 2), False, [(0, 1), (1, 2)]),  # either edge may be the look-alike: both go
        ((1, 2), True, [(1, 2)]),  # robot 1 was seen where (0, 1) puts it: only (1, 2) goes
    ],
)
def test_a_sighting_binds_a_pair_merged_through_a_teammate(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
    wrong_edge: tuple[int, int] | None,
    vouched: bool,
    dropped: list[tuple[int, int]],
) -> None:
    """Robots 0 and 2 are merged only through robot 1 (edges (0, 1) and (1, 2)). When 0 sees 2
    where the chain does not put it, an edge of the chain joins look-alike places; the
    sighting cannot say which, so every edge its own pair's sighting does not vouch for goes."""
    ca, cb, T_true = robots
    tr = MapMergeTracker(3, merger="semantic", merge_every=1000, recheck_every=0)
    tr.update([ca, cb, cb], step=0, attempt=False)
    T_12 = translation(60.0, 0.0) if wrong_edge == (1, 2) else np.eye(3)  # 2 is a copy of 1
    tr._edges[(0, 1)], tr._edges[(1, 2)] = T_true.copy(), T_12
    tr._paths = None
    assert tr.merged(2) and tr.transform(0, 2) is not None
    sightings = {(0, 2): _sighted_at(T_true, cb)}  # the truth: robot 2 is where robot 1 is
    if vouched:
        sightings[(0, 1)] = _sighted_at(T_true, cb)
    tr.update([ca, cb, cb], step=1, sightings=sightings)
    assert [(d.i, d.j) for d in tr.drops] == dropped
    assert all(d.cause == "sighting" for d in tr.drops)
    assert tr.merged(2) is (wrong_edge is None)


def test_a_sighted_pair_attempt_does_not_take_a_pose_away_from_the_sighting(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray], monkeypatch: pytest.MonkeyPatch
) -> None:
    """An attempt's pose that puts the seen robot elsewhere than its sighting is refused (here a
    merger that ignores the sighting's guess answers the look-alike first)."""
    ca, cb, T_true = robots
    truth, wrong = _in_crops(ca, cb, T_true), _in_crops(ca, cb, translation(60.0, 0.0) @ T_true)
    merger = _ScriptedWithBest([(wrong, wrong), (truth, truth)])
    tr = MapMergeTracker(2, merger=merger.merge, merge_every=1, recheck_every=0, confirmations=1)
    _constants(monkeypatch, retry_growth=0.0)
    tr.update([ca, cb], step=1, sightings={(0, 1): _sighted_at(T_true, cb)})  # refused
    assert not tr.merged(0)
    tr.update([ca, cb], step=2)  # the true place: merged
    T = tr.transform(0, 1)
    assert T is not None and merge_error(T, T_true, cb)[0] < 0.5


@pytest.mark.parametrize(
    ("place", "binds", "turn_binds", "kept"),
    [
        ("shifted", True, True, True),  # the maps' place puts robot 1 3 m from the sighting
        ("shifted", False, True, False),  # sightings do not bind a merged pair: moved
        ("turned", True, True, True),  # the same position, half a turn from the sighting
        ("turned", True, False, False),  # the heading not judged: moved
    ],
)
def test_a_recheck_does_not_move_a_sighted_pair_away_from_the_sighting(
    robots: tuple[np.ndarray, np.ndarray, np.ndarray],
    place: str,
    binds: bool,
    turn_binds: bool,
    kept: bool,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """A sighting outranks the maps: a re-check whose maps single out another place (which
    would move the pair, see the test above on ``OUTRANKED_DROP``) keeps the pose the robots
    were seen at, when the other place puts the seen robot elsewhere or turns it from the
    sighting's heading by more than ``PRIOR_TURN_DEG``. The place kept here is not the truth:
    the maps and the sighting disagree, and the sighting wins."""
    from mrexplore.merge.semantic import _turn_about

    ca, cb, T_true = robots
    truth = _in_crops(ca, cb, T_true)
    seen = _sighted_at(T_true, cb)
    (x,), (y,) = map_points(np.array([seen.at_j]), T_true)
    sighted = {
        "shifted": translation(60.0, 0.0) @ T_true,
        "turned": chain(_turn_about(180.0, float(x), float(y)), T_true),
    }[place]
    there = _in_crops(ca, cb, sighted)
    merger = _ScriptedWithBest([(there, there), (truth, truth)])
    tr = MapMergeTracker(
        2, merger=merger.merge, merge_every=1, recheck_every=3, confirmations=1, drop_below=0.0
    )
    monkeypatch.setattr(tracker_module, "SIGHTING_BINDS", binds)
    monkeypatch.setattr(tracker_module, "SIGHTING_TURN_BINDS", turn_binds)
    tr.update([ca, cb], step=1)
    tr.update([ca, cb], step=2, sightings={(0, 1): Sighting(sighted, seen.at_j)})
    assert tr.merged(0)
    tr.update([ca, cb], step=3)  # the re-check
    T = tr.transform(0, 1)
    assert T is not None
    assert (merge_error(T, sighted, cb)[0] < 0.5) is kept
    assert (merge_error(T, T_true, cb)[0] < 0.5) is not kept
