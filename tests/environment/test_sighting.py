"""Sightings: who sees whom, and the guess of the transform between their maps."""

from __future__ import annotations

import numpy as np
import pytest

import mrexplore
from mrexplore.environment.sighting import SightingSensor, sightings
from mrexplore.errors import ConfigError

EXACT = SightingSensor(
    range_m=100.0, noise_range_m=0.0, noise_bearing_rad=0.0, noise_heading_rad=0.0
)


def _sight(env: object, sensor: SightingSensor, rng: np.random.Generator) -> dict:
    sim = env.episode.sim  # type: ignore[attr-defined]
    return sightings(
        sensor,
        sim.world.walls,
        sim.true_poses,
        sim.world.cell_of(sim.true_poses[:, :2]),
        [sim.pose_cell(k) for k in range(sim.n_robots)],
        sim.resolution_m,
        [(0, 1)],
        rng,
    )


def test_an_exact_sighting_gives_the_true_transform_between_the_maps() -> None:
    """Without measurement or odometry noise the guess is the true transform (rounding
    only), at every step the robots see each other, whatever their start headings."""
    env = mrexplore.parallel_env(world="symmetric_office")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    seen = 0
    for _ in range(150):
        env.step({a: int(rng.integers(3)) for a in env.agents})
        got = _sight(env, EXACT, rng).get((0, 1))
        if got is not None:
            seen += 1
            sim = env.episode.sim
            np.testing.assert_allclose(got.T_ij, sim.true_transform(0, 1), atol=1e-9)
            assert got.at_j == pytest.approx(tuple(sim.pose_cell(1)[:2]))
    assert seen > 10


@pytest.mark.parametrize(
    ("wall", "range_m", "seen"),
    [
        (False, 10.0, True),
        (True, 10.0, False),  # a wall between them
        (False, 0.5, False),  # too far: 1 m apart
    ],
)
def test_robots_see_each_other_within_range_with_no_wall_between(
    wall: bool, range_m: float, seen: bool
) -> None:
    walls = np.zeros((40, 40), dtype=bool)
    if wall:
        walls[5:35, 20] = True
    poses = np.array([[0.75, 1.0, 0.0], [1.75, 1.0, np.pi]])  # metres at 0.05 m/cell
    cells = poses[:, :2] / 0.05
    est = [(10.0, 10.0, 0.0), (10.0, 10.0, 0.0)]
    sensor = SightingSensor(range_m=range_m)
    got = sightings(sensor, walls, poses, cells, est, 0.05, [(0, 1)], np.random.default_rng(0))
    assert ((0, 1) in got) is seen


def test_a_noisy_sighting_is_near_the_truth_and_the_same_for_the_same_seed() -> None:
    env = mrexplore.parallel_env(world="symmetric_office")
    env.reset(seed=0)
    rng = np.random.default_rng(0)
    sensor = SightingSensor(range_m=100.0)
    for _ in range(40):
        env.step({a: int(rng.integers(3)) for a in env.agents})
        state = np.random.default_rng(7)
        first = _sight(env, sensor, state).get((0, 1))
        again = _sight(env, sensor, np.random.default_rng(7)).get((0, 1))
        if first is not None:
            break
    assert first is not None and again is not None
    np.testing.assert_array_equal(first.T_ij, again.T_ij)
    first = first.T_ij
    T = env.episode.sim.true_transform(0, 1)
    turn = np.degrees(abs(np.arctan2(first[1, 0], first[0, 0]) - np.arctan2(T[1, 0], T[0, 0])))
    assert 0.0 < turn < 15.0  # 0.05 rad std: within 3 sigma
    centre = np.array([300.0, 300.0, 1.0])
    assert np.hypot(*(first @ centre - T @ centre)[:2]) < 60.0


def test_sighting_options_are_checked_at_the_door() -> None:
    with pytest.raises(ConfigError, match="sighting_range_m"):
        mrexplore.parallel_env(sighting_range_m=-1.0)
    with pytest.raises(ConfigError, match="sighting_noise_heading_rad"):
        mrexplore.parallel_env(sighting_range_m=4.0, sighting_noise_heading_rad=-0.1)


def test_an_env_with_sightings_runs_the_same_for_the_same_seed() -> None:
    """Sightings draw their noise from a child of the run's generator: two runs of one seed
    agree. In this one (random actions) the robots see each other and merge at step 27, near
    the truth; without sightings they have not merged by step 60 (they do at 117)."""
    runs = []
    for sighting in (4.0, 4.0, None):
        env = mrexplore.parallel_env(world="symmetric_office", sighting_range_m=sighting)
        env.reset(seed=14)
        rng = np.random.default_rng(14)
        trace = []
        for _ in range(60):
            _, _, _, _, infos = env.step({a: int(rng.integers(3)) for a in env.agents})
            trace.append((infos["robot_0"]["merged"], infos["robot_0"]["coverage"]))
        runs.append((trace, env.fusion.tracker.transform(0, 1), infos["robot_0"]))
    assert runs[0][0] == runs[1][0]
    T0, T1 = runs[0][1], runs[1][1]
    assert T0 is not None and T1 is not None
    np.testing.assert_array_equal(T0, T1)
    assert 0.0 <= runs[0][2]["merge_error_cells"] < 5.0
    assert runs[2][1] is None
    # the actions do not depend on the maps here, so what the sensors observed is the same
    # with sightings on and off: the sightings' draws leave the run's own noise alone
    assert [c for _, c in runs[0][0]] == [c for _, c in runs[2][0]]


def test_rendezvous_only_needs_sightings_at_the_door() -> None:
    """A tracker that merges only robots that met would never merge without sightings: the
    env and the wrapper refuse it; with sightings the env takes it (typed or untyped)."""
    from mrexplore.merge import in_loop_tracker_options
    from mrexplore.wrappers import MapMergeWrapper

    with pytest.raises(ConfigError, match=r"rendezvous_only.*sighting_range_m"):
        mrexplore.parallel_env(merge_options={"rendezvous_only": True})
    with pytest.raises(ConfigError, match="rendezvous_only"):
        mrexplore.parallel_env(tracker_options=in_loop_tracker_options(rendezvous_only=True))
    env = mrexplore.parallel_env(sighting_range_m=4.0, merge_options={"rendezvous_only": True})
    assert env.fusion.tracker.options.rendezvous_only
    with pytest.raises(ConfigError, match="rendezvous_only"):
        MapMergeWrapper(mrexplore.parallel_env(merger=None), rendezvous_only=True)


def test_rendezvous_only_follows_the_sightings_unless_given() -> None:
    """Left at None, ``rendezvous_only`` is on where sightings reach the tracker and off where
    none do (and for a bare tracker); given, it is kept."""
    from mrexplore.merge import MapMergeTracker, in_loop_tracker_options

    def resolved(**kw: object) -> object:
        return mrexplore.parallel_env(**kw).fusion.tracker.options.rendezvous_only

    assert resolved(sighting_range_m=4.0) is True
    assert resolved() is False
    assert resolved(sighting_range_m=4.0, merge_options={"rendezvous_only": False}) is False
    typed = in_loop_tracker_options()
    assert typed.rendezvous_only is None
    assert resolved(sighting_range_m=4.0, tracker_options=typed) is True
    bare = MapMergeTracker(2, merger="semantic")
    assert bare.options.rendezvous_only is None  # off: it tries pairs nobody saw meet


@pytest.mark.parametrize("rendezvous", [False, True, None])
def test_rendezvous_only_tries_no_pair_before_the_robots_meet(rendezvous: bool | None) -> None:
    """Two robots that never see each other in this run (random actions, 120 steps): the maps
    alone try the pair; with ``rendezvous_only`` (given, or by default with sightings) no
    attempt is made and nothing merges."""
    env = mrexplore.parallel_env(
        world="small_office",
        sighting_range_m=4.0,
        merge_options={} if rendezvous is None else {"rendezvous_only": rendezvous},
    )
    env.reset(seed=1)
    rng = np.random.default_rng(1)
    tracker = env.fusion.tracker
    tried: list[int] = []
    tracker.attempt_observer = lambda rec: tried.append(rec.step)
    for _ in range(120):
        env.step({a: int(rng.integers(3)) for a in env.agents})
    assert not tracker._sighted  # they never met
    assert bool(tried) is (rendezvous is False)
    if rendezvous is not False:
        assert tracker.transform(0, 1) is None
