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


def test_an_env_bench_file_says_its_machine_rollout_and_batched_ratio() -> None:
    script = load_script("results_index")
    doc = {
        "symmetric_office, 2 robots": {"robot_steps_per_s": 2117.4, "p99_ms": 1.59},
        "rollout, coordinated-frontier": {"process_ms": 3.2, "max_over_p50": 4.3},
        "side by side, random": {
            "num_envs": 32,
            "single": {"wall_ratio": 1.0},
            "batched_threads": {"wall_ratio": 1.04},
            "batched_processes": {"wall_ratio": 1.52},
        },
        "machine": {"cores": 2, "usable_cores": 2, "load": [0.6, 1.0, 1.0], "load_after": None},
    }
    what, headline = script.describe(doc)
    assert what.endswith("; side by side, random") and "rollout, coordinated-frontier" in what
    assert headline.startswith("machine: 2 cores, load 0.60 before")
    assert "2,117 robot-steps/s, p99 1.59 ms" in headline
    assert "3.20 ms of process CPU per step, the slowest step 4.30x the median" in headline
    assert "32 worlds in processes: 1.52x the single envs in wall time" in headline
    doc["rollout, coordinated-frontier"].update(merge_ms=1.9, merge_attempts=75)
    _, headline = script.describe(doc)
    assert "3.20 ms of process CPU per step (1.90 in 75 merge attempts), the slowest" in headline
