"""Bad options of ``mrexplore bench merge|env`` are errors (exit 2) before any work."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrexplore.cli import main


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["merge", "--methods", "bogus"], "unknown method(s) ['bogus']"),
        (["merge", "--detectors", "nope"], "unknown detector(s) ['nope']"),
        (["merge", "--families", "moon"], "unknown family"),
        (["merge", "--n", "-1"], "n_cases must be >= 1"),
        (["merge", "--n", "0"], "--n 0 runs only --sizes or --tracker"),
        (["merge", "--seeds", "0-x"], "--seeds: '0-x' is not a seed or a range"),
        (["merge", "--seeds", "5-2"], "--seeds: '5-2' must be seeds >= 0"),
        (
            ["merge", "--families", "lidar", "--lidar-options", "map_l_occ=9"],
            "--lidar-options: option map_l_occ must be in [0.62, 5]",
        ),
        (["merge", "--lidar-options", "map_l_occ=2.6"], "the lidar family is not among"),
        (["env", "--steps", "0"], "--steps must be at least 1"),
        (["env", "--seed", "-1"], "--seed must be an integer >= 0"),
        (["env", "--merge-latency-steps", "x"], "--merge-latency-steps must be integers >= 0"),
        (["env", "--merge-latency-steps", "0,-2"], "--merge-latency-steps must be integers >= 0"),
        (["env", "--evaluate", "yes"], "--evaluate must be 1 and/or 0"),
        (["env", "--batched", "0,8"], "--batched must be integers >= 1"),
        (["env", "--batched", "x"], "--batched must be integers >= 1"),
        (["env", "--batched", "2", "--batched-steps", "0"], "--batched-steps must be at least 1"),
        (["env", "--batched-only"], "--batched-only needs --batched"),
        (["env", "--rollout", "bogus"], "--rollout must name team policies"),
    ],
)
def test_bench_bad_options_exit_2(args: list[str], words: str, capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["bench", *args]) == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1


def test_bench_outputs_are_not_overwritten(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    (tmp_path / "r.md").write_text("earlier")
    assert main(["bench", "merge", "--n", "1", "--out", str(tmp_path / "r")]) == 2
    assert "already exists" in capsys.readouterr().err
    (tmp_path / "e.json").write_text("earlier")
    assert main(["bench", "env", "--steps", "1", "--json", str(tmp_path / "e.json")]) == 2
    assert "already exists" in capsys.readouterr().err
    assert (tmp_path / "r.md").read_text() == (tmp_path / "e.json").read_text() == "earlier"


def test_lidar_options_make_the_lidar_maps_and_are_recorded() -> None:
    """``--lidar-options`` reach the env of the lidar family's episodes (here the mapper's hit
    weight changes the maps) and are recorded in the row and its table's heading."""
    from mrexplore.studies.merge_bench import make_cases, run_bench, to_markdown

    base = make_cases("lidar", 1, 0)[0]
    former = make_cases("lidar", 1, 0, {"map_l_occ": 1.4})[0]
    assert base.name == former.name and not np.array_equal(base.a, former.a)
    rows = run_bench(1, methods=["semantic"], families=["lidar"], lidar_options={"map_l_occ": 1.4})
    assert rows[0]["lidar_options"] == {"map_l_occ": 1.4}
    assert "### lidar (1 cases; maps made with map_l_occ=1.4)" in to_markdown(rows)


def test_merge_sizes_prints_time_and_outcomes_per_size(capsys) -> None:  # type: ignore[no-untyped-def]
    assert main(["bench", "merge", "--n", "0", "--sizes", "120"]) == 0
    out = capsys.readouterr().out
    assert "semantic merge, 120 x 120 cells, 10 pairs: median" in out
    assert "ms CPU" in out and "wrong" in out


def test_env_breakdown_times_every_stage() -> None:
    from mrexplore.studies.env_bench import STAGES, measure

    r = measure(5, 0, warmup=1, breakdown=True, world="small_office", merger=None)
    assert set(r["ms_per_step"]) == {*STAGES, "other"}
    assert all(r["ms_per_step"][k] > 0 for k in STAGES)
    # wall time holds the stepping thread's CPU time (and any wait for the merge worker)
    assert r["wall_s"] >= 0.9 * r["cpu_s"] > 0 and r["steps_per_wall_s"] == 5 / r["wall_s"]


def test_env_rollout_row_splits_the_step_between_policy_and_env(capsys) -> None:  # type: ignore[no-untyped-def]
    """``--rollout``: one row per team, the policy's and the env's parts of the stepping thread
    (not timed: a tiny run)."""
    from mrexplore.studies.env_bench import measure_rollout

    r = measure_rollout(4, 0, "coordinated-frontier", warmup=1, world="small_office")
    assert r["steps"] == 4 and r["policy_ms"] > 0 and r["env_ms"] > 0
    assert r["thread_ms"] == pytest.approx(r["policy_ms"] + r["env_ms"])
    assert r["max_over_p50"] >= 1.0
    assert r["wall_ms"] > 0 and r["merge_attempts"] >= 0 and r["merge_ms"] >= 0.0
    args = ["bench", "env", "--rollout", "coordinated-frontier", "--batched-only", "--steps", "2"]
    assert main([*args, "--merge-latency-steps", "0,8"]) == 0
    out = capsys.readouterr().out
    assert "policy/proc" in out and "max/p50" in out and "attempts" in out
    assert "coordinated-frontier, symmetric_office, 2 robots, merger semantic, latency 8" in out
    assert "coordinated-frontier, symmetric_office, 2 robots, merger semantic, latency 0" in out
    assert main([*args, "--env-options", "merge_every=20"]) == 0
    assert "merger semantic, merge_every=20" in capsys.readouterr().out
    assert main([*args, "--env-options", "world=small_office,n_robots=3"]) == 0
    assert (
        "coordinated-frontier, small_office, 3 robots, merger semantic" in capsys.readouterr().out
    )
    assert main([*args, "--env-options", "merge_every=0"]) == 2  # refused before any row
    assert "merge_every must be an integer >= 1" in capsys.readouterr().err
    assert main(["bench", "env", "--env-options", "merge_every=20"]) == 2
    assert "--env-options applies to the --rollout rows" in capsys.readouterr().err
    assert "symmetric_office, 1 robot " not in out  # --batched-only


def test_env_json_holds_every_row_and_the_machine(tmp_path: Path) -> None:
    import json

    out = tmp_path / "env.json"
    args = ["bench", "env", "--rollout", "coordinated-frontier", "--batched-only", "--steps", "2"]
    assert main([*args, "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert set(doc) == {
        "rollout, coordinated-frontier, symmetric_office, 2 robots, merger semantic",
        "machine",
    }
    assert doc["machine"]["cores"] >= 1 and doc["machine"]["usable_cores"] >= 1
    assert main([*args, "--json", str(out)]) != 0  # an existing result is kept without --force


def test_env_batched_rows_run_on_a_tiny_setting(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """``--batched``: one row per number of worlds (not timed: a tiny run)."""
    out_json = tmp_path / "b.json"
    args = ["bench", "env", "--batched", "1,2", "--batched-only", "--batched-steps", "2"]
    assert main([*args, "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "batch/s" in out and "robot-st/proc-s" in out and "robot-st/wall-s" in out
    assert "batched, N = 1 worlds x 2 robots" in out and "batched, N = 2 worlds x 2 robots" in out
    assert "symmetric_office, 1 robot" not in out  # --batched-only
    import json

    rows = json.loads(out_json.read_text())
    r = rows["batched, N = 2 worlds x 2 robots, merger semantic"]
    assert r["num_envs"] == 2 and r["n_robots"] == 2 and r["steps"] == 2
    assert r["robot_steps_per_s"] == pytest.approx(4 * r["batch_steps_per_s"])


def test_merge_seeds_pool_the_cases_of_each_seed() -> None:
    from mrexplore.studies.merge_bench import run_bench

    one = run_bench(2, methods=["semantic"], families=["real"], seed=1)[0]
    pooled = run_bench(2, methods=["semantic"], families=["real"], seeds=[0, 1])[0]
    assert pooled["n"] == 4
    names = [c["case"] for c in pooled["cases"]]
    assert names[2:] == [f"{c['case']} (seed 1)" for c in one["cases"]]
    assert [c["kind"] for c in pooled["cases"][2:]] == [c["kind"] for c in one["cases"]]
    assert all(n.endswith(" (seed 0)") for n in names[:2])
    assert pooled["correct_overlap40"].count("/") == 1


def test_merge_seeded_row_hands_the_merger_the_truth(monkeypatch) -> None:  # type: ignore[no-untyped-def]
    """``seeded`` runs only when named, and calls the semantic merger with the case's true pose
    among its hypotheses (and nothing else changed)."""
    from mrexplore.studies import merge_bench

    calls: list[dict] = []
    real = merge_bench.merge_maps

    def spy(a, b, method="semantic", **kw):  # type: ignore[no-untyped-def]
        calls.append({"method": method, **kw})
        return real(a, b, method=method, **kw)

    monkeypatch.setattr(merge_bench, "merge_maps", spy)
    rows = merge_bench.run_bench(2, methods=["semantic", "seeded"], families=["symmetric"])
    assert [r["method"] for r in rows] == ["semantic", "seeded"]
    cases = merge_bench.make_cases("symmetric", 2, 0)
    plain, seeded = calls[:2], calls[2:]
    assert all("extra_hypotheses" not in c for c in plain)
    for c, case in zip(seeded, cases, strict=True):
        assert c["method"] == "semantic"
        np.testing.assert_array_equal(c["extra_hypotheses"][0], case.T_ab)
    assert rows[1]["wrong"] == 0
    assert "seeded" not in {r["method"] for r in merge_bench.run_bench(1, families=["symmetric"])}


def test_large_cases_reach_past_the_large_map_bound() -> None:
    """The large family's maps are where the merger's large-map rule acts (b, rotated, beyond
    640 x 640 cells), with the truth known and the resolution of their source."""
    from mrexplore.merge.rotation import hough_pool
    from mrexplore.studies.merge_cases import LARGE_CROP, large_cases

    cases = large_cases(5, seed=0)
    assert [c.name.split("#")[0] for c in cases] == [
        "symmetric_office",
        "twin_wings",
        "warehouse",
        "noisy_office",
        "noisy_warehouse",
    ]
    assert {c.family for c in cases} == {"large"}
    assert {c.resolution_m for c in cases} == {0.05, 0.03}
    for c in cases:
        assert LARGE_CROP[0] <= min(c.a.shape) and max(c.a.shape) <= LARGE_CROP[1]
        assert 0.0 <= c.overlap <= 1.0
    assert sum(hough_pool(c.a.shape, c.b.shape, 409_600) > 1 for c in cases) >= 3


def test_aliased_cases_do_not_overlap() -> None:
    """The aliased family's two crops are disjoint: b under the truth lands on none of a's
    cells, so a refusal is the right answer and any merge is counted wrong."""
    import numpy as np

    from mrexplore.studies.merge_bench import classify
    from mrexplore.studies.merge_cases import aliased_cases, overlap_share

    cases = aliased_cases(4, seed=0)
    assert {c.family for c in cases} == {"aliased"}
    for c in cases:
        assert overlap_share(c.a, c.b, c.T_ab) == 0.0
        assert classify(c, False, None)[0] == "refused"
        assert classify(c, True, np.eye(3))[0] == "wrong"


def test_seeded_summary_counts_rescues_refusals_and_losses() -> None:
    from mrexplore.studies.merge_bench import COLUMNS, seeded_summary, to_markdown

    def row(method: str, kinds: list[str]) -> dict:
        cases = [
            {"overlap": ov, "kind": k}
            for ov, k in zip([0.5, 0.6, 0.7, 0.2, 0.9], kinds, strict=True)
        ]
        return {"method": method, "options": "-", "family": "real", "cases": cases}

    default = row("semantic", ["refused", "refused", "correct", "refused", "refused"])
    seeded = row("seeded", ["correct", "refused", "refused", "correct", "wrong"])
    text = seeded_summary(default, seeded)
    # overlap >= 40 %: refusals at 0.5, 0.6, 0.9 (0.2 is below): one rescued, one wrong, one
    # still refused; the correct merge at 0.7 is lost
    assert "default's 3 refusals, 1 become correct" in text
    assert "1 imprecise or wrong, 1 stay refused" in text
    assert "1 of its correct merges are not correct" in text
    for r in (default, seeded):
        r.update({c: 0 for c in COLUMNS if c not in r} | {"n": 5})
    assert text in to_markdown([default, seeded])
    assert "true pose" not in to_markdown([default])


def test_guided_guess_lies_within_its_bounds_and_repeats() -> None:
    """The ``guided`` method's guess moves b's centre at most GUIDE_SHIFT_CELLS from where the
    truth puts it and turns it at most GUIDE_TURN_DEG, and is the same on every call."""
    from mrexplore.grid import UNKNOWN, map_points, transform_angle
    from mrexplore.studies import merge_bench as mb

    for case in mb.make_cases("real", 4, 3):
        p, q = mb.guide(case), mb.guide(case)
        np.testing.assert_array_equal(p.T_ab, q.T_ab)
        assert (p.radius_cells, p.turn_deg) == (mb.GUIDE_RADIUS_CELLS, mb.GUIDE_REGION_DEG)
        rows, cols = np.nonzero(case.b != UNKNOWN)
        centre = np.array([[cols.mean(), rows.mean()]])
        x0, y0 = map_points(centre, case.T_ab)
        x1, y1 = map_points(centre, p.T_ab)
        assert np.hypot(x1 - x0, y1 - y0)[0] <= mb.GUIDE_SHIFT_CELLS + 1e-9
        turn = np.degrees(transform_angle(p.T_ab) - transform_angle(case.T_ab))
        assert abs((turn + 180) % 360 - 180) <= mb.GUIDE_TURN_DEG + 1e-9


def test_a_refusal_records_how_far_its_judged_pose_lay_from_the_truth() -> None:
    """A refusal after the judgement keeps the pose it refused; the bench measures it against
    the truth (``best_error_cells``, evaluation only): here the truth, refused by a shared-space
    floor no pair can meet. Merges record None."""
    from mrexplore.studies import merge_bench as mb

    cases = mb.make_cases("real", 2, 3)
    refused = mb.evaluate(cases, "semantic", None, min_common_m2=1e9)["cases"]
    assert [c["kind"] for c in refused] == ["refused", "refused"]
    judged = [c["best_error_cells"] for c in refused]
    assert all(e is not None and e < mb.CORRECT_CELLS for e in judged), judged
    merged = mb.evaluate(cases, "semantic", None)["cases"]
    assert all(c["best_error_cells"] is None for c in merged if c["kind"] != "refused")


def test_env_rollout_counts_the_merge_work_of_the_timed_steps_only() -> None:
    """The rollout's merge attempts are those applied during its timed steps, across episode
    resets: a longer run applies at least as many, and they cost CPU."""
    from mrexplore.studies.env_bench import measure_rollout

    opts = {"world": "small_office", "merge_latency_steps": 0, "max_time_s": 4.0}
    short = measure_rollout(10, 0, "coordinated-frontier", warmup=0, **opts)
    long = measure_rollout(90, 0, "coordinated-frontier", warmup=0, **opts)
    assert long["episodes"] > 1  # 40-step episodes: the count goes on across resets
    assert long["merge_attempts"] > short["merge_attempts"] >= 1
    assert long["merge_ms"] > 0.0
    none = measure_rollout(10, 0, "coordinated-frontier", warmup=0, merger=None, **opts)
    assert (none["merge_attempts"], none["merge_rechecks"], none["merge_ms"]) == (0, 0, 0.0)
