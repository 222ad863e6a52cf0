"""Pinned rollouts: observations, rewards, infos and maps of short seeded episodes, hashed.

The digests were recorded before the step was made lean (compiled observation,
tracker bookkeeping from the maps' own known and changed boxes, reused buffers). Any change to
what a step returns, however small, changes a digest: a speed-up must leave them as they are.
A deliberate behaviour change updates them in the same commit, saying why.
"""

from __future__ import annotations

import hashlib
from typing import Any

import numpy as np
import pytest

import mrexplore
from mrexplore import kernels
from mrexplore.policies import make_team_policy


def _feed(h: Any, value: Any) -> None:
    """Hash a nested structure exactly (floats by repr, arrays by dtype, shape and bytes)."""
    if isinstance(value, np.ndarray):
        h.update(f"{value.dtype}{value.shape}".encode())
        h.update(np.ascontiguousarray(value).tobytes())
    elif isinstance(value, dict):
        for k in sorted(value):
            h.update(repr(k).encode())
            _feed(h, value[k])
    elif isinstance(value, (list, tuple)):
        h.update(f"{type(value).__name__}{len(value)}".encode())
        for v in value:
            _feed(h, v)
    else:
        h.update(repr(value).encode())


def _nan(v: Any) -> float:
    return float("nan") if v is None else float(v)


def _info_core(info: dict[str, Any]) -> tuple[Any, ...]:
    """The figures of one agent's infos, the same whichever info layout (nested ``merge_error``
    dict and None, or the flat keys with NaN) the env uses."""
    err = info.get("merge_error")
    if "merge_error_cells" in info:
        cells, deg, drift = (
            info["merge_error_cells"],
            info["merge_error_deg"],
            info["merge_error_drift_cells"],
        )
    elif err is not None:
        cells, deg, drift = err["translation_cells"], err["rotation_deg"], err["drift_cells"]
    else:
        cells = deg = drift = None
    return (
        info["coverage"],
        info["task_time_s"],
        info["step"],
        bool(info["merged"]),
        _nan(info["score"]),
        _nan(info["first_merge_time_s"]),
        _nan(cells),
        _nan(deg),
        _nan(drift),
        info["collisions"],
        bool(info.get("collided", False)),
        info["fused_contradiction"],
        info["merged_wrongly_s"],
        bool(info.get("goal_given", False)),
        bool(info.get("goal_reached", False)),
        bool(info.get("TimeLimit.truncated", False)),
    )


def _infos(infos: dict[str, dict[str, Any]]) -> dict[str, tuple[Any, ...]]:
    return {a: _info_core(i) for a, i in infos.items()}


def rollout_digest(
    steps: int, seed: int, policy: str | None, **options: Any
) -> tuple[str, int | None]:
    """Run ``steps`` steps (random actions when ``policy`` is None); return the digest and the
    first step at which robot_0 was merged (None if never)."""
    penv = mrexplore.parallel_env(**options)
    obs, infos = penv.reset(seed=seed)
    h = hashlib.sha256()
    _feed(h, obs)
    _feed(h, _infos(infos))
    rng = np.random.default_rng(seed)
    team = None
    if policy is not None:
        team = make_team_policy(policy, penv.possible_agents)
        team.reset(np.random.default_rng(seed))
    first_merge = None
    for t in range(steps):
        if not penv.agents:
            break
        if team is not None:
            actions = team.act({a: penv.robot_view(a) for a in penv.agents})
        else:
            actions = {a: int(rng.integers(4)) for a in penv.agents}
        obs, rew, term, trunc, infos = penv.step(actions)
        _feed(h, [obs, rew, term, trunc, _infos(infos)])
        if first_merge is None and infos["robot_0"]["merged"]:
            first_merge = t
    assert penv.sim is not None
    for i, a in enumerate(penv.possible_agents):
        v = penv.robot_view(a)
        _feed(h, [v.map, v.pose_cell, v.teammates, v.transforms, sorted(v.in_range)])
        _feed(h, penv.sim.maps[i].logodds)
    _feed(h, penv.state())
    return h.hexdigest(), first_merge


CASES: dict[str, tuple[int, int, str | None, dict[str, Any]]] = {
    # the default env, merged from step ~150 on: own maps, fused maps, teammates
    "default_merging": (260, 3, "coordinated-frontier", {"world": "symmetric_office"}),
    # egocentric views, range and odometry noise, random actions
    "heading_up_noisy": (
        150,
        5,
        None,
        {
            "world": "small_office",
            "obs_heading_up": True,
            "range_noise_m": 0.02,
            "odom_noise_trans": 0.02,
            "odom_noise_rot": 0.02,
        },
    ),
    # three robots, a radio range, navigation with a goal channel, random headings, merged from
    # step ~100 on, egocentric views
    "navigate_three": (
        150,
        5,
        "coordinated-frontier",
        {
            "world": "small_office",
            "n_robots": 3,
            "task": "navigate",
            "nav_warmup_s": 10.0,
            "comm_range_m": 6.0,
            "aligned_headings": False,
            "obs_heading_up": True,
        },
    ),
    # Explore-Bench's resolution and range; held coverage (map accuracy every step)
    "coarse_held": (
        150,
        1,
        "coordinated-frontier",
        {"world": "symmetric_office_coarse", "max_range_m": 3.0, "coverage_mode": "held"},
    ),
}

#: Recorded on main's code without the lean step: first at 35eda8a, then at each merge of main
#: whose changes reach these figures (0a26b06: merge attempts off the step path; 5d3198e: flat
#: infos, which report -1 where the figures were None); the lean step reproduces each. The two
#: merging cases were re-recorded at the merger's speed work (2026-11-23: the Hough accumulator
#: at half a degree and float64 coarse FFTs move poses by a fraction of a cell; navigate_three's
#: first merge came at step 117 instead of 127, default_merging's at the same step, 137). And
#: again when each pair's merge error (an evaluation info) began to refresh on its own phase
#: (2026-11-24): with the three merge-error figures left out of the hash, both digests were the
#: same before and after the change, so nothing else moved. And when the merger was made to
#: give the same bits on every CPU (2026-11-25: exact integer blur for the rotation spectrum,
#: rounded candidates and coarse scores, BLAS-free transform products): default_merging merges
#: at the same step, 137, its poses a few last bits apart; navigate_three at step 127 again.
#: And when the rest of the transform arithmetic left BLAS/LAPACK (2026-11-25: grid's inverse
#: and point maps, truth's world<->map products, the tracker's and compositor's products, the
#: heading-up turn): both merging cases merge at the same steps as before (137; 127, robot_2
#: never) with the same scores and actions; the tracker's transforms, teammates and merge
#: errors moved by <= 2.3e-13, and navigate_three's robot_1 own-trail channel by one or two
#: pixels at steps 108 and 112 (a floor() on a cell boundary in the turned view).
#: All four re-recorded when the own maps' hit weight became 3.6 (2026-11-27, docs/mapper.md):
#: every map changes. default_merging merges at the same step, 137; navigate_three's seed 2 no
#: longer merged robot_0 within its 150 steps (at step 197), so the case now runs seed 4,
#: merged at step 97. Re-recorded for the place test in the loop (2026-11-28): default_merging
#: merges at step 147; navigate_three's seed 4 no longer merged within its 150 steps, so the case
#: runs seed 5, merged at step 137. coarse_held re-recorded when the held coverage began to
#: credit a wall drawn a cell beside a true wall (2026-11-28): with the coverage info left out of
#: the hash, its digest is the same before and after, so nothing else moved.
PINNED: dict[str, str] = {
    "coarse_held": "42de8198898d002d63d5222115d47c803cc89356a69a2d1451a2f4b1ae5f0758",
    "default_merging": "c8f3b04bae17e0b9b21354e383fb930f82d8281e7c7ed46fca586f1cc34e9ea2",
    "heading_up_noisy": "a43209e97ec6d09939a40edc2359ad80c21fb968da441b6f143da1a1d67e18d8",
    "navigate_three": "7862ba6e00727adff5116b00684612972aa37ff4062c1c4d0e42dd2d5d23a3fe",
}


#: Cases whose robots merge their maps (see the skip in the test).
MERGING = {"default_merging", "navigate_three"}

#: Cases that take seconds (a long merged episode, held coverage): in the expensive set.
SLOW = {"default_merging", "coarse_held"}


@pytest.mark.parametrize(
    "name", [pytest.param(n, marks=[pytest.mark.expensive] if n in SLOW else []) for n in CASES]
)
def test_rollout_is_pinned(name: str) -> None:
    steps, seed, policy, options = CASES[name]
    if name in MERGING and not kernels.enabled():
        pytest.skip(
            "recorded with the compiled merger; its numpy reference (MREXPLORE_NUMBA=0) agrees "
            "to a tolerance, not to the bit, so merged poses differ in their last digits"
        )
    digest, _ = rollout_digest(steps, seed, policy, **options)
    assert digest == PINNED[name]
