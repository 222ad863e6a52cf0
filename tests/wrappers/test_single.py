"""``mrexplore/Explore-v0``: the single-robot Gymnasium env, its checkers and SB3 training."""

from __future__ import annotations

import warnings
from pathlib import Path

import gymnasium
import numpy as np
import pytest

import mrexplore
from mrexplore.errors import ConfigError
from mrexplore.wrappers import SingleRobotExploreEnv

WORLD = "small_office"


def test_make_registered_id_and_step_tuple() -> None:
    env = gymnasium.make("mrexplore/Explore-v0", world=WORLD, max_cycles=3)
    assert isinstance(env.unwrapped, SingleRobotExploreEnv)
    obs, info = env.reset(seed=0)
    assert env.observation_space.contains(obs)
    assert obs.shape == (8, 64, 64) and obs.dtype == np.uint8
    assert {"coverage", "task_time_s", "merged"} <= set(info)
    out = env.step(0)
    assert len(out) == 5
    obs, reward, terminated, truncated, info = out
    assert isinstance(reward, float) and reward == pytest.approx(-0.25)  # "time" reward: -dt_s
    assert terminated is False and truncated is False
    for _ in range(2):
        obs, reward, terminated, truncated, info = env.step(3)
    assert truncated is True and info["TimeLimit.truncated"] is True
    env.close()


def test_same_world_and_start_as_the_team_env() -> None:
    # robot_0's start does not depend on n_robots: the single-robot baseline is comparable.
    single = SingleRobotExploreEnv(world=WORLD)
    team = mrexplore.parallel_env(world=WORLD, n_robots=1)
    obs_s, _ = single.reset(seed=4)
    obs_t, _ = team.reset(seed=4)
    np.testing.assert_array_equal(obs_s, obs_t["robot_0"])
    for a in (0, 1, 0, 2):
        o1, r1, *_ = single.step(a)
        o2, r2, *_ = team.step({"robot_0": a})
        np.testing.assert_array_equal(o1, o2["robot_0"])
        assert r1 == r2["robot_0"]


def test_gymnasium_checker_without_warnings() -> None:
    from gymnasium.utils.env_checker import check_env

    # Through gymnasium.make (with a spec, so that the checker also builds the env in every
    # render mode, "human" included). On a headless machine the env says, once, that "human"
    # shows nothing: that one message is expected; anything else is a failure.
    env = gymnasium.make("mrexplore/Explore-v0", world=WORLD, max_cycles=50)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    others = [
        str(w.message) for w in caught if "render_mode='human' shows nothing" not in str(w.message)
    ]
    assert others == []


def test_sb3_checker_without_warnings() -> None:
    from stable_baselines3.common.env_checker import check_env

    env = SingleRobotExploreEnv(world=WORLD, max_cycles=50)
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        check_env(env, warn=True)
    assert [str(w.message) for w in caught] == []


def test_metadata_matches_the_team_env() -> None:
    team = mrexplore.parallel_env(world=WORLD)
    assert SingleRobotExploreEnv.metadata["render_modes"] == team.metadata["render_modes"]
    assert SingleRobotExploreEnv.metadata["render_fps"] == team.metadata["render_fps"]


def test_render_mode_passed_through() -> None:
    env = SingleRobotExploreEnv(render_mode="rgb_array", world=WORLD)
    env.reset(seed=0)
    frame = env.render()
    assert frame is not None and frame.ndim == 3 and frame.shape[2] == 3
    assert env.penv.render_mode == "rgb_array"


@pytest.mark.parametrize(
    ("options", "match"),
    [
        ({"n_robots": 2}, "exactly one robot"),  # a team does not fit a single-agent API
        ({"wrld": WORLD}, "unknown option"),  # a typo is an error, never ignored
    ],
)
def test_bad_options(options: dict[str, object], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        SingleRobotExploreEnv(**options)


def test_ppo_cnn_trains_saves_loads_predicts(tmp_path: Path, one_torch_thread: None) -> None:
    from stable_baselines3 import PPO

    env = SingleRobotExploreEnv(world=WORLD, max_cycles=40)
    model = PPO("CnnPolicy", env, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=128)
    path = tmp_path / "ppo_single.zip"
    model.save(path)
    loaded = PPO.load(path, device="cpu")
    obs, _ = env.reset(seed=1)
    action, _ = loaded.predict(obs, deterministic=True)
    assert env.action_space.contains(int(action))
    # The loaded policy is the saved one: same greedy action as the model in memory.
    assert int(action) == int(model.predict(obs, deterministic=True)[0])
