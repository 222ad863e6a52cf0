"""The in-loop study: the oracle merger, option checks, tables, and --jobs equal to serial."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

import mrexplore
from mrexplore.studies.loop_study import (
    main,
    run_loop_episode,
    run_study,
)


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
        ["--merge-options", "NO_SUCH_RULE=1"],
        ["--merge-options", "OUTRANKED_DROP=3"],
        ["--env-options", "map_l_oc=2.6"],
        ["--env-options", "map_l_occ=9"],
        ["--env-options", "range_noise_m=0"],
        ["--env-options", "n_robots=1"],
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
    from mrexplore.studies.loop_study import episode_options

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


def test_a_team_of_three_is_measured_like_a_team_of_two(tmp_path: Path) -> None:
    """``--env-options n_robots=3``: every variant but ``single`` runs three robots, recorded
    and printed; the oracle's team merges without a wrong merge."""
    from mrexplore.studies.loop_study import episode_options

    for v in ("semantic", "sighting", "oracle_room", "none"):
        assert episode_options("depot", v, 60.0, env_options={"n_robots": 3})["n_robots"] == 3
    assert episode_options("depot", "single", 60.0, env_options={"n_robots": 3})["n_robots"] == 1
    assert episode_options("depot", "semantic", 60.0)["n_robots"] == 2
    out = tmp_path / "study"
    argv = ["--worlds", "small_office", "--seeds", "1", "--variants", "sighting", "oracle"]
    argv += ["--max-time-s", "40", "--env-options", "n_robots=3", "--out", str(out)]
    assert main(argv) == 0
    doc = json.loads(Path(f"{out}.json").read_text())
    assert doc["env_options"]["n_robots"] == 3 and len(doc["episodes"]) == 2
    oracle = next(e for e in doc["episodes"] if e["variant"] == "oracle")
    assert oracle["merged"] and not oracle["wrong_merge"]
    assert "n_robots=3 (every variant, but 'single' is one robot)" in Path(f"{out}.md").read_text()


def test_merge_options_reach_the_semantic_variants_only(tmp_path: Path) -> None:
    """``--merge-options`` go to the env's ``merge_options`` of the variants that merge with the
    named semantic merger; the oracle, the seeded diagnostic and the baselines keep theirs. The
    options are recorded and printed."""
    from mrexplore.studies.loop_study import episode_options

    mo = {"min_common_m2": 10.0, "confirmations": 3}
    for v in ("semantic", "sighting", "verify"):
        assert episode_options("depot", v, 60.0, merge_options=mo)["merge_options"] == mo
    for v in ("oracle", "seeded", "none", "single"):
        assert "merge_options" not in episode_options("depot", v, 60.0, merge_options=mo)
    out = tmp_path / "study"
    argv = ["--worlds", "small_office", "--seeds", "1", "--variants", "semantic"]
    argv += ["--max-time-s", "2", "--merge-options", "confirmations=3", "--out", str(out)]
    assert main(argv) == 0
    assert json.loads(Path(f"{out}.json").read_text())["merge_options"] == {"confirmations": 3}
    assert "merger options confirmations=3" in Path(f"{out}.md").read_text()


def test_the_verify_variant_is_the_semantic_team_that_checks_candidates(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``verify``: the env of the ``semantic`` variant, with the team policy
    :data:`VERIFY_POLICY` (``coordinated-frontier-verify``) instead of the study's."""
    from mrexplore.experiments import task_time
    from mrexplore.studies import loop_study

    assert loop_study.episode_options("depot", "verify", 60.0) == loop_study.episode_options(
        "depot", "semantic", 60.0
    )
    asked: list[str] = []
    make = task_time.make_team

    def spy(policy: str, agents: list[str], task: str) -> object:
        asked.append(policy)
        return make(policy, agents, task)

    monkeypatch.setattr(task_time, "make_team", spy)
    for v in ("semantic", "verify"):
        loop_study.run_loop_episode("small_office", v, 0, 1.0)
    assert asked == [loop_study.POLICY, loop_study.VERIFY_POLICY]
    assert loop_study.VERIFY_POLICY == "coordinated-frontier-verify"


def test_the_room_oracle_is_the_oracle_held_to_the_mergers_floor(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """``oracle_room``: the env of the ``oracle`` variant, its oracle waiting for
    :data:`ROOM_EVIDENCE_M2` (a room's worth) of known space under the truth."""
    from mrexplore.studies import loop_study
    from mrexplore.studies.oracle import OracleMerger

    assert loop_study.ROOM_EVIDENCE_M2 == 20.0
    assert "oracle_room" not in loop_study.VARIANTS  # asked for by name
    made: list[float] = []
    init = OracleMerger.__init__

    def spy(self: OracleMerger, min_shared_m2: float = 0.0) -> None:
        made.append(min_shared_m2)
        init(self, min_shared_m2)

    monkeypatch.setattr(OracleMerger, "__init__", spy)
    rec = {
        v: loop_study.run_loop_episode("small_office", v, 0, 10.0)
        for v in ("oracle", "oracle_room")
    }
    assert made == [0.0, loop_study.ROOM_EVIDENCE_M2]
    # the robots start 2 m apart: the oracle merges on its second attempt (7 s), while the maps
    # do not share 20 m^2 yet (the threshold both ways: test_oracle.py)
    assert rec["oracle"]["first_merge_time_s"] == pytest.approx(7.0)
    assert not rec["oracle_room"]["merged"]


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
    from mrexplore.studies import loop_study

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


def test_rule_constants_in_the_merge_options_are_set_for_each_episode_only(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Upper-case ``--merge-options`` are the rules' constants: set while an episode runs (in
    its process), restored after it, and not handed to the env as options."""
    import mrexplore.studies.loop_study as study
    from mrexplore.merge import tracker

    seen: list[tuple[bool, object]] = []

    def fake(*args: object) -> dict[str, object]:
        seen.append((tracker.OUTRANKED_DROP, args[7]))
        return {}

    monkeypatch.setattr(study, "_run_loop_episode", fake)
    study.run_loop_episode(
        "depot", "semantic", 1000, 2.0, merge_options={"OUTRANKED_DROP": False, "confirmations": 3}
    )
    assert seen == [(False, {"confirmations": 3})] and tracker.OUTRANKED_DROP is True


def test_the_meeting_oracle_is_the_oracle_for_robots_that_saw_each_other() -> None:
    """``oracle_meet``: the oracle's env with sightings on and the tracker's ``rendezvous_only``,
    so it merges no earlier than the ``oracle``, and only once the robots have met."""
    from mrexplore.studies import loop_study

    assert "oracle_meet" in loop_study.ALL_VARIANTS and "oracle_meet" not in loop_study.VARIANTS
    opts = loop_study.episode_options("small_office", "oracle_meet", 60.0)
    assert opts["sighting_range_m"] == loop_study.SIGHTING_RANGE_M
    assert opts["merge_options"] == {"rendezvous_only": True}
    rec = {
        v: loop_study.run_loop_episode("small_office", v, 0, 20.0)
        for v in ("oracle", "oracle_meet")
    }
    # the robots start 2 m apart and in view: both merge, the meeting oracle not sooner
    assert rec["oracle_meet"]["merged"]
    assert rec["oracle_meet"]["first_merge_time_s"] >= rec["oracle"]["first_merge_time_s"]
