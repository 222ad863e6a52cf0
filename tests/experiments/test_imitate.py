"""Behaviour cloning of the goal-level rule: recording, fitting, the policy folder it writes."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
import pytest
import yaml

from mrexplore.errors import ConfigError, OutputExistsError
from mrexplore.experiments.imitate import (
    Demonstrations,
    clone,
    collect,
    imitate,
    teacher_weights,
)
from mrexplore.policies.candidates import FEATURE_NAMES
from mrexplore.policies.goal_rules import COL, keep_or_burgard

GOAL_ENV = {
    "world": "small_office",
    "n_robots": 2,
    "action_mode": "goal",
    "goal_candidates": 4,
    "reward_mode": "coverage",
    "max_time_s": 20.0,
}
K, F = 4, len(FEATURE_NAMES)


def _synthetic(n: int, rng: np.random.Generator) -> Demonstrations:
    """Random candidate rows labelled by the rule itself (one decision per episode)."""
    x = rng.random((n, K, F), dtype=np.float32)
    x[:, :, COL["is_current"]] = rng.random((n, K)) < 0.1
    masks = (rng.random((n, K)) < 0.8).astype(np.int8)
    masks[:, 0] = 1
    actions = np.array([keep_or_burgard(x[i], masks[i]) for i in range(n)], dtype=np.int64)
    return Demonstrations(x, masks, actions, rng.random(n, dtype=np.float32), np.arange(n))


class _Spaces(gymnasium.Env[Any, Any]):
    """Just the goal-level spaces, to build a model without an env."""

    observation_space = gymnasium.spaces.Dict(
        {
            "observation": gymnasium.spaces.Box(0.0, 10.0, (K, F), np.float32),
            "action_mask": gymnasium.spaces.Box(0, 1, (K,), np.int8),
        }
    )
    action_space = gymnasium.spaces.Discrete(K)


def test_cloning_learns_the_rule_on_held_out_decisions() -> None:
    from sb3_contrib import MaskablePPO

    rng = np.random.default_rng(0)
    demos = _synthetic(3000, rng)
    model = MaskablePPO("MultiInputPolicy", _Spaces(), seed=0, device="cpu")
    history = clone(model.policy, demos, epochs=15, rng=rng)
    first, last = history[0], history[-1]
    assert last["cross_entropy"] < first["cross_entropy"]
    assert last["value_mse"] < first["value_mse"]
    # the held-out decisions (last 10 %) are predicted well, far above a random row (~30 %)
    assert last["holdout_agreement"] > 0.85
    assert last["holdout_agreement_with_choice"] > 0.85


def test_recording_is_seeded_and_labels_every_decision_with_the_rule() -> None:
    a = collect(GOAL_ENV, ["small_office"], decisions=30, seed=5, gamma=0.9)
    b = collect(GOAL_ENV, ["small_office"], decisions=30, seed=5, gamma=0.9)
    assert len(a) >= 30
    assert np.array_equal(a.observations, b.observations) and np.array_equal(a.actions, b.actions)
    assert a.observations.shape[1:] == (K, F) and a.masks.shape == (len(a), K)
    assert all(
        a.actions[i] == keep_or_burgard(a.observations[i], a.masks[i]) for i in range(len(a))
    )
    assert np.isfinite(a.returns).all()


def test_recording_with_turns_holds_every_turn_and_the_rule_on_turn() -> None:
    """With goal_turns, each robot's record alternates its turn (its candidates) and the other
    robot's (row 0 only); the rule labels both."""
    a = collect({**GOAL_ENV, "goal_turns": 1}, ["small_office"], decisions=40, seed=5, gamma=0.9)
    only_row0 = (a.masks[:, 0] == 1) & (a.masks[:, 1:].sum(axis=1) == 0)
    assert only_row0.mean() >= 0.5  # every decision: one turn on, one off, per robot
    assert (~only_row0).any()
    assert all(
        a.actions[i] == keep_or_burgard(a.observations[i], a.masks[i]) for i in range(len(a))
    )


def test_recording_follows_the_teacher_weights() -> None:
    a = collect(GOAL_ENV, ["small_office"], decisions=30, seed=5, gamma=0.9, size_weight=2.0)
    assert all(
        a.actions[i] == keep_or_burgard(a.observations[i], a.masks[i], size_weight=2.0)
        for i in range(len(a))
    )


def _yaml(tmp_path: Path, env: dict[str, Any], **extra: Any) -> Path:
    path = tmp_path / "goal.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "policy": "MultiInputPolicy",
                "env": env,
                "hyperparams": {"n_steps": 8, "batch_size": 8, "n_epochs": 1},
                "policy_kwargs": {"net_arch": [16]},
                **extra,
            }
        )
    )
    return path


@pytest.mark.parametrize(
    ("teacher", "match"),
    [
        ({"gain": 1.0}, "unknown teacher weight 'gain'"),
        ({"size_weight": -1.0}, "size_weight must be a finite number >= 0"),
        ({"size_weight": float("inf")}, "size_weight must be a finite number >= 0"),
        ({"beta": "high"}, "beta must be a finite number >= 0"),
        ([1.0], "teacher section must be a mapping"),
    ],
)
def test_bad_teacher_weights_are_named(tmp_path: Path, teacher: Any, match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        imitate(tmp_path / "a", hyperparams_file=_yaml(tmp_path, GOAL_ENV, teacher=teacher))
    assert not (tmp_path / "a").exists()
    assert teacher_weights({"teacher": {"beta": 2}}) == {"beta": 2.0, "size_weight": 0.0}


def test_bad_input_is_refused_before_any_work(tmp_path: Path) -> None:
    low = _yaml(tmp_path, {k: v for k, v in GOAL_ENV.items() if k != "action_mode"})
    with pytest.raises(ConfigError, match="action_mode: goal"):
        imitate(tmp_path / "a", hyperparams_file=low, progress=False)
    assert not (tmp_path / "a").exists()
    with pytest.raises(ConfigError, match="decisions must be an integer >= 1"):
        imitate(tmp_path / "b", decisions=0, progress=False)
    threads = _yaml(tmp_path, GOAL_ENV, update_threads=0)
    with pytest.raises(ConfigError, match="imitate: argument update_threads must be"):
        imitate(tmp_path / "c", hyperparams_file=threads, decisions=8, progress=False)
    assert not (tmp_path / "c").exists()
    full = tmp_path / "full"
    full.mkdir()
    (full / "keep.txt").write_text("mine")
    with pytest.raises(OutputExistsError):
        imitate(full, hyperparams_file=_yaml(tmp_path, GOAL_ENV), progress=False)
    assert (full / "keep.txt").read_text() == "mine"


@pytest.mark.expensive
def test_the_folder_loads_evaluates_and_continues_with_ppo(tmp_path: Path) -> None:
    from mrexplore.experiments.evaluate import evaluate_folder
    from mrexplore.experiments.train import train
    from mrexplore.experiments.trained import TrainedTeamPolicy

    hyper = _yaml(tmp_path, GOAL_ENV)
    out = tmp_path / "bc"
    config = imitate(out, hyperparams_file=hyper, decisions=40, epochs=2, progress=False)
    assert config["imitation"]["decisions"] >= 40
    assert {"model.zip", "config.yaml", "imitation.json"} <= {p.name for p in out.iterdir()}
    team = TrainedTeamPolicy.load(out, ["robot_0", "robot_1"], deterministic=True)
    assert team.model.observation_space["observation"].shape == (K, F)
    doc = evaluate_folder(out, n_seeds=1, progress=False, worlds=["small_office"])
    assert "trained (maskable_ppo), greedy" in doc["results"]
    cont = train(
        "maskable_ppo",
        16,
        tmp_path / "ppo",
        hyperparams_file=hyper,
        init_from=out,
        eval_every=10_000,
        eval_seeds=1,
        final_eval_seeds=0,
        progress=False,
    )
    assert cont["init_from"]["path"] == str(out / "model.zip")


def test_cloning_runs_on_update_threads(tmp_path: Path, monkeypatch) -> None:  # type: ignore[no-untyped-def]
    import torch

    from mrexplore.experiments import imitate as module

    before = torch.get_num_threads()
    seen: list[int] = []
    fit = module.clone

    def probed(*args: Any, **kwargs: Any) -> Any:
        seen.append(torch.get_num_threads())
        return fit(*args, **kwargs)

    monkeypatch.setattr(module, "clone", probed)
    path = _yaml(tmp_path, GOAL_ENV, torch_threads=1, update_threads=2)
    try:
        config = imitate(
            tmp_path / "a", hyperparams_file=path, decisions=16, epochs=1, progress=False
        )
        assert seen == [2] and torch.get_num_threads() == 1
        assert (config["torch_threads"], config["update_threads"]) == (1, 2)
    finally:
        torch.set_num_threads(before)
