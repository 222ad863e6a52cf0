"""Evaluation statistics: confidence intervals, times to a coverage level, paired comparison."""

from __future__ import annotations

import json
import math
import re
from pathlib import Path

import pytest

from mrexplore.errors import ConfigError
from mrexplore.experiments.episode import EpisodeResult
from mrexplore.experiments.evaluate import (
    BASELINES,
    evaluate_team,
    format_evaluation,
    mean_ci,
    paired,
    summarise,
    t_quantile_975,
    time_to_coverage,
)


def _ep(times: list[float], covs: list[float], success: bool = True) -> EpisodeResult:
    return EpisodeResult(
        task_time_s=times[-1],
        success=success,
        coverage=covs[-1],
        times_s=times,
        coverages=covs,
        first_merge_time_s=None,
        merge_error=None,
        collisions=0,
    )


@pytest.mark.parametrize(
    ("df", "t"),
    [(1, 12.706), (5, 2.571), (10, 2.228), (11, 2.201), (20, 2.086), (30, 2.042), (100, 1.984)],
)
def test_t_quantile_matches_the_table(df: int, t: float) -> None:
    assert t_quantile_975(df) == pytest.approx(t, abs=2e-3)


def test_mean_ci() -> None:
    r = mean_ci([2.0, 4.0])
    assert r["mean"] == 3.0 and r["n"] == 2
    half = 12.706 * math.sqrt(2.0) / math.sqrt(2)
    assert r["ci_low"] == pytest.approx(3.0 - half) and r["ci_high"] == pytest.approx(3.0 + half)
    assert mean_ci([1.0])["ci_low"] is None


def test_time_to_coverage_and_censoring() -> None:
    ep = _ep([0.0, 1.0, 2.0, 3.0], [0.5, 0.85, 0.91, 0.96])
    assert time_to_coverage(ep, 0.9) == 2.0 and time_to_coverage(ep, 0.95) == 3.0
    short = _ep([0.0, 1.0, 5.0], [0.5, 0.92, 0.93], success=False)
    assert time_to_coverage(short, 0.95) is None
    s = summarise([ep, short], times_s=(1.0,))
    # never reached: counted with the episode's end time, and apart
    assert s["time_to"]["0.95"]["values"] == [3.0, 5.0]
    assert s["time_to"]["0.95"]["reached"] == 1
    assert s["time_to"]["0.9"]["values"] == [2.0, 1.0]


def test_paired_comparison() -> None:
    p = paired([10.0, 12.0, 9.0], [11.0, 12.0, 12.0])
    assert p["mean"] == pytest.approx(-4.0 / 3.0)
    assert (p["a_lower"], p["equal"], p["a_higher"]) == (2, 1, 0)
    assert p["ci_low"] < p["mean"] < p["ci_high"]


def test_format_prints_what_was_measured() -> None:
    ep = _ep([0.0, 1.0, 2.0], [0.5, 0.91, 0.96])
    s = summarise([ep, ep], times_s=(1.0,))
    doc = {
        "seeds": [1, 2],
        "paired_baseline": "coordinated-frontier",
        "worlds": {
            "w": {
                "results": {"trained": s, "coordinated-frontier": s},
                "paired": {"trained": {"time_to_0.95": paired([2.0, 2.0], [2.0, 2.0])}},
            }
        },
    }
    text = format_evaluation(doc)
    assert "world w" in text and "2/2" in text and "paired trained - coordinated-frontier" in text


def test_intervals_stay_within_what_the_data_allow() -> None:
    # two very different episodes: the t interval of a time would reach far below 0 s
    fast = _ep([0.0, 1.0, 2.0], [0.5, 0.91, 0.96])
    slow = _ep([0.0, 20.0, 40.0], [0.1, 0.5, 0.96])
    s = summarise([fast, slow], times_s=(10.0,))
    t95 = s["time_to"]["0.95"]
    assert t95["mean"] - 12.706 * t95["std"] / 2**0.5 < 0  # what the formula alone gives
    assert t95["ci_low"] == 0.0 and t95["ci_high"] > t95["mean"]
    cov = s["coverage_at"]["10"]
    assert 0.0 <= cov["ci_low"] <= cov["mean"] <= cov["ci_high"] <= 1.0
    # a difference may be negative: no bound
    assert paired([2.0, 40.0], [30.0, 31.0])["ci_low"] < -20


@pytest.mark.parametrize(("n", "too_small"), [(1, True), (2, True), (3, False)])
def test_tables_say_n_too_small_below_three_seeds(n: int, too_small: bool) -> None:
    eps = [_ep([0.0, 1.0, 2.0 + k], [0.5, 0.91, 0.96]) for k in range(n)]
    s = summarise(eps, times_s=(1.0,))
    doc = {"seeds": list(range(n)), "worlds": {"w": {"results": {"trained": s}}}}
    text = format_evaluation(doc)
    assert ("[n too small]" in text) is too_small
    assert (re.search(r"\[\d+\.\d, \d+\.\d\]", text) is None) is too_small


@pytest.mark.parametrize("planners_finish", [True, False])
def test_the_table_says_its_cap_and_when_the_cap_decides_it(planners_finish: bool) -> None:
    done = _ep([0.0, 50.0, 100.0], [0.5, 0.91, 0.96], success=True)
    cut = _ep([0.0, 75.0, 150.0], [0.2, 0.5, 0.7], success=False)
    s = summarise([done if planners_finish else cut] * 3, times_s=(60.0,))
    doc = {
        "seeds": [1, 2, 3],
        "env": {"world": "w", "max_time_s": 150.0, "target_coverage": 0.95},
        "results": {"trained": summarise([cut] * 3, times_s=(60.0,)), "nearest-frontier": s},
    }
    text = format_evaluation(doc)
    assert text.splitlines()[0].endswith("episodes capped at 150 s, target coverage 95%")
    assert ("no frontier planner reached the target within 150 s" in text) is not planners_finish


class _Forward:
    """A stand-in for a policy trained elsewhere (TorchRL, ...): acts on the observations."""

    uses_observations = True

    def __init__(self, agents: list[str]) -> None:
        self.agents = agents

    def reset(self, rng: object) -> None:
        pass

    def act_obs(self, obs: dict) -> dict[str, int]:
        return {a: 0 for a in obs}


def test_any_team_policy_is_evaluated_against_the_planners(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    env = {"world": "small_office", "n_robots": 2, "max_time_s": 5.0}
    doc = evaluate_team(_Forward, env, n_seeds=1, out=tmp_path / "e", name="mine", progress=False)
    assert set(doc["results"]) == {"mine", *BASELINES}
    assert set(doc["paired"]) == {"mine"} and doc["env"]["task"] == "explore"
    assert json.loads((tmp_path / "e" / "eval.json").read_text())["policy"] == "mine"
    assert "mine" in capsys.readouterr().out
    with pytest.raises(ConfigError, match="factory"):
        evaluate_team("not callable", env, n_seeds=1)  # type: ignore[arg-type]
    with pytest.raises(ConfigError, match="at least 1 seed"):
        evaluate_team(_Forward, env, n_seeds=0)


def forward_team(agents: list[str]) -> _Forward:
    """The factory ``mrexplore evaluate --team-factory test_evaluate:forward_team`` imports
    (pytest puts this folder on the import path)."""
    return _Forward(agents)


def not_a_policy(agents: list[str]) -> object:
    return object()


def test_the_command_evaluates_a_team_factory_like_a_folder(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    from mrexplore.cli import main

    out = tmp_path / "e"
    env = ["--env", "world=small_office", "--env", "n_robots=2", "--max-time-s", "5"]
    argv = ["evaluate", "--team-factory", "test_evaluate:forward_team", *env, "--seeds", "1"]
    assert main([*argv, "--out", str(out)]) == 0
    doc = json.loads((out / "eval.json").read_text())
    assert set(doc["results"]) == {"test_evaluate:forward_team", *BASELINES}
    assert doc["env"]["world"] == "small_office" and doc["env"]["max_time_s"] == 5.0
    assert "wrote" in capsys.readouterr().out
    assert main([*argv, "--out", str(out)]) == 2  # results are not replaced without --force
    assert "--force" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("spec", "words"),
    [
        ("test_evaluate", "package.module:function"),
        ("no_such_module_xyz:f", "cannot import 'no_such_module_xyz'"),
        ("test_evaluate:nope", "has no attribute 'nope'"),
        ("test_evaluate:BASELINES", "not a callable"),
        ("test_evaluate:not_a_policy", "without reset() and act()"),
    ],
)
def test_a_bad_team_factory_is_one_clear_line(
    tmp_path: Path, spec: str, words: str, capsys: pytest.CaptureFixture[str]
) -> None:
    from mrexplore.cli import main

    rc = main(["evaluate", "--team-factory", spec, "--seeds", "1", "--out", str(tmp_path / "e")])
    err = capsys.readouterr().err.strip().splitlines()
    assert rc == 2 and len(err) == 1 and words in err[0] and not (tmp_path / "e").exists()


def test_evaluate_takes_a_folder_or_a_factory(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    from mrexplore.cli import main
    from mrexplore.experiments.evaluate import parse_env_options

    assert main(["evaluate", "--seeds", "1"]) == 2
    assert "policy folder or --team-factory" in capsys.readouterr().err
    both = ["evaluate", str(tmp_path), "--team-factory", "test_evaluate:forward_team"]
    assert main(both) == 2 and "not both" in capsys.readouterr().err
    assert main(["evaluate", str(tmp_path), "--env", "n_robots=3"]) == 2
    assert "--env" in capsys.readouterr().err
    assert parse_env_options(["n_robots=3", "max_time_s=5.0", "obs_dtype=float32"]) == {
        "n_robots": 3,
        "max_time_s": 5.0,
        "obs_dtype": "float32",
    }
    with pytest.raises(ConfigError, match="KEY=VALUE"):
        parse_env_options(["n_robots"])
