"""``mrexplore bench env``: environment steps per second, with a breakdown by stage.

Runs the PettingZoo env with random actions (seeded) and times each stage of a step by
wrapping the env's named step parts on the instance (the env itself carries no timing code):
``act`` (move + lidar cast + own-map update, in the simulator), ``merge`` (fusion stage: merge
attempts and fused-map composition), ``observe`` (observation images), and the rest (reward,
termination, infos, Python overhead).
"""

from __future__ import annotations

import argparse
import json
import time
from collections import defaultdict
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

import mrexplore
from mrexplore.errors import ConfigError
from mrexplore.io_safety import check_outputs, write_text


def _timed(fn: Callable[..., Any], acc: dict[str, float], key: str) -> Callable[..., Any]:
    def wrapper(*args: Any, **kwargs: Any) -> Any:
        t0 = time.perf_counter()
        try:
            return fn(*args, **kwargs)
        finally:
            acc[key] += time.perf_counter() - t0

    return wrapper


def bench_env(steps: int = 2000, seed: int = 0, **options: Any) -> dict[str, Any]:
    """Step the env ``steps`` times with random actions; returns figures (seconds, steps/s)."""
    penv = mrexplore.parallel_env(**options)
    acc: dict[str, float] = defaultdict(float)
    for name in ("_act", "_merge", "_observe"):
        setattr(penv, name, _timed(getattr(penv, name), acc, name.strip("_")))
    rng = np.random.default_rng(seed)
    penv.reset(seed=seed)
    n_act = penv.action_space(penv.possible_agents[0]).n
    done_steps = 0
    episodes = 1
    t0 = time.perf_counter()
    for _ in range(steps):
        if not penv.agents:
            penv.reset()
            episodes += 1
        actions = {a: int(rng.integers(n_act)) for a in penv.agents}
        penv.step(actions)
        done_steps += 1
    total = time.perf_counter() - t0
    parts = {k: acc[k] for k in ("act", "merge", "observe")}
    parts["other"] = total - sum(parts.values())
    return {
        "options": {k: v for k, v in options.items()},
        "steps": done_steps,
        "episodes": episodes,
        "seconds": total,
        "steps_per_s": done_steps / total,
        "robot_updates_per_s": done_steps * penv.config.n_robots / total,
        "ms_per_step": {k: 1000.0 * v / done_steps for k, v in parts.items()},
        "merged_at_end": bool(penv.fusion.merged(penv.possible_agents[0])) if penv.agents else None,
    }


def _print(title: str, r: dict[str, Any]) -> None:
    ms = r["ms_per_step"]
    print(
        f"{title}: {r['steps_per_s']:.0f} env steps/s "
        f"({r['robot_updates_per_s']:.0f} robot updates/s) over "
        f"{r['steps']} steps, {r['episodes']} episode(s)\n"
        f"   per step: act (move+sense+map) {ms['act']:.3f} ms | merge {ms['merge']:.3f} ms | "
        f"observe {ms['observe']:.3f} ms | other {ms['other']:.3f} ms"
    )


def main(argv: Sequence[str] | None = None) -> int:
    """Print env steps/s on the default world and on the Explore-Bench-like 0.1 m/cell world."""
    p = argparse.ArgumentParser(prog="mrexplore bench env", description=__doc__)
    p.add_argument("--steps", type=int, default=2000, help="steps per world (at least 1)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--merger", default="semantic")
    p.add_argument("--json", default=None, help="also write the figures to this JSON file")
    p.add_argument("--force", action="store_true", help="replace an existing --json file")
    args = p.parse_args(argv)
    if args.steps < 1:
        raise ConfigError(f"bench env: --steps must be at least 1, got {args.steps}")
    if args.seed < 0:
        raise ConfigError(f"bench env: --seed must be an integer >= 0, got {args.seed}")
    if args.json:
        check_outputs([args.json], force=args.force, what="mrexplore bench env")
    results = {}
    results["default"] = bench_env(
        args.steps, args.seed, world="symmetric_office", n_robots=2, merger=args.merger
    )
    _print(
        "2 robots, symmetric_office (0.05 m/cell), 360 beams, 4 m, merging on", results["default"]
    )
    results["explore_bench_like"] = bench_env(
        args.steps,
        args.seed,
        world="symmetric_office_coarse",
        n_robots=2,
        max_range_m=3.0,
        merger=args.merger,
    )
    _print(
        "2 robots, symmetric_office_coarse (250x250 cells, 0.1 m/cell, 3 m range; "
        "Explore-Bench's settings)",
        results["explore_bench_like"],
    )
    ref = 10.0
    print(
        f"   vs Explore-Bench's grid env measured at about {ref:.0f} steps/s on this kind of "
        "machine: "
        f"x{results['explore_bench_like']['steps_per_s'] / ref:.0f}"
    )
    if args.json:
        write_text(args.json, json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
