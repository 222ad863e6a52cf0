"""BatchedVecEnv (``make_vec_env(..., batched=True)``): the same run as ParallelEnvVecEnv over
separate copies, SB3's VecEnv contract, a PPO smoke run."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecEnv, VecMonitor

import mrexplore
from mrexplore.environment.batched import BatchedExploreEnv
from mrexplore.environment.parallel_env import MultiRobotExplorationEnv
from mrexplore.errors import ConfigError
from mrexplore.wrappers import BatchedVecEnv, ParallelEnvVecEnv, make_vec_env
from tests.helpers import assert_same

OPTS: dict[str, Any] = {"world": "small_office", "n_robots": 2, "max_cycles": 9}


# {}: the worlds stepped in this process; num_workers: in two worker processes
@pytest.mark.parametrize("engine", [{}, {"num_workers": 2}])
def test_batched_vec_env_equals_the_parallel_env_vec_env(engine: dict[str, Any]) -> None:
    n = 3
    venv = make_vec_env(n_copies=n, seed=4, batched=True, **OPTS, **engine)
    ref = make_vec_env(n_copies=n, seed=4, **OPTS)
    assert isinstance(venv, BatchedVecEnv) and not isinstance(ref, BatchedVecEnv)
    assert venv.num_envs == ref.num_envs == 2 * n
    assert venv.observation_space == ref.observation_space
    assert venv.action_space == ref.action_space
    assert venv.possible_agents == ref.possible_agents
    assert_same(venv.reset(), ref.reset(), "reset")
    assert_same(venv.reset_infos, ref.reset_infos, "reset_infos")
    rng = np.random.default_rng(1)
    dones = 0
    for t in range(30):
        act = rng.integers(0, 4, size=venv.num_envs)
        out, rout = venv.step(act), ref.step(act)
        for name, x, y in zip(("obs", "rew", "done"), out[:3], rout[:3], strict=True):
            assert_same(x, y, f"step {t} {name}")
        for i, (a, b) in enumerate(zip(out[3], rout[3], strict=True)):
            assert_same(a, b, f"step {t} info {i}")
        assert_same(venv.reset_infos, ref.reset_infos, f"step {t} reset_infos")
        dones += int(out[2].sum())
    assert dones == 3 * 2 * n  # three episodes of 9 steps ended in every copy
    # seed() again: the next reset re-seeds every copy the same way
    assert venv.seed(9) == ref.seed(9) == [9, 9, 10, 10, 11, 11]
    assert_same(venv.reset(), ref.reset(), "re-seeded reset")
    venv.close()
    ref.close()


def test_one_robot_per_world_through_the_batched_adapter() -> None:
    opts = {**OPTS, "n_robots": 1}
    venv = make_vec_env(n_copies=2, seed=1, batched=True, **opts)
    ref = make_vec_env(n_copies=2, seed=1, **opts)
    assert_same(venv.reset(), ref.reset(), "reset")
    for t in range(12):
        act = np.array([t % 4, 0])
        for x, y, name in zip(venv.step(act), ref.step(act), "orde", strict=True):
            if name == "e":
                for i, (a, b) in enumerate(zip(x, y, strict=True)):
                    assert_same(a, b, f"step {t} info {i}")
            else:
                assert_same(x, y, f"step {t} {name}")
    venv.close()
    ref.close()


def test_vec_env_contract_of_the_batched_adapter() -> None:
    venv = make_vec_env(n_copies=2, seed=0, batched=True, **OPTS)
    assert isinstance(venv, VecEnv) and isinstance(venv, ParallelEnvVecEnv)
    obs = venv.reset()
    assert obs.shape == (4, *venv.observation_space.shape)
    assert obs.dtype == venv.observation_space.dtype
    assert all(venv.observation_space.contains(o) for o in obs)
    for _ in range(OPTS["max_cycles"]):
        obs, rew, done, infos = venv.step(np.array([venv.action_space.sample() for _ in range(4)]))
    assert rew.dtype == np.float32 and rew.shape == (4,) and done.dtype == bool
    assert done.all() and len(infos) == 4
    for info in infos:
        assert info["TimeLimit.truncated"] is True  # max_cycles: a time limit
        assert info["terminal_observation"].shape == venv.observation_space.shape
    assert [i["step"] for i in venv.reset_infos] == [0, 0, 0, 0]
    # slot -> copy for get_attr / set_attr / env_method / env_is_wrapped
    envs = venv.get_attr("unwrapped")
    assert envs[0] is envs[1] and envs[0] is not envs[2]
    assert isinstance(envs[0], MultiRobotExplorationEnv)
    venv.set_attr("marker", 5, indices=[2])
    assert venv.get_attr("marker", indices=[2, 3]) == [5, 5]
    assert venv.env_method("action_space", "robot_0", indices=0)[0].n == 4
    assert venv.env_is_wrapped(MultiRobotExplorationEnv) == [True] * 4
    assert list(venv.get_images()) == [None, None]
    monitored = VecMonitor(venv)
    monitored.reset()
    monitored.close()
    assert venv.closed


def test_worlds_in_worker_processes_answer_the_vec_env_queries() -> None:
    """get_attr / set_attr / env_method / env_is_wrapped reach the world in its worker."""
    from mrexplore.environment.processes import ProcessBatchedEnv

    venv = make_vec_env(n_copies=3, seed=0, batched=True, num_workers=2, **OPTS)
    assert isinstance(venv.batch, ProcessBatchedEnv) and venv.batch.worker_sizes == [2, 1]
    venv.reset()
    venv.set_attr("marker", 5, indices=[4])  # slot 4: world 2, in the second worker
    assert venv.get_attr("marker", indices=[4, 5]) == [5, 5]
    with pytest.raises(AttributeError):
        venv.get_attr("marker", indices=[0])
    assert venv.env_method("action_space", "robot_0", indices=0)[0].n == 4
    assert venv.env_is_wrapped(MultiRobotExplorationEnv) == [True] * 6
    venv.close()


@pytest.mark.usefixtures("one_torch_thread")
@pytest.mark.parametrize("engine", [{}, {"num_workers": 2}])
def test_ppo_learns_through_the_batched_env(engine: dict[str, Any]) -> None:
    venv = VecMonitor(make_vec_env(n_copies=2, seed=0, batched=True, **OPTS, **engine))
    model = PPO("CnnPolicy", venv, n_steps=64, batch_size=64, n_epochs=1, seed=0, device="cpu")
    model.learn(256)
    assert model.num_timesteps >= 256
    venv.close()


def test_batched_make_vec_env_bad_input() -> None:
    with pytest.raises(ConfigError, match="n_copies"):
        make_vec_env(n_copies=0, batched=True, **OPTS)
    with pytest.raises(ConfigError, match="use_subprocess"):
        make_vec_env(n_copies=2, batched=True, use_subprocess=True, **OPTS)
    venv = make_vec_env(n_copies=2, batched=True, **OPTS)
    venv.reset()
    with pytest.raises(ValueError, match="one per slot"):
        venv.step_async(np.zeros(3, dtype=np.int64))
    venv.close()
    one = mrexplore.vector_env(1, **OPTS)
    assert isinstance(one, BatchedExploreEnv) and one.num_envs == 1
    one.close()
