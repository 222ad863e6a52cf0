"""Training: a tiny run writes model.zip, config.yaml and eval.json, reloads and evaluates."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import yaml

import mrexplore
from mrexplore.errors import ConfigError
from mrexplore.experiments.evaluate import evaluate_folder
from mrexplore.experiments.imitate import teacher_weights
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
def test_tiny_training_run_writes_reloads_and_evaluates(
    tmp_path: Path, algo: str, capsys, monkeypatch
) -> None:  # type: ignore[no-untyped-def]
    import tempfile

    system_tmp = tmp_path / "system_tmp"  # where SB3 would leave an SB3-<time> folder
    system_tmp.mkdir()
    monkeypatch.setattr(tempfile, "tempdir", str(system_tmp))
    monkeypatch.delenv("SB3_LOGDIR", raising=False)
    out = tmp_path / "policy"
    config = train(
        algo=algo,
        timesteps=100,
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
    assert not list(system_tmp.glob("SB3-*"))  # no log folder left in the system temp dir
    # config.yaml round-trips to exactly the settings the run used (seed included)
    assert yaml.safe_load((out / "config.yaml").read_text()) == config
    assert config["seed"] == 3 and config["algo"] == algo and config["env"] == TINY_ENV
    # SB3 stops after whole rollouts (2 slots): the run says so and records the steps it took
    per_rollout = {"ppo": 32 * 2, "a2c": 8 * 2, "dqn": 4 * 2}[algo]
    took = -(-100 // per_rollout) * per_rollout
    assert config["timesteps"] == took and config["timesteps_asked"] == 100
    said = capsys.readouterr().out
    assert f"--timesteps 100 rounds up to {took}" in said and f"{per_rollout} steps" in said
    training = json.loads((out / "eval.json").read_text())["training"]
    assert training["throughput"]["timesteps"] == took
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
    with pytest.raises(ConfigError, match="timesteps"):
        train(timesteps=0, out="/nonexistent/never/created")


# --- refuse bad input at the door, never overwrite a policy ---------------------------------------

SHIPPED = Path(__file__).resolve().parents[2] / "policies" / "ppo_symmetric_2r"


@pytest.mark.parametrize(
    ("args", "words"),
    [
        (["--timesteps", "0"], "timesteps must be an integer >= 1"),
        (["--timesteps", "-5"], "timesteps must be an integer >= 1"),
        (["--seed", "-1"], "seed must be an integer >= 0"),
        (["--eval-seeds", "-1"], "eval_seeds must be an integer >= 1"),
        (["--final-eval-seeds", "-1"], "final_eval_seeds must be an integer >= 0"),
        (["--n-copies", "0"], "n_copies must be an integer >= 1"),
        (["--world", "no_such_world"], "train --world: unknown world 'no_such_world'"),
        (["--world", "random:moon"], "train --world: unknown generator 'moon'"),
    ],
)
def test_train_refuses_bad_numbers_before_any_work(
    tmp_path: Path, args: list[str], words: str, capsys
) -> None:  # type: ignore[no-untyped-def]
    from mrexplore.cli import main

    out = tmp_path / "p"
    assert main(["train", "--out", str(out), *args]) == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1
    assert not out.exists()


@pytest.mark.parametrize(
    ("world", "trains_on", "notice"),
    [
        (None, "random:default", False),  # the settings' world
        ("symmetric_office", "symmetric_office", True),  # a name: the shipped map, as in task-time
        ("random:symmetric_office", "random:symmetric_office", False),  # a fresh one each episode
        ("small_office", "small_office", False),  # shipped only: nothing to confuse it with
    ],
)
def test_world_means_what_it_means_for_every_command(
    world: str | None, trains_on: str, notice: bool, capsys
) -> None:  # type: ignore[no-untyped-def]
    from mrexplore.experiments.train_setup import training_world

    assert training_world(world, "random:default") == trains_on
    said = capsys.readouterr().out
    assert ("--world random:symmetric_office" in said) is notice


def test_train_refuses_an_existing_policy_folder(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    from mrexplore.cli import main

    (tmp_path / "p").mkdir()
    (tmp_path / "p" / "model.zip").write_bytes(b"shipped")
    assert main(["train", "--out", str(tmp_path / "p"), "--timesteps", "10"]) == 2
    assert "not empty" in capsys.readouterr().err
    assert (tmp_path / "p" / "model.zip").read_bytes() == b"shipped"
    (tmp_path / "f").write_text("x")
    assert main(["train", "--out", str(tmp_path / "f"), "--timesteps", "10"]) == 2
    assert "existing file" in capsys.readouterr().err


def test_final_evaluation_scales_with_the_run() -> None:
    from mrexplore.experiments.train import final_eval_seed_count

    assert final_eval_seed_count(2_000) == 2
    assert final_eval_seed_count(300_000) == 20
    assert final_eval_seed_count(10**9) == 20


def _policy_copy(tmp_path: Path, config: str | None = None) -> Path:
    import shutil

    folder = tmp_path / "pol"
    folder.mkdir()
    shutil.copy(SHIPPED / "model.zip", folder / "model.zip")
    shutil.copy(SHIPPED / "config.yaml", folder / "config.yaml")
    if config is not None:
        (folder / "config.yaml").write_text(config)
    return folder


@pytest.mark.parametrize(
    ("config", "model", "words"),
    [
        ("algo: [unclosed\n", None, "is not valid YAML"),  # broken config.yaml
        ("- a list\n", None, "must be a mapping"),
        ("algo: dqn\nenv: {}\n", None, "was saved by 'ppo'"),  # algo does not match the model
        ("algo: sac\n", None, "unknown algo 'sac'"),
        (None, b"not a zip at all", "not a stable-baselines3 model file"),  # corrupt model.zip
    ],
)
def test_evaluate_bad_policy_folder_is_one_clear_error(
    tmp_path: Path, config: str | None, model: bytes | None, words: str, capsys
) -> None:  # type: ignore[no-untyped-def]
    from mrexplore.cli import main

    folder = _policy_copy(tmp_path, config)
    if model is not None:
        (folder / "model.zip").write_bytes(model)
    assert main(["evaluate", str(folder), "--seeds", "1", "--out", str(tmp_path / "e")]) == 2
    err = capsys.readouterr().err
    assert words in err and len(err.strip().splitlines()) == 1


def test_evaluate_never_writes_into_the_policy_folder(tmp_path: Path, monkeypatch, capsys) -> None:  # type: ignore[no-untyped-def]
    from mrexplore.cli import main
    from mrexplore.experiments.evaluate import default_eval_dir

    folder = _policy_copy(tmp_path)
    before = sorted(p.name for p in folder.iterdir())
    monkeypatch.chdir(tmp_path)
    assert default_eval_dir(folder) == Path("eval") / "pol"
    assert main(["evaluate", str(folder), "--seeds", "-1"]) == 2
    assert "at least 1 seed" in capsys.readouterr().err
    assert main(["evaluate", str(folder), "--out", str(folder), "--force"]) == 2
    assert "will not write into" in capsys.readouterr().err
    (tmp_path / "eval" / "pol").mkdir(parents=True)
    (tmp_path / "eval" / "pol" / "eval.json").write_text("{}")
    assert main(["evaluate", str(folder)]) == 2  # an earlier result: needs --force
    assert "not empty" in capsys.readouterr().err
    assert sorted(p.name for p in folder.iterdir()) == before


GOAL_ENV = {**TINY_ENV, "action_mode": "goal", "goal_candidates": 4}


@pytest.mark.expensive
def test_goal_level_maskable_ppo_trains_loads_evaluates_and_runs_task_time(
    tmp_path: Path,
) -> None:
    from sb3_contrib import MaskablePPO

    hyper = tmp_path / "goal.yaml"
    hyper.write_text(
        yaml.safe_dump(
            {
                "policy": "MultiInputPolicy",
                "n_copies": 2,
                "env": GOAL_ENV,
                "worlds": ["small_office", "random:symmetric_office?width_m=10&height_m=8"],
                "hyperparams": {"n_steps": 8, "batch_size": 16, "n_epochs": 1},
                "policy_kwargs": {"net_arch": [16]},
            }
        )
    )
    out = tmp_path / "policy"
    config = train(
        algo="maskable_ppo",
        timesteps=32,
        out=out,
        seed=1,
        hyperparams_file=hyper,
        eval_every=10_000,
        eval_seeds=1,
        final_eval_seeds=0,
        progress=False,
    )
    assert config["worlds"] == ["small_office", "random:symmetric_office?width_m=10&height_m=8"]
    # SB3 + sb3-contrib alone load it and act on a goal-level observation with its mask
    model = MaskablePPO.load(str(out / "model.zip"), device="cpu")
    penv = mrexplore.parallel_env(**{**GOAL_ENV, "world": "small_office"})
    obs, _ = penv.reset(seed=0)
    o = obs["robot_0"]
    action, _ = model.predict(o, action_masks=o["action_mask"].astype(bool), deterministic=True)
    assert o["action_mask"][int(action)] == 1
    team = TrainedTeamPolicy.load(out, penv.possible_agents, deterministic=True)
    actions = team.act_obs(obs)
    assert all(obs[a]["action_mask"][x] == 1 for a, x in actions.items())
    doc = evaluate_folder(
        out, n_seeds=2, out=tmp_path / "eval", progress=False, worlds=["small_office"]
    )
    names = set(doc["results"])
    assert {"trained (maskable_ppo), greedy", "trained (maskable_ppo), sampled"} <= names
    assert {"random", "nearest-frontier", "cost-frontier", "coordinated-frontier"} <= names
    for comp in doc["paired"].values():
        assert comp["time_to_0.95"]["n"] == 2
    tt = run_task_time(  # default tasks: navigate is skipped for a trained policy
        world="small_office",
        seeds=1,
        policy=str(out),
        out=tmp_path / "tt",
        env_options={"max_time_s": 10.0},
        progress=False,
    )
    assert np.isfinite(tt["tasks"]["explore"]["multi"]["mean"])
    assert "navigate" not in tt["tasks"]


@pytest.mark.parametrize(
    ("extra", "words"),
    [
        ({"use_subprocess": True}, "not with use_subprocess"),
        ({"worlds": ["small_office", "tb3_office"]}, "worlds list"),
        ({"env": {**TINY_ENV, "action_mode": "goal"}}, "not action_mode='goal'"),
        ({"batched": False, "num_workers": 2}, "it needs batched: true"),
        ({"num_workers": 0}, "num_workers must be an integer >= 1, got 0"),
    ],
)
def test_batched_training_refuses_what_it_cannot_batch_before_any_work(
    tmp_path: Path, extra: dict[str, object], words: str
) -> None:
    path = _tiny_yaml(tmp_path, "ppo")
    cfg = {**yaml.safe_load(path.read_text()), "batched": True, **extra}
    path.write_text(yaml.safe_dump(cfg))
    with pytest.raises(ConfigError, match=words):
        train(algo="ppo", timesteps=32, out=tmp_path / "run", hyperparams_file=path)
    assert not (tmp_path / "run").exists()


@pytest.mark.expensive
def test_batched_training_learns_the_same_weights_on_threads_and_in_processes(
    tmp_path: Path, monkeypatch
) -> None:  # type: ignore[no-untyped-def]
    import torch
    from stable_baselines3 import PPO

    from mrexplore.environment.processes import ProcessBatchedEnv

    started: list[int] = []
    start = ProcessBatchedEnv.__init__

    def counted(self, *args, **kwargs):  # type: ignore[no-untyped-def]
        started.append(kwargs["num_workers"])
        start(self, *args, **kwargs)

    monkeypatch.setattr(ProcessBatchedEnv, "__init__", counted)
    weights = {}
    runs = {
        "copies": {},
        "batched": {"batched": True},
        "workers": {"batched": True, "num_workers": 2},
    }
    for name, extra in runs.items():
        path = _tiny_yaml(tmp_path, "ppo")
        path.write_text(
            yaml.safe_dump({**yaml.safe_load(path.read_text()), "n_copies": 2, **extra})
        )
        config = train(
            algo="ppo",
            timesteps=128,
            out=tmp_path / name,
            hyperparams_file=path,
            eval_every=10**6,
            final_eval_seeds=0,
            progress=False,
        )
        assert config.get("num_workers") == extra.get("num_workers")
        weights[name] = PPO.load(tmp_path / name / "model.zip", device="cpu").policy.state_dict()
    assert started == [2]  # the last run stepped its copies in 2 worker processes
    a = weights["copies"]
    for b in (weights["batched"], weights["workers"]):
        assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)


def _goal_yaml(tmp_path: Path, name: str, net: list[int], lr: float = 3e-4) -> Path:
    path = tmp_path / f"{name}.yaml"
    path.write_text(
        yaml.safe_dump(
            {
                "policy": "MultiInputPolicy",
                "n_copies": 1,
                "env": GOAL_ENV,
                "hyperparams": {"n_steps": 8, "batch_size": 8, "n_epochs": 1, "learning_rate": lr},
                "policy_kwargs": {"net_arch": net},
            }
        )
    )
    return path


@pytest.mark.expensive
def test_init_from_starts_from_the_saved_weights_and_refuses_another_network(
    tmp_path: Path,
) -> None:
    import torch
    from sb3_contrib import MaskablePPO

    quiet: dict[str, Any] = {
        "eval_every": 10_000,
        "eval_seeds": 1,
        "final_eval_seeds": 0,
        "progress": False,
    }
    first = tmp_path / "first"
    train(
        "maskable_ppo", 16, first, seed=1, hyperparams_file=_goal_yaml(tmp_path, "a", [16]), **quiet
    )
    # learning rate 0: the continued run's weights stay those it started from
    frozen = _goal_yaml(tmp_path, "frozen", [16], lr=0.0)
    config = train(
        "maskable_ppo",
        16,
        tmp_path / "second",
        seed=2,
        hyperparams_file=frozen,
        init_from=first,
        **quiet,
    )
    assert config["init_from"]["path"] == str(first / "model.zip")
    assert len(config["init_from"]["sha256"]) == 64
    a = MaskablePPO.load(str(first / "model.zip"), device="cpu").policy.state_dict()
    b = MaskablePPO.load(str(tmp_path / "second" / "model.zip"), device="cpu").policy.state_dict()
    assert a.keys() == b.keys() and all(torch.equal(a[k], b[k]) for k in a)
    other = _goal_yaml(tmp_path, "wide", [32])
    with pytest.raises(ConfigError, match="does not fit"):
        train(
            "maskable_ppo", 16, tmp_path / "third", hyperparams_file=other, init_from=first, **quiet
        )
    assert not any((tmp_path / "third").iterdir())  # no config of a run that did not start
    with pytest.raises(ConfigError, match=r"no such model\.zip"):
        train("maskable_ppo", 16, tmp_path / "fourth", init_from=tmp_path / "nowhere", **quiet)
    assert not (tmp_path / "fourth").exists()  # refused before any work


@pytest.mark.expensive
def test_recurrent_ppo_carries_each_robots_memory_and_clears_it_on_reset(tmp_path: Path) -> None:
    from mrexplore.experiments.trained import model_algo

    hyper = tmp_path / "lstm.yaml"
    hyper.write_text(
        yaml.safe_dump(
            {
                "policy": "MultiInputLstmPolicy",
                "n_copies": 1,
                "env": GOAL_ENV,
                "hyperparams": {"n_steps": 8, "batch_size": 8, "n_epochs": 1},
                "policy_kwargs": {"net_arch": [16], "lstm_hidden_size": 8},
            }
        )
    )
    out = tmp_path / "policy"
    train("recurrent_ppo", 16, out, seed=1, hyperparams_file=hyper, eval_every=10_000,
          eval_seeds=1, final_eval_seeds=0, progress=False)  # fmt: skip
    assert model_algo(out / "model.zip") == "recurrent_ppo"
    penv = mrexplore.parallel_env(**{**GOAL_ENV, "world": "small_office"})
    obs, _ = penv.reset(seed=0)
    team = TrainedTeamPolicy.load(out, penv.possible_agents, deterministic=True)
    assert team.recurrent
    team.reset(np.random.default_rng(0))
    first = team.act_obs(obs)
    assert set(first) == set(penv.possible_agents)
    assert all(0 <= x < 4 for x in first.values())
    h, _c = team._lstm["robot_0"]
    assert h.shape == (1, 1, 8) and np.any(h != 0)  # the state moved from its zero start
    # one robot alone gets the state it had in the batch: the same action as in a batch
    again = TrainedTeamPolicy.load(out, penv.possible_agents, deterministic=True)
    again.reset(np.random.default_rng(0))
    assert again.act_obs({"robot_1": obs["robot_1"]}) == {"robot_1": first["robot_1"]}
    team.reset(np.random.default_rng(0))
    assert team._lstm == {}
    assert team.act_obs(obs) == first  # a new episode starts from zero memory again


@pytest.mark.parametrize(
    "name",
    [
        "maskable_ppo",
        "maskable_ppo_gain",
        "maskable_ppo_memory",
        "maskable_ppo_imitated",
        "maskable_ppo_turns",
        "maskable_ppo_size",
    ],
)
def test_shipped_goal_recipes_build_their_env_and_worlds(name: str) -> None:
    import importlib.resources

    import mrexplore

    path = importlib.resources.files("mrexplore") / "configs" / f"{name}.yaml"
    cfg = load_hyperparams("maskable_ppo", str(path))
    for world in cfg.get("worlds") or [cfg["env"]["world"]]:
        env = mrexplore.parallel_env(**{**cfg["env"], "world": world})
        obs, _ = env.reset(seed=0)
        assert all(env.observation_space(a).contains(obs[a]) for a in env.agents)
    with_turns = name in ("maskable_ppo_turns", "maskable_ppo_size")
    assert bool(cfg["env"].get("goal_turns", 0)) == with_turns
    # only the size recipe's teacher values frontier length (imitate reads the section)
    assert teacher_weights(cfg)["size_weight"] == (2.0 if name == "maskable_ppo_size" else 0.0)
