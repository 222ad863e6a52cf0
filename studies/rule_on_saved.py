#!/usr/bin/env python
"""The goal-level rule ``keep_or_burgard``, with and without turns, on a saved evaluation's
worlds, paired with its saved coordinated-frontier and learned-policy rows.

Usage: ``python studies/rule_on_saved.py --saved docs/results/goal_policy_eval/office/eval.json
[--seeds 50] [--check-seeds 5] [--size-weight W] [--planner NAME] [--json OUT] [--force]``

Runs :class:`~mrexplore.policies.goal_rules.KeepOrBurgardTeam` (keep the current target while
it is a valid row, else Burgard's pick) in the saved evaluation's goal-level env on its seeds,
once as saved (every robot chooses at once) and once with ``goal_turns=1`` (the robots choose in
turn, each seeing the targets chosen before it), both with the rule's ``size_weight`` (default
0, Burgard's utility). Before using the saved rows it re-runs
coordinated-frontier on the first ``--check-seeds`` seeds and stops unless their times equal
the saved ones (the rows must belong to this code). Prints, per variant, the worlds that reached
the saved target coverage, the mean time to 95 %, and paired differences (mean, 95 % interval)
against coordinated-frontier and the saved learned policy (greedy), and turns minus no turns.
``--planner NAME`` also runs a registered planner (e.g. ``coordinated-frontier-size``) on the
same seeds and prints it minus coordinated-frontier and minus the rule with turns.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from mrexplore.environment.goal_actions import split_options
from mrexplore.experiments.evaluate import PAIRED_BASELINE, evaluate_policies, paired
from mrexplore.io_safety import check_outputs, write_text
from mrexplore.policies import POLICIES, make_team_policy
from mrexplore.policies.goal_rules import KeepOrBurgardTeam

LEVEL = "0.95"
LEARNED = "trained (maskable_ppo), greedy"


def _times(summary: dict[str, Any]) -> list[float]:
    return list(summary["time_to"][LEVEL]["values"])


def _fmt(d: dict[str, float]) -> str:
    return f"{d['mean']:+.1f} [{d['ci_low']:+.1f}, {d['ci_high']:+.1f}]"


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--saved", required=True, help="an eval.json of mrexplore evaluate (goal level)")
    p.add_argument("--seeds", type=int, default=50)
    p.add_argument("--check-seeds", type=int, default=5)
    p.add_argument(
        "--size-weight", type=float, default=0.0, help="the rule's frontier-length weight (>= 0)"
    )
    p.add_argument("--planner", default=None, help="a registered planner to run beside the rule")
    p.add_argument("--json", default=None, help="write the per-seed times here")
    p.add_argument("--force", action="store_true", help="overwrite an existing --json")
    args = p.parse_args(argv)
    if not args.size_weight >= 0:
        p.error(f"--size-weight must be >= 0, got {args.size_weight}")
    if args.planner is not None and args.planner not in POLICIES:
        p.error(f"--planner {args.planner!r} is not one of {sorted(POLICIES)}")
    saved_path = Path(args.saved)
    if not saved_path.is_file():
        p.error(f"--saved {saved_path} is not a file")
    if args.json is not None:
        check_outputs([Path(args.json)], [saved_path], force=args.force)
    doc = json.loads(saved_path.read_text())
    env = dict(doc["env"])
    if env.get("action_mode") != "goal":
        p.error(f"--saved {saved_path} is not a goal-level evaluation")
    if not 1 <= args.seeds <= len(doc["seeds"]) or not 0 <= args.check_seeds <= args.seeds:
        p.error(f"need 1 <= --seeds <= {len(doc['seeds'])} and 0 <= --check-seeds <= --seeds")
    seeds = doc["seeds"][: args.seeds]
    out: dict[str, Any] = {
        "saved": str(saved_path),
        "seeds": seeds,
        "size_weight": args.size_weight,
        "worlds": {},
    }
    for world, rows in doc["worlds"].items():
        opts = {**env, "world": world}
        cf = _times(rows["results"][PAIRED_BASELINE])[: args.seeds]
        learned = _times(rows["results"][LEARNED])[: args.seeds]
        _, _, base = split_options(opts)  # the planners run on the low level
        check = seeds[: args.check_seeds]
        if check:
            again = evaluate_policies(
                {"cf": lambda ag: make_team_policy("coordinated-frontier", ag)},
                base,
                check,
                progress=False,
            )["cf"]
            if _times(again) != cf[: len(check)]:
                print(
                    f"{world}: coordinated-frontier does not reproduce the saved rows", flush=True
                )
                return 1
        res = {}
        for name, turns in (("rule", 0), ("rule with turns", 1)):
            s = evaluate_policies(
                {name: lambda ag: KeepOrBurgardTeam(ag, size_weight=args.size_weight)},
                {**opts, "goal_turns": turns},
                seeds,
                progress=False,
            )[name]
            res[name] = _times(s)
            print(
                f"{world}, {name}: reached {s['time_to'][LEVEL]['reached']}/{len(seeds)}, "
                f"time to 95 % {s['time_to'][LEVEL]['mean']:.1f} s; minus coordinated-frontier "
                f"{_fmt(paired(res[name], cf))}; minus the saved policy "
                f"{_fmt(paired(res[name], learned))}",
                flush=True,
            )
        print(
            f"{world}: turns minus no turns {_fmt(paired(res['rule with turns'], res['rule']))}",
            flush=True,
        )
        if args.planner is not None:
            s = evaluate_policies(
                {args.planner: lambda ag: make_team_policy(args.planner, ag)},
                base,
                seeds,
                progress=False,
            )[args.planner]
            res[args.planner] = _times(s)
            print(
                f"{world}, {args.planner}: reached {s['time_to'][LEVEL]['reached']}/{len(seeds)}, "
                f"time to 95 % {s['time_to'][LEVEL]['mean']:.1f} s; minus coordinated-frontier "
                f"{_fmt(paired(res[args.planner], cf))}; minus the rule with turns "
                f"{_fmt(paired(res[args.planner], res['rule with turns']))}",
                flush=True,
            )
        out["worlds"][world] = {**res, PAIRED_BASELINE: cf, LEARNED: learned}
    if args.json is not None:
        write_text(Path(args.json), json.dumps(out, indent=2))
    return 0


if __name__ == "__main__":
    sys.exit(main())
