"""Merging in the loop: robots exploring a symmetric world get merged, and never wrongly."""

from __future__ import annotations

import numpy as np
import pytest

import mrexplore
from mrexplore.grid import known_bbox
from mrexplore.policies import make_team_policy

pytestmark = pytest.mark.expensive  # end-to-end episodes: deselect with -m "not expensive"


@pytest.mark.parametrize(
    ("aligned", "seed"),
    [
        (True, 3),  # aligned starts (the paper's setting): translation-only relation
        (False, 4),  # random start headings: the maps are rotated w.r.t. each other
    ],
)
def test_merge_happens_and_is_never_wrong(aligned: bool, seed: int) -> None:
    penv = mrexplore.parallel_env(
        world="symmetric_office", aligned_headings=aligned, max_time_s=400.0
    )
    penv.reset(seed=seed)
    team = make_team_policy("coordinated-frontier", penv.possible_agents)
    team.reset(np.random.default_rng(0))
    merged_steps = 0
    while penv.agents and merged_steps < 300:
        views = {a: penv.robot_view(a) for a in penv.agents}
        for v in views.values():
            # the box the views and planners read instead of the canvas holds every known cell
            tight = known_bbox(v.map)
            assert v.known_box is not None and tight is not None
            (r0, r1, c0, c1), (t0, t1, u0, u1) = v.known_box, tight
            assert r0 <= t0 and r1 >= t1 and c0 <= u0 and c1 >= u1
        _, _, _, _, infos = penv.step(team.act(views))
        for info in infos.values():
            if info["merged"]:
                merged_steps += 1
                err = (info["merge_error_cells"], info["merge_error_deg"])
                # A wrong merge (a look-alike room) would be metres off: every accepted
                # transform must be within 2 cells of the truth, at every step.
                assert err[0] < 2.0 and err[1] < 2.0, err
            else:
                assert info["merge_error_cells"] == -1.0  # unknown
    assert merged_steps > 0, "the robots never merged their maps"


def test_views_carry_the_mergers_candidates_until_the_merge() -> None:
    """``robot_view(...).hypotheses``: before the merge, the merger's candidates for the
    teammate's map and that map as the teammate holds it (no ground truth); after, none. The
    team that goes to check them (``coordinated-frontier-verify``) merges, and never wrongly."""
    penv = mrexplore.parallel_env(world="symmetric_office", aligned_headings=False, max_time_s=400)
    penv.reset(seed=4)
    team = make_team_policy("coordinated-frontier-verify", penv.possible_agents)
    team.reset(np.random.default_rng(0))
    seen_candidates = merged_steps = 0
    while penv.agents and merged_steps < 100:
        views = {a: penv.robot_view(a) for a in penv.agents}
        for a, view in views.items():
            if view.merged:
                assert view.hypotheses == {}
            for mate, (cands, mate_map) in view.hypotheses.items():
                assert mate != a and all(T.shape == (3, 3) for T in cands)
                np.testing.assert_array_equal(mate_map, penv.local_map(mate))
                seen_candidates += 1
        _, _, _, _, infos = penv.step(team.act(views))
        for info in infos.values():
            if info["merged"]:
                merged_steps += 1
                assert info["merge_error_cells"] < 2.0 and info["merge_error_deg"] < 2.0
    assert seen_candidates > 0 and merged_steps > 0
