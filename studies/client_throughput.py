"""Throughput of each RL client on our env, next to our own SB3 adapter, on the same settings.

Settings for every client: world ``small_office``, 2 robots, episodes of 100 steps
(``max_cycles``), torch on 1 thread. One *env step* moves both robots (2 agent steps).

Two figures per client, both per second of CPU time of this process (``time.process_time``:
all threads of this process, so it is fair to in-process clients; Ray's own daemons are not
counted, and RLlib runs with ``num_env_runners=0`` so that sampling happens in this process):

* rollout: random actions through the client's env interface (auto-reset included);
* train: the client's PPO (its own default-style model, 1 epoch, minibatch 64) for 512 env
  steps, sampling and updates together. The models differ (SB3's NatureCNN, RLlib's 4-layer
  CNN, a small TorchRL ConvNet), so the training figures compare whole pipelines, not envs.

Run: ``python studies/client_throughput.py`` (about 4 minutes on 2 cores); ``--only sb3,rllib``.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any

import numpy as np
import torch

import mrexplore

SETTINGS: dict[str, Any] = {"world": "small_office", "n_robots": 2, "max_cycles": 100}
ROLLOUT_STEPS = 400
TRAIN_STEPS = 512


def _cpu(fn: Callable[[], int]) -> tuple[float, float, int]:
    """(CPU s, wall s, env steps) of ``fn``, which returns the env steps it made."""
    c0, w0 = time.process_time(), time.perf_counter()
    steps = fn()
    return time.process_time() - c0, time.perf_counter() - w0, steps


def bench_raw() -> dict[str, Any]:
    penv = mrexplore.parallel_env(**SETTINGS)
    rng = np.random.default_rng(0)
    penv.reset(seed=0)

    def roll() -> int:
        for _ in range(ROLLOUT_STEPS):
            if not penv.agents:
                penv.reset()
            penv.step({a: int(rng.integers(4)) for a in penv.agents})
        return ROLLOUT_STEPS

    return {"rollout": _cpu(roll)}


def bench_sb3_ours() -> dict[str, Any]:
    from stable_baselines3 import PPO

    from mrexplore.wrappers import make_vec_env

    venv = make_vec_env(n_copies=1, seed=0, **SETTINGS)
    venv.reset()
    return _bench_sb3_vec(venv, PPO, ppo_seed=0)


def _bench_sb3_vec(venv: Any, ppo: Any, ppo_seed: int | None) -> dict[str, Any]:
    """Rollout and PPO-training figures of an SB3-style vector env (one copy, two robots)."""
    from stable_baselines3.common.logger import Logger

    rng = np.random.default_rng(0)

    def roll() -> int:
        for _ in range(ROLLOUT_STEPS):
            venv.step(rng.integers(0, 4, size=venv.num_envs))
        return ROLLOUT_STEPS

    out = {"rollout": _cpu(roll)}
    model = ppo(
        "CnnPolicy", venv, n_steps=128, batch_size=64, n_epochs=1, seed=ppo_seed, device="cpu"
    )
    # SB3's default logger would make an empty SB3-<time> folder in the temp directory per run
    model.set_logger(Logger(None, []))
    out["train"] = _cpu(lambda: model.learn(TRAIN_STEPS * 2).num_timesteps // 2)
    venv.close()
    return out


def bench_supersuit() -> dict[str, Any]:
    import supersuit as ss
    from stable_baselines3 import PPO

    venv = ss.concat_vec_envs_v1(
        ss.pettingzoo_env_to_vec_env_v1(mrexplore.parallel_env(**SETTINGS)),
        1,
        num_cpus=0,
        base_class="stable_baselines3",
    )
    venv.venv.reset(seed=0)
    # no PPO seed: SuperSuit's SB3 wrapper cannot be seeded (see the README's recipe)
    return _bench_sb3_vec(venv, PPO, ppo_seed=None)


def bench_gymnasium() -> dict[str, Any]:
    import gymnasium

    # Gymnasium's vector API is single-agent: 2 copies of the one-robot env, so one vector
    # step is 2 robot steps, as one step of the 2-robot env.
    opts = {k: v for k, v in SETTINGS.items() if k != "n_robots"}
    envs = gymnasium.make_vec("mrexplore/Explore-v0", num_envs=2, vectorization_mode="sync", **opts)
    envs.reset(seed=0)

    def roll() -> int:
        for _ in range(ROLLOUT_STEPS):
            envs.step(envs.action_space.sample())
        return ROLLOUT_STEPS

    out = {"rollout": _cpu(roll)}
    envs.close()
    return out


def bench_torchrl() -> dict[str, Any]:
    from tensordict.nn import TensorDictModule
    from torch import nn
    from torch.distributions import Categorical
    from torchrl.collectors import Collector
    from torchrl.envs.libs.pettingzoo import PettingZooWrapper
    from torchrl.modules import MultiAgentConvNet, MultiAgentMLP, ProbabilisticActor
    from torchrl.objectives import ClipPPOLoss, ValueEstimators

    env = PettingZooWrapper(
        env=mrexplore.parallel_env(**SETTINGS, obs_dtype="float32"),
        categorical_actions=True,
        seed=0,
    )
    out = {
        "rollout": _cpu(lambda: int(env.rollout(ROLLOUT_STEPS, break_when_any_done=False).numel()))
    }
    group, n = "robot", 2

    def net(n_out: int) -> nn.Module:
        return nn.Sequential(
            MultiAgentConvNet(
                n_agents=n,
                centralized=False,
                share_params=True,
                num_cells=[16, 32],
                kernel_sizes=[8, 4],
                strides=[4, 2],
            ),
            MultiAgentMLP(
                n_agent_inputs=None,
                n_agent_outputs=n_out,
                n_agents=n,
                centralized=False,
                share_params=True,
                depth=1,
                num_cells=64,
            ),
        )

    obs_key = (group, "observation")
    actor = ProbabilisticActor(
        TensorDictModule(net(4), in_keys=[obs_key], out_keys=[(group, "logits")]),
        in_keys=[(group, "logits")],
        out_keys=[env.action_key],
        distribution_class=Categorical,
        return_log_prob=True,
        log_prob_key=(group, "sample_log_prob"),
    )
    critic = TensorDictModule(net(1), in_keys=[obs_key], out_keys=[(group, "state_value")])
    td = env.reset()
    actor(td)
    critic(td)
    loss = ClipPPOLoss(actor_network=actor, critic_network=critic, entropy_coeff=0.01)
    loss.set_keys(
        reward=(group, "reward"),
        action=env.action_key,
        value=(group, "state_value"),
        done=(group, "done"),
        terminated=(group, "terminated"),
        sample_log_prob=(group, "sample_log_prob"),
    )
    loss.make_value_estimator(ValueEstimators.GAE, gamma=0.99, lmbda=0.95)
    opt = torch.optim.Adam(loss.parameters(), lr=3e-4)

    def train() -> int:
        collector = Collector(env, actor, frames_per_batch=256, total_frames=TRAIN_STEPS)
        frames = 0
        for batch in collector:
            with torch.no_grad():
                loss.value_estimator(
                    batch,
                    params=loss.critic_network_params,
                    target_params=loss.target_critic_network_params,
                )
            flat = batch.reshape(-1)
            for idx in torch.randperm(flat.shape[0]).split(64):
                parts = loss(flat[idx])
                total = parts["loss_objective"] + parts["loss_critic"] + parts["loss_entropy"]
                opt.zero_grad()
                total.backward()
                opt.step()
            frames += int(batch.numel())
        collector.shutdown()
        return frames

    out["train"] = _cpu(train)
    return out


def bench_rllib() -> dict[str, Any]:
    import ray

    from mrexplore.experiments.train_rllib import build_ppo_config

    ray.init(num_cpus=2, include_dashboard=False, logging_level="ERROR")
    try:
        cfg = build_ppo_config(
            {**SETTINGS, "obs_layout": "hwc", "obs_dtype": "float32"},
            {"train_batch_size_per_learner": 256, "minibatch_size": 64, "num_epochs": 1},
            env_runners=0,
            seed=0,
            rollout_fragment_length=64,
        )
        algo = cfg.build_algo()
        runner = algo.env_runner

        def roll() -> int:
            episodes = runner.sample(num_timesteps=ROLLOUT_STEPS, random_actions=True)
            return sum(int(e.env_steps()) for e in episodes)

        out = {"rollout": _cpu(roll)}

        def train() -> int:
            start = None
            steps = 0
            while steps < TRAIN_STEPS:
                res = algo.train()
                steps = int(res["num_env_steps_sampled_lifetime"])
                start = steps if start is None else start
            return steps

        out["train"] = _cpu(train)
        algo.stop()
    finally:
        ray.shutdown()
    return out


CLIENTS: dict[str, Callable[[], dict[str, Any]]] = {
    "raw ParallelEnv": bench_raw,
    "sb3 (ours)": bench_sb3_ours,
    "supersuit+sb3": bench_supersuit,
    "gymnasium vector (2x1 robot)": bench_gymnasium,
    "torchrl": bench_torchrl,
    "rllib": bench_rllib,
}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    p.add_argument("--only", default="", help="comma-separated substrings of client names")
    args = p.parse_args()
    torch.set_num_threads(1)
    wanted = [w for w in args.only.split(",") if w]
    print(
        f"settings: {SETTINGS}; rollout {ROLLOUT_STEPS} env steps (random actions), "
        f"train {TRAIN_STEPS} env steps (PPO, 1 epoch); figures: env steps per CPU second "
        "of this process (time.process_time), wall in brackets"
    )
    print(f"{'client':<30} {'rollout steps/CPU s':>24} {'train steps/CPU s':>24}")
    for name, fn in CLIENTS.items():
        if wanted and not any(w in name for w in wanted):
            continue
        res = fn()
        cells = []
        for part in ("rollout", "train"):
            if part in res:
                cpu, wall, steps = res[part]
                cells.append(f"{steps / cpu:>8.1f} ({steps / wall:>6.1f} wall)")
            else:
                cells.append(f"{'-':>24}")
        print(f"{name:<30} {cells[0]:>24} {cells[1]:>24}", flush=True)


if __name__ == "__main__":
    main()
