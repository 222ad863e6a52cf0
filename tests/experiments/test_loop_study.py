"""The in-loop study: the oracle merger, option checks, tables, and --jobs equal to serial."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import numpy as np
import pytest

import mrexplore
from mrexplore.errors import ConfigError
from mrexplore.experiments.loop_study import (
    VARIANTS,
    OracleMerger,
    SeededMerger,
    format_tables,
    main,
    run_loop_episode,
    run_study,
    summarize,
)
from mrexplore.merge.common import translation


def test_oracle_answers_the_truth_once_the_maps_share_a_cell() -> None:
    oracle = OracleMerger()
    penv = mrexplore.parallel_env(world="small_office", merger=oracle)
    oracle.bind(penv)
    penv.reset(seed=0)  # robots 2 m apart: their first scans overlap
    a, b = penv.local_map("robot_0"), penv.local_map("robot_1")
    res = oracle.merge_pair(0, 1, a, b, (0, 0), (0, 0))
    assert res.matched and res.overlap_cells > 0 and res.method == "oracle"
    np.testing.assert_allclose(res.transform, penv.sim.true_transform(0, 1))
    # crops: the answer maps crop cells to crop cells
    res2 = oracle.merge_pair(0, 1, a[5:, 7:], b[3:, 2:], (7, 5), (2, 3))
    expected = translation(-7, -5) @ penv.sim.true_transform(0, 1) @ translation(2, 3)
    np.testing.assert_allclose(res2.transform, expected)
    nothing = np.full_like(b, -1)
    assert not oracle.merge_pair(0, 1, a, nothing, (0, 0), (0, 0)).matched


def test_oracle_needs_ids_and_a_bound_env() -> None:
    oracle = OracleMerger()
    m = np.zeros((4, 4), dtype=np.int8)
    with pytest.raises(ConfigError):
        oracle.merge(m, m)
    with pytest.raises(ConfigError):
        oracle.merge_pair(0, 1, m, m, (0, 0), (0, 0))


def test_oracle_merges_through_the_tracker_with_confirmations() -> None:
    oracle = OracleMerger()
    penv = mrexplore.parallel_env(world="small_office", merger=oracle)
    oracle.bind(penv)
    _, infos = penv.reset(seed=0)
    assert not infos["robot_0"]["merged"]  # no attempt at reset (single-scan maps)
    rng = np.random.default_rng(5)
    while not infos["robot_0"]["merged"]:
        _, _, _, _, infos = penv.step(
            {a: int(rng.choice(4, p=[0.7, 0.15, 0.15, 0.0])) for a in penv.agents}
        )
    # attempts start at steps 10 and 20 (0.25 s each) and take effect merge_latency_steps
    # later: accepted at the second, agreeing one
    k = penv.config.merge_latency_steps
    assert infos["robot_0"]["first_merge_time_s"] == pytest.approx((20 + k) * 0.25)
    assert infos["robot_0"]["merge_error_cells"] < 1e-6
    T = penv.fusion.transforms("robot_0")["robot_1"]
    np.testing.assert_allclose(T, penv.sim.true_transform(0, 1), atol=1e-9)


def test_seeded_merger_judges_the_truth_by_the_semantic_rules() -> None:
    """The diagnostic ``seeded`` variant: the semantic merger with the true pose among its
    hypotheses, judged by the same rules. On the two first scans the rival test still refuses
    (the truth is judged, not accepted); once the maps grow it merges at the truth, through the
    tracker. It is not a default variant."""
    seeded = SeededMerger()
    penv = mrexplore.parallel_env(world="small_office", merger=seeded)
    seeded.bind(penv)
    _, infos = penv.reset(seed=0)
    a, b = penv.local_map("robot_0"), penv.local_map("robot_1")
    first = seeded.merge_pair(0, 1, a, b, (0, 0), (0, 0))
    assert not first.matched and "ambiguous" in first.reason and first.method == "semantic"
    rng = np.random.default_rng(5)
    for _ in range(400):
        if infos["robot_0"]["merged"]:
            break
        _, _, _, _, infos = penv.step(
            {r: int(rng.choice(4, p=[0.7, 0.15, 0.15, 0.0])) for r in penv.agents}
        )
    assert infos["robot_0"]["merged"]
    assert 0.0 <= infos["robot_0"]["merge_error_cells"] < 2.0
    assert "seeded" not in VARIANTS
    with pytest.raises(ConfigError):
        SeededMerger().merge_pair(0, 1, a, b, (0, 0), (0, 0))


@pytest.mark.parametrize(
    "argv",
    [
        ["--worlds", "no_such_world"],
        ["--seeds", "0"],
        ["--first-seed", "-1"],
        ["--variants", "semantic", "magic"],
        ["--variants", "none", "none"],
        ["--max-time-s", "-5"],
        ["--max-time-s", "nan"],
        ["--jobs", "0"],
        ["--task", "dance"],
        ["--task", "navigate", "--nav-goal", "moon"],
        ["--task", "navigate", "--max-time-s", "100"],
        ["--merge-options", "min_comon_m2=10"],
        ["--merge-options", "min_common_m2=-1"],
        ["--merge-options", "confirmations"],
        ["--env-options", "map_l_oc=2.6"],
        ["--env-options", "map_l_occ=9"],
        ["--env-options", "range_noise_m=0"],
    ],
)
def test_bad_options_fail_before_any_work(
    argv: list[str], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "study"
    assert main([*argv, "--out", str(out)]) == 2
    assert "error" in capsys.readouterr().out
    assert not list(tmp_path.iterdir())


def test_env_options_reach_every_variant(tmp_path: Path) -> None:
    """``--env-options`` go to every variant's env (here the mapper's hit weight, which the
    episode's maps then carry); recorded in the JSON and printed."""
    from mrexplore.experiments.loop_study import episode_options

    for v in ("semantic", "oracle", "none", "single"):
        assert episode_options("depot", v, 60.0, env_options={"map_l_occ": 2.6})["map_l_occ"] == 2.6
    env = mrexplore.parallel_env(
        **episode_options("depot", "none", 60.0, env_options={"map_l_occ": 2.6})
    )
    env.reset(seed=0)
    assert env.sim is not None and env.sim.maps[0].l_occ == 2.6
    out = tmp_path / "study"
    argv = ["--worlds", "small_office", "--seeds", "1", "--variants", "none"]
    argv += ["--max-time-s", "2", "--env-options", "map_l_occ=2.6", "--out", str(out)]
    assert main(argv) == 0
    doc = json.loads(Path(f"{out}.json").read_text())
    assert doc["extra_env_options"] == {"map_l_occ": 2.6} and doc["env_options"]["map_l_occ"] == 2.6
    assert "env options map_l_occ=2.6" in Path(f"{out}.md").read_text()


def test_merge_options_reach_the_semantic_variants_only(tmp_path: Path) -> None:
    """``--merge-options`` go to the env's ``merge_options`` of the variants that merge with the
    named semantic merger; the oracle, the seeded diagnostic and the baselines keep theirs. The
    options are recorded and printed."""
    from mrexplore.experiments.loop_study import episode_options

    mo = {"min_common_m2": 10.0, "confirmations": 3}
    for v in ("semantic", "sighting"):
        assert episode_options("depot", v, 60.0, merge_options=mo)["merge_options"] == mo
    for v in ("oracle", "seeded", "none", "single"):
        assert "merge_options" not in episode_options("depot", v, 60.0, merge_options=mo)
    out = tmp_path / "study"
    argv = ["--worlds", "small_office", "--seeds", "1", "--variants", "semantic"]
    argv += ["--max-time-s", "2", "--merge-options", "confirmations=3", "--out", str(out)]
    assert main(argv) == 0
    assert json.loads(Path(f"{out}.json").read_text())["merge_options"] == {"confirmations": 3}
    assert "merger options confirmations=3" in Path(f"{out}.md").read_text()


def test_outputs_are_not_overwritten_without_force(tmp_path: Path) -> None:
    out = tmp_path / "study"
    Path(f"{out}.md").write_text("keep me")
    argv = ["--worlds", "small_office", "--seeds", "1", "--variants", "none", "single"]
    argv += ["--max-time-s", "2", "--out", str(out)]
    assert main(argv) == 2
    assert Path(f"{out}.md").read_text() == "keep me"
    assert main([*argv, "--force"]) == 0
    doc = json.loads(Path(f"{out}.json").read_text())
    assert [e["variant"] for e in doc["episodes"]] == ["none", "single"]
    assert all(e["task_time_s"] == pytest.approx(2.0) for e in doc["episodes"])
    assert "### small_office" in Path(f"{out}.md").read_text()


#: The env options a study document records (what ``format_tables`` prints in its heading).
_ENV_OPTIONS = {
    "range_noise_m": 0.02,
    "odom_noise_trans": 0.01,
    "odom_noise_rot": 0.005,
    "odom_noise_rot_per_m": 0.001,
    "target_coverage": 0.95,
    "max_time_s": 600.0,
}


def _ep(variant: str, seed: int, t: float, merged_at: float | None, **kw: Any) -> dict[str, Any]:
    return {
        "world": "w",
        "variant": variant,
        "seed": seed,
        "merged": merged_at is not None,
        "first_merge_time_s": merged_at,
        "task_time_s": t,
        "reached": t < 600,
        "coverage": 0.95,
        "wrong_merge": kw.get("wrong", False),
        "merged_wrongly_s": kw.get("wrong_s", 0.0),
        "max_fused_contradiction": kw.get("contr"),
        "merges_lost": kw.get("lost", 0),
    }


def test_summary_and_tables() -> None:
    eps = [
        _ep("semantic", 0, 300.0, 100.0, wrong=True, wrong_s=12.5, contr=0.2, lost=2),
        _ep("semantic", 1, 600.0, None, contr=0.01),
        _ep("oracle", 0, 200.0, 20.0, contr=0.01),
        _ep("oracle", 1, 400.0, 30.0),
    ]
    s = summarize(eps, ["w"], ["semantic", "oracle"])["w"]
    assert s["semantic"]["merged"] == 1 and s["semantic"]["median_first_merge_s"] == 100.0
    assert s["semantic"]["task_time_mean_s"] == 450.0 and s["semantic"]["reached"] == 1
    assert s["semantic"]["wrong_merge_episodes"] == 1 and s["semantic"]["merged_wrongly_s"] == 12.5
    assert s["semantic"]["max_fused_contradiction"] == 0.2
    assert s["semantic"]["vs_oracle"] == pytest.approx(0.5)
    assert s["oracle"]["median_first_merge_s"] == 25.0 and s["oracle"]["vs_oracle"] == 0.0
    assert s["semantic"]["merges_lost"] == 2 and s["oracle"]["merges_lost"] == 0
    # paired on the same seeds: +100 and +200 s; t(1) = 12.706, sd 70.7 -> +-635.3
    p = s["semantic"]["minus_oracle_s"]
    assert p["mean"] == 150.0 and p["ci_low"] == pytest.approx(150.0 - 635.31, abs=0.01)
    assert s["oracle"]["minus_oracle_s"] is None
    old = summarize(
        [{k: v for k, v in e.items() if k != "merges_lost"} for e in eps], ["w"], ["semantic"]
    )["w"]["semantic"]
    assert old["merges_lost"] is None and old["minus_oracle_s"] is None  # no oracle asked for
    doc = {
        "policy": "p",
        "seeds": [0, 1],
        "env_options": _ENV_OPTIONS,
        "summary": {"w": s},
    }
    text = format_tables(doc)
    assert "+150.0 s [-485.3, +785.3]" in text
    assert "+50.0%" in text and "450.0 +- 150.0 s" in text and "1/2" in text
    assert "| semantic | 1/2 |" in format_tables(doc, markdown=True)
    assert not math.isnan(s["oracle"]["task_time_std_s"])


def test_an_option_variant_is_paired_with_the_default_merger() -> None:
    """``sighting`` (and ``seeded``) runs are the semantic merger with one option: the study
    prints each one's paired difference to ``semantic`` per world and over all worlds, and in
    how many episodes the first merge came earlier or later (never merging is latest)."""
    eps = [
        _ep("semantic", 0, 300.0, 100.0),
        _ep("semantic", 1, 400.0, None),
        _ep("sighting", 0, 280.0, 60.0),
        _ep("sighting", 1, 390.0, 90.0),
        {**_ep("semantic", 0, 200.0, 50.0), "world": "v"},
        {**_ep("sighting", 0, 200.0, 70.0), "world": "v"},
    ]
    s = summarize(eps, ["w", "v"], ["semantic", "sighting"])
    d = s["w"]["sighting"]["minus_semantic"]
    assert d["task_time_s"]["mean"] == -15.0 and d["episodes"] == 2
    assert (d["first_merge_earlier"], d["first_merge_later"]) == (2, 0)
    assert "minus_semantic" not in s["w"]["semantic"]
    doc = {
        "policy": "p",
        "seeds": [0, 1],
        "variants": ["semantic", "sighting"],
        "episodes": eps,
        "env_options": _ENV_OPTIONS,
        "summary": s,
    }
    text = format_tables(doc)
    assert "sighting minus semantic, paired over 2 episodes: task time -15.0 s" in text
    # over both worlds: -20, -10 and 0 s; the first merge earlier in 2, later in 1
    assert "all worlds: sighting minus semantic, paired over 3 episodes: task time -10.0 s" in text
    assert "first merge earlier in 2, later in 1" in text


@pytest.mark.expensive
def test_jobs_give_the_serial_results() -> None:
    kw: dict[str, Any] = {
        "worlds": ["small_office"],
        "seeds": 2,
        "first_seed": 0,
        "variants": ["semantic", "oracle"],
        "max_time_s": 15.0,
        "progress": False,
    }
    serial = run_study(jobs=1, **kw)
    parallel = run_study(jobs=2, **kw)
    assert parallel == serial
    assert len(serial["episodes"]) == 4


def test_gain_shares_compare_with_the_oracle_against_both_baselines() -> None:
    eps = [_ep(v, 0, t, None) for v, t in (("semantic", 60.0), ("oracle", 40.0))]
    eps += [_ep("none", 0, 80.0, None), _ep("single", 0, 140.0, None)]
    s = summarize(eps, ["w"], ["semantic", "oracle", "none", "single"])["w"]
    # never merging 80 s, the oracle 40 s, the merger 60 s: half the gain; one robot 140 s: 80 %
    assert s["semantic"]["gain_vs_none"] == pytest.approx(0.5)
    assert s["semantic"]["gain_vs_single"] == pytest.approx(0.8)
    assert all(s[v]["gain_vs_none"] is None for v in ("oracle", "none", "single"))
    assert (
        summarize(eps[:2], ["w"], ["semantic", "oracle"])["w"]["semantic"]["gain_vs_none"] is None
    )


def test_navigation_times_the_drive_after_the_warm_up(tmp_path: Path) -> None:
    """``--task navigate``: the team explores 120 s, then robot_0 drives to its goal; the task
    time counts from the goal, and the head of the table says so."""
    out = tmp_path / "nav"
    argv = ["--worlds", "small_office", "--seeds", "1", "--variants", "none", "single"]
    argv += ["--task", "navigate", "--max-time-s", "125", "--out", str(out)]
    assert main(argv) == 0
    doc = json.loads(Path(f"{out}.json").read_text())
    assert doc["env_options"]["task"] == "navigate" and doc["env_options"]["nav_goal"] == "far"
    assert all(0.0 < e["task_time_s"] <= 5.0 for e in doc["episodes"])
    assert "then robot_0 drives to a goal" in Path(f"{out}.md").read_text()


@pytest.mark.parametrize("seed", [1004, 1007])
def test_two_look_alike_aisles_are_not_merged(seed: int) -> None:
    """Depot, exact odometry: early on the two robots map different aisles whose maps share no
    wall at all; the merger matched them on a few metres of look-alike racks (seed 1004: 104-164
    wall cells, merged wrongly at 12 s; seed 1007: after a run of ambiguous refusals, once the
    search stopped finding the rival, at 37 s). Neither may merge wrongly now."""
    rec = run_loop_episode("depot", "semantic", seed, 45.0, noise=False)
    assert not rec["wrong_merge"] and rec["merged_wrongly_s"] == 0.0


def test_against_prints_and_records_the_paired_difference(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """``--against`` compares a run with another study's episodes of the same seeds: the same
    options give a difference of 0 in every episode; a file that is not a study, or one with
    none of the run's episodes, is refused before any work, and nothing is written."""
    argv = ["--worlds", "small_office", "--seeds", "2", "--variants", "none", "--max-time-s", "3"]
    first, second = tmp_path / "first", tmp_path / "second"
    assert main([*argv, "--out", str(first)]) == 0
    assert main([*argv, "--out", str(second), "--against", f"{first}.json"]) == 0
    doc = json.loads(Path(f"{second}.json").read_text())
    d = doc["against"]["all_worlds"]["none"]
    assert d["episodes"] == 2 and d["task_time_s"]["mean"] == 0.0 and d["reached"] == [0, 0]
    assert "small_office, none: task time +0.0 s" in Path(f"{second}.md").read_text()
    (tmp_path / "junk.json").write_text('{"rows": []}')
    capsys.readouterr()
    third = tmp_path / "third"
    assert main([*argv, "--out", str(third), "--against", str(tmp_path / "junk.json")]) == 2
    assert "is not a loop study's JSON" in capsys.readouterr().out
    assert not Path(f"{third}.json").exists()
    other_seeds = [*argv, "--first-seed", "7"]  # seeds the first run does not hold
    assert main([*other_seeds, "--out", str(third), "--against", f"{first}.json"]) == 2
    assert "holds no episode of this run's" in capsys.readouterr().out
    assert not Path(f"{third}.json").exists()


def test_reuse_takes_the_episodes_a_study_of_the_same_settings_holds(
    tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    """``--reuse`` takes a study's episodes instead of running them (none of them is run again)
    and the document equals a fresh run's but for the count it records; a study made with other
    settings or by other code, one that holds none of the run's episodes, and a file given twice
    are refused before any work, naming why."""
    from mrexplore.experiments import loop_study

    base = ["--worlds", "small_office", "--seeds", "2", "--max-time-s", "3"]
    first, fresh, second = tmp_path / "first", tmp_path / "fresh", tmp_path / "second"
    assert main([*base, "--variants", "none", "--out", str(first)]) == 0
    both = [*base, "--variants", "none", "single"]
    assert main([*both, "--out", str(fresh)]) == 0
    run = loop_study.run_loop_episode

    def only_new(world: str, variant: str, *args: Any, **kw: Any) -> dict[str, Any]:
        assert variant != "none", "a reused episode was run again"
        return run(world, variant, *args, **kw)

    monkeypatch.setattr(loop_study, "run_loop_episode", only_new)
    assert main([*both, "--out", str(second), "--reuse", f"{first}.json"]) == 0
    doc = json.loads(Path(f"{second}.json").read_text())
    assert doc.pop("reused") == {f"{first}.json": 2}
    assert doc == json.loads(Path(f"{fresh}.json").read_text())
    assert f"episodes taken from studies of the same settings: 2 from {first}.json" in (
        Path(f"{second}.md").read_text()
    )
    capsys.readouterr()
    third = tmp_path / "third"
    refusals = [
        (["--env-options", "map_l_occ=2.6"], "env_options map_l_occ: None there, 2.6 here"),
        (["--merge-options", "confirmations=3"], "merge_options confirmations: None there, 3 here"),
        (["--first-seed", "7"], "holds no episode of this run's"),
    ]
    for extra, words in refusals:
        assert main([*both, *extra, "--out", str(third), "--reuse", f"{first}.json"]) == 2
        assert words in capsys.readouterr().out
    assert main([*both, "--out", str(third), "--reuse", f"{first}.json", f"{first}.json"]) == 2
    assert "given twice" in capsys.readouterr().out
    old = json.loads(Path(f"{first}.json").read_text())
    del old["source_digest"]  # a study made before studies recorded their code
    (tmp_path / "old.json").write_text(json.dumps(old))
    assert main([*both, "--out", str(third), "--reuse", str(tmp_path / "old.json")]) == 2
    assert "made by other code, worlds or maps" in capsys.readouterr().out
    assert not Path(f"{third}.json").exists()
