"""Where a PPO run's time goes: collecting rollouts through the batched env vs the update.

    python studies/ppo_split.py                       # 8 worlds x 2 robots, 8,192 robot-steps
    python studies/ppo_split.py --copies 8 --timesteps 16384
    python studies/ppo_split.py --unbatched           # the same through separate copies
    python studies/ppo_split.py --workers 2           # the batched env in 2 worker processes

Trains stable-baselines3 PPO exactly as ``mrexplore train --algo ppo`` sets it up (the
``mrexplore/configs/ppo.yaml`` policy, env options and hyperparameters, one torch thread while
collecting and ``update_threads`` while updating), but
through the batched env (``make_vec_env(..., batched=True)``), and times, on this instance:

* ``collect_rollouts`` (env stepping + policy forward + buffer), and inside it the VecEnv's
  ``step_wait`` (the env alone: all worlds' steps and auto-resets);
* ``train`` (the PPO update: epochs of minibatch gradient steps).

For each part it prints wall time and CPU time of the main thread (``time.thread_time``: the
env steps and, with one torch thread, the network run in this thread; CPU time does not count
other processes' turns on a shared machine), as shares of the ``learn()`` call. The process CPU
time is printed too: it also counts the shared merge worker thread and torch's helper threads.
Nothing is written (no model is saved).
"""

from __future__ import annotations

import argparse
import os
import time
from collections import defaultdict
from collections.abc import Callable, Sequence
from typing import Any


def _timed(fn: Callable[..., Any], acc: dict[str, float], key: str) -> Callable[..., Any]:
    """``fn`` adding its wall, thread-CPU and process-CPU seconds to ``acc[key + ...]``."""

    def wrapper(*args: Any, **kwargs: Any) -> Any:
        w0, t0, p0 = time.perf_counter(), time.thread_time(), time.process_time()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[key + "_wall"] += time.perf_counter() - w0
            acc[key + "_cpu"] += time.thread_time() - t0
            acc[key + "_proc"] += time.process_time() - p0

    return wrapper


def main(argv: Sequence[str] | None = None) -> int:
    """Train briefly and print the split (see the module docstring)."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--copies", type=int, default=8, help="worlds in the batched env (8)")
    p.add_argument("--robots", type=int, default=2, help="robots per world (2)")
    p.add_argument("--timesteps", type=int, default=8192, help="robot-steps to train (8192)")
    p.add_argument("--n-steps", type=int, default=None, help="PPO n_steps per slot (ppo.yaml)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--workers",
        type=int,
        default=None,
        help="step the batched env's worlds in this many worker processes (num_workers) "
        "instead of threads",
    )
    p.add_argument(
        "--update-threads",
        type=int,
        default=None,
        help="PyTorch threads during the PPO update (ppo.yaml's update_threads); collection "
        "keeps torch_threads",
    )
    p.add_argument(
        "--torch-threads",
        type=int,
        default=None,
        help="PyTorch threads while collecting (ppo.yaml's torch_threads)",
    )
    p.add_argument(
        "--unbatched",
        action="store_true",
        help="through make_vec_env's default adapter (separate copies) instead, for comparison",
    )
    args = p.parse_args(argv)

    import torch
    from stable_baselines3 import PPO
    from stable_baselines3.common.logger import Logger
    from stable_baselines3.common.vec_env import VecMonitor

    from mrexplore.errors import ConfigError
    from mrexplore.experiments.threads import PhaseThreads, phase_threads
    from mrexplore.experiments.train import load_hyperparams, training_world
    from mrexplore.wrappers.sb3_vec import make_vec_env

    cfg = load_hyperparams("ppo")
    if args.update_threads is not None:
        cfg["update_threads"] = args.update_threads
    if args.torch_threads is not None:
        cfg["torch_threads"] = args.torch_threads
    try:
        collect_threads, update_threads = phase_threads(cfg, "ppo_split")
    except ConfigError as err:
        p.error(str(err))
    torch.set_num_threads(collect_threads)
    env_opts = dict(cfg["env"])
    env_opts["world"] = training_world(None, env_opts["world"])
    env_opts["n_robots"] = args.robots
    hyper = dict(cfg["hyperparams"])
    if args.n_steps is not None:
        hyper["n_steps"] = args.n_steps
    batched = not args.unbatched
    if args.workers is not None:
        if not batched:
            p.error("--workers is for the batched env (not with --unbatched)")
        env_opts["num_workers"] = args.workers
    inner = make_vec_env(n_copies=args.copies, seed=args.seed, batched=batched, **env_opts)
    acc: dict[str, float] = defaultdict(float)
    inner.step_wait = _timed(inner.step_wait, acc, "env")  # type: ignore[method-assign]
    venv = VecMonitor(inner)
    model = PPO(
        cfg["policy"],
        venv,
        seed=args.seed,
        device="cpu",
        verbose=0,
        policy_kwargs=dict(cfg.get("policy_kwargs") or {}),
        **hyper,
    )
    # SB3's default logger would make an empty SB3-<time> folder in the temp directory per run
    model.set_logger(Logger(None, []))
    model.collect_rollouts = _timed(model.collect_rollouts, acc, "collect")  # type: ignore[method-assign]
    model.train = _timed(model.train, acc, "train")  # type: ignore[method-assign]
    w0, t0, p0 = time.perf_counter(), time.thread_time(), time.process_time()
    model.learn(args.timesteps, callback=PhaseThreads(collect_threads, update_threads))
    wall, cpu, proc = (
        time.perf_counter() - w0,
        time.thread_time() - t0,
        time.process_time() - p0,
    )
    venv.close()
    slots = args.copies * args.robots
    rollout = hyper["n_steps"] * slots
    load = os.getloadavg()
    print(
        f"PPO ({cfg['policy']}, ppo.yaml hyperparameters, n_steps {hyper['n_steps']} x "
        f"{slots} slots = {rollout} robot-steps per rollout, {hyper['n_epochs']} epochs, "
        f"batch {hyper['batch_size']}) through the "
        f"{'default adapter (separate copies)' if not batched else 'batched env'}"
        f"{'' if args.workers is None else f' in {args.workers} worker processes'}: "
        f"{args.copies} worlds x "
        f"{args.robots} robots, world {env_opts['world']}; {model.num_timesteps} robot-steps; "
        f"torch threads {collect_threads} collecting, {update_threads} updating; "
        f"load average {load[0]:.2f} {load[1]:.2f}"
    )
    print(f"{'part':<44} {'wall s':>8} {'share':>6} {'CPU s':>8} {'share':>6} {'proc CPU s':>10}")

    def line(label: str, w: float, c: float, pr: float) -> None:
        print(f"{label:<44} {w:>8.2f} {w / wall:>6.1%} {c:>8.2f} {c / cpu:>6.1%} {pr:>10.2f}")

    line("learn() total", wall, cpu, proc)
    line("collect_rollouts (env + policy forward)", *(acc[f"collect_{k}"] for k in WCP))
    line("  of which the env (VecEnv.step_wait)", *(acc[f"env_{k}"] for k in WCP))
    line(
        "  of which policy forward, buffer, callbacks",
        *(acc[f"collect_{k}"] - acc[f"env_{k}"] for k in WCP),
    )
    line("train (the PPO update)", *(acc[f"train_{k}"] for k in WCP))
    line(
        "other (set-up, logging)",
        *(
            t - acc[f"collect_{k}"] - acc[f"train_{k}"]
            for t, k in zip((wall, cpu, proc), WCP, strict=True)
        ),
    )
    print(
        f"samples (robot-steps) per wall second: collection "
        f"{model.num_timesteps / acc['collect_wall']:,.0f}, training overall "
        f"{model.num_timesteps / wall:,.0f}"
    )
    env_cpu = acc["env_cpu"]
    print(
        f"env: {model.num_timesteps / env_cpu:,.0f} robot-steps per CPU second of the stepping "
        f"thread ({1000 * env_cpu / (model.num_timesteps / slots):.2f} ms CPU per batched step "
        f"of {args.copies} worlds); env / update CPU = {env_cpu / acc['train_cpu']:.2f}"
    )
    return 0


#: The three clocks of every timed part, in print order.
WCP = ("wall", "cpu", "proc")


if __name__ == "__main__":
    raise SystemExit(main())
