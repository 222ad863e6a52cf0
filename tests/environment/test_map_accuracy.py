"""Map-accuracy infos (fused_contradiction, merged_wrongly_s) and coverage_mode="held"."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

import mrexplore
from mrexplore.truth import MapScorer

SMALL: dict[str, Any] = {"world": "small_office", "n_robots": 2}


def test_infos_carry_map_accuracy_on_every_step() -> None:
    penv = mrexplore.parallel_env(**{**SMALL, "max_cycles": 30})
    _, infos = penv.reset(seed=1)
    rng = np.random.default_rng(0)
    while True:
        for i in infos.values():
            c, w = i["fused_contradiction"], i["merged_wrongly_s"]
            assert isinstance(c, float) and (math.isnan(c) or 0.0 <= c <= 1.0)
            assert c < 0.05  # a correct own map (no odometry noise) barely contradicts
            assert isinstance(w, float) and w == 0.0
            assert {"coverage", "merged", "merge_error", "first_merge_time_s"} <= set(i)
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
    warp = penv._scorer.warp
    monkeypatch.setattr(penv._scorer, "warp", lambda *a: calls.append(1) or warp(*a))
    for _ in range(5):
        penv.step({a: 3 for a in penv.agents})
    assert calls == []  # unchanged maps cost nothing
    penv.step({a: 0 for a in penv.agents})  # moving changes the maps
    assert len(calls) == 2


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
