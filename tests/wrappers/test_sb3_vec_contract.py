"""ParallelEnvVecEnv against SB3's VecEnv contract, on tiny hand-made ParallelEnvs (fast, exact)."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import pytest
from _toy_envs import CountEnv
from pettingzoo.utils.wrappers import BaseParallelWrapper
from stable_baselines3.common.vec_env import VecMonitor

from mrexplore.errors import ConfigError
from mrexplore.wrappers import ParallelEnvVecEnv


class Marker(BaseParallelWrapper):  # type: ignore[type-arg]
    """A do-nothing wrapper to test ``env_is_wrapped``."""


def test_slots_dones_terminal_obs_idle_and_auto_reset() -> None:
    venv = ParallelEnvVecEnv([lambda: CountEnv(n=3, horizon=4)])
    assert venv.num_envs == 3
    obs = venv.reset()
    np.testing.assert_array_equal(obs[:, 0], [0, 10, 20])
    assert [i["reset"] for i in venv.reset_infos] == [0, 0, 0]
    # t = 1: everyone alive.
    obs, rew, done, infos = venv.step(np.array([0, 1, 2]))
    np.testing.assert_array_equal(obs[:, 0], [1, 11, 21])
    np.testing.assert_array_equal(rew, [1, 2, 3])
    assert rew.dtype == np.float32 and done.dtype == bool
    assert not done.any()
    assert [i["TimeLimit.truncated"] for i in infos] == [False] * 3
    # t = 2: a2 terminates (a true end: not TimeLimit.truncated).
    obs, rew, done, infos = venv.step(np.array([0, 1, 2]))
    np.testing.assert_array_equal(done, [False, False, True])
    np.testing.assert_array_equal(infos[2]["terminal_observation"], [22])
    assert infos[2]["TimeLimit.truncated"] is False
    assert "terminal_observation" not in infos[0]
    # t = 3: a2's slot is idle: zero obs, zero reward, not done, its action ignored.
    obs, rew, done, infos = venv.step(np.array([2, 2, 1]))
    np.testing.assert_array_equal(obs[:, 0], [3, 13, 0])
    np.testing.assert_array_equal(rew, [3, 4, 0])
    np.testing.assert_array_equal(done, [False, False, False])
    assert infos[2] == {"idle": True}
    env = venv.get_attr("unwrapped", indices=0)[0]
    assert env.last_actions == {"a0": 2, "a1": 2}
    # t = 4: a0 and a1 truncate; the copy auto-resets: new episode's first obs returned.
    obs, rew, done, infos = venv.step(np.array([0, 0, 0]))
    np.testing.assert_array_equal(done, [True, True, False])
    np.testing.assert_array_equal(obs[:, 0], [100, 110, 120])
    np.testing.assert_array_equal(infos[0]["terminal_observation"], [4])
    np.testing.assert_array_equal(infos[1]["terminal_observation"], [14])
    assert infos[0]["TimeLimit.truncated"] is True
    assert [i["reset"] for i in venv.reset_infos] == [1, 1, 1]
    assert env.seeds == [None, None]  # an auto-reset does not re-seed
    venv.close()


def test_two_copies_stack_in_slot_order_and_seed_next_reset_only() -> None:
    venv = ParallelEnvVecEnv([lambda: CountEnv(n=2, early=None) for _ in range(2)])
    assert venv.num_envs == 4 and venv.slot(1, 0) == 2
    seeds = venv.seed(10)
    assert list(seeds) == [10, 10, 11, 11]  # one seed per slot: its copy's seed
    venv.set_options({"x": 1})
    venv.reset()
    venv.reset()
    envs = venv.get_attr("unwrapped")
    assert envs[0] is envs[1] and envs[2] is envs[3] and envs[0] is not envs[2]
    assert envs[0].seeds == [10, None] and envs[2].seeds == [11, None]
    assert envs[0].options == [{"x": 1}, None]
    obs, *_ = venv.step(np.zeros(4, dtype=np.int64))
    np.testing.assert_array_equal(obs[:, 0], [101, 111, 101, 111])  # 2nd episode, t = 1
    venv.close()


def test_attr_method_wrapped_and_images() -> None:
    venv = ParallelEnvVecEnv(
        [
            lambda: Marker(CountEnv(n=2, render_mode="rgb_array")),
            lambda: CountEnv(n=2, render_mode="rgb_array"),
        ]
    )
    assert venv.render_mode == "rgb_array"
    venv.reset()
    assert venv.get_attr("horizon") == [4, 4, 4, 4]
    venv.set_attr("horizon", 7, indices=[2, 3])
    assert venv.get_attr("horizon") == [4, 4, 7, 7]
    assert venv.env_method("ping", 5, indices=[1, 2]) == [(0, 5), (0, 5)]
    assert venv.env_is_wrapped(Marker) == [True, True, False, False]  # type: ignore[arg-type]
    images = venv.get_images()
    assert len(images) == 2 and images[0] is not None and images[0].shape == (2, 3, 3)
    assert venv.render().shape[2] == 3  # SB3 tiles the copies' frames
    with pytest.raises(IndexError):
        venv.get_attr("horizon", indices=[4])
    venv.close()


def test_vec_monitor_reports_per_robot_episodes() -> None:
    venv = VecMonitor(ParallelEnvVecEnv([lambda: CountEnv(n=2, horizon=3, early=None)]))
    venv.reset()
    infos: list[dict[str, Any]] = []
    for _ in range(3):
        _, _, done, infos = venv.step(np.zeros(2, dtype=np.int64))
    assert done.all()
    # a0 collects 1 + 2 + 3, a1 collects 2 + 3 + 4, over 3 steps.
    assert infos[0]["episode"]["r"] == pytest.approx(6.0) and infos[0]["episode"]["l"] == 3
    assert infos[1]["episode"]["r"] == pytest.approx(9.0)
    venv.close()


class _OtherSpaces(CountEnv):
    def __init__(self, which: str) -> None:
        super().__init__(n=2)
        self.which = which

    def observation_space(self, agent: str) -> gymnasium.spaces.Space[Any]:
        if self.which == "obs" and agent == "a1":
            return gymnasium.spaces.Box(0, 1e6, (2,), dtype=np.float32)
        return self._obs

    def action_space(self, agent: str) -> gymnasium.spaces.Space[Any]:
        if self.which == "act" and agent == "a1":
            return gymnasium.spaces.Discrete(5)
        return self._act


@pytest.mark.parametrize(
    ("fns", "match"),
    [
        # a1's observation has another shape: one policy cannot take both
        ([lambda: _OtherSpaces("obs")], "different observation spaces"),
        # a1 has more actions
        ([lambda: _OtherSpaces("act")], "different action spaces"),
        # copies with different team sizes
        ([lambda: CountEnv(n=2), lambda: CountEnv(n=3)], "copy 1 differs"),
        # nothing to run
        ([], "at least one"),
    ],
)
def test_construction_errors(fns: list[Any], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        ParallelEnvVecEnv(fns)


def test_wrong_number_of_actions() -> None:
    venv = ParallelEnvVecEnv([lambda: CountEnv(n=2)])
    venv.reset()
    with pytest.raises(ValueError, match="one per slot"):
        venv.step_async(np.zeros(3, dtype=np.int64))


def test_subprocess_copies_match_in_process_copies() -> None:
    fns = [lambda: CountEnv(n=3, horizon=4), lambda: CountEnv(n=3, horizon=3, early=None)]
    local = ParallelEnvVecEnv(fns)
    remote = ParallelEnvVecEnv(fns, use_subprocess=True)
    try:
        for v in (local, remote):
            v.seed(5)
        np.testing.assert_array_equal(local.reset(), remote.reset())
        assert local.reset_infos == remote.reset_infos
        rng = np.random.default_rng(0)
        for _ in range(7):  # across both copies' episode ends
            actions = rng.integers(0, 3, size=6)
            a, b = local.step(actions), remote.step(actions)
            for x, y in zip(a[:3], b[:3], strict=True):
                np.testing.assert_array_equal(x, y)
            for ia, ib in zip(a[3], b[3], strict=True):
                assert ia.keys() == ib.keys()
                for k in ia:
                    np.testing.assert_array_equal(ia[k], ib[k])
        assert remote.get_attr("seeds", indices=[0, 3]) == [
            [5, None],
            [6, None, None],
        ]  # auto-resets at t=4; 3, 6
        assert remote.env_method("ping", 1, indices=[4]) == [(2, 1)]
        remote.set_attr("horizon", 9, indices=[5])
        assert remote.get_attr("horizon") == [4, 4, 4, 9, 9, 9]
        with pytest.raises(AttributeError):
            remote.get_attr("no_such_attribute")  # the worker's exception reaches the parent
    finally:
        local.close()
        remote.close()
    assert not any(p.is_alive() for p in (c.process for c in remote._copies))
