"""The task-time experiment and the demo run end to end on a small world and write valid files."""

from __future__ import annotations

import csv
import json
from pathlib import Path

import cv2
import pytest

from mrexplore.cli import main
from mrexplore.errors import OutputExistsError
from mrexplore.experiments import task_time
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


# --- validate first, resume, never overwrite (issue 14) -------------------------------------


def _no_episodes(*args: object, **kwargs: object) -> None:
    raise AssertionError("an episode ran before the arguments were checked")


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--max-time-s", "10", "--nav-warmup-s", "20"], "nav_warmup_s (20.0) must be shorter"),
        (["--first-seed", "-1"], "first_seed must be an integer >= 0"),
        (["--seeds", "0"], "seeds must be an integer >= 1"),
        (["--policy", "nope"], "unknown policy 'nope'"),
        (["--world", "no_such_world"], "no_such_world"),
        (["--workers", "0"], "workers must be an integer >= 1"),
        (["--address", " "], "address must be a Ray address"),
    ],
)
def test_task_time_checks_every_argument_before_any_episode(
    tmp_path: Path, monkeypatch, args: list[str], words: str, capsys
) -> None:  # type: ignore[no-untyped-def]
    monkeypatch.setattr(task_time, "run_episode", _no_episodes)
    rc = main(["task-time", "--world", "small_office", "--out", str(tmp_path / "r"), *args])
    assert rc == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1


def test_task_time_resumes_and_keeps_results(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    calls: list[int] = []
    interrupts = [2]  # interrupt once, at the second episode
    real = task_time.run_episode

    def interrupted(opts, team, seed):  # type: ignore[no-untyped-def]
        calls.append(seed)
        if len(calls) in interrupts:
            interrupts.clear()
            raise KeyboardInterrupt
        return real(opts, team, seed)

    kw = {
        "world": "small_office",
        "seeds": 1,
        "policy": "nearest-frontier",
        "out": tmp_path,
        "tasks": ("explore",),
        "env_options": {"max_time_s": 10.0},
        "progress": False,
    }
    monkeypatch.setattr(task_time, "run_episode", interrupted)
    with pytest.raises(KeyboardInterrupt):
        run_task_time(**kw)  # type: ignore[arg-type]
    assert not (tmp_path / "task_time.json").exists()
    log = (tmp_path / "episodes.jsonl").read_bytes()
    calls.clear()
    doc = run_task_time(**kw)  # type: ignore[arg-type]
    assert len(calls) == 1  # the single-robot episode was saved; only the team one ran again
    assert len(doc["tasks"]["explore"]["single"]["task_times_s"]) == 1
    assert not (tmp_path / "episodes.jsonl").exists()  # complete: the log is gone
    with pytest.raises(OutputExistsError, match="already exists"):
        run_task_time(**kw)  # type: ignore[arg-type]
    other = tmp_path / "other"
    other.mkdir()
    (other / "episodes.jsonl").write_bytes(log)
    with pytest.raises(OutputExistsError, match="other settings"):
        run_task_time(**{**kw, "out": other, "policy": "random"})  # type: ignore[arg-type]
    (tmp_path / "episodes.jsonl").write_bytes(log)
    calls.clear()
    run_task_time(**{**kw, "force": True})  # type: ignore[arg-type]
    assert len(calls) == 2  # --force starts over: no episode of the earlier run is reused


def test_task_time_out_naming_a_file(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    (tmp_path / "f").write_text("x")
    assert main(["task-time", "--out", str(tmp_path / "f"), "--seeds", "1"]) == 2
    assert "existing file" in capsys.readouterr().err


def test_demo_refuses_to_overwrite_and_bad_seed(tmp_path: Path, monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    from mrexplore.experiments import demo

    monkeypatch.setattr(demo, "run_episode", _no_episodes)
    (tmp_path / "final.png").write_bytes(b"earlier")
    assert main(["demo", "--out", str(tmp_path)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert main(["demo", "--out", str(tmp_path / "new"), "--seed", "-1"]) == 2
    assert "seed must be an integer >= 0" in capsys.readouterr().err
    assert (tmp_path / "final.png").read_bytes() == b"earlier"


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


@pytest.mark.expensive
def test_ray_workers_give_the_serial_results(tmp_path: Path) -> None:
    """2 seeds on 2 local Ray workers: the same task_time.json as the serial run."""
    pytest.importorskip("ray")
    kw = {
        "world": "small_office",
        "seeds": 2,
        "first_seed": 3,
        "policy": "nearest-frontier",
        "tasks": ("explore",),
        "env_options": {"max_time_s": 20.0, "aligned_headings": False},
        "progress": False,
    }
    serial = run_task_time(out=tmp_path / "serial", **kw)  # type: ignore[arg-type]
    parallel = run_task_time(out=tmp_path / "ray", workers=2, **kw)  # type: ignore[arg-type]
    assert parallel == serial
    for name in ("task_time.json", "task_time.csv"):
        assert (tmp_path / "ray" / name).read_bytes() == (tmp_path / "serial" / name).read_bytes()
    single = serial["tasks"]["explore"]["single"]  # type: ignore[index]
    assert len(single["task_times_s"]) == 2


def test_a_resumed_episode_keeps_every_field() -> None:
    # A log line read back must give the EpisodeResult the run produced (Ray results and
    # resumed runs go through it), map-accuracy fields included.
    from mrexplore.experiments.episode import EpisodeResult

    r = EpisodeResult(
        task_time_s=12.5,
        success=True,
        coverage=0.96,
        times_s=[0.0, 0.25],
        coverages=[0.1, 0.2],
        first_merge_time_s=2.5,
        merge_error={"translation_cells": 0.5, "rotation_deg": 0.1, "drift_cells": 0.0},
        collisions=3,
        max_fused_contradiction=0.004,
        merged_wrongly_s=1.25,
        wrong_merge=True,
    )
    back = task_time._episode_from_json(json.loads(json.dumps(task_time._episode_to_json(r))))
    assert back == r
