"""Each RL client's recipe (docs/guide/training.md) trains or rolls out for a few hundred steps,
and its own model reads our 8 channels as channels: with the wrong axis (64 "channels") these
tests fail."""

from __future__ import annotations

import importlib.util
from collections.abc import Callable
from typing import Any

import numpy as np
import pytest
import torch

import mrexplore

Recipe = Callable[[str], dict[str, Any]]


def _needs(module: str) -> pytest.MarkDecorator:
    return pytest.mark.skipif(
        importlib.util.find_spec(module) is None,
        reason=f"{module} not installed (pip install -e '.[all]')",
    )


def _first_conv(module: torch.nn.Module) -> torch.nn.Conv2d:
    return next(m for m in module.modules() if isinstance(m, torch.nn.Conv2d))


@pytest.mark.expensive
@_needs("supersuit")
def test_supersuit_sb3_recipe_trains_on_channels_first_with_distinct_copies(
    recipe: Recipe,
) -> None:
    ns = recipe("supersuit")
    model, venv = ns["model"], ns["venv"]
    assert model.num_timesteps >= 256
    assert _first_conv(model.policy.features_extractor).in_channels == 8
    # the seed order of the recipe: copies 0 and 1 are different episodes (different worlds)
    copies = venv.venv.vec_envs
    worlds = [c.par_env.world.walls for c in copies]
    assert worlds[0].shape != worlds[1].shape or not np.array_equal(worlds[0], worlds[1])
    venv.close()


@_needs("supersuit")
def test_supersuit_tutorial_order_makes_identical_copies() -> None:
    # The pitfall the training guide warns about, kept as a test so the warning stays true.
    import supersuit as ss

    penv = mrexplore.parallel_env(world="random:symmetric_office?width_m=10&height_m=8")
    penv.reset(seed=42)  # the tutorial seeds here, before the copies are made
    venv = ss.concat_vec_envs_v1(
        ss.pettingzoo_env_to_vec_env_v1(penv), 2, num_cpus=0, base_class="stable_baselines3"
    )
    venv.reset()
    a, b = (c.par_env for c in venv.venv.vec_envs)
    assert np.array_equal(a.world.walls, b.world.walls)
    assert np.array_equal(a.sim.true_poses, b.sim.true_poses)
    with pytest.raises(AttributeError):
        venv.seed(0)  # SuperSuit's SB3 wrapper cannot be seeded the SB3 way
    venv.close()


@pytest.mark.expensive
def test_gymnasium_vector_recipe_trains_and_stacks_numeric_infos(recipe: Recipe) -> None:
    ns = recipe("gymnasium")
    net, infos = ns["net"], ns["infos"]
    assert _first_conv(net).in_channels == 8 == ns["envs"].single_observation_space.shape[0]
    assert ns["update"] == 3 and torch.isfinite(ns["loss"])
    for key, value in infos.items():
        assert value.dtype != object, key  # one number per copy: no None, no nested dicts
        assert value.shape == (2,)
    assert 0.0 < float(ns["coverage"].min()) <= 1.0


@pytest.mark.expensive
@_needs("torchrl")
def test_torchrl_recipe_checks_specs_and_trains_on_channels_first(recipe: Recipe) -> None:
    torch.manual_seed(0)
    ns = recipe("torchrl")
    env, actor, critic = ns["env"], ns["actor"], ns["critic"]
    obs_spec = env.observation_spec["robot", "observation"]
    assert obs_spec.shape[-3:] == (8, 64, 64) and obs_spec.dtype == torch.float32
    for net in (actor, critic):
        assert _first_conv(net).in_channels == 8
    assert ns["batch"].numel() == 128 and torch.isfinite(ns["total"])
    # every info key became a float tensor of one value per robot
    info = ns["batch"]["robot", "info"]
    assert set(info.keys()) == set(mrexplore.environment.infos.INFO_KEYS)


@pytest.mark.expensive
@_needs("ray")
def test_rllib_recipe_trains_a_shared_policy_on_channels_last(recipe: Recipe) -> None:
    ns = recipe("rllib")
    module, result = ns["module"], ns["result"]
    assert _first_conv(module).in_channels == 8  # the 8 channels, not 64 rows
    runners = result["env_runners"]
    assert runners["num_env_steps_sampled_lifetime"] >= 256
    # The team reward: RLlib sums returns over agents (2 robots: twice one robot's return).
    per_agent = runners["agent_episode_returns_mean"]["robot_0"]
    assert per_agent == pytest.approx(-0.25 * 100)  # max_cycles=100 steps of -dt_s
    assert runners["episode_return_mean"] == pytest.approx(2 * per_agent)


@pytest.mark.expensive  # importing RLlib alone takes ~10 s
@_needs("ray")
def test_rllib_wrapper_renders_our_frames() -> None:
    # RLlib's ParallelPettingZooEnv.render() passes its own render_mode (None) positionally.
    from ray.rllib.env.wrappers.pettingzoo_env import ParallelPettingZooEnv

    env = ParallelPettingZooEnv(
        mrexplore.parallel_env(world="small_office", render_mode="rgb_array", max_cycles=5)
    )
    env.reset(seed=0)
    frame = env.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8
