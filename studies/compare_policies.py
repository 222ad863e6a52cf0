#!/usr/bin/env python
"""Two trained policy folders side by side on the same held-out worlds, paired.

Usage: ``python studies/compare_policies.py A B [--seeds 20] [--world SPEC] [--max-time-s S]
[--sampled]``

Used for the goal policy's memory experiment (``goal_memory`` 1 vs 0 at the same training steps):
each folder runs with the env options of its own ``config.yaml`` (so each sees the observation it
was trained on), greedily unless ``--sampled``, on seeds from ``EVAL_SEED_BASE`` up; prints, per
folder, the times to 90 % and 95 % coverage (mean, 95 % CI, how many reached it) and the paired
difference A - B with its 95 % CI. Nothing is hard-coded: it prints what it measured.
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

from mrexplore.experiments.evaluate import (
    COVERAGE_LEVELS,
    EVAL_SEED_BASE,
    eval_env_options,
    evaluate_policies,
    paired,
)
from mrexplore.experiments.trained import load_team_policy, read_config


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("a")
    p.add_argument("b")
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--world", default=None, help="world spec (default: each config's world)")
    p.add_argument("--max-time-s", type=float, default=None)
    p.add_argument("--sampled", action="store_true", help="sample actions instead of arg-max")
    p.add_argument("--json", default=None, help="also write the figures to this JSON file")
    args = p.parse_args()
    seeds = list(range(EVAL_SEED_BASE, EVAL_SEED_BASE + args.seeds))
    results = {}
    for folder in (args.a, args.b):
        opts = eval_env_options(read_config(folder))
        if args.world:
            opts["world"] = args.world
        if args.max_time_s:
            opts["max_time_s"] = args.max_time_s
        agents = [f"robot_{i}" for i in range(int(opts.get("n_robots", 2)))]
        team = load_team_policy(folder, agents, deterministic=not args.sampled)
        results[folder] = evaluate_policies({folder: lambda ag, t=team: t}, opts, seeds)[folder]
    doc: dict[str, object] = {"seeds": seeds, "sampled": args.sampled, "results": results}
    for level in COVERAGE_LEVELS:
        key = f"{level:g}"
        for folder, s in results.items():
            t = s["time_to"][key]
            print(
                f"{folder}: time to {level:.0%} {t['mean']:.1f} s "
                f"[{t['ci_low']:.1f}, {t['ci_high']:.1f}], reached {t['reached']}/{len(seeds)}"
            )
        d = paired(
            results[args.a]["time_to"][key]["values"], results[args.b]["time_to"][key]["values"]
        )
        doc[f"paired_time_to_{key}"] = d
        print(
            f"paired A - B, time to {level:.0%}: {d['mean']:+.1f} s [{d['ci_low']:+.1f}, "
            f"{d['ci_high']:+.1f}]; A lower in {d['a_lower']}, equal {d['equal']}, "
            f"higher {d['a_higher']}"
        )
    if args.json:
        Path(args.json).write_text(json.dumps(doc, indent=2))


if __name__ == "__main__":
    main()
