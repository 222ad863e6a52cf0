"""The keep-or-Burgard rule of the goal-level env (the teacher of ``mrexplore imitate``)."""

from __future__ import annotations

import numpy as np
import pytest

import mrexplore
from mrexplore.policies.candidates import FEATURE_NAMES
from mrexplore.policies.goal_rules import COL, KeepOrBurgardTeam, keep_or_burgard

F = len(FEATURE_NAMES)


def _rows(path_rel: list[float], claim: list[float] | None = None) -> np.ndarray:
    x = np.zeros((len(path_rel), F), dtype=np.float32)
    x[:, COL["path_rel"]] = path_rel
    if claim is not None:
        x[:, COL["claim"]] = claim
    return x


def test_burgard_pick_trades_path_against_claims() -> None:
    ones = np.ones(3, dtype=np.int8)
    assert keep_or_burgard(_rows([0.2, 0.5, 1.0]), ones) == 0  # nearest when nothing is claimed
    assert keep_or_burgard(_rows([0.2, 0.5, 1.0], [0.4, 0.0, 0.0]), ones) == 1
    # beta weighs the path: with beta 0 only the claims count (first unclaimed row)
    assert keep_or_burgard(_rows([0.2, 0.5, 1.0], [0.4, 0.0, 0.0]), ones, beta=0.0) == 1
    assert keep_or_burgard(_rows([0.2, 0.5, 1.0], [0.1, 0.0, 0.0]), ones, beta=3.0) == 0


def test_the_size_weight_trades_frontier_length_against_path() -> None:
    ones = np.ones(3, dtype=np.int8)
    x = _rows([0.2, 0.5, 1.0])
    x[:, COL["size_m"]] = [0.05, 0.3, 0.6]  # 0.5 m, 3 m and 6 m of frontier
    assert keep_or_burgard(x, ones) == 0  # size_weight 0: Burgard's pick, the nearest
    assert keep_or_burgard(x, ones, size_weight=0.5) == 0  # 0.825 against 0.65 and 0.3
    assert keep_or_burgard(x, ones, size_weight=2.0) == 2  # 1.2 beats 1.1 and 0.9
    x[0, COL["is_current"]] = 1.0  # a current target is kept whatever the weights
    assert keep_or_burgard(x, ones, size_weight=2.0) == 0


def test_the_current_target_is_kept_and_masked_rows_never_chosen() -> None:
    x = _rows([0.2, 0.5, 1.0])
    x[2, COL["is_current"]] = 1.0
    assert keep_or_burgard(x, np.ones(3, dtype=np.int8)) == 2
    # a masked current row is not kept, and the masked nearest row is skipped
    assert keep_or_burgard(x, np.array([0, 1, 0], dtype=np.int8)) == 1
    assert keep_or_burgard(x, np.zeros(3, dtype=np.int8)) == 0  # nothing valid: wait (row 0)
    # the memory columns after the first F do not change the choice
    wide = np.concatenate([x, np.ones_like(x)], axis=1)
    assert keep_or_burgard(wide, np.ones(3, dtype=np.int8)) == 2


def test_the_team_drives_the_goal_level_env_to_its_target() -> None:
    env = mrexplore.parallel_env(
        world="small_office", action_mode="goal", target_coverage=0.9, max_time_s=120.0
    )
    team = KeepOrBurgardTeam(env.possible_agents)
    obs, _ = env.reset(seed=3)
    while env.agents:
        chosen = team.act_obs(obs)
        assert all(obs[a]["action_mask"][r] == 1 for a, r in chosen.items())
        obs, _, _, _, _ = env.step(chosen)
    assert env.unwrapped.coverage >= 0.9
    with pytest.raises(TypeError, match="act_obs"):
        team.act({})
