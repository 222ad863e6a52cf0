"""ParallelEnvVecEnv and MapMergeWrapper on our own env (``small_office``): slot-by-slot agreement
with the ParallelEnv over an episode boundary, PPO with ``CnnPolicy``, subprocess copies."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecMonitor

import mrexplore
from mrexplore.errors import ConfigError
from mrexplore.wrappers import MapMergeWrapper, ParallelEnvVecEnv, make_vec_env

WORLD = "small_office"
OPTS: dict[str, Any] = {"world": WORLD, "n_robots": 2, "max_cycles": 5}


def _assert_same(x: Any, y: Any, where: str) -> None:
    if isinstance(x, dict):
        assert isinstance(y, dict) and x.keys() == y.keys(), where
        for k in x:
            _assert_same(x[k], y[k], f"{where}.{k}")
    elif isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        np.testing.assert_array_equal(x, y, err_msg=where)
    else:
        assert x == y, (where, x, y)


def test_slots_line_up_with_the_parallel_env_over_an_episode_boundary() -> None:
    venv = make_vec_env(n_copies=1, seed=3, **OPTS)
    ref = mrexplore.parallel_env(**OPTS)
    agents = ref.possible_agents
    assert venv.num_envs == 2 and venv.possible_agents == agents
    obs = venv.reset()
    ref_obs, ref_infos = ref.reset(seed=3)
    for j, a in enumerate(agents):
        np.testing.assert_array_equal(obs[j], ref_obs[a])
        _assert_same(venv.reset_infos[j], ref_infos[a], f"reset info {a}")
    rng = np.random.default_rng(0)
    boundaries = 0
    for step in range(8):
        actions = rng.integers(0, 4, size=2)
        v_obs, v_rew, v_done, v_infos = venv.step(actions)
        r_obs, r_rew, r_term, r_trunc, r_infos = ref.step(
            {a: int(actions[j]) for j, a in enumerate(agents)}
        )
        ended = all(r_term[a] or r_trunc[a] for a in agents)
        if ended:
            boundaries += 1
            next_obs, next_infos = ref.reset()  # the adapter's auto-reset draws no new seed
        for j, a in enumerate(agents):
            where = f"step {step} slot {j}"
            assert v_rew[j] == np.float32(r_rew[a]), where
            assert v_done[j] == (r_term[a] or r_trunc[a]), where
            info = dict(v_infos[j])
            assert info.pop("TimeLimit.truncated") == (r_trunc[a] and not r_term[a]), where
            if ended:
                np.testing.assert_array_equal(info.pop("terminal_observation"), r_obs[a])
                np.testing.assert_array_equal(v_obs[j], next_obs[a])
                _assert_same(venv.reset_infos[j], next_infos[a], where)
            else:
                assert "terminal_observation" not in info, where
                np.testing.assert_array_equal(v_obs[j], r_obs[a])
            expected = dict(r_infos[a])
            expected.pop("TimeLimit.truncated", None)
            _assert_same(info, expected, where)
        if step == 4:
            assert ended and v_done.all()  # max_cycles=5: the boundary is at the 5th step
    assert boundaries == 1
    venv.close()


def test_ppo_cnn_on_the_multi_robot_adapter(tmp_path: Path, one_torch_thread: None) -> None:
    venv = VecMonitor(make_vec_env(n_copies=1, seed=0, world=WORLD, n_robots=2, max_cycles=40))
    model = PPO("CnnPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(total_timesteps=256)  # 2 rollouts x 64 steps x 2 robots
    path = tmp_path / "ppo_team.zip"
    model.save(path)
    loaded = PPO.load(path, device="cpu")
    obs = venv.reset()
    actions, _ = loaded.predict(obs, deterministic=True)
    assert actions.shape == (2,) and set(actions.tolist()) <= {0, 1, 2, 3}
    np.testing.assert_array_equal(actions, model.predict(obs, deterministic=True)[0])
    venv.close()


def test_merge_wrapper_on_our_env_and_in_the_adapter() -> None:
    from pettingzoo.test import parallel_api_test

    def make() -> MapMergeWrapper:
        # The inner env does not merge: the wrapper's FusionStage is the one merging path.
        return MapMergeWrapper(
            mrexplore.parallel_env(world=WORLD, n_robots=2, merger=None, max_cycles=30),
            merge_every=5,
            view_m=12.8,
        )

    env = make()
    assert env.observation_space("robot_0").shape == (4, 64, 64)  # own_pose_cell: robots channel
    parallel_api_test(env, num_cycles=10)
    obs, infos = env.reset(seed=0)
    assert set(infos["robot_0"]) >= {"merged", "transform", "score", "coverage"}
    assert infos["robot_0"]["transform"] == {"robot_1": None} or infos["robot_0"]["merged"]
    # The robot is at the image centre of the robots channel.
    assert obs["robot_0"][3][32, 32] == 255
    venv = ParallelEnvVecEnv([make])
    venv.seed(0)
    assert venv.reset().shape == (2, 4, 64, 64)
    out = venv.step(np.zeros(2, dtype=np.int64))
    assert out[0].shape == (2, 4, 64, 64)
    venv.close()


def test_make_vec_env_refuses_bad_input_before_starting_workers() -> None:
    with pytest.raises(ConfigError, match="unknown option"):
        make_vec_env(n_copies=2, use_subprocess=True, wrld=WORLD)
    with pytest.raises(ConfigError, match="n_copies"):
        make_vec_env(n_copies=0, world=WORLD)


@pytest.mark.expensive
def test_subprocess_copies_of_our_env_match_in_process() -> None:
    opts = {**OPTS, "max_cycles": 3}
    local = make_vec_env(n_copies=2, seed=11, **opts)
    remote = make_vec_env(n_copies=2, seed=11, use_subprocess=True, **opts)
    try:
        np.testing.assert_array_equal(local.reset(), remote.reset())
        rng = np.random.default_rng(1)
        for _ in range(4):  # crosses the boundary at step 3
            actions = rng.integers(0, 4, size=4)
            a, b = local.step(actions), remote.step(actions)
            for x, y in zip(a[:3], b[:3], strict=True):
                np.testing.assert_array_equal(x, y)
            for j, (ia, ib) in enumerate(zip(a[3], b[3], strict=True)):
                _assert_same(ia, ib, f"slot {j}")
        assert remote.get_attr("render_mode") == [None] * 4
    finally:
        local.close()
        remote.close()
