"""Env speed against Explore-Bench's grid env, side by side in one run.

    git clone https://github.com/efc-robot/Explore-Bench /tmp/explore-bench
    git -C /tmp/explore-bench checkout ce3b98a09bf593b0716b26555dc4cccbd9e83cd3
    nice -n 5 python studies/speed_vs_explore_bench.py --explore-bench /tmp/explore-bench

Explore-Bench is not vendored, installed or modified: the script imports one module of the
checkout, the grid env its DRL training uses (``onpolicy/onpolicy/envs/GridEnv/GridEnv.py``, with
its sibling ``Astar.py``), built as its training script builds it (``train_grid.py``:
``GridEnv(0.1, 3, num_agents, 100)``: 0.1 m/cell, 3 m sensor range) on the 250 x 250 room map
it ships (``datasets/room1_modified.pgm``, 0.1 m/cell). Written and measured against commit
``ce3b98a`` (2024-02-28, the newest of the repository we found); other commits may work.

**What one step is, on each side.** Ours: ``parallel_env(world="symmetric_office_coarse",
max_range_m=3.0)`` (250 x 250 cells at 0.1 m, 2 robots, 360 beams, 3 m), merging on (the
default ``semantic`` merger) and off (``merger=None``), each robot one random action (0.125 m
forward or a 22.5 degree turn) followed by its lidar scan, map update, merging and observations.
Theirs: ``GridEnv.step(goals)`` where each robot's goal is a random free 8-neighbour of its
cell (drawn from its ground-truth map, outside the timing), so each robot moves one cell (0.1 m)
along an A* path of two cells and takes one 360 degree scan (its ``step`` scans at every third
pose of the path and at the last one): the cheapest step their env has, so the ratio is the
least favourable to us. (In their training loop a step is a macro action, a policy goal turned
into a frontier by ``get_short_term_goal`` and driven to, which costs more per step.) Their
env unions the robots' maps with known poses; ours merges by map matching (merging on) or not
at all (off). Episodes are reset outside the timing: ours when the env says so, theirs when it
says done or after 20 steps, the episode length of their training script (``train_grid.sh``:
``--max_steps 20``), so their rounds sample several random start cells (a step's cost depends
on the free space around the robots).

**How it is timed.** CPU time of the stepping thread (``time.thread_time``) around each
``step`` call, summed per round; steps/s = steps / that time. Rounds alternate the order of the
sides (theirs, ours merging on, ours merging off, then the reverse), so a change of the
machine's load hits every side alike; the printed figures are medians over rounds, and each
ratio is the median of the per-round ratios. CPU time of the whole process (all threads) is
printed beside it: our merge attempts run in a worker thread (``merge_latency_steps``), whose
time the stepping thread's clock does not count. Warm-up steps (numba compiles our kernels on
first use) are not timed.

**Shims** (all in :func:`load_grid_env` and :func:`make_theirs`, nothing written to the
checkout): the module is imported under a private package name so that
``onpolicy/__init__.py`` and ``onpolicy/envs/__init__.py`` (which import ``absl`` and set flags)
do not run; its ``window`` module (matplotlib display, which calls ``sys.exit`` when matplotlib
is missing) is replaced by a no-op ``Window``, never used without ``visualization=True``;
``gym`` (the old OpenAI package, not installable beside our pins) is served by ``gymnasium``
for the two names it uses (``gym.Env``, ``gym.spaces.Box/Dict``) unless ``gym`` is installed;
and ``reset()``, which lists a hard-coded ``/home/nics/...`` folder and picks a map at random,
sees the checkout's ``datasets/`` folder holding only the room map (the module's ``os`` name is
swapped for an object answering ``listdir`` and ``path.join``, the only two calls it makes).
Their ``step`` runs unmodified. Their randomness (start cells, headings) comes from Python's
``random``, seeded with ``--seed``.
"""

from __future__ import annotations

import argparse
import importlib
import json
import os
import statistics
import subprocess
import sys
import time
import types
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

HERE = Path(__file__).resolve().parent.parent

#: The Explore-Bench commit this script was written and measured against.
EB_COMMIT = "ce3b98a09bf593b0716b26555dc4cccbd9e83cd3"
EB_URL = "https://github.com/efc-robot/Explore-Bench"
#: The grid env module and the map, relative to the checkout's top folder.
GRID_ENV_DIR = Path("onpolicy/onpolicy/envs/GridEnv")
ROOM_MAP = "room1_modified.pgm"
#: Their training script's settings: GridEnv(0.1, 3, num_agents, 100).
EB_RESOLUTION_M = 0.1
EB_RANGE_M = 3.0
EB_MAX_STEPS = 100
#: Their training episodes: train_grid.sh runs --max_steps 20 steps per episode, then resets.
EB_EPISODE_STEPS = 20
N_ROBOTS = 2
PACKAGE = "_explore_bench_gridenv"
THEIRS = "Explore-Bench grid env"


class BenchError(Exception):
    """A problem the user can fix (bad path, failed import): printed without a traceback."""


HOW_TO_GET = (
    f"get a checkout with: git clone {EB_URL} <dir> && git -C <dir> checkout {EB_COMMIT[:7]}"
)


def find_grid_env(root: str | Path) -> Path:
    """The grid env folder of an Explore-Bench checkout at ``root``; :class:`BenchError` if the
    path is not one."""
    top = Path(root).expanduser()
    if not top.is_dir():
        raise BenchError(f"--explore-bench {root}: no such folder; {HOW_TO_GET}")
    folder = top / GRID_ENV_DIR
    missing = [
        str(GRID_ENV_DIR / name)
        for name in ("GridEnv.py", "Astar.py", f"datasets/{ROOM_MAP}")
        if not (folder / name).is_file()
    ]
    if missing:
        raise BenchError(
            f"--explore-bench {root}: not an Explore-Bench checkout (missing "
            f"{', '.join(missing)}); {HOW_TO_GET}"
        )
    return folder


def checkout_commit(root: str | Path) -> str:
    """The checkout's commit (``git rev-parse HEAD``), or ``"unknown"``."""
    try:
        out = subprocess.run(
            ["git", "-C", str(root), "rev-parse", "HEAD"],
            capture_output=True,
            text=True,
            timeout=10,
            check=True,
        )
        return out.stdout.strip() or "unknown"
    except (OSError, subprocess.SubprocessError):
        return "unknown"


class _NoWindow:
    """Stands in for their matplotlib ``Window`` (only built with ``visualization=True``)."""

    def __init__(self, *args: Any, **kwargs: Any) -> None:
        pass

    def __getattr__(self, name: str) -> Callable[..., None]:
        return lambda *args, **kwargs: None


def _gym_shim() -> types.ModuleType:
    """A ``gym`` module made of gymnasium's ``Env`` and ``spaces`` (what their module uses)."""
    import gymnasium

    gym = types.ModuleType("gym")
    gym.Env = gymnasium.Env  # type: ignore[attr-defined]
    gym.spaces = gymnasium.spaces  # type: ignore[attr-defined]
    return gym


def load_grid_env(folder: Path) -> types.ModuleType:
    """Import ``GridEnv.py`` from ``folder`` with the shims of the module doc; the module.

    Raises:
        BenchError: the import failed (its error is in the message).
    """
    pkg = types.ModuleType(PACKAGE)
    pkg.__path__ = [str(folder)]
    window = types.ModuleType(f"{PACKAGE}.window")
    window.Window = _NoWindow  # type: ignore[attr-defined]
    added = {PACKAGE: pkg, f"{PACKAGE}.window": window}
    try:
        importlib.import_module("gym")
    except ImportError:
        added["gym"] = _gym_shim()
    for name in [n for n in sys.modules if n == PACKAGE or n.startswith(PACKAGE + ".")]:
        del sys.modules[name]
    sys.modules.update(added)
    try:
        module = importlib.import_module(f"{PACKAGE}.GridEnv")
    except (Exception, SystemExit) as e:  # their window.py exits on a missing package
        raise BenchError(
            f"importing Explore-Bench's grid env ({folder / 'GridEnv.py'}) failed: "
            f"{type(e).__name__}: {e}"
        ) from None
    finally:
        if "gym" in added:
            del sys.modules["gym"]  # their module keeps its reference; no global alias left
    if not hasattr(module, "GridEnv"):
        raise BenchError(f"{folder / 'GridEnv.py'} defines no GridEnv class; {HOW_TO_GET}")
    # reset() picks a random map from a hard-coded folder: show it the room map only
    datasets = folder / "datasets"
    module.os = types.SimpleNamespace(  # type: ignore[attr-defined]
        listdir=lambda _path: [ROOM_MAP],
        path=types.SimpleNamespace(join=lambda _path, name: str(datasets / name)),
    )
    return module


@dataclass
class Side:
    """One contestant: ``next_action()`` (untimed: draws an action, resets a finished episode)
    and ``step(action)`` (timed)."""

    name: str
    next_action: Callable[[], Any]
    step: Callable[[Any], Any]
    steps_per_round: int


_NEIGHBOURS = [(-1, -1), (-1, 0), (-1, 1), (0, -1), (0, 1), (1, -1), (1, 0), (1, 1)]


def make_theirs(module: types.ModuleType, seed: int, steps: int) -> Side:
    """Their env as their training builds it, on the room map; random one-cell goals."""
    import random

    import numpy as np

    random.seed(seed)  # their start cells and headings
    rng = np.random.default_rng(seed)
    try:
        env = module.GridEnv(EB_RESOLUTION_M, EB_RANGE_M, N_ROBOTS, EB_MAX_STEPS)
        env.reset()
    except Exception as e:
        raise BenchError(
            f"building Explore-Bench's grid env failed: {type(e).__name__}: {e}"
        ) from None
    state = {"t": 0}

    def goals() -> list[list[int]] | None:
        out = []
        for x, y in env.agent_pos:
            free = [
                [x + dx, y + dy]
                for dx, dy in _NEIGHBOURS
                if 0 <= x + dx < env.gt_map.shape[0]
                and 0 <= y + dy < env.gt_map.shape[1]
                and env.gt_map[x + dx, y + dy] == 254
            ]
            if not free:
                return None
            out.append(free[int(rng.integers(len(free)))])
        return out

    def next_action() -> list[list[int]]:
        while True:
            if state["t"] >= EB_EPISODE_STEPS:
                env.reset()
                state["t"] = 0
            g = goals()
            if g is not None:
                state["t"] += 1
                return g
            state["t"] = EB_EPISODE_STEPS  # a robot boxed in on a lone free cell: new episode

    def step(action: list[list[int]]) -> None:
        _, _, dones, _ = env.step(action)
        if bool(np.any(dones)):
            state["t"] = EB_EPISODE_STEPS

    return Side(THEIRS, next_action, step, steps)


def make_ours(merger: str | None, seed: int, steps: int) -> Side:
    """Our env at Explore-Bench's settings (``EXPLORE_BENCH_WORLD``), 2 robots, random actions."""
    import numpy as np

    if str(HERE) not in sys.path:
        sys.path.insert(0, str(HERE))
    import mrexplore
    from mrexplore.studies.env_bench import EXPLORE_BENCH_WORLD

    penv = mrexplore.parallel_env(**EXPLORE_BENCH_WORLD, n_robots=N_ROBOTS, merger=merger)
    rng = np.random.default_rng(seed)
    penv.reset(seed=seed)
    n_act = int(penv.action_space(penv.possible_agents[0]).n)

    def next_action() -> dict[str, int]:
        if not penv.agents:
            penv.reset()
        return {a: int(rng.integers(n_act)) for a in penv.agents}

    name = f"mrexplore, merging {'on (' + merger + ')' if merger else 'off'}"
    return Side(name, next_action, penv.step, steps)


def run_round(
    side: Side,
    clock: Callable[[], float] = time.thread_time,
    proc_clock: Callable[[], float] = time.process_time,
) -> tuple[float, float]:
    """Step ``side`` ``steps_per_round`` times; (CPU s of the stepping thread, of the process)
    spent inside ``step`` only."""
    thread = proc = 0.0
    for _ in range(side.steps_per_round):
        action = side.next_action()
        p0 = proc_clock()
        t0 = clock()
        side.step(action)
        thread += clock() - t0
        proc += proc_clock() - p0
    return thread, proc


def alternate(
    sides: Sequence[Side],
    rounds: int,
    clock: Callable[[], float] = time.thread_time,
    proc_clock: Callable[[], float] = time.process_time,
    log: Callable[[str], None] | None = None,
) -> dict[str, dict[str, list[float]]]:
    """Run every side once per round, the order reversed every other round; per side the
    steps/s of each round by the stepping thread's (``thread``) and the process's (``process``)
    CPU time, in round order."""
    out: dict[str, dict[str, list[float]]] = {s.name: {"thread": [], "process": []} for s in sides}
    for k in range(rounds):
        order = list(sides) if k % 2 == 0 else list(reversed(sides))
        for side in order:
            thread, proc = run_round(side, clock, proc_clock)
            n = side.steps_per_round
            out[side.name]["thread"].append(n / thread if thread > 0 else float("inf"))
            out[side.name]["process"].append(n / proc if proc > 0 else float("inf"))
        if log is not None:
            log(
                f"round {k + 1}/{rounds} ({' -> '.join(s.name for s in order)}): "
                + ", ".join(f"{s.name} {out[s.name]['thread'][-1]:.1f}" for s in sides)
                + " steps/s"
            )
    return out


def summarize(
    rates: dict[str, dict[str, list[float]]], reference: str
) -> dict[str, dict[str, float]]:
    """Per side: median steps/s over rounds (thread and process CPU) and the median over rounds
    of the per-round ratio to ``reference``."""
    ref = rates[reference]
    out = {}
    for name, r in rates.items():
        out[name] = {
            "steps_per_s": statistics.median(r["thread"]),
            "ms_per_step": 1000.0 / statistics.median(r["thread"]),
            "steps_per_process_cpu_s": statistics.median(r["process"]),
            "ratio": statistics.median(
                a / b for a, b in zip(r["thread"], ref["thread"], strict=True)
            ),
            "ratio_process_cpu": statistics.median(
                a / b for a, b in zip(r["process"], ref["process"], strict=True)
            ),
        }
    return out


def _positive(text: str) -> int:
    v = int(text)
    if v < 1:
        raise argparse.ArgumentTypeError(f"must be an integer >= 1, got {text}")
    return v


def main(argv: Sequence[str] | None = None) -> int:
    """Measure both envs in alternating rounds and print steps/s and the ratios."""
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--explore-bench", required=True, help="top folder of an Explore-Bench checkout")
    p.add_argument("--rounds", type=_positive, default=7, help="alternating rounds (default 7)")
    p.add_argument("--their-steps", type=_positive, default=20, help="their steps per round")
    p.add_argument("--our-steps", type=_positive, default=600, help="our steps per round and side")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--json", default=None, help="also write the figures to this JSON file")
    p.add_argument("--force", action="store_true", help="replace an existing --json file")
    args = p.parse_args(argv)
    prog = "speed_vs_explore_bench"
    if str(HERE) not in sys.path:
        sys.path.insert(0, str(HERE))
    from mrexplore.errors import MrexploreError
    from mrexplore.io_safety import check_outputs, write_text

    try:
        if args.json:
            check_outputs([args.json], force=args.force, what=prog)
        folder = find_grid_env(args.explore_bench)
        module = load_grid_env(folder)
        commit = checkout_commit(args.explore_bench)
        theirs = make_theirs(module, args.seed, args.their_steps)
        sides = [
            theirs,
            make_ours("semantic", args.seed, args.our_steps),
            make_ours(None, args.seed, args.our_steps),
        ]
    except (BenchError, MrexploreError) as e:
        print(f"{prog}: error: {e}", file=sys.stderr)
        return 2
    load = os.getloadavg()
    print(
        f"{prog}: {THEIRS} (Explore-Bench {commit}, {GRID_ENV_DIR}/GridEnv.py, "
        f"{ROOM_MAP} 250 x 250 at {EB_RESOLUTION_M} m, {EB_RANGE_M:g} m range, one-cell goals) "
        f"vs mrexplore (symmetric_office_coarse 250 x 250 at 0.1 m, 3 m, 360 beams); "
        f"{N_ROBOTS} robots, random actions, seed {args.seed}; {args.rounds} alternating rounds "
        f"of {args.their_steps} / {args.our_steps} steps; CPU time of the stepping thread; "
        f"load average {load[0]:.2f} {load[1]:.2f} {load[2]:.2f} on {os.cpu_count()} cores",
        flush=True,
    )
    for side in sides:  # warm-up, not timed (numba compiles our kernels on first use)
        for _ in range(2 if side is theirs else 30):
            side.step(side.next_action())
    rates = alternate(sides, args.rounds, log=lambda s: print(s, flush=True))
    summary = summarize(rates, THEIRS)
    print(
        f"{'side (medians over rounds)':<40} {'steps/s':>9} {'ms/step':>9} {'ratio':>8} "
        f"{'st/proc-s':>10} {'ratio proc':>10}"
    )
    for name, s in summary.items():
        print(
            f"{name:<40} {s['steps_per_s']:>9.1f} {s['ms_per_step']:>9.3f} "
            f"{s['ratio']:>7.1f}x {s['steps_per_process_cpu_s']:>10.1f} "
            f"{s['ratio_process_cpu']:>9.1f}x"
        )
    load = os.getloadavg()
    print(f"load average after: {load[0]:.2f} {load[1]:.2f} {load[2]:.2f}")
    if args.json:
        write_text(
            args.json,
            json.dumps(
                {
                    "explore_bench_commit": commit,
                    "seed": args.seed,
                    "rounds": args.rounds,
                    "steps_per_round": {s.name: s.steps_per_round for s in sides},
                    "per_round_steps_per_s": rates,
                    "summary": summary,
                },
                indent=2,
            ),
        )
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
