"""``docs/results/index.md`` is what ``scripts/results_index.py`` makes of the JSON files now."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

from tests.helpers import load_script

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"


def test_results_index_is_up_to_date() -> None:
    script = load_script("results_index")
    fresh = script.render(RESULTS)
    committed = (RESULTS / "index.md").read_text()
    assert committed == fresh, "docs/results/index.md is stale: run python scripts/results_index.py"


def test_every_study_has_a_row_with_a_headline() -> None:
    script = load_script("results_index")
    found = script.studies(RESULTS)
    assert len(found) >= 10
    for _name, json_path, _files in found:
        what, headline = script.describe(json.loads(json_path.read_text()))
        assert what and headline and headline != "-", json_path


def test_check_and_atomic_rewrite(tmp_path: Path) -> None:
    script = load_script("results_index")
    shutil.copy(RESULTS / "task_time.json", tmp_path / "task_time.json")
    assert script.main(["--results", str(tmp_path), "--check"]) == 1  # no index yet
    assert script.main(["--results", str(tmp_path)]) == 0
    assert script.main(["--results", str(tmp_path), "--check"]) == 0
    text = (tmp_path / "index.md").read_text()
    assert "task_time" in text and "-47.1 %" in text
    assert sorted(p.name for p in tmp_path.iterdir()) == ["index.md", "task_time.json"]


def test_a_family_part_s_worlds_are_one_range() -> None:
    script = load_script("results_index")
    names = [f"family:paper_like/test4/{i}" for i in range(40)] + ["depot", "family:f/tune/3"]
    assert script._worlds(names) == (
        "family:paper_like/test4/0-39 (40 worlds), depot, family:f/tune/3"
    )
    assert script._worlds(["family:f/t/0", "family:f/t/2"]) == "family:f/t/0, family:f/t/2"
