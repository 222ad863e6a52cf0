"""Exploration stalls on real maps: how many episodes reach the coverage target.

For each world, team size (1 robot; 2 robots coordinated, merging on) and kind of start
(aligned headings as ``task-time``, or random headings), runs seeds ``first .. first + n - 1``
and prints how many episodes reached the target (95 % within 600 s by default) and the mean task
time in simulated seconds (a stalled episode counts its 600 s).

    python studies/stalls.py --worlds tb3_office depot --seeds 10 --first-seed 1000
"""

from __future__ import annotations

import argparse
import statistics

from mrexplore.experiments.episode import run_episode
from mrexplore.experiments.task_time import make_team


def main() -> None:
    """Parse the arguments, run the episodes, print one line per setting."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", nargs="+", default=["tb3_office", "depot"])
    ap.add_argument("--seeds", type=int, default=10)
    ap.add_argument("--first-seed", type=int, default=1000)
    ap.add_argument("--robots", type=int, nargs="+", default=[1, 2])
    ap.add_argument("--headings", nargs="+", default=["aligned", "random"])
    ap.add_argument("--policy", default="coordinated-frontier")
    args = ap.parse_args()
    seeds = range(args.first_seed, args.first_seed + args.seeds)
    for world in args.worlds:
        for n in args.robots:
            for headings in args.headings:
                opts = {"world": world, "n_robots": n, "aligned_headings": headings == "aligned"}
                runs = [
                    run_episode(
                        opts, make_team(args.policy, [f"robot_{i}" for i in range(n)], "explore"), s
                    )
                    for s in seeds
                ]
                ok = sum(r.success for r in runs)
                mean = statistics.fmean(r.task_time_s for r in runs)
                stalls = [
                    f"{s}:{r.coverage:.1%}"
                    for s, r in zip(seeds, runs, strict=True)
                    if not r.success
                ]
                print(
                    f"{world:<17} {n} robot(s) {headings:<8} reached {ok:>2}/{len(runs)}  "
                    f"mean {mean:6.1f} s  not reached: {' '.join(stalls) or '-'}",
                    flush=True,
                )


if __name__ == "__main__":
    main()
