"""Train an exploration policy with stable-baselines3 PPO, a few hundred steps (a smoke run).

Every robot of the team is one slot of an SB3 ``VecEnv`` (``make_vec_env``), all sharing one
policy. A useful policy needs ~300k steps: ``mrexplore train`` does that with evaluations against
the frontier baselines (docs/guide/training.md).

    python examples/train_policy.py
"""

import tempfile
from pathlib import Path

import torch
from stable_baselines3 import PPO

from mrexplore.wrappers import make_vec_env

torch.set_num_threads(1)  # as `mrexplore train` does: threads slow a small CNN on a few cores
venv = make_vec_env(n_copies=1, world="small_office", n_robots=2, seed=0)  # 2 slots
model = PPO("CnnPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, verbose=0)
model.learn(total_timesteps=256)

obs = venv.reset()
actions, _ = model.predict(obs, deterministic=True)
print(f"trained {model.num_timesteps} steps; actions for {venv.num_envs} robots: {actions}")

with tempfile.TemporaryDirectory() as out:
    model.save(Path(out) / "model.zip")
    print("saved and reloaded:", PPO.load(Path(out) / "model.zip").observation_space.shape)
venv.close()
