"""The PettingZoo env: official API checks, determinism, spaces, no ground truth, bad input."""

from __future__ import annotations

import sys

import numpy as np
import pytest
from pettingzoo.test import api_test, parallel_api_test, render_test
from pettingzoo.test.max_cycles_test import max_cycles_test
from pettingzoo.test.state_test import state_test

import mrexplore
from mrexplore.environment.infos import INFO_KEYS
from mrexplore.errors import ConfigError, WorldError
from mrexplore.merge import in_loop_semantic_options

SMALL = {"world": "small_office", "max_time_s": 60.0}


def test_parallel_api() -> None:
    parallel_api_test(mrexplore.parallel_env(**SMALL), num_cycles=300)


def test_aec_api() -> None:
    api_test(mrexplore.env(**SMALL), num_cycles=100)


def test_render() -> None:
    render_test(lambda render_mode=None: mrexplore.env(render_mode=render_mode, **SMALL))


def test_max_cycles() -> None:
    max_cycles_test(sys.modules["mrexplore"])


def test_state() -> None:
    state_test(mrexplore.env(**SMALL), mrexplore.parallel_env(**SMALL))


def test_spaces_are_cached_and_documented_shape() -> None:
    penv = mrexplore.parallel_env(**SMALL)
    for a in penv.possible_agents:
        assert penv.observation_space(a) is penv.observation_space(a)
        assert penv.action_space(a) is penv.action_space(a)
        assert penv.observation_space(a).shape == (8, 64, 64)
        assert penv.observation_space(a).dtype == np.uint8
    assert penv.metadata["is_parallelizable"] is True
    assert penv.state_space.shape == (16, 64, 64)


def _rollout(seed: int, steps: int, **options: object) -> list[tuple]:
    penv = mrexplore.parallel_env(**{**SMALL, "max_time_s": 10_000.0, **options})
    obs, _ = penv.reset(seed=seed)
    rng = np.random.default_rng(123)
    trace = []
    for _ in range(steps):
        if not penv.agents:
            obs, _ = penv.reset()
        actions = {a: int(rng.integers(4)) for a in penv.agents}
        obs, rew, term, trunc, info = penv.step(actions)
        trace.append(
            (
                {a: o.tobytes() for a, o in obs.items()},
                rew,
                term,
                trunc,
                {a: (i["coverage"], i["merged"], i["collisions"]) for a, i in info.items()},
                penv.sim.true_poses.tobytes(),
            )
        )
    return trace


@pytest.mark.expensive
def test_determinism_over_1000_steps() -> None:
    # PettingZoo 1.27's parallel_seed_test effectively compares one step: this compares 1,000.
    a = _rollout(7, 1000, range_noise_m=0.02, odom_noise_trans=0.02, odom_noise_rot=0.02)
    b = _rollout(7, 1000, range_noise_m=0.02, odom_noise_trans=0.02, odom_noise_rot=0.02)
    assert a == b
    c = _rollout(8, 50)
    assert c != a[:50]


def test_episode_observations_in_space_and_infos_complete() -> None:
    penv = mrexplore.parallel_env(**{**SMALL, "max_cycles": 120})
    obs, infos = penv.reset(seed=3)
    steps = 0
    while penv.agents:
        for a, o in obs.items():
            assert penv.observation_space(a).contains(o)
        assert penv.state_space.contains(penv.state())
        obs, rew, _term, _trunc, infos = penv.step(
            {a: penv.action_space(a).sample() for a in penv.agents}
        )
        steps += 1
        for a, i in infos.items():
            assert tuple(i) == INFO_KEYS  # the same flat keys on every step
            assert 0.0 <= i["coverage"] <= 1.0
            assert rew[a] == pytest.approx(-0.25)  # time mode: -dt per step
    assert steps == 120
    assert all(i.get("TimeLimit.truncated") for i in infos.values())


def test_observation_carries_no_absolute_position() -> None:
    """Shifting the whole world inside a bigger grid moves every true pose, yet each robot's
    observation (own frame) must stay byte-identical: nothing absolute leaks into it."""
    from mrexplore.world import World, load_world

    base = load_world("small_office")
    pad = 37
    # Rows are padded at the bottom (row 0 = lowest y) and columns at the left: +pad cells in x, y.
    walls = np.pad(base.walls, ((pad, 11), (pad, 5)), constant_values=True)
    shifted = World(
        walls=walls, resolution_m=base.resolution_m, origin_m=base.origin_m, name="shifted"
    )
    probe = mrexplore.parallel_env(world=base, n_robots=2, merger=None)
    probe.reset(seed=5)
    starts = probe.sim.start_poses.copy()

    def run(world: World, starts: np.ndarray) -> list[bytes]:
        penv = mrexplore.parallel_env(world=world, n_robots=2, merger=None, max_time_s=1000.0)
        obs, _ = penv.reset(seed=5, options={"starts": starts})
        out = [o.tobytes() for o in obs.values()]
        rng = np.random.default_rng(0)
        for _ in range(40):
            obs, *_ = penv.step({a: int(rng.integers(4)) for a in penv.agents})
            out.extend(o.tobytes() for o in obs.values())
        return out

    shift = np.array([pad * base.resolution_m, pad * base.resolution_m, 0.0])
    assert run(base, starts) == run(shifted, starts + shift)


def test_single_robot_baseline_shares_robot0_start() -> None:
    one = mrexplore.parallel_env(**SMALL, n_robots=1)
    two = mrexplore.parallel_env(**SMALL, n_robots=2)
    one.reset(seed=11)
    two.reset(seed=11)
    np.testing.assert_array_equal(one.sim.start_poses[0], two.sim.start_poses[0])


def test_navigation_goal_same_for_single_and_team() -> None:
    one = mrexplore.parallel_env(**SMALL, n_robots=1, task="navigate")
    two = mrexplore.parallel_env(**SMALL, n_robots=2, task="navigate")
    one.reset(seed=4)
    two.reset(seed=4)
    assert one.robot_view("robot_0").goal_cell == two.robot_view("robot_0").goal_cell
    assert two.robot_view("robot_1").goal_cell is None


@pytest.mark.parametrize(
    ("options", "error"),
    [
        ({"n_robotz": 2}, ConfigError),  # a typo in an option name
        ({"n_robots": 0}, ConfigError),  # no robot
        ({"max_range_m": -1.0}, ConfigError),  # negative range
        ({"reward_mode": "speed"}, ConfigError),  # unknown reward mode
        ({"coverage_mode": "seen"}, ConfigError),  # unknown coverage mode
        ({"world": "no_such_world"}, WorldError),  # unknown world
    ],
)
def test_bad_options(options: dict, error: type[Exception]) -> None:
    with pytest.raises(error):
        mrexplore.parallel_env(**{**SMALL, **options})


def test_bad_actions_and_agents() -> None:
    penv = mrexplore.parallel_env(**SMALL)
    with pytest.raises(RuntimeError, match="reset"):
        penv.step({"robot_0": 0})
    penv.reset(seed=0)
    with pytest.raises(ValueError, match="outside the action space"):
        penv.step({"robot_0": 7, "robot_1": 0})
    with pytest.raises(KeyError, match="unknown agent"):
        penv.step({"robot_9": 0})
    with pytest.raises(KeyError, match="unknown agent"):
        penv.observation_space("robot_9")


def test_step_after_end_is_an_error() -> None:
    penv = mrexplore.parallel_env(**{**SMALL, "max_cycles": 2})
    penv.reset(seed=0)
    penv.step({a: 3 for a in penv.agents})
    penv.step({a: 3 for a in penv.agents})
    assert penv.agents == []
    with pytest.raises(RuntimeError, match="reset"):
        penv.step({"robot_0": 0})


def test_render_frame_shape() -> None:
    penv = mrexplore.parallel_env(render_mode="rgb_array", **SMALL)
    penv.reset(seed=0)
    frame = penv.render()
    assert frame.ndim == 3 and frame.shape[2] == 3 and frame.dtype == np.uint8


def test_out_of_range_teammates_are_where_they_were_last_heard() -> None:
    """comm_range_m: once out of range, a robot keeps the fused map it had and the teammate's
    last heard position, not its live one."""
    penv = mrexplore.parallel_env(world="small_office", merger="semantic", comm_range_m=100.0)
    penv.reset(seed=0)
    # Force a merge with the true transform (evaluation code may; robots may not) to test the
    # radio rule alone.
    T = penv.sim.true_transform(0, 1)
    penv.fusion.tracker._edges[(0, 1)] = T
    penv.fusion.tracker._paths = None
    penv.step({a: 3 for a in penv.agents})
    heard = penv.robot_view("robot_0").teammates["robot_1"]
    assert penv.robot_view("robot_0").in_range == frozenset({"robot_1"})
    penv.radio.comm_range_m = 1e-3
    for _ in range(8):
        penv.step({"robot_0": 3, "robot_1": 0})
    view = penv.robot_view("robot_0")
    assert view.in_range == frozenset()
    assert view.teammates["robot_1"] == heard  # robot_1 moved, robot_0 cannot know
    c, r, _ = penv.sim.pose_cell(1)
    live = mrexplore.grid.apply_transform(T, np.array([[c, r]]))[0]
    assert np.hypot(*(live - np.array(heard))) > 1.0


def test_navigation_warmup_hides_the_goal_then_restarts_robot0() -> None:
    penv = mrexplore.parallel_env(world="small_office", task="navigate", nav_warmup_s=1.0)
    _, infos = penv.reset(seed=4)
    start = penv.sim.start_poses[0].copy()
    assert penv.robot_view("robot_0").goal_cell is None and not infos["robot_0"]["goal_given"]
    for _ in range(3):  # 0.75 s: still exploring
        _, _, _, _, infos = penv.step({"robot_0": 0, "robot_1": 0})
        assert infos["robot_0"]["task_time_s"] == 0.0 and not infos["robot_0"]["goal_given"]
    _, _, _, _, infos = penv.step({"robot_0": 0, "robot_1": 0})  # t = 1.0 s: the goal is given
    assert infos["robot_0"]["goal_given"] and infos["robot_0"]["task_time_s"] == 0.0
    assert penv.robot_view("robot_0").goal_cell is not None
    np.testing.assert_allclose(penv.sim.true_poses[0], start)  # back at its start
    _, _, _, _, infos = penv.step({"robot_0": 3, "robot_1": 3})
    assert infos["robot_0"]["task_time_s"] == pytest.approx(0.25)


@pytest.mark.parametrize(
    ("options", "words"),
    [
        ({"aligned_headings": "no"}, "aligned_headings must be True or False"),
        ({"obs_heading_up": "yes"}, "obs_heading_up must be True or False"),
        ({"nav_return_to_start": 0}, "nav_return_to_start must be True or False"),
        ({"odom_noise_trans": 100}, r"odom_noise_trans must be in \[0, 0.5\].*got 100"),
        ({"odom_noise_rot": 5.0}, r"odom_noise_rot must be in \[0, 1\].*got 5.0"),
        ({"odom_noise_rot_per_m": 2.0}, r"odom_noise_rot_per_m must be in \[0, 1\].*got 2.0"),
        ({"range_noise_m": 10.0}, "range_noise_m=10.0 must be below max_range_m"),
        ({"map_l_free": -0.5}, r"map_l_free must be in \[-5, -1.1\].*got -0.5"),
        ({"map_l_occ": 0.5}, r"map_l_occ must be in \[0.62, 5\].*got 0.5"),
        ({"semantic_options": {"min_margin": 0.1}}, "semantic_options must be a mrexplore"),
        ({"tracker_options": 0.9}, "tracker_options must be a mrexplore.merge.TrackerOptions"),
        (
            {"merger": None, "semantic_options": in_loop_semantic_options()},
            "semantic_options are the semantic merger's; merger is None",
        ),
    ],
)
def test_bad_option_values_name_the_option(options: dict, words: str) -> None:
    with pytest.raises(ConfigError, match=words):
        mrexplore.parallel_env(**{**SMALL, **options})


def test_numpy_scalars_are_accepted_as_numbers_and_bools() -> None:
    penv = mrexplore.parallel_env(
        **{
            **SMALL,
            "n_robots": np.int64(2),
            "obs_size_px": np.int32(40),
            "max_range_m": np.float32(3.0),
            "aligned_headings": np.bool_(False),
            "map_l_occ": np.float32(2.5),
        }
    )
    assert type(penv.config.n_robots) is int and penv.config.aligned_headings is False
    penv.reset(seed=np.int64(3))


@pytest.mark.parametrize("seed", [-1, 1.5, "3", True])
def test_bad_reset_seed_is_a_config_error(seed: object) -> None:
    penv = mrexplore.parallel_env(**SMALL)
    with pytest.raises(ConfigError, match="seed must be an integer >= 0"):
        penv.reset(seed=seed)  # type: ignore[arg-type]


@pytest.mark.parametrize("merger", ["semantic", "paper", "orb"])
def test_plain_pickle_with_a_named_merger(merger: str) -> None:
    import pickle

    penv = mrexplore.parallel_env(**{**SMALL, "merger": merger})
    penv.reset(seed=0)
    clone = pickle.loads(pickle.dumps(penv))
    assert clone.agents == penv.agents


def test_reset_makes_no_merge_attempt() -> None:
    # Single-scan maps cannot be merged; an attempt per pair at every reset only costs time.
    penv = mrexplore.parallel_env(world="symmetric_office")
    penv.reset(seed=0)
    assert penv.fusion.tracker.last_result(0, 1) is None


def test_teammate_goal_is_near_robot_1_start_and_the_same_for_every_team_size() -> None:
    goals = []
    for n in (1, 2):
        penv = mrexplore.parallel_env(
            world="symmetric_office", task="navigate", nav_goal="teammate", n_robots=n
        )
        penv.reset(seed=3)
        goals.append(penv.task.goal.world_xy.copy())  # type: ignore[union-attr]
        if n == 2:
            assert penv.sim is not None
            d_mate = np.hypot(*(goals[-1] - penv.sim.start_poses[1, :2]))
            d_self = np.hypot(*(goals[-1] - penv.sim.start_poses[0, :2]))
            assert d_mate <= 3.0 + 1e-9 and d_self >= 10.0 - 1e-9
    np.testing.assert_array_equal(goals[0], goals[1])
    with pytest.raises(ConfigError, match="nav_goal"):
        mrexplore.parallel_env(task="navigate", nav_goal="near")


def test_making_an_env_sets_opencv_to_one_thread_once(monkeypatch: pytest.MonkeyPatch) -> None:
    """The first env of a process sets ``cv2.setNumThreads(1)``; a user's later setting
    stands through the envs made after it."""
    import cv2

    from mrexplore.environment import parallel_env as module

    monkeypatch.setattr(module, "_OPENCV_SET", False)
    before = cv2.getNumThreads()
    try:
        cv2.setNumThreads(2)
        mrexplore.parallel_env(world="small_office").close()
        assert cv2.getNumThreads() == 1
        cv2.setNumThreads(2)
        mrexplore.parallel_env(world="small_office").close()
        assert cv2.getNumThreads() == 2
    finally:
        cv2.setNumThreads(before)
