"""``studies/merge_by_map.py``: bench cases per source map, refusals by their reasons' words."""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType
from typing import Any

import pytest

from tests.helpers import load_study


def _script() -> ModuleType:
    return load_study("merge_by_map")


def _case(name: str, overlap: float, kind: str, reason: str = "") -> dict[str, Any]:
    return {"case": name, "overlap": overlap, "kind": kind, "reason": reason}


def _doc() -> dict[str, Any]:
    cases = [
        _case("nav2/depot.yaml#0 (seed 1)", 0.6, "correct"),
        _case("nav2/depot.yaml#1 (seed 1)", 0.5, "refused", "ambiguous: best 1.000 vs 0.990"),
        _case("nav2/depot.yaml#2 (seed 1)", 0.45, "refused", "ambiguous: best 0.990 vs 0.985"),
        _case("nav2/depot.yaml#3 (seed 1)", 0.2, "refused", "ambiguous: best 1.000 vs 1.000"),
        _case("office.yaml#0 (seed 1)", 0.9, "wrong"),
    ]
    rows = [
        {"method": "semantic", "options": "-", "family": "real", "cases": cases},
        {"method": "semantic", "options": "slide_test=True", "family": "real", "cases": cases},
        {"method": "orb", "detector": "orb", "options": "-", "family": "real", "cases": cases},
        {"method": "orb", "detector": "sift", "options": "-", "family": "real", "cases": cases},
    ]
    return {"rows": rows}


def test_counts_the_default_rows_above_the_overlap_floor(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "bench.json"
    f.write_text(json.dumps(_doc()))
    t = _script().tally([_doc(), _doc()], "semantic", 0.4)  # two files add up
    depot = t[("real", "nav2/depot.yaml")]
    assert (depot["pairs"], depot["correct"], depot["refused"]) == (6, 2, 4)
    assert depot["reasons"] == {"ambiguous: best": 4}
    assert t[("real", "office.yaml")]["wrong"] == 2
    assert _script().main([str(f)]) == 0
    out = capsys.readouterr().out
    assert "nav2/depot.yaml" in out and "1 /     3" in out and "ambiguous: best" in out
    orb = _script().tally([_doc()], "orb", 0.4, "sift")  # one detector's rows, not both
    assert orb[("real", "nav2/depot.yaml")]["pairs"] == 3
    assert _script().main([str(f), "--method", "orb"]) == 2  # which detector?
    assert "orb, sift" in capsys.readouterr().err


def test_refusals_whose_judged_pose_was_the_truth_are_counted(
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Files that record the refused pose's error (``best_error_cells``) say how many refusals
    gave away the truth (within 2 cells plus the case's drift); older files say nothing."""
    cases = [
        {**_case("w#0", 0.8, "refused", "ambiguous: best 1.0"), "best_error_cells": 0.5},
        {**_case("w#1", 0.8, "refused", "ambiguous: best 1.0"), "best_error_cells": 80.0},
        {
            **_case("w#2", 0.8, "refused", "ambiguous: best 1.0"),
            "best_error_cells": 2.5,
            "drift_cells": 1.0,
        },
        {**_case("w#3", 0.8, "refused", "too few wall cells"), "best_error_cells": None},
    ]
    doc = {"rows": [{"method": "semantic", "options": "-", "family": "lidar", "cases": cases}]}
    t = _script().tally([doc], "semantic", 0.4)[("lidar", "w")]
    assert (t["refused"], t["judged"], t["truth_refused"]) == (4, 3, 2)
    assert "the refused pose was the truth in 2 of 3" in _script().format_tally(
        {("lidar", "w"): t}, 0.4
    )
    old = _script().format_tally(_script().tally([_doc()], "semantic", 0.4), 0.4)
    assert "refused pose" not in old


@pytest.mark.parametrize(
    ("content", "argv_tail"),
    [("not json", []), ('{"rows": [{"method": "semantic"}]}', []), ("{}", [])],
)
def test_bad_files_fail_at_the_door(
    tmp_path: Path, content: str, argv_tail: list[str], capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "bad.json"
    f.write_text(content)
    assert _script().main([str(f), *argv_tail]) == 2
    assert "error" in capsys.readouterr().err
    assert f.read_text() == content  # read only


def test_an_overlap_floor_outside_zero_one_is_refused(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    f = tmp_path / "bench.json"
    f.write_text(json.dumps(_doc()))
    assert _script().main([str(f), "--min-overlap", "1.5"]) == 2
    assert "--min-overlap" in capsys.readouterr().err


def test_the_docstring_examples_hold() -> None:
    import doctest

    result = doctest.testmod(_script())
    assert result.attempted >= 3 and result.failed == 0
