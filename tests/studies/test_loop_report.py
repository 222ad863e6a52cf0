"""The loop study's figures: summaries, gain shares, paired variants and the tables."""

from __future__ import annotations

import math
from typing import Any

import pytest

from mrexplore.studies.loop_report import format_tables, summarize

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


def test_against_reads_the_room_oracle_of_the_other_run() -> None:
    """A run without the room oracle, ``--against`` one with it: the episodes it merged of
    those that run's room oracle merged, and its mean task time relative to the oracle's on
    the same seeds, recorded and printed."""
    from mrexplore.studies.loop_report import _against_text, against

    mine = [_ep("sighting", 1, 110.0, 30.0), _ep("sighting", 2, 130.0, None)]
    theirs = [
        _ep("sighting", 1, 100.0, 20.0),
        _ep("sighting", 2, 120.0, 25.0),
        _ep("oracle_room", 1, 100.0, 10.0),
        _ep("oracle_room", 2, 100.0, 15.0),
        _ep("oracle_room", 3, 90.0, 15.0),  # a seed this run did not run: not counted
    ]
    doc = {"variants": ["sighting"], "worlds": ["w"], "episodes": mine}
    a = against(doc, {"episodes": theirs}, "that.json")
    d = a["references"]["sighting"]
    assert d["merged_where_room_oracle_merged"] == (1, 2)
    assert d["vs_room_oracle"] == pytest.approx(0.2)
    text = "\n".join(_against_text(a))
    assert "sighting against that run's room oracle: merged in 1 of the 2 episodes" in text
    assert "+20.0%" in text
    no_oracle = against(doc, {"episodes": theirs[:2]}, "that.json")["references"].get(
        "sighting", {}
    )
    assert "merged_where_room_oracle_merged" not in no_oracle


def test_a_run_with_the_meeting_oracle_is_measured_against_it() -> None:
    """``oracle_meet`` in the run (or in the ``--against`` run): each merging variant's episodes
    merged of those it merged and its mean task time relative to it, recorded and printed."""
    from mrexplore.studies.loop_report import _against_text, against, aggregate

    eps = [
        _ep("sighting", 1, 110.0, 30.0),
        _ep("sighting", 2, 130.0, None),
        _ep("oracle_meet", 1, 100.0, 20.0),
        _ep("oracle_meet", 2, 100.0, 40.0),
    ]
    for e in eps:
        e["wrong_merge"], e["merged_wrongly_s"] = False, 0.0
    agg = aggregate(eps, ["sighting", "oracle_meet"])
    s = agg["variants"]["sighting"]
    assert s["merged_where_oracle_meet_merged"] == [1, 2]
    assert s["vs_oracle_meet"] == pytest.approx(0.2)
    assert "vs_oracle_meet" not in agg["variants"]["oracle_meet"]
    doc = {"variants": ["sighting"], "worlds": ["w"], "episodes": eps[:2]}
    text = "\n".join(_against_text(against(doc, {"episodes": eps[2:]}, "that.json")))
    assert "sighting against that run's meeting oracle: merged in 1 of the 2 episodes" in text


def test_the_merge_work_is_averaged_per_episode_and_printed() -> None:
    """The merge attempts and re-checks the episodes recorded: their means per episode per
    merging variant, in one line under the table; records made before they were counted give
    None and no line."""
    from mrexplore.studies.loop_report import _work_text, aggregate

    eps = [_ep("semantic", 1, 110.0, 30.0), _ep("semantic", 2, 130.0, None)]
    eps += [_ep("none", 1, 150.0, None), _ep("none", 2, 160.0, None)]
    for e, (n, r) in zip(eps, [(10, 1), (20, 0), (0, 0), (0, 0)], strict=True):
        e.update(merge_attempts=n, merge_rechecks=r)
    s = aggregate(eps, ["semantic", "none"])["variants"]
    assert (s["semantic"]["merge_attempts_mean"], s["semantic"]["merge_rechecks_mean"]) == (15, 0.5)
    assert _work_text(s) == "merge work, mean per episode: semantic 15.0 attempts, 0.5 re-checks"
    old = aggregate([_ep("semantic", 1, 110.0, 30.0)], ["semantic"])["variants"]
    assert old["semantic"]["merge_attempts_mean"] is None and _work_text(old) is None
