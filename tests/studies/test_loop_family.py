"""The loop study on a world family: its flags, the aggregate, the bound, workers equal serial."""

from __future__ import annotations

import json
import math
from pathlib import Path

import pytest

from mrexplore.errors import ConfigError
from mrexplore.studies.loop_report import aggregate, binomial_upper_bound
from mrexplore.studies.loop_study import (
    FAMILY_VARIANTS,
    _worlds_and_variants,
    family_worlds,
    main,
    run_study,
)
from mrexplore.world.family import family_world


@pytest.mark.parametrize(
    ("k", "n", "expect"),
    [
        (0, 20, 1.0 - 0.05 ** (1 / 20)),  # no event: 1 - alpha^(1/n), about 3 / n
        (1, 10, 0.3941633),  # Beta(2, 9) 95 % quantile
        (5, 10, 0.7775589),  # Beta(6, 5)
        (3, 100, 0.0757108),  # Beta(4, 97)
        (10, 10, 1.0),  # every trial: nothing above 1
    ],
)
def test_binomial_upper_bound_is_clopper_pearson(k: int, n: int, expect: float) -> None:
    bound = binomial_upper_bound(k, n)
    assert bound is not None and math.isclose(bound, expect, rel_tol=1e-6)


def test_binomial_upper_bound_edges() -> None:
    assert binomial_upper_bound(0, 0) is None
    with pytest.raises(ValueError, match="0 <= k <= n"):
        binomial_upper_bound(3, 2)


def test_aggregate_counts_over_worlds() -> None:
    def ep(world: str, variant: str, seed: int, merged: bool, wrong: bool, t: float) -> dict:
        return {
            "world": world,
            "variant": variant,
            "seed": seed,
            "merged": merged,
            "first_merge_time_s": 10.0 if merged else None,
            "wrong_merge": wrong,
            "task_time_s": t,
            "reached": True,
            "merged_wrongly_s": 12.5 if wrong else 0.0,
            # a wrong merge is dropped 4 s after the maps first contradicted it
            "drops_s": [[20.0, 24.0]] if wrong else [],
        }

    eps = [
        ep("a", "semantic", 1, True, True, 90.0),
        ep("b", "semantic", 1, False, False, 110.0),
        ep("a", "oracle_room", 1, True, False, 80.0),
        ep("b", "oracle_room", 1, True, False, 100.0),
        ep("a", "none", 1, False, False, 120.0),
        ep("b", "none", 1, False, False, 120.0),
    ]
    agg = aggregate(eps, ["semantic", "oracle_room", "none"])
    sem = agg["variants"]["semantic"]
    assert (sem["episodes"], sem["merged"], sem["wrong_merge_episodes"]) == (2, 1, 1)
    assert sem["wrong_merge_upper95"] == pytest.approx(binomial_upper_bound(1, 2))
    assert (sem["merged_wrongly_s"], sem["drops"], sem["contradiction_to_drop_max_s"]) == (
        12.5,
        1,
        4.0,
    )
    assert sem["first_merge_median_s"] == 10.0
    room = agg["semantic_against"]["oracle_room"]
    assert room["relative_task_time"] == pytest.approx(100.0 / 90.0 - 1.0)
    assert (room["merged_only_semantic"], room["merged_only_oracle_room"]) == (0, 1)
    assert agg["semantic_against"]["none"]["relative_task_time"] == pytest.approx(100 / 120 - 1)
    # of the two episodes the room oracle merged, the merger merged one
    assert sem["merged_where_room_oracle_merged"] == [1, 2]
    assert "merged_where_room_oracle_merged" not in agg["variants"]["none"]
    assert "by_layout" not in agg
    by = aggregate(eps, ["semantic", "oracle_room", "none"], {"a": "hall", "b": "open_plan"})
    hall, plan = by["by_layout"]["hall"]["semantic"], by["by_layout"]["open_plan"]["semantic"]
    assert (hall["episodes"], hall["merged"], hall["wrong_merge_episodes"]) == (1, 1, 1)
    assert (plan["merged"], plan["merged_where_room_oracle_merged"]) == (0, [0, 1])
    assert plan["task_time_mean_s"] == 110.0
    # one layout: no table by layout
    assert "by_layout" not in aggregate(eps, ["semantic"], {"a": "hall", "b": "hall"})


def test_the_report_prints_the_share_and_the_layouts() -> None:
    from mrexplore.studies.loop_report import _layout_lines, _share_text

    assert _share_text([3, 4]) == "3/4 (75%)" and _share_text(None) == _share_text([0, 0]) == "-"
    s = {"episodes": 2, "merged": 1, "wrong_merge_episodes": 0, "task_time_mean_s": 50.0}
    s["merged_where_room_oracle_merged"] = [1, 2]
    doc = {
        "seeds": [1000],
        "family": {"name": "f", "part": "tune", "world_seeds": [0, 1], "layouts": ["x", "y"]},
        "aggregate": {"by_layout": {"x": {"semantic": s}, "y": {"semantic": s}}},
    }
    text = "\n".join(_layout_lines(doc, markdown=False))
    assert "By layout (family f, tune part" in text and "1/2 (50%)" in text
    assert _layout_lines({"aggregate": {}}, markdown=True) == []


@pytest.mark.parametrize(
    ("argv", "words"),
    [
        (["--family", "nope", "--part", "tune"], "unknown family 'nope'"),
        (["--family", "paper_like", "--part", "dev"], "unknown part 'dev'"),
        (["--family", "paper_like"], "--family needs --part"),
        (["--part", "tune"], "--part needs --family"),
        (["--family", "paper_like", "--part", "tune", "--worlds", "0"], "--worlds must be"),
        (["--family", "paper_like", "--part", "tune", "--worlds", "depot"], "how many worlds"),
    ],
)
def test_bad_family_flags_fail_before_any_work(
    argv: list[str], words: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*argv, "--out", str(tmp_path / "x")]) == 2
    assert words in capsys.readouterr().out
    assert not list(tmp_path.iterdir())


def test_family_flags_pick_the_parts_worlds_and_variants() -> None:
    worlds, variants, family = _worlds_and_variants(["3"], None, "office_row", "test")
    assert worlds == [f"family:office_row/test/{k}" for k in range(3)]
    assert variants == list(FAMILY_VARIANTS) and family == ("office_row", "test")
    assert _worlds_and_variants(None, None, None, None)[2] is None  # the fixed worlds
    with pytest.raises(ConfigError, match=r"worlds 0 \.\. 1"):
        run_study(
            ["family:paper_like/tune/1", "family:paper_like/tune/0"], family=("paper_like", "tune")
        )


def test_bench_loop_on_a_family_end_to_end(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "fam"
    argv = ["--family", "paper_like", "--part", "tune", "--worlds", "1", "--seeds", "1"]
    argv += ["--variants", "none", "--max-time-s", "20", "--out", str(out)]
    assert main(argv) == 0
    text = capsys.readouterr().out
    doc = json.loads(Path(f"{out}.json").read_text())
    assert doc["family"] == {
        "name": "paper_like",
        "part": "tune",
        "specs": ["family:paper_like/tune/0"],
        "world_seeds": [0],
        "layouts": [family_world("paper_like", "tune", 0).meta["layout"]],
    }
    assert [e["world"] for e in doc["episodes"]] == ["family:paper_like/tune/0"]
    assert doc["aggregate"]["variants"]["none"]["episodes"] == 1
    # every table says where it was measured
    assert "family:paper_like/tune/0 (world seed 0; episode seeds 1000-1000)" in text
    assert "All worlds (family paper_like, tune part, worlds 0-0 (world seeds 0-0)" in text
    assert "world seed 0" in Path(f"{out}.md").read_text()


def test_family_workers_rebuild_worlds_and_equal_serial() -> None:
    worlds = family_worlds("office_row", "test", 2)
    kw = {"seeds": 1, "variants": ["none"], "max_time_s": 8.0, "progress": False}
    serial = run_study(worlds, jobs=1, family=("office_row", "test"), **kw)  # type: ignore[arg-type]
    pooled = run_study(worlds, jobs=2, family=("office_row", "test"), **kw)  # type: ignore[arg-type]
    assert serial["episodes"] == pooled["episodes"]
    assert serial["family"]["world_seeds"] == [100_000, 100_001]


def test_the_dropped_column_names_the_causes_other_than_contradiction() -> None:
    """A record's ``drop_causes`` are counted per variant; the report's dropped column lists
    the drops not made for the maps' contradiction (older records, without causes: the count)."""
    from mrexplore.studies.loop_report import _drops_text

    base = {"world": "a", "variant": "sighting", "merged": True, "first_merge_time_s": 5.0}
    base |= {"wrong_merge": False, "task_time_s": 50.0, "reached": True, "merged_wrongly_s": 0.0}
    two = {"drops_s": [[1.0, 2.0], [3.0, 3.0]], "drop_causes": ["contradicted", "sighting"]}
    eps = [
        {**base, "seed": 1, **two},
        {**base, "seed": 2, "drops_s": [[4.0, 4.0]], "drop_causes": ["moved"]},
        {**base, "seed": 3, "drops_s": [[5.0, 6.0]]},
    ]
    s = aggregate(eps, ["sighting"])["variants"]["sighting"]
    assert s["drops"] == 4 and s["drop_causes"] == {"contradicted": 1, "moved": 1, "sighting": 1}
    assert _drops_text(s) == "4 (1 moved, 1 sighting)"
    assert _drops_text({"drops": 2, "drop_causes": {}}) == "2"


def test_rendezvous_only_is_refused_for_variants_without_sightings(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["--family", "paper_like", "--part", "tune", "--worlds", "1", "--seeds", "1"]
    argv += ["--merge-options", "rendezvous_only=true", "--out", str(tmp_path / "x")]
    assert main([*argv, "--variants", "semantic", "sighting"]) == 2
    assert "only 'sighting' has sightings (drop ['semantic'])" in capsys.readouterr().out
    assert not list(tmp_path.iterdir())
