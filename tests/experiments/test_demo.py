"""The demo's per-pair summary: when each robot pair merged and how long it held a wrong merge."""

from __future__ import annotations

from pathlib import Path
from types import SimpleNamespace
from typing import Any

import numpy as np
import pytest

from mrexplore.experiments import demo
from mrexplore.experiments.demo import PairLedger, PairRecord, format_pairs
from mrexplore.experiments.episode import EpisodeResult, run_episode
from mrexplore.experiments.task_time import make_team
from mrexplore.grid import make_transform
from mrexplore.merge.common import MergeResult
from mrexplore.studies.oracle import OracleMerger

RIGHT = {"translation_cells": 0.5, "rotation_deg": 0.1, "drift_cells": 0.0}
WRONG = {"translation_cells": 40.0, "rotation_deg": 0.0, "drift_cells": 0.0}


class _Truth:
    """Merge errors as a script: ``errors[agent][teammate]`` (set before each step)."""

    def __init__(self) -> None:
        self.errors: dict[str, dict[str, dict[str, float]]] = {}

    def merge_errors(self, agent: str, transforms: dict[str, Any]) -> dict[str, Any]:
        return {b: e for b, e in self.errors.get(agent, {}).items() if b in transforms}


def _fake_env(agents: list[str]) -> tuple[Any, _Truth]:
    truth = _Truth()
    episode = SimpleNamespace(
        truth=truth, sim=SimpleNamespace(time_s=0.0), transforms={a: {} for a in agents}
    )
    return SimpleNamespace(possible_agents=agents, episode=episode), truth


def _hold(env: Any, truth: _Truth, a: str, b: str, err: dict[str, float] | None) -> None:
    """``a`` holds a transform to ``b`` with error ``err`` (None: holds none)."""
    if err is None:
        env.episode.transforms[a].pop(b, None)
        truth.errors.get(a, {}).pop(b, None)
    else:
        env.episode.transforms[a][b] = np.eye(3)
        truth.errors.setdefault(a, {})[b] = err


def test_the_ledger_times_each_pairs_merge_and_wrong_merge() -> None:
    agents = ["robot_0", "robot_1", "robot_2"]
    env, truth = _fake_env(agents)
    ledger = PairLedger()
    ledger.bind(env)
    script = [
        # (time s, changes): robot_0 merges robot_1 right at 1 s; robot_2 holds a wrong
        # transform to robot_0 from 2 s to 3 s, then a right one
        (1.0, [("robot_0", "robot_1", RIGHT)]),
        (2.0, [("robot_2", "robot_0", WRONG)]),
        (3.0, []),
        (4.0, [("robot_2", "robot_0", RIGHT)]),
    ]
    for step, (t, changes) in enumerate(script, start=1):
        env.episode.sim.time_s = t
        for a, b, err in changes:
            _hold(env, truth, a, b, err)
        ledger.step(step)
    p01 = ledger.pairs[("robot_0", "robot_1")]
    p02 = ledger.pairs[("robot_0", "robot_2")]
    p12 = ledger.pairs[("robot_1", "robot_2")]
    assert (p01.first_merge_time_s, p01.wrong_merge, p01.merged_wrongly_s) == (1.0, False, 0.0)
    assert (p02.first_merge_time_s, p02.first_wrong_time_s, p02.merged_wrongly_s) == (
        2.0,
        2.0,
        2.0,  # wrong after the steps ending at 2 s and 3 s, one second each
    )
    assert p12.first_merge_time_s is None and not p12.wrong_merge
    text = format_pairs(ledger.pairs).splitlines()
    assert "robot_0 - robot_1: merged at t = 1.0 s, no wrong merge" in text[1]
    assert "robot_0 - robot_2: merged at t = 2.0 s, held a WRONG merge for 2.0 s" in text[2]
    assert text[3].endswith("robot_1 - robot_2: never merged")
    assert text[4].startswith("  WARNING: 1 of 3 pairs held a wrong merge")


def test_one_robot_has_no_pair_lines() -> None:
    assert format_pairs({}) == ""
    assert "WARNING" not in format_pairs({("robot_0", "robot_1"): PairRecord(3.0)})


def test_the_demo_prints_a_wrong_merge(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    # The episode is synthetic: one step after which robot_1 holds a wrong transform to robot_0.
    def fake_run(opts: Any, team: Any, seed: int, **kw: Any) -> EpisodeResult:
        env, truth = _fake_env(["robot_0", "robot_1"])
        kw["prepare"](env)
        env.episode.sim.time_s = 0.25
        _hold(env, truth, "robot_1", "robot_0", WRONG)
        kw["on_step"](1)
        frame = np.zeros((8, 8, 3), np.uint8)
        return EpisodeResult(0.25, False, 0.1, [0.0, 0.25], [0.0, 0.1], 0.25, WRONG, 0, [frame])

    monkeypatch.setattr(demo, "run_episode", fake_run)
    summary = demo.run_demo(out=tmp_path, world="small_office")
    out = capsys.readouterr().out
    assert "robot_0 - robot_1: merged at t = 0.2 s, held a WRONG merge for 0.2 s" in out
    assert "WARNING: 1 of 1 pairs held a wrong merge" in out
    (pair,) = summary["pairs"]
    assert pair["robots"] == ["robot_0", "robot_1"] and pair["wrong_merge"] is True
    assert pair["merged_wrongly_s"] == 0.25


class _ShiftedOracle(OracleMerger):
    """The true transform moved by 40 cells (2 m): a deliberately wrong merge."""

    def merge_pair(self, *args: Any) -> MergeResult:
        res = super().merge_pair(*args)
        if res.transform is not None:
            res.transform = make_transform(0.0, 40.0, 0.0) @ res.transform
        return res


def test_the_ledger_agrees_with_the_envs_wrong_merge_seconds() -> None:
    # A real episode with a wrong merger: the pair's seconds are the env's merged_wrongly_s
    # (two robots: both hold the one wrong transform of the pair).
    oracle, ledger = _ShiftedOracle(), PairLedger()

    def prepare(penv: Any) -> None:
        oracle.bind(penv)
        ledger.bind(penv)

    opts = {
        "world": "small_office",
        "n_robots": 2,
        "merger": oracle,
        "recheck_every": 10_000,  # no re-check: the wrong transform stays
        "max_time_s": 20.0,
    }
    team = make_team("nearest-frontier", ["robot_0", "robot_1"], "explore")
    res = run_episode(opts, team, 0, on_step=ledger.step, prepare=prepare)
    (rec,) = ledger.pairs.values()
    assert res.wrong_merge and rec.wrong_merge
    assert rec.first_merge_time_s == res.first_merge_time_s
    assert rec.merged_wrongly_s == pytest.approx(res.merged_wrongly_s)
    assert rec.merged_wrongly_s > 0.0
