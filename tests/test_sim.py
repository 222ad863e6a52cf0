"""The simulation core: determinism, start independence from the team size, bookkeeping."""

from __future__ import annotations

import math
from typing import Any

import numpy as np
import pytest

from mrexplore.errors import ConfigError
from mrexplore.grid import UNKNOWN
from mrexplore.robot import Action, RobotConfig
from mrexplore.sensors import LidarConfig
from mrexplore.sim import SimConfig, Simulation, canvas_for
from mrexplore.world.world import World


def office() -> World:
    """A bordered 0.1 m grid (4 x 3 m) with an inner wall and a door: two rooms."""
    walls = np.zeros((30, 40), dtype=bool)
    walls[[0, -1], :] = True
    walls[:, [0, -1]] = True
    walls[:, 20] = True
    walls[12:18, 20] = False  # a door
    walls[5:8, 5:9] = True  # a pillar
    return World(walls=walls, resolution_m=0.1, name="office")


def small_config(**kwargs: object) -> SimConfig:
    return SimConfig(
        robot=RobotConfig(radius_m=0.15),
        lidar=LidarConfig(n_beams=90, max_range_m=3.0, noise_std_m=0.01),
        **kwargs,  # type: ignore[arg-type]
    )


def rollout(n_robots: int, seed: int, steps: int, cfg: SimConfig) -> Simulation:
    sim = Simulation(office(), n_robots, cfg)
    rng = np.random.default_rng(seed)
    sim.reset(rng)
    act_rng = np.random.default_rng(seed + 1)
    for _ in range(steps):
        # mostly forward, some turns: robots travel and hit walls
        act = np.where(
            act_rng.random(n_robots) < 0.6, Action.FORWARD, act_rng.integers(1, 4, n_robots)
        )
        sim.step(act, rng)
    return sim


def test_same_seed_same_everything_over_200_steps() -> None:
    cfg = small_config(
        aligned_headings=False,
        odom_noise_trans=0.05,
        odom_noise_rot=0.05,
        odom_noise_rot_per_m=0.02,
    )
    a = rollout(2, 11, 200, cfg)
    b = rollout(2, 11, 200, cfg)
    assert np.array_equal(a.start_poses, b.start_poses)
    assert np.array_equal(a.true_poses, b.true_poses)
    assert np.array_equal(a.est_poses, b.est_poses)
    for ma, mb in zip(a.maps, b.maps, strict=True):
        assert np.array_equal(ma.logodds, mb.logodds)
        assert np.array_equal(ma.to_int8(), mb.to_int8())
    assert np.array_equal(a.observed, b.observed)
    assert a.coverage() == b.coverage()
    c = rollout(2, 12, 200, cfg)
    assert not np.array_equal(a.true_poses, c.true_poses)


def test_robot_0_start_does_not_depend_on_team_size() -> None:
    for aligned in (True, False):
        cfg = small_config(aligned_headings=aligned)
        one = Simulation(office(), 1, cfg)
        two = Simulation(office(), 2, cfg)
        one.reset(np.random.default_rng(3))
        two.reset(np.random.default_rng(3))
        assert np.array_equal(one.start_poses[0], two.start_poses[0])


def test_noise_free_odometry_matches_the_truth_in_the_own_frame() -> None:
    sim = rollout(2, 5, 60, small_config(aligned_headings=False))
    for i in range(2):
        T = sim.world_from_map(i)
        c, r, th = sim.pose_cell(i)
        p = T @ np.array([c, r, 1.0])
        true_cell = sim.world.cell_of(sim.true_poses[i : i + 1, :2])[0]
        assert p[:2] == pytest.approx(true_cell, abs=1e-6)
        dth = (th + sim.start_poses[i, 2] - sim.true_poses[i, 2] + math.pi) % (
            2 * math.pi
        ) - math.pi
        assert abs(dth) < 1e-9


def test_noisy_odometry_drifts() -> None:
    sim = rollout(
        1, 5, 120, small_config(odom_noise_trans=0.2, odom_noise_rot=0.2, odom_noise_rot_per_m=0.2)
    )
    exact = sim._own_frame(sim.true_poses)
    assert not np.allclose(exact, sim.est_poses, atol=1e-3)


def test_bookkeeping_after_steps() -> None:
    cfg = small_config()
    sim = Simulation(office(), 2, cfg)
    rng = np.random.default_rng(0)
    sim.reset(rng)
    assert sim.steps == 0 and sim.time_s == 0.0
    cov0 = sim.coverage()
    assert 0.0 < cov0 <= 1.0
    total_new = np.zeros(2, dtype=int)
    collided_any = False
    for _ in range(40):
        info = sim.step(np.array([Action.FORWARD, Action.TURN_LEFT]), rng)
        total_new += info.newly_observed
        collided_any |= bool(info.collided[0])
    assert collided_any  # forty forward steps in a 4 m world must hit a wall
    assert sim.steps == 40 and sim.time_s == pytest.approx(10.0)
    assert sim.coverage() >= cov0
    # newly observed counts add up to the observed cells (after the first scan)
    assert (total_new == sim.observed.reshape(2, -1).sum(axis=1) - _first_scan_counts(cfg)).all()
    # team coverage equals the union computed from scratch
    union = sim.observed.any(axis=0)
    assert sim.coverage() == pytest.approx((union & sim.reachable).sum() / sim.reachable.sum())
    assert sim.coverage([0]) <= sim.coverage()
    assert sim.trail_cells(0).shape == (41, 2)
    assert sim.last_scan is not None and sim.last_scan.ranges_m.shape == (2, 90)
    for m in sim.maps:
        assert (m.to_int8() != UNKNOWN).any()
        assert m.known_bbox() is not None


def _first_scan_counts(cfg: SimConfig) -> np.ndarray:
    sim = Simulation(office(), 2, cfg)
    sim.reset(np.random.default_rng(0))
    return sim.observed.reshape(2, -1).sum(axis=1)


def test_canvas_holds_any_start() -> None:
    world = office()
    (h, w), (c0, r0) = canvas_for(world, 0.1)
    diag = math.ceil(math.hypot(4.0, 3.0) / 0.1)
    assert c0 == r0 and c0 % 64 == 0 and c0 >= diag + 16
    assert h == w == 2 * c0 + 1
    # a bigger world of the same parity class gets the same start cell modulo 64
    (_, _), (c1, _) = canvas_for(
        World(walls=np.zeros((130, 170), dtype=bool), resolution_m=0.1), 0.1
    )
    assert c1 % 64 == 0 and c1 > c0


def test_starts_option_and_errors() -> None:
    world = office()
    sim = Simulation(world, 2, small_config())
    good = np.array([[1.0, 1.0, 0.5], [3.0, 2.0, -0.5]])
    sim.reset(np.random.default_rng(0), starts=good)
    assert np.array_equal(sim.start_poses, good)
    with pytest.raises(ConfigError, match="collision"):
        sim.reset(np.random.default_rng(0), starts=np.array([[2.05, 0.5, 0.0], [1.0, 1.0, 0.0]]))
    with pytest.raises(ConfigError):
        sim.reset(np.random.default_rng(0), starts=good[:1])
    with pytest.raises(ConfigError):
        sim.step(np.zeros(3, dtype=int), np.random.default_rng(0))
    with pytest.raises(RuntimeError):
        Simulation(world, 1, small_config()).step(np.zeros(1, dtype=int), np.random.default_rng(0))
    with pytest.raises(ConfigError):
        SimConfig(odom_noise_trans=-0.1)
    for bad in ({"map_l_free": 0.5}, {"map_l_occ": -1.0}, {"map_l_occ": 6.0}, {"map_l_free": True}):
        with pytest.raises(ConfigError, match="map_l_free and map_l_occ"):
            SimConfig(**bad)
    with pytest.raises(ConfigError):
        Simulation(world, 0)


def test_drift_allowance_is_zero_with_exact_odometry_and_grows_with_drift() -> None:
    import mrexplore

    for noisy, check in ((False, lambda d: d == 0.0), (True, lambda d: d > 0.0)):
        opts = {"odom_noise_trans": 0.05, "odom_noise_rot": 0.05} if noisy else {}
        env = mrexplore.parallel_env(world="small_office", n_robots=2, merger=None, **opts)
        env.reset(seed=3)
        for k in range(40):
            env.step({a: (0 if k % 5 else 1) for a in env.agents})
        assert env.sim is not None
        cells = np.array([[10.0, 10.0], [60.0, 40.0]])
        assert check(env.sim.drift_allowance(0, 1, cells))


def test_a_placement_keeps_the_drift_its_map_was_built_with() -> None:
    """``place`` makes the robot's estimate exact, but its map keeps the drift it was built
    with: the merge-error allowance must not fall (a navigation protocol puts robot_0 back at its
    start; a correct merge of the bent maps then read as a wrong one)."""
    import mrexplore

    env = mrexplore.parallel_env(
        world="small_office", n_robots=2, merger=None, odom_noise_trans=0.05, odom_noise_rot=0.05
    )
    env.reset(seed=3)
    for k in range(40):
        env.step({a: (0 if k % 5 else 1) for a in env.agents})
    sim = env.sim
    assert sim is not None
    cells = np.array([[10.0, 10.0], [60.0, 40.0]])
    before = sim.drift_allowance(0, 1, cells)
    sim.place(0, sim.start_poses[0])
    pos, hdg = sim._pose_drift()
    assert pos[0] == pytest.approx(0.0, abs=1e-9) and hdg[0] == pytest.approx(0.0, abs=1e-9)
    assert sim.drift_allowance(0, 1, cells) == pytest.approx(before)


def test_one_call_sensing_equals_the_separate_calls(monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled world sensing step (cast, then every own-map update, in one call) gives the
    maps, coverage, change notes and scans of the separate cast and per-robot updates."""
    cfg = small_config(odom_noise_trans=0.05, odom_noise_rot=0.05, aligned_headings=False)
    a = rollout(3, 21, 150, cfg)

    def separate(self: Simulation, rng: np.random.Generator) -> Any:
        scan, newly, covered = self.cast(rng)
        for i in range(self.n_robots):
            self.integrate(i, scan)
        return scan, newly, covered

    monkeypatch.setattr(Simulation, "_sense_compiled", separate)
    b = rollout(3, 21, 150, cfg)
    assert np.array_equal(a.observed, b.observed) and a.coverage() == b.coverage()
    assert a.last_scan is not None and b.last_scan is not None
    assert np.array_equal(a.last_scan.ranges_m, b.last_scan.ranges_m)
    for i, (ma, mb) in enumerate(zip(a.maps, b.maps, strict=True)):
        assert np.array_equal(ma.logodds, mb.logodds)
        assert np.array_equal(ma.to_int8(), mb.to_int8())
        assert ma.change() == mb.change() and ma.version > 0
        assert np.array_equal(a.trail_cells(i), b.trail_cells(i))


def test_a_pickled_simulation_steps_on_as_the_original() -> None:
    """Unpickling re-links the maps to one stack, so the compiled step updates what they show."""
    import copy
    import pickle

    a = rollout(2, 5, 60, small_config())
    b = pickle.loads(pickle.dumps(a))
    ra, rb = np.random.default_rng(9), np.random.default_rng(9)
    for act in ([0, 0], [1, 0], [0, 2], [0, 0]) * 10:
        a.step(np.array(act), ra)
        b.step(np.array(act), rb)
    c = copy.deepcopy(b)
    c.step(np.array([0, 0]), np.random.default_rng(3))
    b.step(np.array([0, 0]), np.random.default_rng(3))
    for mb, mc in zip(b.maps, c.maps, strict=True):
        assert mb.version > 0 and np.array_equal(mb.to_int8(), mc.to_int8())
        assert mb.change() == mc.change()
    a.step(np.array([0, 0]), np.random.default_rng(3))
    for ma, mb in zip(a.maps, b.maps, strict=True):
        assert np.array_equal(ma.logodds, mb.logodds) and ma.change() == mb.change()
