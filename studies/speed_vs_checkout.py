"""Env speed of this checkout against another one, measured side by side in one run.

    python studies/speed_vs_checkout.py --base /path/to/older/checkout [--rounds 3] [--steps 1500]

Each round runs the same harness (:func:`mrexplore.studies.env_bench.measure` of *this*
checkout, which uses only the public env API) on every setting, once on the other tree and once
on this one, in fresh processes whose ``import mrexplore`` resolves to that tree, alternating
setting by setting so that a change of the machine's load hits both sides alike. Run each tree
once before (numba compiles its kernels into the tree's ``__pycache__`` on first use). Figures
are CPU time of the stepping thread; the printed ratio is this tree over the base, per setting,
as the median over rounds.

Create the base tree with ``git worktree add --detach ../base <commit>``.
"""

from __future__ import annotations

import argparse
import json
import statistics
import subprocess
import sys
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent.parent
HARNESS = HERE / "mrexplore" / "studies" / "env_bench.py"

# Run in the child: load the harness by path, with the chosen tree first on sys.path.
CHILD = """
import importlib.util, json, sys
sys.path.insert(0, sys.argv[1])
spec = importlib.util.spec_from_file_location("harness", sys.argv[2])
h = importlib.util.module_from_spec(spec); spec.loader.exec_module(h)
import mrexplore
assert mrexplore.__file__.startswith(sys.argv[1]), mrexplore.__file__
out = {}
for label, opts in json.loads(sys.argv[3]):
    if "team" in opts:  # a realistic rollout (measure_rollout), else random actions
        team = opts.pop("team")
        out[label] = h.measure_rollout(int(sys.argv[4]), 0, team, **opts)
    else:
        out[label] = h.measure(int(sys.argv[4]), 0, **opts)
print(json.dumps(out))
"""


def run(tree: Path, settings: list[tuple[str, dict[str, Any]]], steps: int) -> dict[str, Any]:
    """One measurement of every setting on ``tree`` in a fresh process."""
    res = subprocess.run(
        [sys.executable, "-c", CHILD, str(tree), str(HARNESS), json.dumps(settings), str(steps)],
        check=True,
        capture_output=True,
        text=True,
    )
    return dict(json.loads(res.stdout.strip().splitlines()[-1]))


def _proc_ratio(runs: dict[str, list[dict[str, Any]]], label: str) -> float | None:
    """Median ratio of steps per second of process CPU time (all threads), if measured."""
    try:
        return statistics.median(
            t[label]["steps_per_process_cpu_s"] / b[label]["steps_per_process_cpu_s"]
            for b, t in zip(runs["base"], runs["this"], strict=True)
        )
    except KeyError:
        return None


def _print_rollouts(
    runs: dict[str, list[dict[str, Any]]], label: str, rounds: int, base: Path, this: Path
) -> int:
    """Every round's rollout rows of both trees, then the medians and this / base."""
    from mrexplore.studies.env_bench import ROLLOUT_HEADER, rollout_row

    print(f"{rounds} alternating rounds, base then this\nbase: {base}\nthis: {this}")
    print(ROLLOUT_HEADER)
    for k in range(rounds):
        for name in ("base", "this"):
            print(rollout_row(f"round {k + 1}, {name}", runs[name][k][label]))
    keys: tuple[str, ...] = (
        "process_ms",
        "thread_ms",
        "policy_ms",
        "env_ms",
        "policy_share",
        "p50_ms",
    )
    keys += ("p99_ms", "max_ms", "max_over_p50")
    med = {
        name: {key: statistics.median(r[label][key] for r in runs[name]) for key in keys}
        for name in runs
    }
    for name in ("base", "this"):
        print(rollout_row(f"median over rounds, {name}", med[name]))
    pairs = list(zip(runs["base"], runs["this"], strict=True))

    def ratio(key: str) -> float:
        return statistics.median(t[label][key] / b[label][key] for b, t in pairs)

    line = f"process CPU {ratio('process_ms'):.2f}x, policy {ratio('policy_ms'):.2f}x"
    if all(b[label].get("merge_ms", 0) > 0 for b, _ in pairs):  # a tree that reports it
        line += f", merge worker {ratio('merge_ms'):.2f}x"
    print(f"this / base, median of the rounds' ratios: {line}")
    return 0


def rows(
    robots: list[int], merger: str | None, env_options: str | None
) -> list[tuple[str, dict[str, Any]]]:
    """The random-action settings (label, env options): ``mrexplore bench env``'s table, or
    with ``env_options`` (``"k=v,k=v"``) those options on the default world per team size."""
    from mrexplore.studies.env_bench import DEFAULT_WORLD, settings
    from mrexplore.studies.merge_bench import parse_options

    if env_options is None:
        return settings(robots, merger)
    extra = parse_options(env_options, flag="--env-options")
    return [
        (f"{n} robots, {env_options}", {**DEFAULT_WORLD, **extra, "n_robots": n, "merger": merger})
        for n in robots
    ]


def rollout_setting(
    team: str, merger: str | None, env_options: str | None
) -> tuple[str, dict[str, Any]]:
    """The realistic rollout's setting (label, env options with ``team``): the default world,
    2 robots, with ``env_options`` (``"k=v,k=v"``, e.g. ``n_robots=8``) over it."""
    from mrexplore.studies.env_bench import DEFAULT_WORLD
    from mrexplore.studies.merge_bench import parse_options

    extra = {} if env_options is None else parse_options(env_options, flag="--env-options")
    label = f"{team}, symmetric_office, {extra.get('n_robots', 2)} robots"
    if env_options is not None:
        label += f", {env_options}"
    return label, {**DEFAULT_WORLD, "merger": merger, **extra, "team": team}


def main() -> int:
    """Measure both trees in turn and print steps/s, p50/p99 and the ratio per setting."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--base", required=True, help="the other checkout (its top folder)")
    p.add_argument("--rounds", type=int, default=3)
    p.add_argument("--steps", type=int, default=1500)
    p.add_argument("--robots", default="1,2,4,8")
    p.add_argument("--merger", default="semantic", help='a merge method, or "none"')
    p.add_argument(
        "--rollout",
        default=None,
        metavar="TEAM",
        help="instead of random actions: a realistic rollout driven by this team policy "
        "(symmetric_office, 2 robots unless --env-options say n_robots; measure_rollout), "
        "e.g. coordinated-frontier",
    )
    p.add_argument(
        "--env-options",
        default=None,
        metavar="K=V,K=V",
        help="env options of every random-action row (or of the rollout), e.g. the training "
        "setup of ppo.yaml: "
        "'world=random:symmetric_office?width_m=10&height_m=8,obs_heading_up=true'",
    )
    args = p.parse_args()
    sys.path.insert(0, str(HERE))
    merger = None if args.merger.lower() == "none" else args.merger
    robots = [int(v) for v in args.robots.split(",")]
    table = rows(robots, merger, args.env_options)
    if args.rollout is not None:
        table = [rollout_setting(args.rollout, merger, args.env_options)]
    base, this = Path(args.base).resolve(), HERE
    runs: dict[str, list[dict[str, Any]]] = {"base": [], "this": []}
    for k in range(args.rounds):
        # setting by setting, base then this: a drift of the machine's load hits both alike
        got: dict[str, dict[str, Any]] = {"base": {}, "this": {}}
        for setting in table:
            for name, tree in (("base", base), ("this", this)):
                got[name].update(run(tree, [setting], args.steps))
        for name in runs:
            runs[name].append(got[name])
        print(f"round {k + 1}/{args.rounds} done", file=sys.stderr, flush=True)
    if args.rollout is not None:
        return _print_rollouts(runs, table[0][0], args.rounds, base, this)
    print(
        f"{args.steps} random-action steps per setting, {args.rounds} alternating rounds, "
        f"merger {merger}; CPU time of the stepping thread; medians over rounds\n"
        f"base: {base}\nthis: {this}"
    )
    print(
        f"{'setting':<44} {'base st/s':>9} {'this st/s':>9} {'ratio':>6} "
        f"{'this robot-st/s':>15} {'p50 ms b/t':>13} {'p99 ms b/t':>13}"
    )
    for label, _ in table:

        def med(name: str, key: str, label: str = label) -> float:
            return statistics.median(r[label][key] for r in runs[name])

        ratios = [
            t[label]["steps_per_s"] / b[label]["steps_per_s"]
            for b, t in zip(runs["base"], runs["this"], strict=True)
        ]
        print(
            f"{label:<44} {med('base', 'steps_per_s'):>9.0f} {med('this', 'steps_per_s'):>9.0f} "
            f"{statistics.median(ratios):>5.2f}x {med('this', 'robot_steps_per_s'):>15.0f} "
            f"{med('base', 'p50_ms'):>6.2f}/{med('this', 'p50_ms'):<6.2f}"
            f"{med('base', 'p99_ms'):>6.1f}/{med('this', 'p99_ms'):<6.1f}"
            + (
                f" process CPU: {proc:.2f}x"
                if (proc := _proc_ratio(runs, label)) is not None
                else ""
            )
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
