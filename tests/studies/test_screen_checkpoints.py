"""``studies/screen_checkpoints.py``: every checkpoint of a run against coordinated-frontier on
screening seeds, and the refusals (seeds overlapping the reported ones, a folder not a run)."""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType

import pytest
import yaml

from mrexplore.experiments.train import train
from tests.helpers import load_study

GOAL_ENV = {
    "world": "small_office",
    "n_robots": 2,
    "reward_mode": "coverage",
    "max_time_s": 10.0,
    "action_mode": "goal",
    "goal_candidates": 4,
}


def _script() -> ModuleType:
    return load_study("screen_checkpoints")


def test_refuses_reported_seeds_and_a_folder_that_is_no_run(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    screen = _script()
    assert screen.main([str(tmp_path), "--worlds", "small_office", "--first-seed", "1000000"]) == 2
    assert "overlaps the seeds of reported evaluations" in capsys.readouterr().err
    assert screen.main([str(tmp_path), "--worlds", "small_office"]) == 2
    assert "not a mrexplore train folder" in capsys.readouterr().err
    twins = [tmp_path / d / "run" for d in ("a", "b")]
    for r in twins:
        r.mkdir(parents=True)
        (r / "config.yaml").write_text("algo: maskable_ppo\n")
    assert screen.main([*map(str, twins), "--worlds", "small_office"]) == 2
    assert "share a folder name" in capsys.readouterr().err


@pytest.mark.expensive
def test_every_checkpoint_and_the_final_model_are_screened(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    hyper = tmp_path / "goal.yaml"
    hyper.write_text(
        yaml.safe_dump(
            {
                "policy": "MultiInputPolicy",
                "n_copies": 1,
                "env": GOAL_ENV,
                "hyperparams": {"n_steps": 8, "batch_size": 8, "n_epochs": 1},
                "policy_kwargs": {"net_arch": [8]},
            }
        )
    )
    run = tmp_path / "run"
    # eval_every 8: a checkpoint every 8 decisions (4 calls of the 2-slot VecEnv)
    train("maskable_ppo", 16, run, seed=1, hyperparams_file=hyper, eval_every=8, eval_seeds=1,
          final_eval_seeds=0, progress=False)  # fmt: skip
    screen = _script()
    labels = [label for label, _ in screen.candidates(run)]
    assert labels[-1] == "run@final" and len(labels) >= 2
    out = tmp_path / "screen.json"
    args = [str(run), "--worlds", "small_office", "--seeds", "2", "--max-time-s", "10"]
    assert screen.main([*args, "--json", str(out)]) == 0
    doc = json.loads(out.read_text())
    assert doc["seeds"] == [1000100, 1000101]
    assert {r["candidate"] for r in doc["ranking"]} == set(labels)
    assert "ranked by the mean paired difference" in capsys.readouterr().out
    assert screen.main([*args, "--json", str(out)]) == 2  # an existing result needs --force
