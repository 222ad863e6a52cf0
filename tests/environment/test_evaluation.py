"""The truth monitor's bookkeeping (evaluation only)."""

from __future__ import annotations

from typing import Any

import numpy as np
import pytest

from mrexplore.environment.evaluation import ERROR_REFRESH_STEPS, TruthMonitor


@pytest.mark.parametrize("n", [2, 3, 4, 8])
def test_merge_error_refreshes_spread_over_the_period(n: int) -> None:
    """Each ordered pair refreshes its merge error on its own phase, spread evenly, so the
    pairs' refreshes do not pile up in one step."""
    monitor = TruthMonitor.__new__(TruthMonitor)  # the phase needs only the agents
    monitor.agents = [f"robot_{k}" for k in range(n)]
    pairs = [(i, j) for i in range(n) for j in range(n) if i != j]
    phases = [monitor._refresh_phase(i, j) for i, j in pairs]
    assert all(0 <= p < ERROR_REFRESH_STEPS for p in phases)
    per_step = [phases.count(p) for p in range(ERROR_REFRESH_STEPS)]
    assert max(per_step) == -(-len(pairs) // ERROR_REFRESH_STEPS)  # as even as it can be
    if n == 2:
        assert phases == [0, ERROR_REFRESH_STEPS // 2]


def test_compiled_merge_errors_equal_the_numpy_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled sampling of a pair's merge error gives the numpy path's figures bit for
    bit: on the maps of a noisy rollout, for the true transform and for wrong ones."""
    import numpy as np

    import mrexplore
    from mrexplore import kernels
    from mrexplore.grid import chain, make_transform

    if not kernels.HAVE_NUMBA:
        pytest.skip("numba not installed")
    env = mrexplore.parallel_env(
        world="small_office", n_robots=3, odom_noise_trans=0.02, odom_noise_rot=0.01
    )
    env.reset(seed=5)
    rng = np.random.default_rng(0)
    checked = 0
    for step in range(120):
        env.step({a: int(rng.integers(4)) for a in env.agents})
        if step % 20 != 19:
            continue
        monitor = env.episode.truth
        sim = env.episode.sim
        for i in range(3):
            for j in range(3):
                if i == j:
                    continue
                T_true = sim.true_transform(i, j)
                wrong = chain(make_transform(0.3, 7.5, -3.25), T_true)
                for T in (T_true, wrong):
                    figures = []
                    for use in (True, False):
                        monkeypatch.setattr(kernels, "USE_NUMBA", use)
                        monitor._errors.clear()
                        figures.append(monitor._pair_error(i, j, T))
                    assert figures[0] == figures[1]
                    assert figures[0] is not None
                    checked += 1
    assert checked == 6 * 6 * 2


# ---------------------------------------------------------------- held coverage, wrong merges
# Two identical rooms side by side above a hall, each with its door at the same place: a map
# of the right room moved 50 columns to the left lies on the left room's true free space.
TWIN_OFFSET_COLS = 50


def _twin_rooms() -> Any:
    from mrexplore.world.world import World

    walls = np.ones((50, 100), dtype=bool)
    walls[3:11, 3:97] = False  # the hall
    for c0 in (5, 5 + TWIN_OFFSET_COLS):
        walls[14:44, c0 : c0 + 40] = False  # a room, 2 m x 1.5 m
        walls[11:14, c0 + 15 : c0 + 25] = False  # its door onto the hall
    return World(walls=walls, resolution_m=0.05, name="twin_rooms")


class _FakeFusion:
    """The fusion stage as TruthMonitor reads it: robot 0's fused map is set by the test
    (its own map with robot 1's placed by a chosen transform); robot 1 is not merged."""

    def __init__(self, sim: Any) -> None:
        self.sim = sim
        self.maps = {"robot_0": sim.maps[0].to_int8(), "robot_1": sim.maps[1].to_int8()}
        self.version = 0

    def fuse(self, T_01: Any) -> None:
        from mrexplore.grid import UNKNOWN
        from mrexplore.truth import map_in_world

        own = self.sim.maps[0].to_int8()
        placed = map_in_world(self.sim.maps[1].to_int8(), T_01, own.shape)
        self.maps["robot_0"] = np.where(own == UNKNOWN, placed, own).astype(np.int8)
        self.version += 1

    def fused(self, agent: str) -> Any:
        return self.maps[agent]

    def fused_version(self, agent: str) -> int:
        return self.version

    def fused_change(self, agent: str) -> tuple[int, None]:
        return self.version, None  # changed anywhere: score it whole

    def fused_changed_cells(self, agent: str) -> None:
        return None  # the box says what changed


def test_held_credits_a_wrongly_merged_robot_with_its_own_map_only() -> None:
    """Robot 1's map of the right room, merged into robot 0's one room to the left, lands on
    the left room's free space: its cells would count at their true place. Holding that wrong
    transform, robot 0 is credited with its own map's free cells only; with the correct
    transform, with the fused map's (the teammate's room included)."""
    from typing import cast

    from mrexplore.grid import chain, make_transform
    from mrexplore.merge.fusion import FusionStage
    from mrexplore.sensors import LidarConfig
    from mrexplore.sim import SimConfig, Simulation

    # one short-range scan each, noiseless: robot 0 sees the left part of the left room,
    # robot 1 the right part of the right room
    sim = Simulation(_twin_rooms(), 2, SimConfig(lidar=LidarConfig(max_range_m=1.0)))
    starts = np.array([[0.625, 1.475, 0.0], [(88 + 0.5) * 0.05, 1.475, 0.0]])
    sim.reset(np.random.default_rng(0), starts=starts)
    fusion = _FakeFusion(sim)
    agents = ["robot_0", "robot_1"]
    monitor = TruthMonitor(agents, sim, cast(FusionStage, fusion), held=True)
    scorer = monitor.scorer

    def held_of(grid: Any) -> int:
        return scorer.held_free(scorer.warp(grid, sim.world_from_map(0)))

    own = held_of(sim.maps[0].to_int8())
    T_true = sim.true_transform(0, 1)
    T_wrong = chain(make_transform(0.0, -float(TWIN_OFFSET_COLS), 0.0), T_true)

    fusion.fuse(T_wrong)
    wrong = {"robot_1": T_wrong}
    assert monitor.holds_wrong("robot_0", wrong)
    fused_wrong = held_of(fusion.fused("robot_0"))
    assert fused_wrong > own + 50  # the misplaced cells land on true free space ...
    assert monitor.map_accuracy(0)[1] == fused_wrong  # ... and the fused map's figure has them
    assert monitor.held_free(0, wrong) == own  # ... but the held coverage does not

    fusion.fuse(T_true)
    right = {"robot_1": T_true}
    assert not monitor.holds_wrong("robot_0", right)
    fused_right = held_of(fusion.fused("robot_0"))
    assert fused_right > own + 50  # the teammate's room, at its true place
    assert monitor.held_free(0, right) == fused_right
    # unmerged robot 1: its own map, as always
    assert monitor.held_free(1, {}) == scorer.held_free(
        scorer.warp(sim.maps[1].to_int8(), sim.world_from_map(1))
    )


def test_a_transform_held_through_teammates_is_allowed_each_merged_pairs_drift(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Robot 0 holds robot 2's map through robot 1 (pairs 0-1 and 1-2 merged): each merge may
    be off by its own two robots' drift, so the transform is allowed the sum over the chain
    (robot 1's bent map counts in both); merged directly, the pair's own allowance."""
    import mrexplore
    from mrexplore.errors import ConfigError

    env = mrexplore.parallel_env(world="small_office", n_robots=3, merger="semantic")
    env.reset(seed=5)
    sim, monitor = env.episode.sim, env.episode.truth
    tracker = monitor.fusion.tracker
    with pytest.raises(ConfigError, match="not merged"):
        tracker.chain_edges(0, 2)
    # a stand-in allowance that names its pair: (a, b) -> 10 a + b + 1 cells
    monkeypatch.setattr(sim, "drift_allowance_at", lambda a, b, radius: 10.0 * a + b + 1.0)
    for edges, allowed in (([(0, 1), (1, 2)], (0 + 1 + 1) + (10 + 2 + 1)), ([(0, 2)], 3.0)):
        tracker._edges = {e: sim.true_transform(*e) for e in edges}
        tracker._paths = None
        monitor._errors.clear()
        assert tracker.chain_edges(0, 2) == edges
        T = tracker.transform(0, 2)
        err = monitor._pair_error(0, 2, T)
        assert err is not None and err["drift_cells"] == allowed
        assert err["translation_cells"] < 1e-6  # the chain of true transforms is the truth
