"""PyTorch threads by phase: collection on ``torch_threads``, updates on ``update_threads``."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import torch
import yaml

from mrexplore.errors import ConfigError
from mrexplore.experiments.threads import PhaseThreads, phase_threads
from mrexplore.experiments.train import train


@pytest.mark.parametrize(
    ("cfg", "words"),
    [
        ({"torch_threads": 0}, "torch_threads must be an integer >= 1, got 0"),
        ({"update_threads": True}, "update_threads must be an integer >= 1, got True"),
        ({"update_threads": "two"}, "update_threads must be an integer >= 1, got 'two'"),
        ({"torch_threads": 1.5}, "torch_threads must be an integer >= 1, got 1.5"),
    ],
)
def test_bad_thread_counts_are_named(cfg: dict[str, Any], words: str) -> None:
    with pytest.raises(ConfigError, match=words):
        phase_threads(cfg)


def test_update_threads_default_to_the_collection_threads() -> None:
    assert phase_threads({"torch_threads": 3}) == (3, 3)
    assert phase_threads({"torch_threads": 1, "update_threads": 2}) == (1, 2)


def test_train_refuses_a_bad_thread_count_before_any_work(tmp_path: Path) -> None:
    path = tmp_path / "ppo.yaml"
    tiny = {"n_steps": 8, "batch_size": 8, "n_epochs": 1}
    env = {"world": "small_office", "n_robots": 1, "max_time_s": 2.0}
    cfg = {"policy": "CnnPolicy", "update_threads": 0, "env": env, "hyperparams": tiny}
    path.write_text(yaml.safe_dump(cfg))
    out = tmp_path / "run"
    with pytest.raises(ConfigError, match="update_threads must be an integer >= 1, got 0"):
        train(out=out, timesteps=1, hyperparams_file=path, final_eval_seeds=0, progress=False)
    assert not out.exists()


def test_updates_run_on_update_threads_and_collection_on_torch_threads() -> None:
    import gymnasium as gym
    from stable_baselines3 import PPO
    from stable_baselines3.common.callbacks import BaseCallback, CallbackList
    from stable_baselines3.common.logger import Logger

    before = torch.get_num_threads()
    seen: dict[str, set[int]] = {"collect": set(), "update": set()}

    class Probe(BaseCallback):
        def _on_step(self) -> bool:
            seen["collect"].add(torch.get_num_threads())
            return True

    model = PPO("MlpPolicy", gym.make("CartPole-v1"), n_steps=32, batch_size=32, n_epochs=1)
    model.set_logger(Logger(None, []))
    update = model.train

    def probed_train() -> None:
        seen["update"].add(torch.get_num_threads())
        update()

    model.train = probed_train  # type: ignore[method-assign]
    try:
        model.learn(96, callback=CallbackList([PhaseThreads(1, 2), Probe()]))
        assert seen == {"collect": {1}, "update": {2}}
        assert torch.get_num_threads() == 1  # collection's count once training ends
    finally:
        torch.set_num_threads(before)


def test_shipped_ppo_recipe_updates_on_two_threads() -> None:
    from mrexplore.experiments.train import load_hyperparams

    assert phase_threads(load_hyperparams("ppo")) == (1, 2)
