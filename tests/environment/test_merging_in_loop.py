"""Merging in the loop: robots exploring a symmetric world get merged, and never wrongly."""

from __future__ import annotations

import numpy as np
import pytest

import mrexplore
from mrexplore.policies import make_team_policy


@pytest.mark.parametrize(
    "options",
    [
        {"world": "small_office"},  # aligned starts: translation-only relation
        {"world": "small_office", "aligned_headings": False},  # rotated maps
    ],
)
def test_merge_happens_and_is_never_wrong(options: dict) -> None:
    penv = mrexplore.parallel_env(**options, max_time_s=200.0)
    penv.reset(seed=2)
    team = make_team_policy("coordinated-frontier", penv.possible_agents)
    team.reset(np.random.default_rng(0))
    merged_steps = 0
    while penv.agents:
        views = {a: penv.robot_view(a) for a in penv.agents}
        _, _, _, _, infos = penv.step(team.act(views))
        for info in infos.values():
            if info["merged"]:
                merged_steps += 1
                err = info["merge_error"]
                # A wrong merge (the look-alike room) would be metres off: every accepted
                # transform must be within 2 cells of the truth, at every step.
                assert err["translation_cells"] < 2.0, err
                assert err["rotation_deg"] < 2.0, err
    assert merged_steps > 0, "the robots never merged their maps"
