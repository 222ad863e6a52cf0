"""``mrexplore bench wrappers [--world W] [--steps N]``: throughput of the wrappers.

Prints steps per second (and robot-steps per second, the unit SB3 counts) for the raw
``ParallelEnv``, the single-robot env, the merge wrapper, and the SB3 adapter in-process and with
subprocesses, all with random actions from a seeded Generator. Figures, not asserts.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable
from typing import Any

import numpy as np
from pettingzoo import ParallelEnv

import mrexplore


def _rate(fn: Callable[[], None], steps: int) -> float:
    t0 = time.perf_counter()
    fn()
    return steps / (time.perf_counter() - t0)


def main(argv: list[str] | None = None) -> None:
    """Run the benchmark and print one line per configuration."""
    from mrexplore.wrappers import (
        MapMergeWrapper,
        ParallelEnvVecEnv,
        SingleRobotExploreEnv,
        make_vec_env,
    )

    p = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    p.add_argument("--world", default="small_office")
    p.add_argument("--steps", type=int, default=200)
    p.add_argument("--robots", type=int, default=2)
    args = p.parse_args(argv)
    n, r, world = args.steps, args.robots, args.world
    rng = np.random.default_rng(0)
    opts = {"world": world, "n_robots": r, "max_cycles": 10_000}

    def run_parallel(env: ParallelEnv[str, Any, int]) -> Callable[[], None]:
        def go() -> None:
            env.reset(seed=0)
            for _ in range(n):
                env.step({a: int(rng.integers(4)) for a in env.agents})

        return go

    print(f"world={world} robots={r} steps={n} (random actions)")
    raw = _rate(run_parallel(mrexplore.parallel_env(**opts)), n)
    print(
        f"  {'ParallelEnv (built-in merging)':42s} {raw:8.1f} steps/s  {raw * r:8.1f} robot-steps/s"
    )
    wrapped = MapMergeWrapper(mrexplore.parallel_env(**{**opts, "merger": None}), view_m=25.6)
    w = _rate(run_parallel(wrapped), n)
    print(
        f"  MapMergeWrapper(env with merger=None)      {w:8.1f} steps/s  {w * r:8.1f} robot-steps/s"
    )
    single = SingleRobotExploreEnv(world=world, max_cycles=10_000)

    def go_single() -> None:
        single.reset(seed=0)
        for _ in range(n):
            single.step(int(rng.integers(4)))

    s = _rate(go_single, n)
    print(f"  SingleRobotExploreEnv (1 robot)            {s:8.1f} steps/s")
    for copies, sub in ((1, False), (2, False), (2, True)):
        venv: ParallelEnvVecEnv = make_vec_env(n_copies=copies, use_subprocess=sub, seed=0, **opts)
        venv.reset()

        def go_vec(v: ParallelEnvVecEnv = venv) -> None:
            for _ in range(n):
                v.step(rng.integers(0, 4, size=v.num_envs))

        v_rate = _rate(go_vec, n)
        venv.close()
        where = "subprocesses" if sub else "in-process "
        print(
            f"  ParallelEnvVecEnv {copies} copies {where}     {v_rate:8.1f} steps/s  "
            f"{v_rate * copies * r:8.1f} robot-steps/s"
        )


if __name__ == "__main__":
    main()
