"""Merge attempts off the step path: a fixed delay, the same run whatever the machine's speed."""

from __future__ import annotations

import hashlib
import threading
import time

import numpy as np
import pytest

import mrexplore
from mrexplore.errors import ConfigError
from mrexplore.merge import MergeResult, merge_maps
from mrexplore.policies import make_team_policy


class _Semantic:
    """The semantic merger with the env's in-loop options, optionally slowed down at random
    (an unseeded generator: the delays differ from run to run, as a loaded machine's do)."""

    def __init__(self, slow: bool) -> None:
        self.slow = slow
        self.rng = np.random.default_rng()
        self.threads: set[str] = set()

    def merge(self, a: np.ndarray, b: np.ndarray) -> MergeResult:
        self.threads.add(threading.current_thread().name)
        if self.slow:
            time.sleep(float(self.rng.uniform(0.0, 0.03)))
        return merge_maps(a, b, method="semantic", min_common_m2=20.0)


def _run(slow: bool, steps: int, latency: int) -> tuple[str, int | None, set[str]]:
    merger = _Semantic(slow)
    penv = mrexplore.parallel_env(
        world="symmetric_office",
        aligned_headings=False,
        merger=merger,
        merge_latency_steps=latency,
        max_time_s=steps * 0.25 + 1.0,
    )
    penv.reset(seed=7)
    team = make_team_policy("coordinated-frontier", penv.possible_agents)
    team.reset(np.random.default_rng(7))
    digest = hashlib.sha256()
    first_merge = None
    for t in range(steps):
        if not penv.agents:
            break
        obs, rew, _, _, _ = penv.step(team.act({a: penv.robot_view(a) for a in penv.agents}))
        for a in sorted(obs):
            digest.update(obs[a].tobytes())
            digest.update(np.float64(rew[a]).tobytes())
            T = penv.fusion.transforms(a)
            digest.update(
                repr(
                    sorted(
                        (k, None if v is None else np.round(v, 9).tolist()) for k, v in T.items()
                    )
                ).encode()
            )
        if first_merge is None and penv.fusion.merged("robot_0"):
            first_merge = t
    return digest.hexdigest(), first_merge, merger.threads


@pytest.mark.expensive
def test_same_run_whatever_the_merger_speed() -> None:
    fast = _run(slow=False, steps=1000, latency=8)
    slow = _run(slow=True, steps=1000, latency=8)
    assert fast[1] is not None, "no merge in 1000 steps: the test would prove nothing"
    assert fast[:2] == slow[:2]
    # the merger ran in the worker thread, not in the stepping thread
    assert fast[2] and all(name.startswith("mrexplore-merge") for name in fast[2])


def test_latency_option_is_validated() -> None:
    with pytest.raises(ConfigError, match="merge_latency_steps"):
        mrexplore.parallel_env(merge_latency_steps=-1)
    with pytest.raises(ConfigError, match="merge_latency_steps"):
        mrexplore.parallel_env(merge_latency_steps=2.5)


def test_wait_idle_finishes_the_started_attempts_and_changes_nothing() -> None:
    """``MapMergeTracker.wait_idle`` (for timing): after it, no attempt is running on the
    worker, and a run that waits after every step is the run that does not."""
    from concurrent.futures import Future

    def run(wait: bool) -> tuple[list[bytes], int]:
        merger = _Semantic(slow=True)
        penv = mrexplore.parallel_env(
            world="symmetric_office", merger=merger, merge_latency_steps=8, max_time_s=60.0
        )
        penv.reset(seed=3)
        team = make_team_policy("coordinated-frontier", penv.possible_agents)
        team.reset(np.random.default_rng(3))
        tracker = penv.fusion.tracker
        seen, waited = [], 0
        for _ in range(120):
            obs, _, _, _, _ = penv.step(team.act({a: penv.robot_view(a) for a in penv.agents}))
            seen.append(b"".join(obs[a].tobytes() for a in sorted(obs)))
            if wait and any(isinstance(jb.outcome, Future) for jb in tracker._jobs):
                tracker.wait_idle()
                waited += 1
                assert all(jb.outcome.done() for jb in tracker._jobs)
        penv.close()
        return seen, waited

    waited_run, waits = run(wait=True)
    assert waits > 0, "no attempt started: the test would prove nothing"
    assert waited_run == run(wait=False)[0]
