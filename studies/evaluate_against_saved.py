#!/usr/bin/env python
"""``mrexplore evaluate`` for a new goal-level policy, reusing a saved evaluation's rows once
they are shown to reproduce on this code.

Usage: ``python studies/evaluate_against_saved.py NEW --saved OLD/eval.json --seeds 50
--max-time-s 300 --worlds W [W ...] --out DIR [--check-seeds 10] [--force]``

Used for the goal policy with memory against the shipped ``policies/goal_ppo_2r``: the full
``mrexplore evaluate`` re-runs random, nearest-, cost- and coordinated-frontier (half its time)
and the paired comparison with the shipped policy needs its 300 episodes again. Per world this
script runs NEW greedily and sampled on every seed (as ``mrexplore evaluate``), re-runs
``coordinated-frontier`` on every seed and the saved learned policy greedily on the first
``--check-seeds`` seeds, and compares their per-seed times to 90 % / 95 % and task times with
the saved ones. Only when every one is equal are the saved rows (the other baselines and the
saved learned policy) reused; otherwise the baselines are re-run in full and the saved policy
is re-run on every seed (nothing is taken on trust). Prints the same table as
``mrexplore evaluate`` (the saved learned rows labelled ``saved: ...``), the paired comparison
with coordinated-frontier, and NEW minus the saved learned policy, paired on the same worlds
(greedy - greedy, sampled - sampled); writes ``eval.json`` and ``eval.png`` per world under
``--out`` and a combined ``eval.json``.
"""

from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path
from typing import Any

from mrexplore.environment.goal_actions import split_options
from mrexplore.experiments.evaluate import (
    BASELINES,
    COVERAGE_LEVELS,
    EVAL_SEED_BASE,
    PAIRED_BASELINE,
    eval_env_options,
    evaluate_policies,
    format_evaluation,
    paired,
    write_evaluation,
)
from mrexplore.experiments.trained import TrainedTeamPolicy, load_team_policy, read_config
from mrexplore.io_safety import check_out_dir
from mrexplore.policies import make_team_policy

KEYS = tuple(f"{lv:g}" for lv in COVERAGE_LEVELS)


def _values(summary: dict[str, Any]) -> dict[str, list[float]]:
    """The per-seed figures a reuse check compares: times to each level and task times."""
    out = {f"time_to_{k}": list(summary["time_to"][k]["values"]) for k in KEYS}
    out["task_time_s"] = list(summary["task_time_s"]["values"])
    return out


def _same(new: dict[str, Any], saved: dict[str, Any], n: int) -> bool:
    a, b = _values(new), _values(saved)
    return all(a[k][:n] == b[k][:n] for k in a)


def _learned(folder: str, agents: list[str]) -> dict[str, Any]:
    team = load_team_policy(folder, agents)
    assert isinstance(team, TrainedTeamPolicy)
    greedy = TrainedTeamPolicy(team.model, agents, deterministic=True)
    sampled = TrainedTeamPolicy(team.model, agents, deterministic=False)
    return {"greedy": lambda ag: greedy, "sampled": lambda ag: sampled}


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__)
    p.add_argument("folder")
    p.add_argument("--saved", required=True, help="an eval.json of `mrexplore evaluate --worlds`")
    p.add_argument("--seeds", type=int, default=50)
    p.add_argument("--max-time-s", type=float, default=None)
    p.add_argument("--worlds", nargs="+", required=True)
    p.add_argument("--check-seeds", type=int, default=10)
    p.add_argument("--out", required=True)
    p.add_argument("--force", action="store_true")
    args = p.parse_args()
    out = check_out_dir(args.out, force=args.force, what="evaluate_against_saved")
    saved_doc = json.loads(Path(args.saved).read_text())
    saved_folder = str(saved_doc.get("policy_folder") or Path(args.saved).parent)
    if not (Path(saved_folder) / "model.zip").is_file():
        saved_folder = str(Path(args.saved).parent)
    seeds = list(range(EVAL_SEED_BASE, EVAL_SEED_BASE + args.seeds))
    if saved_doc["seeds"] != seeds:
        raise SystemExit("the saved evaluation used other seeds (the same --seeds is needed)")
    config = read_config(args.folder)
    env = eval_env_options(config)
    saved_env = eval_env_options(read_config(saved_folder))
    if args.max_time_s is not None:
        env["max_time_s"] = saved_env["max_time_s"] = float(args.max_time_s)
    if float(saved_doc["env"]["max_time_s"]) != float(env["max_time_s"]):
        raise SystemExit("the saved evaluation used another max_time_s")
    low = split_options(env)[2]
    agents = [f"robot_{i}" for i in range(int(env.get("n_robots", 2)))]
    name = f"trained ({config.get('algo', 'ppo')})"
    # the saved rows carry the saved policy's algorithm, which may differ (recurrent_ppo)
    saved_name = f"trained ({read_config(saved_folder).get('algo', 'ppo')})"
    new = _learned(args.folder, agents)
    old = _learned(saved_folder, agents)
    by_world: dict[str, Any] = {}
    checks: dict[str, Any] = {}
    vs_saved: dict[str, Any] = {}
    for w in args.worlds:
        saved_rows = saved_doc["worlds"][w]["results"]
        saved_learned = {m: saved_rows[f"{saved_name}, {m}"] for m in ("greedy", "sampled")}
        print(f"world {w}: checking the saved rows reproduce", flush=True)
        coord = evaluate_policies(
            {PAIRED_BASELINE: lambda ag: make_team_policy(PAIRED_BASELINE, ag)},
            {**low, "world": w},
            seeds,
        )[PAIRED_BASELINE]
        check_seeds = seeds[: args.check_seeds]
        old_check = evaluate_policies(
            {"greedy": old["greedy"]}, {**saved_env, "world": w}, check_seeds
        )["greedy"]
        ok_coord = _same(coord, saved_rows[PAIRED_BASELINE], len(seeds))
        ok_old = _same(old_check, saved_learned["greedy"], len(check_seeds))
        checks[w] = {
            "coordinated_frontier_all_seeds_equal": ok_coord,
            f"saved_greedy_first_{len(check_seeds)}_seeds_equal": ok_old,
        }
        print(f"  reproduce: {checks[w]}", flush=True)
        print("  the new policy, greedy and sampled", flush=True)
        rows = evaluate_policies(
            {f"{name}, {m}": f for m, f in new.items()}, {**env, "world": w}, seeds
        )
        if ok_coord:
            baselines = {b: saved_rows[b] for b in BASELINES if b != PAIRED_BASELINE}
        else:
            print("  re-running the baselines in full", flush=True)
            baselines = evaluate_policies(
                {
                    b: (lambda ag, b=b: make_team_policy(b, ag))
                    for b in BASELINES
                    if b != PAIRED_BASELINE
                },
                {**low, "world": w},
                seeds,
            )
        if not (ok_coord and ok_old):
            print("  re-running the saved policy in full", flush=True)
            saved_learned = evaluate_policies(old, {**saved_env, "world": w}, seeds)
        results = dict(rows)
        results.update({f"saved: {m}": s for m, s in saved_learned.items()})
        results.update(baselines)
        results[PAIRED_BASELINE] = coord
        comparison = {
            lname: {
                f"time_to_{k}": paired(
                    results[lname]["time_to"][k]["values"],
                    results[PAIRED_BASELINE]["time_to"][k]["values"],
                )
                for k in KEYS
            }
            for lname in list(rows) + [f"saved: {m}" for m in ("greedy", "sampled")]
        }
        vs_saved[w] = {
            m: {
                f"time_to_{k}": paired(
                    rows[f"{name}, {m}"]["time_to"][k]["values"],
                    saved_learned[m]["time_to"][k]["values"],
                )
                for k in KEYS
            }
            for m in ("greedy", "sampled")
        }
        by_world[w] = {"results": results, "paired": comparison}
        doc_w = {
            "policy_folder": args.folder,
            "saved": args.saved,
            "env": {**env, "world": w},
            "seeds": seeds,
            "paired_baseline": PAIRED_BASELINE,
            "results": results,
            "paired": comparison,
            "reuse_check": checks[w],
            "paired_vs_saved": vs_saved[w],
        }
        safe = w.replace("random:", "").translate(str.maketrans("?&=", "___"))
        write_evaluation(doc_w, out / safe)
    doc = {
        "policy_folder": args.folder,
        "saved": args.saved,
        "saved_policy_folder": saved_folder,
        "command": "python studies/evaluate_against_saved.py "
        + " ".join(f"'{a}'" if "?" in a else a for a in sys.argv[1:]),
        "env": env,
        "seeds": seeds,
        "paired_baseline": PAIRED_BASELINE,
        "reuse_check": checks,
        "worlds": by_world,
        "paired_vs_saved": vs_saved,
    }
    (out / "eval.json").write_text(json.dumps(doc, indent=2))
    print(format_evaluation(doc))
    for w, comp in vs_saved.items():
        for m, c in comp.items():
            for key, d in c.items():
                print(
                    f"paired new {m} - saved {m} on {w}, {key} (s): mean {d['mean']:+.1f} "
                    f"[{d['ci_low']:+.1f}, {d['ci_high']:+.1f}], n {d['n']}; new lower in "
                    f"{d['a_lower']}, equal in {d['equal']}, higher in {d['a_higher']}"
                )
    print(f"wrote {out}/eval.json and one folder per world")


if __name__ == "__main__":
    main()
