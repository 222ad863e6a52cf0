"""``mrexplore train --backend rllib``: arguments checked before Ray starts; a short real run on
local Ray with an env runner writes a checkpoint whose policy reads our 8 channels."""

from __future__ import annotations

from pathlib import Path

import pytest
import yaml

from mrexplore.errors import ConfigError, OutputExistsError
from mrexplore.experiments.task_time import run_task_time
from mrexplore.experiments.train import main

SMALL = {
    "env": {
        "world": "small_office",
        "n_robots": 2,
        "obs_layout": "hwc",
        "obs_dtype": "float32",
        "max_time_s": 20.0,
    },
    "rollout_fragment_length": 64,
    "hyperparams": {"train_batch_size_per_learner": 256, "minibatch_size": 64, "num_epochs": 1},
}


def _small(tmp_path: Path, **env: object) -> Path:
    cfg = {**SMALL, "env": {**SMALL["env"], **env}}  # type: ignore[dict-item]
    path = tmp_path / "rllib.yaml"
    path.write_text(yaml.safe_dump(cfg))
    return path


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--env-runners", "-1"], "env_runners must be an integer >= 0"),
        (["--timesteps", "0"], "timesteps must be an integer >= 1"),
        (["--algo", "dqn"], "PPO only"),
        (["--address", ""], "address must be a Ray address"),
    ],
)
def test_bad_arguments_fail_before_ray(tmp_path: Path, args: list[str], words: str) -> None:
    with pytest.raises(ConfigError, match=words):
        main(["--backend", "rllib", "--out", str(tmp_path / "run"), *args])
    assert not (tmp_path / "run").exists()


def test_the_wrong_observation_format_is_refused(tmp_path: Path) -> None:
    hp = _small(tmp_path, obs_layout="chw")
    with pytest.raises(ConfigError, match="obs_layout must be 'hwc'"):
        main(["--backend", "rllib", "--hyperparams", str(hp), "--out", str(tmp_path / "r")])


def test_a_non_empty_out_is_refused_without_force(tmp_path: Path) -> None:
    out = tmp_path / "run"
    out.mkdir()
    (out / "keep.txt").write_text("user data")
    with pytest.raises(OutputExistsError):
        main(["--backend", "rllib", "--hyperparams", str(_small(tmp_path)), "--out", str(out)])
    assert (out / "keep.txt").read_text() == "user data"


def test_address_needs_the_rllib_backend(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="--address needs --backend rllib"):
        main(["--address", "auto", "--out", str(tmp_path / "r")])


@pytest.mark.expensive
def test_rllib_backend_trains_with_an_env_runner_and_saves_the_shared_policy(
    tmp_path: Path,
) -> None:
    pytest.importorskip("ray.rllib")
    import json

    import torch
    from ray.rllib.core.rl_module.rl_module import RLModule

    out = tmp_path / "run"
    hp = _small(tmp_path)
    args = ["--backend", "rllib", "--hyperparams", str(hp), "--out", str(out)]
    assert main([*args, "--timesteps", "300", "--env-runners", "1", "--final-eval-seeds", "1"]) == 0
    doc = json.loads((out / "train.json").read_text())
    assert doc["history"][-1]["env_steps"] >= 300
    last = doc["history"][-1]
    # 20 s episodes of coverage reward: one robot's return is the team's; RLlib's sums both
    assert last["team_return_mean"] is not None
    assert last["rllib_episode_return_mean"] == pytest.approx(2 * last["team_return_mean"])
    config = yaml.safe_load((out / "config.yaml").read_text())
    assert config["env_runners"] == 1
    # the steps taken are recorded, with the number asked when they differ
    assert config["timesteps"] == last["env_steps"]
    assert config.get("timesteps_asked", 300) == 300
    module = RLModule.from_checkpoint(
        out / "checkpoint" / "learner_group" / "learner" / "rl_module" / "shared"
    )
    conv = next(m for m in module.modules() if isinstance(m, torch.nn.Conv2d))
    assert conv.in_channels == 8
    # the folder works where an SB3 one does: the final evaluation and task-time
    assert "trained (ppo rllib)" in json.loads((out / "eval.json").read_text())["results"]
    doc = run_task_time(
        world="small_office",
        seeds=1,
        policy=str(out),
        out=tmp_path / "tt",
        tasks=("explore",),
        env_options={"max_time_s": 10.0},
        progress=False,
    )
    assert doc["options"]["obs_layout"] == "hwc"  # the format the policy was trained on
    assert len(doc["tasks"]["explore"]["multi"]["task_times_s"]) == 1
