"""The batched env (``mrexplore.vector_env``): the same run as separate copies, bit for bit;
the Gymnasium ``VectorEnv`` contract for one robot; bad input."""

from __future__ import annotations

from typing import Any

import gymnasium
import numpy as np
import pytest
from gymnasium.vector import AutoresetMode, SyncVectorEnv

import mrexplore
from mrexplore.environment.batched import BatchedExploreEnv, ExploreVectorEnv
from mrexplore.errors import ConfigError
from tests.helpers import assert_same

WORLD = "small_office"


# 1: the calling thread steps every world; 3: the caller and two pool threads share the 3 worlds
@pytest.mark.parametrize("num_threads", [1, 3])
def test_batched_team_equals_separate_copies_bit_for_bit_over_auto_resets(
    num_threads: int,
) -> None:
    """N worlds, merging on (delayed attempts on the one shared worker), random actions over
    several episodes: every array equals what N separate envs seeded ``seed + k`` give, at any
    number of stepping threads."""
    # (random actions seldom take a robot out of its first place, where the merger's place
    # test waits: off here, so merges are accepted and their arrays compared)
    n, seed = 3, 11
    opts = {
        "world": WORLD,
        "n_robots": 2,
        "max_cycles": 70,
        "merge_every": 5,
        "merge_options": {"place_test": False},
    }
    venv = mrexplore.vector_env(num_envs=n, num_threads=num_threads, **opts)
    assert isinstance(venv, BatchedExploreEnv) and venv.num_threads == num_threads
    refs = [mrexplore.parallel_env(**opts) for _ in range(n)]
    agents = refs[0].possible_agents
    rng = np.random.default_rng(0)
    obs, infos = venv.reset(seed=seed)
    ref_out = [r.reset(seed=seed + k) for k, r in enumerate(refs)]
    for k, (o, inf) in enumerate(ref_out):
        for j, a in enumerate(agents):
            np.testing.assert_array_equal(obs[k, j], o[a])
            for key, v in inf[a].items():
                assert_same(infos[key][k, j].item(), v, f"reset {key}")
    resets = 0
    scored = False
    for t in range(220):
        act = rng.integers(0, 4, size=(n, 2))
        obs, rew, term, trunc, infos = venv.step(act)
        assert obs.shape == (n, 2, 8, 64, 64) and obs.dtype == np.uint8
        assert rew.dtype == np.float32 and term.dtype == bool and trunc.dtype == bool
        for k, r in enumerate(refs):
            o, rw, te, tr, inf = r.step({a: int(act[k, j]) for j, a in enumerate(agents)})
            ended = not r.agents
            now_o, now_inf = o, inf
            if ended:
                resets += 1
                assert infos["_final_obs"][k] and infos["_final_info"][k]
                final_obs, final_info = infos["final_obs"][k], infos["final_info"]
                now_o, now_inf = r.reset()
            for j, a in enumerate(agents):
                assert rew[k, j] == np.float32(rw[a])
                assert term[k, j] == te[a] and trunc[k, j] == tr[a]
                where = f"step {t} copy {k} {a}"
                if ended:
                    np.testing.assert_array_equal(final_obs[j], o[a], err_msg=where)
                    for key, v in inf[a].items():
                        assert_same(final_info[key][k, j].item(), v, f"{where} final {key}")
                np.testing.assert_array_equal(obs[k, j], now_o[a], err_msg=where)
                for key, v in now_inf[a].items():
                    assert_same(infos[key][k, j].item(), v, f"{where} {key}")
                scored |= inf[a]["score"] != -1.0
            if not ended and "_final_obs" in infos:
                assert not infos["_final_obs"][k] and infos["final_obs"][k] is None
    assert resets >= n * 2  # auto-resets were exercised
    assert scored  # merge attempts ran (on the shared worker) and reached the infos
    venv.close()


def test_one_shared_merge_worker_for_all_copies() -> None:
    venv = BatchedExploreEnv(2, world=WORLD, max_cycles=5)
    pools = {id(e.fusion.tracker._pool) for e in venv.envs}
    assert pools == {id(venv._executor)}
    venv.close()
    assert venv.closed
    venv.close()  # idempotent


def _sync(n: int, **opts: Any) -> SyncVectorEnv:
    return SyncVectorEnv(
        [lambda: gymnasium.make("mrexplore/Explore-v0", **opts) for _ in range(n)],
        autoreset_mode=AutoresetMode.SAME_STEP,
    )


def test_single_robot_is_a_gymnasium_vector_env_equal_to_sync_vector_env() -> None:
    """One robot: a real ``VectorEnv`` whose spaces, arrays, infos and same-step auto-reset are
    exactly ``SyncVectorEnv(SAME_STEP)`` over ``mrexplore/Explore-v0`` copies."""
    n, opts = 3, {"world": WORLD, "max_cycles": 6}
    venv = mrexplore.vector_env(num_envs=n, n_robots=1, **opts)
    ref = _sync(n, **opts)
    assert isinstance(venv, gymnasium.vector.VectorEnv) and isinstance(venv, ExploreVectorEnv)
    assert venv.metadata["autoreset_mode"] == AutoresetMode.SAME_STEP
    assert venv.num_envs == n
    assert venv.single_observation_space == ref.single_observation_space
    assert venv.single_action_space == ref.single_action_space
    assert venv.observation_space == ref.observation_space
    assert venv.action_space == ref.action_space
    obs, infos = venv.reset(seed=5)
    robs, rinfos = ref.reset(seed=5)
    assert obs.shape == (n, 8, 64, 64)
    assert venv.observation_space.contains(obs)
    assert_same(obs, robs, "reset obs")
    assert_same(infos, rinfos, "reset infos")
    venv.action_space.seed(0)
    ended = 0
    for t in range(14):
        act = venv.action_space.sample()
        out = venv.step(act)
        rout = ref.step(act)
        for name, x, y in zip(("obs", "rew", "term", "trunc", "infos"), out, rout, strict=True):
            assert_same(x, y, f"step {t} {name}")
        ended += int(np.count_nonzero(out[3]))
        assert venv.observation_space.contains(out[0])
    assert ended >= n  # the 6-step episodes ended and were reset in the same step
    venv.close()
    ref.close()


def test_single_robot_seeding_reproduces() -> None:
    def run(seed: int) -> list[np.ndarray]:
        venv = mrexplore.vector_env(num_envs=2, n_robots=1, world=WORLD, max_cycles=4)
        obs, _ = venv.reset(seed=seed)
        out = [obs]
        for _ in range(6):
            out.append(venv.step(np.array([0, 1]))[0])
        venv.close()
        return out

    a, b, c = run(7), run(7), run(8)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x, y)
    assert any(not np.array_equal(x, y) for x, y in zip(a, c, strict=True))


def test_obs_layout_and_dtype_options_are_respected() -> None:
    venv = mrexplore.vector_env(
        num_envs=2, world=WORLD, obs_layout="hwc", obs_dtype="float32", max_cycles=3
    )
    obs, _ = venv.reset(seed=0)
    assert obs.shape == (2, 2, 64, 64, 8) and obs.dtype == np.float32
    assert venv.observation_space.shape == (2, 2, 64, 64, 8)
    venv.close()


@pytest.mark.parametrize("bad", [0, -1, 2.0, "4", True, None])
def test_bad_num_envs_is_a_config_error_naming_it(bad: Any) -> None:
    with pytest.raises(ConfigError, match="num_envs"):
        mrexplore.vector_env(num_envs=bad, world=WORLD)


@pytest.mark.parametrize("bad", [0, -1, 2.0, "2", True])
def test_bad_num_threads_is_a_config_error_naming_it(bad: Any) -> None:
    with pytest.raises(ConfigError, match="num_threads"):
        mrexplore.vector_env(num_envs=2, world=WORLD, num_threads=bad)


def test_threads_default_to_the_cores_and_never_exceed_the_worlds() -> None:
    from mrexplore.environment.batched import usable_cores

    venv = mrexplore.vector_env(num_envs=2, world=WORLD, max_cycles=3)
    assert venv.num_threads == min(2, usable_cores())
    venv.close()
    venv = mrexplore.vector_env(num_envs=2, world=WORLD, max_cycles=3, num_threads=8)
    assert venv.num_threads == 2
    venv.close()


def test_an_error_in_one_world_is_raised_by_the_step() -> None:
    """A world that fails while another thread steps the rest: the step raises its error."""
    venv = BatchedExploreEnv(3, world=WORLD, max_cycles=3, num_threads=3)
    venv.reset(seed=0)

    def broken(actions: Any) -> Any:
        raise RuntimeError("world 1 broke")

    venv.envs[1].step = broken  # type: ignore[method-assign]
    with pytest.raises(RuntimeError, match="world 1 broke"):
        venv.step(np.zeros((3, 2), dtype=np.int64))
    venv.close()


def test_bad_options_and_actions() -> None:
    with pytest.raises(ConfigError, match="action_mode"):
        mrexplore.vector_env(num_envs=2, world=WORLD, action_mode="goal")
    with pytest.raises(ConfigError, match="n_robots"):
        ExploreVectorEnv(2, world=WORLD, n_robots=2)
    with pytest.raises(ConfigError, match="no_such_option"):
        mrexplore.vector_env(num_envs=2, world=WORLD, no_such_option=1)
    venv = mrexplore.vector_env(num_envs=2, world=WORLD, max_cycles=3)
    with pytest.raises(RuntimeError, match="reset"):
        venv.step(np.zeros((2, 2), dtype=np.int64))
    venv.reset(seed=0)
    with pytest.raises(ValueError, match="shape"):
        venv.step(np.zeros(2, dtype=np.int64))
    with pytest.raises(ValueError, match="action"):
        venv.step(np.full((2, 2), 7))
    with pytest.raises(ValueError, match="integers"):
        venv.step(np.zeros((2, 2)))
    assert [e.sim.steps for e in venv.envs] == [0, 0]  # a bad action steps no world
    with pytest.raises(ConfigError, match="reset_mask"):
        venv.reset(options={"reset_mask": np.array([True, False])})
    venv.close()


def test_gymnasium_vector_wrappers_read_the_autoreset_mode() -> None:
    """RecordEpisodeStatistics takes the same-step mode from the metadata and counts episodes."""
    from gymnasium.wrappers.vector import RecordEpisodeStatistics

    venv = RecordEpisodeStatistics(
        mrexplore.vector_env(num_envs=2, n_robots=1, world=WORLD, max_cycles=3)
    )
    venv.reset(seed=0)
    for _ in range(3):
        *_, infos = venv.step(np.array([0, 3]))
    assert infos["_episode"].all()
    np.testing.assert_array_equal(infos["episode"]["l"], [3, 3])
    np.testing.assert_allclose(infos["episode"]["r"], [-0.75, -0.75])
    venv.close()


def test_team_decisions_on_the_stepping_threads_give_the_same_run_at_any_thread_count() -> None:
    """A coordinated-frontier team per world, its decisions made by ``map_worlds`` on the
    stepping threads: 1 and 3 threads give the same observations and rewards, bit for bit."""
    from mrexplore.policies import make_team_policy

    def rollout(num_threads: int) -> list[np.ndarray]:
        venv = BatchedExploreEnv(3, world=WORLD, max_cycles=30, num_threads=num_threads)
        agents = venv.possible_agents
        teams = [make_team_policy("coordinated-frontier", agents) for _ in range(3)]
        for k, t in enumerate(teams):
            t.reset(np.random.default_rng(k))
        obs, _ = venv.reset(seed=4)
        out = [obs]
        for _ in range(25):
            acts = venv.map_worlds(
                lambda k, env: [
                    teams[k].act({a: env.robot_view(a) for a in agents})[a] for a in agents
                ]
            )
            obs, rew, *_ = venv.step(np.array(acts))
            out += [obs, rew]
        venv.close()
        return out

    for a, b in zip(rollout(1), rollout(3), strict=True):
        np.testing.assert_array_equal(a, b)
