"""Map-accuracy infos (fused_contradiction, merged_wrongly_s) and coverage_mode="held"."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

import mrexplore
from mrexplore.environment.evaluation import is_wrong_merge
from mrexplore.grid import make_transform
from mrexplore.merge.common import MergeResult
from mrexplore.studies.oracle import OracleMerger
from mrexplore.truth import IncrementalScore, MapScorer

SMALL: dict[str, Any] = {"world": "small_office", "n_robots": 2}


class ShiftedOracle(OracleMerger):
    """The true transform moved by 40 cells (2 m): a deliberately wrong merge."""

    def merge_pair(self, *args: Any) -> MergeResult:
        res = super().merge_pair(*args)
        if res.transform is not None:
            res.transform = make_transform(0.0, 40.0, 0.0) @ res.transform
        return res


def _scripted_run(merger: Any, steps: int, **options: Any) -> list[dict[str, dict[str, Any]]]:
    """Fixed actions (independent of the maps), so runs with different mergers move alike."""
    penv = mrexplore.parallel_env(**{**SMALL, "merger": merger, **options})
    if isinstance(merger, OracleMerger):
        merger.bind(penv)
    _, infos = penv.reset(seed=0)  # robots start 2 m apart: the oracle merges at once
    rng = np.random.default_rng(5)
    out = [infos]
    for _ in range(steps):
        acts = {a: int(rng.choice(4, p=[0.7, 0.15, 0.15, 0.0])) for a in penv.agents}
        _, _, _, _, infos = penv.step(acts)
        out.append(infos)
    return out


def test_infos_carry_map_accuracy_on_every_step() -> None:
    penv = mrexplore.parallel_env(**{**SMALL, "max_cycles": 30})
    _, infos = penv.reset(seed=1)
    rng = np.random.default_rng(0)
    while True:
        for i in infos.values():
            c, w = i["fused_contradiction"], i["merged_wrongly_s"]
            assert isinstance(c, float) and (c == -1.0 or 0.0 <= c <= 1.0)  # -1: no claim
            assert c < 0.05  # a correct own map (no odometry noise) barely contradicts
            assert isinstance(w, float) and w == 0.0
            assert {"coverage", "merged", "merge_error_cells", "first_merge_time_s"} <= set(i)
        if not penv.agents:
            break
        _, _, _, _, infos = penv.step({a: int(rng.integers(4)) for a in penv.agents})


def test_contradiction_is_cached_on_the_fused_map_version(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    penv = mrexplore.parallel_env(**{**SMALL, "range_noise_m": 0.0})
    penv.reset(seed=0)
    penv.step({a: 3 for a in penv.agents})  # stay: the maps settle
    calls = []
    warp = penv.episode.truth.scorer.warp
    monkeypatch.setattr(penv.episode.truth.scorer, "warp", lambda *a: calls.append(1) or warp(*a))
    # the incremental scorer (when OpenCV's sampling could be pinned down) stands for the warp
    for name in ("update", "update_cells"):
        method = getattr(IncrementalScore, name)
        monkeypatch.setattr(
            IncrementalScore,
            name,
            lambda *a, m=method: calls.append(1) or m(*a),  # type: ignore[misc]
        )
    for _ in range(5):
        penv.step({a: 3 for a in penv.agents})
    assert calls == []  # unchanged maps cost nothing
    penv.step({a: 0 for a in penv.agents})  # moving changes the maps
    assert len(calls) == 2


def test_a_wrong_transform_is_seen_and_lowers_held_coverage() -> None:
    steps = 120
    # no re-check: the tracker would drop the wrong transform at step 100
    opts = {"coverage_mode": "held", "recheck_every": 10_000}
    right = _scripted_run(OracleMerger(), steps, **opts)
    wrong = _scripted_run(ShiftedOracle(), steps, **opts)
    merged = [k for k, infos in enumerate(right) if infos["robot_0"]["merged"]]
    assert merged and merged[0] < steps - 20, "the oracle should merge early"
    end_r, end_w = right[-1]["robot_0"], wrong[-1]["robot_0"]
    assert end_w["merged"] and end_w["merge_error_cells"] >= 5.0
    assert end_r["merge_error_cells"] < 1.0
    assert end_w["merged_wrongly_s"] > 0.0 and end_r["merged_wrongly_s"] == 0.0
    assert end_w["fused_contradiction"] > end_r["fused_contradiction"] + 0.02
    # Same motion, same own maps: the wrong merge costs held coverage on every merged step
    # (holding it, each robot is credited with its own map only; the right team with its
    # fused maps), where misplaced free cells landing on true free space once made up for it.
    held_r = np.array([right[k]["robot_0"]["coverage"] for k in merged])
    held_w = np.array([wrong[k]["robot_0"]["coverage"] for k in merged])
    assert (held_w < held_r).all()
    assert held_w.mean() < held_r.mean() - 0.01
    assert end_w["coverage"] < end_r["coverage"] - 0.01


def test_observed_mode_ignores_a_wrong_transform() -> None:
    right = _scripted_run(OracleMerger(), 80)
    wrong = _scripted_run(ShiftedOracle(), 80)
    assert wrong[-1]["robot_0"]["merged_wrongly_s"] > 0.0
    assert [i["robot_0"]["coverage"] for i in wrong] == [i["robot_0"]["coverage"] for i in right]


def test_held_coverage_is_the_best_robots_correctly_placed_free_space() -> None:
    penv = mrexplore.parallel_env(**{**SMALL, "coverage_mode": "held", "target_coverage": 0.3})
    _, infos = penv.reset(seed=3)
    scorer = MapScorer(penv.world.walls, penv.sim.reachable)
    rng = np.random.default_rng(1)
    done = False
    while not done:
        _, _, terms, truncs, infos = penv.step(
            {a: int(rng.choice(4, p=[0.7, 0.15, 0.15, 0.0])) for a in penv.agents}
        )
        held = max(
            scorer.held_free(scorer.warp(penv.fusion.fused(a), penv.sim.world_from_map(k)))
            for k, a in enumerate(penv.possible_agents)
        )
        assert infos["robot_0"]["coverage"] == pytest.approx(held / penv.sim.reachable_cells)
        assert infos["robot_0"]["coverage"] <= penv.sim.coverage() + 1e-9
        done = terms["robot_0"] or truncs["robot_0"]
    assert terms["robot_0"] and infos["robot_0"]["coverage"] >= 0.3


def test_held_coverage_credits_a_robot_holding_a_wrong_transform_with_its_own_map() -> None:
    """Under a wrong merge the held coverage is the best robot's own map (each holds a wrong
    transform), not its fused map, whose shifted teammate cells partly land on free space."""
    merger = ShiftedOracle()
    penv = mrexplore.parallel_env(
        **{**SMALL, "merger": merger, "coverage_mode": "held", "recheck_every": 10_000}
    )
    merger.bind(penv)
    penv.reset(seed=0)
    assert penv.episode is not None and penv.episode.truth is not None and penv.sim is not None
    truth, sim = penv.episode.truth, penv.sim
    scorer = MapScorer(penv.world.walls, sim.reachable)
    rng = np.random.default_rng(5)
    wrong_steps = fused_more = 0
    for _ in range(60):
        acts = {a: int(rng.choice(4, p=[0.7, 0.15, 0.15, 0.0])) for a in penv.agents}
        _, _, _, _, infos = penv.step(acts)
        expect, fused_held = 0, 0
        for k, a in enumerate(penv.possible_agents):
            T = sim.world_from_map(k)
            err = truth.merge_error(a, penv.episode.transforms[a])
            wrong = err is not None and is_wrong_merge(err)
            fused = scorer.held_free(scorer.warp(penv.fusion.fused(a), T))
            own = scorer.held_free(scorer.warp(sim.maps[k].to_int8(), T))
            expect = max(expect, own if wrong else fused)
            fused_held = max(fused_held, fused)
            wrong_steps += wrong
        assert infos["robot_0"]["coverage"] == pytest.approx(expect / sim.reachable_cells)
        fused_more += fused_held > expect
    assert wrong_steps > 50  # the oracle merges (wrongly) at once
    assert fused_more > 10  # steps on which the fused maps' misplaced cells would have counted


@pytest.mark.parametrize("coverage_mode", ["observed", "held"])
def test_incremental_scores_equal_a_full_warp_every_step(
    coverage_mode: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The map accuracy kept from the changed boxes (the own map's changed cells before a
    merge) equals warping and scoring the whole own-or-fused map, at every step, before and
    after a merge, with odometry drift."""
    by_cells = []
    update_cells = IncrementalScore.update_cells
    monkeypatch.setattr(
        IncrementalScore,
        "update_cells",
        lambda *a: by_cells.append(1) or update_cells(*a),  # type: ignore[misc]
    )
    merger = OracleMerger()
    penv = mrexplore.parallel_env(
        **{**SMALL, "merger": merger, "coverage_mode": coverage_mode, "odom_noise_trans": 0.02}
    )
    merger.bind(penv)
    penv.reset(seed=0)
    rng = np.random.default_rng(7)
    assert penv.episode is not None and penv.sim is not None
    merged = False
    for _ in range(60):
        acts = {a: int(rng.choice(4, p=[0.7, 0.15, 0.15, 0.0])) for a in penv.agents}
        _, _, _, _, infos = penv.step(acts)
        for i, a in enumerate(penv.possible_agents):
            truth = penv.episode.truth
            assert truth.incremental.get(i) is not None  # the sampling was pinned down
            merged = merged or infos[a]["merged"]
            warped = penv.episode.truth.scorer.warp(
                penv.fusion.fused(a), penv.sim.world_from_map(i)
            )
            share, held = penv.episode.truth.scorer.scores(warped, held=coverage_mode == "held")
            got = infos[a]["fused_contradiction"]
            assert got == share or (math.isnan(got) and math.isnan(share))
            if held is not None:
                assert penv.episode.truth.map_accuracy(i)[1] == held
    assert merged and len(by_cells) > 20
