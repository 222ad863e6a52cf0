"""The task-time experiment and the demo run end to end on a small world and write valid files."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import pytest

from mrexplore.cli import main
from mrexplore.experiments.task_time import run_task_time


@pytest.mark.expensive
def test_task_time_end_to_end(tmp_path: Path) -> None:
    doc = run_task_time(
        world="small_office",
        seeds=2,
        policy="nearest-frontier",
        out=tmp_path,
        progress=False,
        env_options={"max_time_s": 120.0},
        nav_warmup_s=20.0,
    )
    data = json.loads((tmp_path / "task_time.json").read_text())
    assert data == json.loads(json.dumps(doc))
    for task in ("explore", "navigate"):
        entry = data["tasks"][task]
        for team in ("single", "multi"):
            times = entry[team]["task_times_s"]
            assert len(times) == 2 and all(0 < t <= 120.0 for t in times)
            assert entry[team]["success_rate"] > 0
            assert abs(entry[team]["mean"] - sum(times) / 2) < 1e-9
        expected = 1 - entry["multi"]["mean"] / entry["single"]["mean"]
        assert abs(entry["reduction"] - expected) < 1e-9
    with (tmp_path / "task_time.csv").open() as f:
        rows = list(csv.DictReader(f))
    assert len(rows) == 2 * 2 * 2
    img = cv2.imread(str(tmp_path / "task_time.png"))
    assert img is not None and img.shape[0] > 100


@pytest.mark.expensive
def test_demo_command_writes_pictures(tmp_path: Path) -> None:
    out = tmp_path / "demo"
    assert main(["demo", "--out", str(out), "--world", "small_office"]) == 0
    assert (out / "episode.gif").stat().st_size > 1000
    img = cv2.imread(str(out / "final.png"))
    assert img is not None and img.shape[1] > 1000


def test_task_time_json_has_map_accuracy(tmp_path: Path) -> None:
    run_task_time(
        world="small_office",
        seeds=1,
        tasks=["explore"],
        out=tmp_path,
        progress=False,
        env_options={"max_time_s": 5.0},
    )
    data = json.loads((tmp_path / "task_time.json").read_text())
    for team in ("single", "multi"):
        entry = data["tasks"]["explore"][team]
        (c,) = entry["max_fused_contradiction"]
        assert isinstance(c, float) and 0.0 <= c < 0.05
        assert entry["merged_wrongly_s"] == [0.0]
