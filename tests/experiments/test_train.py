"""Training: a tiny run writes model.zip, config.yaml and eval.json, reloads and evaluates."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import yaml

import mrexplore
from mrexplore.errors import ConfigError
from mrexplore.experiments.evaluate import evaluate_folder
from mrexplore.experiments.task_time import run_task_time
from mrexplore.experiments.train import load_hyperparams, train
from mrexplore.experiments.trained import TrainedTeamPolicy

TINY_ENV = {
    "world": "random:symmetric_office?width_m=10&height_m=8",
    "n_robots": 2,
    "reward_mode": "coverage",
    "max_time_s": 10.0,
}
TINY_HYPER = {
    "ppo": {"n_steps": 32, "batch_size": 32, "n_epochs": 1},
    "a2c": {"n_steps": 8},
    "dqn": {"buffer_size": 500, "learning_starts": 32, "batch_size": 16, "train_freq": 4},
}


def _tiny_yaml(tmp_path: Path, algo: str) -> Path:
    path = tmp_path / f"{algo}.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "policy": "CnnPolicy",
                "n_copies": 1,
                "use_subprocess": False,
                "torch_threads": 1,
                "env": TINY_ENV,
                "hyperparams": TINY_HYPER[algo],
            }
        )
    )
    return path


@pytest.mark.parametrize("algo", ["ppo", "a2c", "dqn"])
@pytest.mark.expensive
def test_tiny_training_run_writes_reloads_and_evaluates(tmp_path: Path, algo: str) -> None:
    out = tmp_path / "policy"
    config = train(
        algo=algo,
        timesteps=96,
        out=out,
        seed=3,
        hyperparams_file=_tiny_yaml(tmp_path, algo),
        eval_every=64,
        eval_seeds=1,
        final_eval_seeds=1,
        progress=False,
    )
    for name in ("model.zip", "config.yaml", "eval.json"):
        assert (out / name).is_file(), name
    # config.yaml round-trips to exactly the settings the run used (seed included)
    assert yaml.safe_load((out / "config.yaml").read_text()) == config
    assert config["seed"] == 3 and config["algo"] == algo and config["env"] == TINY_ENV
    # reload and act on a real observation
    penv = mrexplore.parallel_env(**{**TINY_ENV, "world": "small_office"})
    obs, _ = penv.reset(seed=0)
    team = TrainedTeamPolicy.load(out, penv.possible_agents)
    actions = team.act_obs(obs)
    assert set(actions) == set(penv.possible_agents)
    assert all(penv.action_space(a).contains(x) for a, x in actions.items())
    # evaluation side by side with the baselines, on held-out seeds
    doc = evaluate_folder(out, n_seeds=1, out=tmp_path / "eval", progress=False)
    assert {"random", "nearest-frontier", "coordinated-frontier"} <= set(doc["results"])
    assert all(s >= 1_000_000 for s in doc["seeds"])
    for summary in doc["results"].values():
        assert 0.0 <= summary["final_coverage"]["mean"] <= 1.0


@pytest.mark.expensive
def test_task_time_accepts_a_trained_policy_folder(tmp_path: Path) -> None:
    out = tmp_path / "policy"
    train(
        algo="ppo",
        timesteps=64,
        out=out,
        hyperparams_file=_tiny_yaml(tmp_path, "ppo"),
        eval_every=10_000,
        eval_seeds=1,
        final_eval_seeds=1,
        progress=False,
    )
    doc = run_task_time(
        world="small_office",
        seeds=1,
        policy=str(out),
        out=tmp_path / "tt",
        tasks=("explore",),
        env_options={"max_time_s": 10.0},
        progress=False,
    )
    assert np.isfinite(doc["tasks"]["explore"]["single"]["mean"])


def test_bad_training_input() -> None:
    with pytest.raises(ConfigError, match="unknown algorithm"):
        load_hyperparams("sac")
    with pytest.raises(ConfigError, match="not found"):
        load_hyperparams("ppo", "/no/such/file.yaml")
    with pytest.raises(ConfigError, match="not a trained policy folder"):
        evaluate_folder("/no/such/folder", n_seeds=1)
