"""``mrexplore train``: one shared policy for all robots with stable-baselines3.

Hyperparameters live in YAML files per algorithm (``mrexplore/configs/{ppo,a2c,dqn}.yaml``, the
rl-baselines3-zoo habit), not in code. Worlds for training are drawn from the seeded generators
(``random:<generator>``), a fresh one per episode, so the policy cannot memorise one map;
evaluation uses seeds from 1,000,000 up (``EVAL_SEED_BASE``), never used in training. Writes
``model.zip``, ``config.yaml`` (every setting needed to rerun, the seed included), ``eval.json``
and ``checkpoints/``; TensorBoard logs in ``tb/`` when tensorboard is installed.
"""

from __future__ import annotations

import argparse
import copy
import hashlib
import importlib.resources
import importlib.util
import json
import platform
import time
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import Any

import yaml

from mrexplore.errors import ConfigError
from mrexplore.experiments.evaluate import (
    BASELINES,
    EVAL_SEED_BASE,
    evaluate_folder,
    evaluate_policies,
    write_evaluation,
)
from mrexplore.experiments.train_setup import (
    final_eval_seed_count,
    rollout_steps,
    rounded_timesteps,
    training_world,
)
from mrexplore.experiments.trained import ALGOS, TrainedTeamPolicy, algo_class
from mrexplore.io_safety import atomic_path, check_out_dir, write_text
from mrexplore.options import integer_argument


def load_hyperparams(algo: str, path: str | Path | None = None) -> dict[str, Any]:
    """The YAML hyperparameter file of ``algo`` (or the file at ``path``)."""
    if algo not in ALGOS:
        raise ConfigError(f"unknown algorithm {algo!r}; choose one of {', '.join(ALGOS)}")
    if path is not None:
        if not Path(path).is_file():
            raise ConfigError(f"hyperparameter file {path} not found")
        text = Path(path).read_text()
    else:
        text = (importlib.resources.files("mrexplore") / "configs" / f"{algo}.yaml").read_text()
    cfg = yaml.safe_load(text)
    for key in ("policy", "env", "hyperparams"):
        if key not in cfg:
            raise ConfigError(f"hyperparameter file for {algo} has no '{key}' section")
    return dict(cfg)


def save_for_inference(model: Any, path: str | Path) -> Path:
    """Save ``model`` without its optimizer's moment estimates (Adam keeps two per weight,
    doubling the file: 7.9 MB -> under 3 MB for our CnnPolicy). Loading and predicting are
    unaffected; resuming training would restart the moments (use the checkpoint instead)."""
    optimizer = getattr(model.policy, "optimizer", None)
    if optimizer is not None:
        optimizer.state.clear()
    model.save(str(path))
    return Path(path)


def _init_file(init_from: str | Path) -> Path:
    """The ``model.zip`` that ``--init-from`` names (a file, or a folder holding one)."""
    path = Path(init_from)
    if path.is_dir():
        path = path / "model.zip"
    if not path.is_file():
        raise ConfigError(f"train: --init-from {init_from}: no such model.zip")
    return path


def _load_weights(model: Any, path: Path) -> None:
    """Copy the network weights of the saved model at ``path`` into ``model`` (built from this
    run's config); a model of other spaces or another network is refused by name."""
    from stable_baselines3.common.save_util import load_from_zip_file

    try:
        data, params, _ = load_from_zip_file(str(path), device="cpu")
    except Exception as err:  # a zip that SB3 cannot read: name the file, not the library
        raise ConfigError(f"train: --init-from {path}: not a saved model ({err})") from None
    for space in ("observation_space", "action_space"):
        if data is None or data.get(space) != getattr(model, space):
            raise ConfigError(
                f"train: --init-from {path}: its {space.replace('_', ' ')} differs from this "
                "run's env (another env config or action mode)"
            )
    try:
        model.policy.load_state_dict(params["policy"])
    except (KeyError, RuntimeError) as err:
        first = str(err).strip().splitlines()[0] if str(err).strip() else type(err).__name__
        raise ConfigError(
            f"train: --init-from {path}: its network does not fit this run's policy ({first}); "
            "use the algorithm, policy and policy_kwargs it was trained with"
        ) from None


def versions() -> dict[str, str]:
    """Versions of mrexplore and the libraries a trained model depends on (for config.yaml)."""
    import gymnasium
    import numpy
    import pettingzoo
    import stable_baselines3
    import torch

    import mrexplore

    versions = {
        "mrexplore": mrexplore.__version__,
        "stable_baselines3": stable_baselines3.__version__,
        "torch": torch.__version__,
        "gymnasium": gymnasium.__version__,
        "pettingzoo": pettingzoo.__version__,
        "numpy": numpy.__version__,
        "python": platform.python_version(),
    }
    # Some versions are str subclasses (torch's TorchVersion) that YAML cannot represent.
    return {k: str(v) for k, v in versions.items()}


def train(
    algo: str = "ppo",
    timesteps: int = 1_000_000,
    out: str | Path = "runs/ppo",
    world: str | None = None,
    n_robots: int | None = None,
    seed: int = 0,
    hyperparams_file: str | Path | None = None,
    eval_every: int = 50_000,
    eval_seeds: int = 5,
    final_eval_seeds: int | None = None,
    n_copies: int | None = None,
    progress: bool = True,
    force: bool = False,
    init_from: str | Path | None = None,
) -> dict[str, Any]:
    """Train, evaluate periodically against the frontier baselines, save; returns the config.

    ``init_from``: a ``model.zip`` (or a policy folder holding one) of the same algorithm,
    observation and action spaces and network: training starts from its weights (with fresh
    optimizer moments, which an inference ``model.zip`` does not keep) instead of a random
    network. ``timesteps`` then counts the new steps only; ``config.yaml`` records the file and
    its SHA-256.

    stable-baselines3 stops only after a whole rollout (``n_steps`` x env slots for PPO and
    A2C, ``train_freq`` x slots for DQN), so ``timesteps`` is rounded up to one: the run
    prints the number when it differs, and ``config.yaml`` records it as ``timesteps`` (the
    number asked for as ``timesteps_asked``).

    Every argument is checked, and ``out`` refused when it is a file or a non-empty folder
    (without ``force``), before any work. ``final_eval_seeds=None`` scales the final
    evaluation to the run (:func:`final_eval_seed_count`); 0 skips it. Each file is written
    through a temporary name, so an interrupted run leaves no half-written file.

    Raises:
        ConfigError: a bad argument (``timesteps < 1``, ``seed < 0``, ...).
        OutputExistsError: ``out`` is refused (see above).
    """
    from stable_baselines3.common.callbacks import BaseCallback, CallbackList, CheckpointCallback
    from stable_baselines3.common.vec_env import VecMonitor
    from tqdm import tqdm

    from mrexplore.experiments.threads import PhaseThreads, phase_threads
    from mrexplore.policies import make_team_policy
    from mrexplore.wrappers.sb3_vec import make_vec_env

    timesteps = integer_argument("train", "timesteps", timesteps, 1)
    seed = integer_argument("train", "seed", seed, 0)
    eval_every = integer_argument("train", "eval_every", eval_every, 1)
    eval_seeds = integer_argument("train", "eval_seeds", eval_seeds, 1)
    final_seeds = (
        final_eval_seed_count(timesteps)
        if final_eval_seeds is None
        else integer_argument("train", "final_eval_seeds", final_eval_seeds, 0)
    )
    init_file = None if init_from is None else _init_file(init_from)
    cfg = load_hyperparams(algo, hyperparams_file)
    collect_threads, update_threads = phase_threads(cfg)
    env_opts = dict(cfg["env"])
    env_opts["world"] = training_world(world, env_opts.get("world", "random:symmetric_office"))
    # ``worlds`` in the YAML: copy k trains on worlds[k % len] (several families per batch);
    # --world replaces them all.
    worlds = [str(w) for w in cfg.get("worlds") or []] if world is None else []
    if n_robots is not None:
        env_opts["n_robots"] = integer_argument("train", "n_robots", n_robots, 1)
    n_copies = n_copies if n_copies is not None else cfg.get("n_copies", 1)
    copies = integer_argument("train", "n_copies", n_copies, 1)
    use_subprocess = bool(cfg.get("use_subprocess", False))
    # ``batched: true``: the copies as one batched env (make_vec_env(batched=True): one engine,
    # one merge worker for all copies; the same slots, seeds and results)
    batched = bool(cfg.get("batched", False))
    if batched and (use_subprocess or worlds):
        raise ConfigError(
            "train: batched: true takes one world spec for every copy, in this process "
            "(not with use_subprocess or a worlds list)"
        )
    # ``num_workers`` (with ``batched: true``): the batched copies stepped in that many worker
    # processes, each with its own GIL (the same slots, seeds and results)
    workers = cfg.get("num_workers")
    if workers is not None:
        workers = integer_argument("train", "num_workers", workers, 1)
        if not batched:
            raise ConfigError(
                "train: num_workers steps a batched env's copies in worker processes: it needs "
                "batched: true"
            )
    out = check_out_dir(out, force=force, what="mrexplore train")
    from mrexplore.environment.config import EnvConfig
    from mrexplore.environment.goal_actions import split_options

    _, goal_opts, low_opts = split_options(
        env_opts
    )  # goal-level options apart (action_mode="goal")
    if batched and goal_opts is not None:
        raise ConfigError(
            "train: batched: true batches the low-level env only, not action_mode='goal'"
        )
    EnvConfig.from_kwargs(**{k: v for k, v in low_opts.items() if k != "world"})  # options check
    out.mkdir(parents=True, exist_ok=True)
    config = {
        "algo": algo,
        "timesteps": int(timesteps),
        "seed": int(seed),
        "policy": cfg["policy"],
        "n_copies": copies,
        "use_subprocess": use_subprocess,
        "batched": batched,
        **({"num_workers": workers} if workers is not None else {}),
        # a reduction's rounding follows its thread count: the run's bits follow these
        "torch_threads": collect_threads,
        "update_threads": update_threads,
        "env": env_opts,
        **({"worlds": worlds} if worlds else {}),
        "hyperparams": cfg["hyperparams"],
        "policy_kwargs": cfg.get("policy_kwargs", {}),
        "eval": {
            "seed_base": EVAL_SEED_BASE,
            "every": eval_every,
            "seeds": eval_seeds,
            "final_seeds": final_seeds,
        },
        "versions": versions(),
    }
    if init_file is not None:
        digest = hashlib.sha256(init_file.read_bytes()).hexdigest()
        config["init_from"] = {"path": str(init_file), "sha256": digest}

    import torch

    # collection on torch_threads (on 2 cores, more would fight the env for the CPU); the
    # updates on update_threads, set by PhaseThreads around each rollout
    torch.set_num_threads(collect_threads)
    if worlds:
        import functools

        import mrexplore
        from mrexplore.wrappers.sb3_vec import ParallelEnvVecEnv

        fns: list[Callable[[], Any]] = [
            functools.partial(
                mrexplore.parallel_env, **{**env_opts, "world": worlds[k % len(worlds)]}
            )
            for k in range(copies)
        ]
        inner: Any = ParallelEnvVecEnv(fns, use_subprocess=use_subprocess)
        inner.seed(seed)
    else:
        inner = make_vec_env(
            n_copies=copies,
            use_subprocess=use_subprocess,
            seed=seed,
            batched=batched,
            **(env_opts if workers is None else {**env_opts, "num_workers": workers}),
        )
    if algo == "maskable_ppo":
        from mrexplore.wrappers.action_masks import VecActionMasks

        inner = VecActionMasks(inner)
    venv = VecMonitor(inner)
    tb = str(out / "tb") if importlib.util.find_spec("tensorboard") is not None else None
    model = algo_class(algo)(
        cfg["policy"],
        venv,
        seed=seed,
        device="cpu",
        verbose=0,
        tensorboard_log=tb,
        policy_kwargs=copy.deepcopy(cfg.get("policy_kwargs") or None),
        **cfg["hyperparams"],
    )
    if init_file is not None:
        _load_weights(model, init_file)
    # SB3 stops only after a whole rollout: say so now, and record the steps the run takes
    per_rollout, made_of = rollout_steps(model)
    asked, timesteps = timesteps, rounded_timesteps(timesteps, per_rollout)
    if timesteps != asked:
        at = list(config).index("timesteps")
        items = list(config.items())
        items[at : at + 1] = [("timesteps", timesteps), ("timesteps_asked", asked)]
        config = dict(items)
        print(
            f"train: --timesteps {asked:,} rounds up to {timesteps:,}: {algo} collects whole "
            f"rollouts of {per_rollout:,} steps ({made_of}); config.yaml records {timesteps:,}"
        )
    # written once the start is known good: a refused --init-from leaves no config behind
    write_text(out / "config.yaml", yaml.safe_dump(config, sort_keys=False))
    eval_env = {**env_opts, "task": "explore"}
    baseline_env = split_options(eval_env)[2]  # the planners act on the low-level env
    periodic_seeds = list(range(EVAL_SEED_BASE, EVAL_SEED_BASE + eval_seeds))
    baseline: dict[str, Any] = {}
    if eval_every <= timesteps:  # periodic evaluations will happen: compare with the baselines
        if progress:
            print(f"evaluating the frontier baselines on {eval_seeds} held-out seed(s) first")
        baseline = evaluate_policies(
            {b: (lambda ag, b=b: make_team_policy(b, ag)) for b in BASELINES if b != "random"},
            baseline_env,
            periodic_seeds,
            progress=False,
        )
    history: list[dict[str, Any]] = []

    class _Progress(BaseCallback):
        """tqdm progress bar and periodic evaluation against the frontier baselines."""

        def __init__(self) -> None:
            super().__init__()
            self.bar = tqdm(
                total=int(timesteps), desc=f"train {algo}", unit="step", disable=not progress
            )
            self.next_eval = eval_every
            self.t0 = time.perf_counter()

        def _on_step(self) -> bool:
            self.bar.update(self.training_env.num_envs)
            if self.num_timesteps >= self.next_eval:
                self.next_eval += eval_every
                res = evaluate_policies(
                    {"trained": lambda ag: TrainedTeamPolicy(self.model, ag)},
                    eval_env,
                    periodic_seeds,
                    progress=False,
                )["trained"]
                entry = {
                    "timesteps": int(self.num_timesteps),
                    "wall_s": time.perf_counter() - self.t0,
                    "task_time_s": res["task_time_s"]["mean"],
                    "final_coverage": res["final_coverage"]["mean"],
                    "coverage_at": {k: v["mean"] for k, v in res["coverage_at"].items()},
                }
                history.append(entry)
                self.logger.record("eval/final_coverage", entry["final_coverage"])
                self.logger.record("eval/task_time_s", entry["task_time_s"])
                for name, s in baseline.items():
                    self.logger.record(
                        f"eval/baseline_{name}_final_coverage", s["final_coverage"]["mean"]
                    )
                self.bar.write(
                    f"[eval @ {self.num_timesteps}] trained: coverage "
                    f"{entry['final_coverage']:.1%}, "
                    f"task time {entry['task_time_s']:.1f} s | "
                    + ", ".join(
                        f"{n}: {s['final_coverage']['mean']:.1%}" for n, s in baseline.items()
                    )
                )
            return True

        def _on_training_end(self) -> None:
            self.bar.close()

    ckpt_every = max(1, eval_every // max(1, venv.num_envs))
    callbacks = CallbackList(
        [
            PhaseThreads(collect_threads, update_threads),
            _Progress(),
            CheckpointCallback(ckpt_every, str(out / "checkpoints"), name_prefix=algo),
        ]
    )
    if tb is None:
        # Without TensorBoard, SB3 would make an empty SB3-<time> folder in the system's temp
        # directory on every run: its logger writes nowhere instead (eval.json has the figures).
        from stable_baselines3.common.logger import configure

        model.set_logger(configure(str(out), format_strings=[]))
    t0 = time.perf_counter()
    model.learn(total_timesteps=int(timesteps), callback=callbacks)
    train_s = time.perf_counter() - t0
    with atomic_path(out / "checkpoints" / f"{algo}_final_with_optimizer.zip") as tmp:
        model.save(str(tmp))  # to resume
    with atomic_path(out / "model.zip") as tmp:
        save_for_inference(model, tmp)
    venv.close()
    throughput = {
        "timesteps": int(model.num_timesteps),
        "wall_s": train_s,
        "env_steps_per_s": model.num_timesteps / train_s,
    }
    training = {"throughput": throughput, "history": history, "baseline_periodic": baseline}
    if final_seeds > 0:
        doc = evaluate_folder(out, n_seeds=final_seeds, progress=progress)
        doc["training"] = training
        write_evaluation(doc, out)
    else:
        write_text(out / "eval.json", json.dumps({"training": training}, indent=2))
    print(
        f"trained {model.num_timesteps} steps in {train_s:.0f} s "
        f"({throughput['env_steps_per_s']:.0f} env steps/s including updates); wrote {out}"
    )
    return config


def main(argv: Sequence[str] | None = None) -> int:
    """CLI: ``mrexplore train --algo ppo --world random:symmetric_office --n-robots 2
    --timesteps N``.

    Writes to ``--out DIR``.
    """
    p = argparse.ArgumentParser(prog="mrexplore train", description=__doc__)
    p.add_argument(
        "--backend",
        default="sb3",
        choices=("sb3", "rllib"),
        help="sb3 (default): stable-baselines3 in this process; rllib: RLlib PPO on Ray "
        "(local, or --address), with --env-runners sampling actors",
    )
    p.add_argument("--algo", default="ppo", choices=ALGOS)
    p.add_argument(
        "--world",
        default=None,
        help="the world to train on, as every command reads it: a shipped world's name (the "
        "same map every episode), a map YAML, or random:<generator>[?options] (a fresh world "
        "each episode); default: the settings' world (fresh 10 x 8 m offices)",
    )
    p.add_argument("--n-robots", type=int, default=None)
    p.add_argument(
        "--timesteps",
        type=int,
        default=1_000_000,
        help="at least 1; sb3 rounds it up to whole rollouts (n_steps x env slots), which the "
        "run prints and config.yaml records",
    )
    p.add_argument(
        "--out",
        default=None,
        help="new folder for model.zip, config.yaml, eval.json (default: runs/<algo>); an "
        "existing non-empty folder is refused without --force",
    )
    p.add_argument("--force", action="store_true", help="replace the files of a non-empty --out")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--hyperparams", default=None, help="a YAML file instead of the shipped one")
    p.add_argument("--eval-every", type=int, default=50_000)
    p.add_argument("--eval-seeds", type=int, default=5)
    p.add_argument(
        "--final-eval-seeds",
        type=int,
        default=None,
        help="held-out seeds of the final evaluation (default: scaled to --timesteps, 2 to 20; "
        "0 skips it)",
    )
    p.add_argument("--n-copies", type=int, default=None)
    p.add_argument(
        "--init-from",
        default=None,
        help="start from the weights of this model.zip (or policy folder) of the same "
        "algorithm, spaces and network; --timesteps counts the new steps",
    )
    p.add_argument(
        "--env-runners",
        type=int,
        default=2,
        help="rllib: env runner actors (one CPU each; 0 samples in the driver)",
    )
    p.add_argument(
        "--address",
        default=None,
        help="rllib: join the Ray cluster at this address ('auto' or HEAD_IP:6379 of "
        "`ray start --head`); default: local Ray",
    )
    args = p.parse_args(argv)
    if args.backend == "rllib":
        if args.algo != "ppo":
            raise ConfigError("train --backend rllib trains PPO only (--algo ppo)")
        if args.init_from is not None:
            raise ConfigError("train: --init-from needs --backend sb3")
        from mrexplore.experiments.train_rllib import train_rllib

        train_rllib(
            timesteps=args.timesteps,
            out=args.out if args.out is not None else "runs/rllib",
            world=args.world,
            n_robots=args.n_robots,
            seed=args.seed,
            env_runners=args.env_runners,
            address=args.address,
            hyperparams_file=args.hyperparams,
            final_eval_seeds=args.final_eval_seeds,
            force=args.force,
        )
        return 0
    if args.address is not None:
        raise ConfigError("train: --address needs --backend rllib")
    train(
        algo=args.algo,
        timesteps=args.timesteps,
        out=args.out if args.out is not None else f"runs/{args.algo}",
        world=args.world,
        n_robots=args.n_robots,
        seed=args.seed,
        hyperparams_file=args.hyperparams,
        eval_every=args.eval_every,
        eval_seeds=args.eval_seeds,
        final_eval_seeds=args.final_eval_seeds,
        n_copies=args.n_copies,
        force=args.force,
        init_from=args.init_from,
    )
    return 0
