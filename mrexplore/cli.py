"""The ``mrexplore`` command: ``demo | merge | task-time | world | bench | train | evaluate |
imitate``."""

from __future__ import annotations

import argparse
import sys
from collections.abc import Sequence

from mrexplore.errors import MrexploreError

#: What ``--world`` means, the same for every command (``train`` and ``evaluate --worlds`` too).
WORLD_HELP = (
    "a shipped world's name (e.g. symmetric_office: the same map every episode), a map YAML, "
    "or random:<generator>[?options] (a fresh world each episode, e.g. random:symmetric_office)"
)


def _demo(args: argparse.Namespace) -> int:
    from mrexplore.experiments.demo import run_demo

    run_demo(
        out=args.out,
        world=args.world,
        seed=args.seed,
        policy=args.policy,
        n_robots=args.n_robots,
        force=args.force,
    )
    return 0


def _task_time(args: argparse.Namespace) -> int:
    from mrexplore.errors import ConfigError
    from mrexplore.experiments.task_time import run_task_time

    if args.rendezvous_only and args.sighting_range_m is None:
        raise ConfigError(
            "--rendezvous-only merges only robots that saw each other: give --sighting-range-m"
        )

    run_task_time(
        world=args.world,
        seeds=args.seeds,
        policy=args.policy,
        out=args.out,
        first_seed=args.first_seed,
        tasks=args.tasks,
        env_options={
            "max_time_s": args.max_time_s,
            "nav_goal": args.nav_goal,
            **(
                {} if args.sighting_range_m is None else {"sighting_range_m": args.sighting_range_m}
            ),
            **(
                {}
                if args.rendezvous_only is None
                else {"merge_options": {"rendezvous_only": args.rendezvous_only}}
            ),
        },
        nav_warmup_s=args.nav_warmup_s,
        force=args.force,
        workers=args.workers,
        address=args.address,
    )
    return 0


def _world_check(args: argparse.Namespace) -> int:
    from mrexplore.world.check import check_map

    found = check_map(args.map, radius_m=args.radius_m, max_range_m=args.max_range_m)
    print(found.report())
    return 0 if found.ok else 1


def _merge(argv: Sequence[str]) -> int:
    from mrexplore.experiments.merge_files import main

    return int(main(list(argv)))


def _bench(argv: Sequence[str]) -> int:
    what = argv[0] if argv else ""
    rest = list(argv[1:])
    if what == "merge":
        from mrexplore.studies.merge_bench import main as merge_main

        return int(merge_main(rest))
    if what == "loop":
        from mrexplore.studies.loop_study import main as loop_main

        return int(loop_main(rest))
    if what == "env":
        from mrexplore.studies.env_bench import main as env_main

        return int(env_main(rest))
    if what == "sensor":
        from mrexplore.studies.sensor_bench import main as sensor_main

        return int(sensor_main(rest))
    if what == "policies":
        from mrexplore.studies.policy_bench import main as policies_main

        policies_main(rest)
        return 0
    if what == "wrappers":
        from mrexplore.studies.wrapper_bench import main as wrappers_main

        wrappers_main(rest)
        return 0
    usage = (
        "usage: mrexplore bench {merge,loop,env,sensor,policies,wrappers} [options]"
        "  (each takes --help)\n"
        "  merge     the merge table: method x detector on symmetric worlds and real maps\n"
        "  loop      in-loop study: merges, task time against an oracle merger, wrong merges\n"
        "  env       environment steps per second with a per-stage breakdown\n"
        "  sensor    lidar cast, own-map update and simulator step (numba or numpy path)\n"
        "  policies  planner speed and policy cost per step\n"
        "  wrappers  merge wrapper, single-robot env and SB3 adapter throughput"
    )
    if what in ("-h", "--help"):
        print(usage)
        return 0
    print(usage, file=sys.stderr)
    return 2


def _train(argv: Sequence[str]) -> int:
    from mrexplore.experiments.train import main as train_main

    return int(train_main(list(argv)))


def _imitate(argv: Sequence[str]) -> int:
    from mrexplore.experiments.imitate import main as imitate_main

    return int(imitate_main(list(argv)))


def _evaluate(argv: Sequence[str]) -> int:
    from mrexplore.experiments.evaluate import main as eval_main

    return int(eval_main(list(argv)))


def _version() -> str:
    """The installed package's version (its metadata), else the source tree's ``__version__``."""
    from importlib.metadata import PackageNotFoundError, version

    try:
        return version("mrexplore")
    except PackageNotFoundError:  # pragma: no cover - a source tree that was never installed
        from mrexplore import __version__

        return __version__


def build_parser() -> argparse.ArgumentParser:
    """The top-level parser (sub-commands with their own options)."""
    p = argparse.ArgumentParser(prog="mrexplore", description=__doc__)
    p.add_argument("--version", action="version", version=f"mrexplore {_version()}")
    sub = p.add_subparsers(dest="command", required=True)

    d = sub.add_parser(
        "demo",
        help="one two-robot episode -> demo/episode.gif, demo/final.png",
        description="Run one episode with the coordinated frontier policy and write a GIF of it "
        "and a PNG of the end and of the moment of the merge; print task time, coverage and "
        "the merge's error against the truth.",
    )
    d.add_argument("--out", default="demo", help="output folder (default: demo)")
    d.add_argument("--world", default="symmetric_office", help=WORLD_HELP)
    d.add_argument("--seed", type=int, default=0, help="episode seed (default 0)")
    d.add_argument("--policy", default="coordinated-frontier", help="team policy name")
    d.add_argument("--n-robots", type=int, default=2, help="team size (default 2)")
    d.add_argument("--force", action="store_true", help="replace an earlier demo's pictures")

    t = sub.add_parser(
        "task-time",
        help="single vs multi-robot task times (the paper's experiment)",
        description="For each seed, run the single-robot and the two-robot episode from the "
        "same start of robot_0, for exploration and navigation; write task_time.json/.csv/.png "
        "and print a table like the paper's. Each exploration episode gives two times: "
        "'observed' (the team's sensors together saw the target share of the world: the "
        "paper's measure, blind to wrong merges) and 'held' (some robot holds that share at "
        "the true place in its own-or-fused map: a wrong merge costs time, as it would a real "
        "team). Navigation ends at the goal, so it has the observed column only. Per team: "
        "episodes merged, median first merge, episodes that held a wrong merge (a transform "
        ">= 5 cells off the truth) and the seconds they held it, and the largest share of a "
        "robot's map contradicting the truth; a warning line follows the table when any "
        "episode held a wrong merge. The seed paper's figures are printed on symmetric_office "
        "only, the shipped world built like the paper's.",
    )
    t.add_argument("--world", default="symmetric_office", help=WORLD_HELP)
    t.add_argument("--seeds", type=int, default=20, help="number of seeds (default 20)")
    t.add_argument("--first-seed", type=int, default=1000, help="first seed (default 1000)")
    t.add_argument(
        "--policy",
        default="coordinated-frontier",
        help="a policy name (random, nearest-frontier, cost-frontier, coordinated-frontier, "
        "coordinated-frontier-size, coordinated-frontier-verify) or a trained policy folder",
    )
    t.add_argument("--out", default="results", help="output folder (default: results)")
    t.add_argument(
        "--tasks", nargs="+", default=["explore", "navigate"], choices=["explore", "navigate"]
    )
    t.add_argument("--max-time-s", type=float, default=600.0, help="truncation, simulated s")
    t.add_argument(
        "--sighting-range-m",
        type=float,
        default=None,
        help="robots that see each other within this many metres (no wall between) measure "
        "their relative pose, which guides and binds the merger (a rendezvous); 4.0 is "
        "recommended on floors with repeated rooms, where the maps alone merge look-alike "
        "rooms (default: off)",
    )
    t.add_argument(
        "--rendezvous-only",
        action=argparse.BooleanOptionalAction,
        default=None,
        help="with --sighting-range-m: merge a pair of robots only once they have seen each "
        "other (the maps then place them within the sighting's region): no merge of "
        "look-alike rooms before the robots meet, none for robots that never meet. On by "
        "default with sightings; --no-rendezvous-only lets the maps alone merge robots that "
        "never met",
    )
    t.add_argument(
        "--nav-warmup-s",
        type=float,
        default=120.0,
        help="navigation: seconds of exploring before robot_0 gets its goal (default 120)",
    )
    t.add_argument(
        "--nav-goal",
        choices=["far", "teammate"],
        default="far",
        help="navigation: robot_0's goal is any cell >= 10 m away (far, default) or one near "
        "robot_1's start, a place the teammate maps (teammate: the seed paper's protocol)",
    )
    t.add_argument(
        "--force",
        action="store_true",
        help="replace earlier results in --out (an interrupted run with the same settings "
        "resumes without it)",
    )
    t.add_argument(
        "--workers",
        type=int,
        default=1,
        help="episodes run at once as Ray tasks (default 1: serial, no Ray); local Ray with "
        "this many CPUs unless --address is given",
    )
    t.add_argument(
        "--address",
        default=None,
        help="join the Ray cluster at this address ('auto', or HEAD_IP:6379 of `ray start "
        "--head`) and run the episodes there",
    )

    w = sub.add_parser(
        "world",
        help="check a map before running on it: mrexplore world check MAP.yaml",
        description="Tools for worlds (map_server YAML + PGM/PNG).",
    )
    wsub = w.add_subparsers(dest="world_command", required=True)
    wc = wsub.add_parser(
        "check",
        help="report size, reachable area, disconnected parts, walls, resolution",
        description="Report a map's size (cells and metres), resolution, the free area the "
        "robots reach from the largest free component, the free parts they never reach, "
        "whether it has walls, and whether the resolution is too coarse for the robot and its "
        "lidar (the env's defaults unless given). Exit code 0 when usable, 1 with the "
        "problems named otherwise.",
    )
    wc.add_argument("map", help="the map_server YAML")
    wc.add_argument(
        "--radius-m", type=float, default=None, help="robot radius (default: the env's, 0.15)"
    )
    wc.add_argument(
        "--max-range-m", type=float, default=None, help="lidar range (default: the env's, 4.0)"
    )

    for name, helptext in (
        ("merge", "merge two map_server maps: mrexplore merge a.yaml b.yaml -o merged.yaml"),
        ("bench", "benchmarks: mrexplore bench {merge,loop,env,sensor,policies,wrappers}"),
        ("train", "train a shared policy with stable-baselines3"),
        ("evaluate", "a policy (trained folder or --team-factory) against the baselines"),
        ("imitate", "clone the goal-level keep-or-Burgard rule (a start for train --init-from)"),
    ):
        sub.add_parser(name, help=helptext, add_help=False)
    return p


def main(argv: Sequence[str] | None = None) -> int:
    """Entry point of the ``mrexplore`` command; returns the exit code."""
    argv = list(sys.argv[1:] if argv is None else argv)
    passthrough = {
        "merge": _merge,
        "bench": _bench,
        "train": _train,
        "evaluate": _evaluate,
        "imitate": _imitate,
    }
    try:
        if argv and argv[0] in passthrough:
            return passthrough[argv[0]](argv[1:])
        args = build_parser().parse_args(argv)
        if args.command == "demo":
            return _demo(args)
        if args.command == "task-time":
            return _task_time(args)
        if args.command == "world":
            return _world_check(args)
    except (MrexploreError, FileNotFoundError, IsADirectoryError, PermissionError) as exc:
        print(f"mrexplore: error: {exc}", file=sys.stderr)
        return 2
    return 2


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
