"""``mrexplore train --backend rllib``: one shared PPO policy for all robots with RLlib, on Ray.

Local Ray by default; ``address`` joins a cluster (``ray start --head`` on one machine, ``ray
start --address=HEAD:6379`` on the others, mrexplore installed on each). ``env_runners`` actors
step env copies in parallel (one CPU each); the learner updates the model in the driver. The
observation is channels-last float (``obs_layout="hwc"``, ``obs_dtype="float32"``) so that
RLlib's default CNN reads our 8 channels as channels. Writes ``config.yaml`` (every setting, the
seed included), ``train.json`` (per iteration: steps, returns, throughput) and ``checkpoint/``
(``Algorithm.save_to_path``; the policy alone is ``checkpoint/learner_group/learner/rl_module/
shared``, loadable with ``RLModule.from_checkpoint``).

Returns in ``train.json``: ``team_return_mean`` is one robot's episode return (the team reward);
RLlib's own ``episode_return_mean`` sums over robots (n_robots times it), kept as
``rllib_episode_return_mean``.
"""

from __future__ import annotations

import importlib.resources
import json
import logging
import time
from pathlib import Path
from typing import Any

import yaml

from mrexplore.errors import ConfigError
from mrexplore.io_safety import check_out_dir, write_text
from mrexplore.options import integer_argument

#: The name RLlib knows our env by (``register_env``).
ENV_NAME = "mrexplore"
#: The one policy every robot is mapped to.
POLICY_ID = "shared"


def make_rllib_env(env_config: dict[str, Any]) -> Any:
    """RLlib's ``ParallelPettingZooEnv`` over :func:`mrexplore.parallel_env` (env runners call
    it with the ``env_config`` dict; module level so that Ray can pickle it by reference)."""
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv

    import mrexplore

    return ParallelPettingZooEnv(mrexplore.parallel_env(**dict(env_config)))


def _shared_policy(agent_id: Any, episode: Any = None, **kwargs: Any) -> str:
    """Every robot acts with (and trains) the same policy."""
    return POLICY_ID


def load_rllib_config(path: str | Path | None = None) -> dict[str, Any]:
    """The RLlib YAML (``configs/rllib_ppo.yaml``, or the file at ``path``)."""
    if path is not None:
        if not Path(path).is_file():
            raise ConfigError(f"hyperparameter file {path} not found")
        text = Path(path).read_text()
    else:
        text = (importlib.resources.files("mrexplore") / "configs" / "rllib_ppo.yaml").read_text()
    cfg = yaml.safe_load(text)
    if not isinstance(cfg, dict) or not isinstance(cfg.get("env"), dict):
        raise ConfigError("the RLlib hyperparameter file needs an 'env' mapping")
    if not isinstance(cfg.get("hyperparams"), dict):
        raise ConfigError("the RLlib hyperparameter file needs a 'hyperparams' mapping")
    return dict(cfg)


def build_ppo_config(
    env_options: dict[str, Any],
    hyperparams: dict[str, Any],
    env_runners: int,
    seed: int,
    rollout_fragment_length: int | str = "auto",
) -> Any:
    """The ``PPOConfig`` of a shared policy over our env (new API stack)."""
    from ray.rllib.algorithms.ppo import PPOConfig
    from ray.rllib.core.rl_module.multi_rl_module import MultiRLModuleSpec
    from ray.rllib.core.rl_module.rl_module import RLModuleSpec
    from ray.tune.registry import register_env

    register_env(ENV_NAME, make_rllib_env)
    return (
        PPOConfig()
        .environment(ENV_NAME, env_config=dict(env_options))
        .multi_agent(policies={POLICY_ID}, policy_mapping_fn=_shared_policy)
        .rl_module(rl_module_spec=MultiRLModuleSpec(rl_module_specs={POLICY_ID: RLModuleSpec()}))
        .env_runners(
            num_env_runners=env_runners,
            num_cpus_per_env_runner=1,
            rollout_fragment_length=rollout_fragment_length,
        )
        .training(**hyperparams)
        .debugging(seed=seed)  # env runner k seeds its env copies from seed and k
    )


def train_rllib(
    timesteps: int = 200_000,
    out: str | Path = "runs/rllib",
    world: str | None = None,
    n_robots: int | None = None,
    seed: int = 0,
    env_runners: int = 2,
    address: str | None = None,
    hyperparams_file: str | Path | None = None,
    final_eval_seeds: int | None = None,
    progress: bool = True,
    force: bool = False,
) -> dict[str, Any]:
    """Train the shared policy for at least ``timesteps`` env steps; returns the config.

    RLlib stops after a whole training batch, so the run may take more steps than asked:
    ``config.yaml`` then records the steps taken as ``timesteps`` (and ``timesteps_asked``).

    Then evaluates it against the frontier baselines on held-out seeds, as ``train`` does for
    SB3 (``eval.json``, ``eval.png``; ``final_eval_seeds=None`` scales the count to the run,
    0 skips it); ``mrexplore evaluate`` and ``task-time --policy`` take the folder too.

    Every argument is checked and ``out`` refused when it is a file or a non-empty folder
    (without ``force``) before Ray starts.

    Raises:
        ConfigError: a bad argument, or Ray/RLlib not installed.
        OutputExistsError: ``out`` is refused.
    """
    from mrexplore.environment.config import EnvConfig
    from mrexplore.experiments.train_setup import final_eval_seed_count, training_world

    timesteps = integer_argument("train", "timesteps", timesteps, 1)
    final_seeds = (
        final_eval_seed_count(timesteps)
        if final_eval_seeds is None
        else integer_argument("train", "final_eval_seeds", final_eval_seeds, 0)
    )
    seed = integer_argument("train", "seed", seed, 0)
    env_runners = integer_argument("train", "env_runners", env_runners, 0)
    if address is not None and (not isinstance(address, str) or not address.strip()):
        raise ConfigError(f"train: address must be a Ray address like 'auto', got {address!r}")
    cfg = load_rllib_config(hyperparams_file)
    env_opts = dict(cfg["env"])
    env_opts["world"] = training_world(world, env_opts.get("world", "random:symmetric_office"))
    if n_robots is not None:
        env_opts["n_robots"] = integer_argument("train", "n_robots", n_robots, 1)
    checked = EnvConfig.from_kwargs(**{k: v for k, v in env_opts.items() if k != "world"})
    if checked.obs_layout != "hwc" or checked.obs_dtype != "float32":
        raise ConfigError(
            "train --backend rllib: env options obs_layout must be 'hwc' and obs_dtype "
            "'float32' (RLlib's default CNN reads channels last, as floats)"
        )
    out = check_out_dir(out, force=force, what="mrexplore train")
    try:
        import ray
        import ray.rllib  # the extra, not only Ray core
    except ImportError as exc:
        raise ConfigError(
            "train --backend rllib needs RLlib: pip install 'mrexplore[rllib]'"
        ) from exc
    ppo = build_ppo_config(
        env_opts,
        dict(cfg["hyperparams"]),
        env_runners,
        seed,
        cfg.get("rollout_fragment_length", "auto"),
    )
    out.mkdir(parents=True, exist_ok=True)
    config = {
        "backend": "rllib",
        "algo": "ppo",
        "timesteps": timesteps,
        "seed": seed,
        "env_runners": env_runners,
        "address": address,
        "env": env_opts,
        "hyperparams": cfg["hyperparams"],
        "versions": {"ray": str(ray.__version__)},
    }
    write_text(out / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    started = not ray.is_initialized()
    if started:
        ray.init(address=address, include_dashboard=False, logging_level=logging.WARNING)
    history: list[dict[str, Any]] = []
    n = int(env_opts.get("n_robots", 2))
    try:
        algo = ppo.build_algo()
        t0 = time.perf_counter()
        steps = 0
        while steps < timesteps:
            result = algo.train()
            runners = result.get("env_runners", {})
            steps = int(result.get("num_env_steps_sampled_lifetime", 0))
            wall = time.perf_counter() - t0
            agent_returns = runners.get("agent_episode_returns_mean", {})
            entry = {
                "iteration": int(result.get("training_iteration", len(history) + 1)),
                "env_steps": steps,
                "wall_s": wall,
                "env_steps_per_s": steps / wall if wall > 0 else 0.0,
                # one robot's return = the team return; RLlib's sums over the robots
                "team_return_mean": agent_returns.get("robot_0"),
                "rllib_episode_return_mean": runners.get("episode_return_mean"),
                "episodes": runners.get("num_episodes_lifetime"),
            }
            history.append(entry)
            if progress:
                ret = entry["team_return_mean"]
                print(
                    f"[rllib] iter {entry['iteration']}: {steps}/{timesteps} env steps, "
                    f"{entry['env_steps_per_s']:.0f} steps/s, team return "
                    + ("-" if ret is None else f"{ret:.2f}")
                    + f" ({n} robots)"
                )
        checkpoint = algo.save_to_path(str((out / "checkpoint").resolve()))
        algo.stop()
    finally:
        if started:
            ray.shutdown()
    if steps != timesteps:  # RLlib stops after a whole training batch: record what it took
        if progress:
            print(
                f"train: --timesteps {timesteps:,} took {steps:,} env steps (whole training "
                f"batches); config.yaml records {steps:,}"
            )
        items = list(config.items())
        at = [k for k, _ in items].index("timesteps")
        items[at : at + 1] = [("timesteps", steps), ("timesteps_asked", timesteps)]
        config = dict(items)
        write_text(out / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    doc = {"config": config, "history": history, "checkpoint": str(checkpoint)}
    write_text(out / "train.json", json.dumps(doc, indent=2, default=str))
    if final_seeds > 0:
        from mrexplore.experiments.evaluate import evaluate_folder, write_evaluation

        write_evaluation(evaluate_folder(out, n_seeds=final_seeds, progress=progress), out)
    if progress:
        print(f"trained {steps} env steps with RLlib; wrote {out}")
    return config
