"""Pinned rollouts: observations, rewards, infos and maps of short seeded episodes, hashed.

The digests were recorded before the step was made lean (issue 12: compiled observation,
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


def rollout_digest(
    steps: int, seed: int, policy: str | None, **options: Any
) -> tuple[str, int | None]:
    """Run ``steps`` steps (random actions when ``policy`` is None); return the digest and the
    first step at which robot_0 was merged (None if never)."""
    penv = mrexplore.parallel_env(**options)
    obs, infos = penv.reset(seed=seed)
    h = hashlib.sha256()
    _feed(h, obs)
    _feed(h, infos)
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
        _feed(h, [obs, rew, term, trunc, infos])
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
    # step ~120 on, egocentric views
    "navigate_three": (
        150,
        2,
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

#: Recorded at 35eda8a (before issue 12's lean step).
PINNED: dict[str, str] = {
    "coarse_held": "6abfe16b1cf5428a6f701ee9a2793178bd547bdd4e113173bd03c8204a419c23",
    "default_merging": "840cbf30f759c9a685fe1b66992349b3147ebb7265c40919a802228264f43ea8",
    "heading_up_noisy": "70688f6cdfadd8272f99547db680cb5b2b003ce4ab854556bc8a68a63608a231",
    "navigate_three": "4748d602f34791fb91b0962bd208b5c38b11bc72dcba313da065b18f0a2a8788",
}


#: Cases that take seconds (a long merged episode, held coverage): in the expensive set.
SLOW = {"default_merging", "coarse_held"}


@pytest.mark.parametrize(
    "name", [pytest.param(n, marks=[pytest.mark.expensive] if n in SLOW else []) for n in CASES]
)
def test_rollout_is_pinned(name: str) -> None:
    steps, seed, policy, options = CASES[name]
    digest, _ = rollout_digest(steps, seed, policy, **options)
    assert digest == PINNED[name]
