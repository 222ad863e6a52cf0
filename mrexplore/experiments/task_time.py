"""The single- versus multi-robot task-time experiment (the seed paper's headline result).

For each seed, the single-robot and the two-robot episode start ``robot_0`` at the same place
(same world, same seed), for the exploration task and for the navigation task. Task times are
simulated seconds. Writes ``task_time.json``, ``task_time.csv`` and ``task_time.png`` and prints a
table like the paper's.

Size: the experiment (serial or on Ray), its table, CSV, JSON and plot in one place, so the
paper's figure regenerates from one command.
"""

from __future__ import annotations

import csv
import json
import logging
import math
import statistics
from collections.abc import Iterator, Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

import mrexplore
from mrexplore.errors import ConfigError, OutputExistsError
from mrexplore.experiments.episode import EpisodeResult, run_episode
from mrexplore.io_safety import atomic_path, check_out_dir, check_outputs, write_text
from mrexplore.options import integer_argument
from mrexplore.types import RobotView

#: The seed paper's figures (Durdu & Korkmaz 2019, section 4): seconds.
PAPER = {"explore": {"single": 105.0, "multi": 65.0}, "navigate": {"single": 125.0, "multi": 85.0}}
TASKS = ("explore", "navigate")
#: Seconds the team explores before robot_0 is given its navigation goal.
NAV_WARMUP_S = 120.0


class NavigateTeam:
    """Navigation task team. Until ``robot_0`` has its goal (the warm-up), everybody explores with
    the exploration team policy; then ``robot_0`` drives to its goal while teammates keep
    exploring, so their (merged) maps show robot_0 the way through space it has not seen."""

    def __init__(self, agents: Sequence[str], explore_team: Any, goal_policy: Any) -> None:
        self.agents = list(agents)
        self.explore_team = explore_team
        self.goal_policy = goal_policy

    def reset(self, rng: np.random.Generator) -> None:
        self.explore_team.reset(rng)
        self.goal_policy.reset(rng)

    def act(self, views: Mapping[str, RobotView]) -> dict[str, int]:
        lead = self.agents[0]
        if lead not in views or views[lead].goal_cell is None:
            return dict(self.explore_team.act(views))
        actions: dict[str, int] = {}
        others = {a: v for a, v in views.items() if a != lead}
        if others:
            actions.update(self.explore_team.act(others))
        actions[lead] = int(self.goal_policy.act(views[lead]))
        return actions


def make_team(policy: str, agents: Sequence[str], task: str) -> Any:
    """A team policy by name (``mrexplore.policies.POLICIES``) or a trained policy folder."""
    from mrexplore.policies import GoalPolicy, make_team_policy

    if Path(policy).is_dir():
        from mrexplore.experiments.trained import load_team_policy

        team: Any = load_team_policy(policy, agents)
    else:
        team = make_team_policy(policy, list(agents))
    if task == "navigate":
        return NavigateTeam(agents, team, GoalPolicy())
    return team


def _stats(xs: Sequence[float]) -> dict[str, float]:
    return {
        "mean": float(statistics.fmean(xs)) if xs else 0.0,
        "std": float(statistics.pstdev(xs)) if len(xs) > 1 else 0.0,
    }


EPISODE_LOG = "episodes.jsonl"
RESULT_FILES = ("task_time.json", "task_time.csv", "task_time.png")


def _episode_to_json(r: EpisodeResult) -> dict[str, Any]:
    return {**r.summary(), "times_s": r.times_s, "coverages": r.coverages}


def _episode_from_json(d: Mapping[str, Any]) -> EpisodeResult:
    return EpisodeResult(
        task_time_s=float(d["task_time_s"]),
        success=bool(d["success"]),
        coverage=float(d["coverage"]),
        times_s=[float(x) for x in d["times_s"]],
        coverages=[float(x) for x in d["coverages"]],
        first_merge_time_s=d["first_merge_time_s"],
        merge_error=d["merge_error"],
        collisions=int(d["collisions"]),
        # the map-accuracy fields too, so a resumed (or Ray) run writes what a serial one does
        max_fused_contradiction=(
            math.nan if d.get("max_fused_contradiction") is None else d["max_fused_contradiction"]
        ),
        merged_wrongly_s=float(d.get("merged_wrongly_s", 0.0)),
        wrong_merge=bool(d.get("wrong_merge", False)),
    )


def _load_log(path: Path, settings: Mapping[str, Any], force: bool) -> dict[str, EpisodeResult]:
    """Episodes finished by an earlier run with the same settings (``task/team/seed`` -> result).

    A log written with other settings is refused without ``force`` (and then started over)."""
    if not path.is_file():
        return {}
    lines = path.read_text().splitlines()
    try:
        head = json.loads(lines[0]) if lines else {}
    except ValueError:
        head = {}
    if force:
        path.unlink()  # --force means a fresh run: no episode of an earlier run is reused
        return {}
    if head.get("settings") != json.loads(json.dumps(settings, default=str)):
        if not force:
            raise OutputExistsError(
                f"task-time: {path} holds episodes of a run with other settings; choose another "
                "--out or pass --force to start over"
            )
        path.unlink()
        return {}
    done: dict[str, EpisodeResult] = {}
    for line in lines[1:]:
        try:
            rec = json.loads(line)
            done[rec["key"]] = _episode_from_json(rec["result"])
        except (ValueError, KeyError, TypeError):
            continue  # a line cut by an interruption: that episode runs again
    return done


#: One episode of the experiment: (task, team name, seed, env options).
Job = tuple[str, str, int, dict[str, Any]]


def run_job(policy: str, job: Job) -> EpisodeResult:
    """Run one episode of the experiment (a fresh team policy; the same in every process)."""
    task, _, seed, opts = job
    n = int(opts["n_robots"])
    team = make_team(policy, [f"robot_{i}" for i in range(n)], task)
    return run_episode(opts, team, seed)


def _for_workers(policy: str, job: Job) -> tuple[str, Job]:
    """Paths made absolute: a Ray worker need not start in the driver's folder."""
    task, team_name, seed, opts = job
    opts = dict(opts)
    if isinstance(opts.get("world"), str) and Path(opts["world"]).is_file():
        opts["world"] = str(Path(opts["world"]).resolve())
    if Path(policy).is_dir():
        policy = str(Path(policy).resolve())
    return policy, (task, team_name, seed, opts)


def _ray_results(
    policy: str, jobs: Sequence[Job], workers: int, address: str | None
) -> Iterator[tuple[Job, EpisodeResult]]:
    """Run ``jobs`` as Ray tasks (one CPU each), at most ``workers`` in flight, and yield each
    result as it completes. Starts local Ray with ``workers`` CPUs when ``address`` is None and
    Ray is not running, else joins the cluster at ``address``; shuts down only what it started."""
    try:
        import ray
    except ImportError as exc:
        raise ConfigError(
            "task-time --workers/--address needs Ray: pip install 'mrexplore[rllib]'"
        ) from exc
    started = not ray.is_initialized()
    if started:
        if address is None:
            ray.init(num_cpus=workers, include_dashboard=False, logging_level=logging.WARNING)
        else:
            ray.init(address=address, logging_level=logging.WARNING)
    remote = ray.remote(num_cpus=1)(run_job)
    pending: dict[Any, Job] = {}
    queue = iter(jobs)
    try:
        while True:
            # Ray schedules the tasks; this only bounds how many wait in its queue at once.
            for job in queue:
                p, remote_job = _for_workers(policy, job)
                pending[remote.remote(p, remote_job)] = job
                if len(pending) >= workers:
                    break
            if not pending:
                return
            ready, _ = ray.wait(list(pending), num_returns=1)
            for ref in ready:
                yield pending.pop(ref), ray.get(ref)
    finally:
        for ref in pending:
            ray.cancel(ref)
        if started:
            ray.shutdown()


def run_task_time(
    world: str = "symmetric_office",
    seeds: int = 20,
    policy: str = "coordinated-frontier",
    out: str | Path = "results",
    first_seed: int = 0,
    tasks: Sequence[str] = TASKS,
    env_options: Mapping[str, Any] | None = None,
    progress: bool = True,
    nav_warmup_s: float = NAV_WARMUP_S,
    force: bool = False,
    workers: int = 1,
    address: str | None = None,
) -> dict[str, Any]:
    """Run the experiment and write the result files; returns the JSON document.

    ``workers > 1`` or an ``address`` runs the episodes as Ray tasks (local Ray with ``workers``
    CPUs, or the cluster at ``address``, e.g. ``"auto"`` or ``"HEAD_IP:6379"``), at most
    ``workers`` at a time; every episode depends only on its seed and settings, so the results
    are those of the serial run.

    Navigation episodes first explore for ``nav_warmup_s`` (the same for one robot and for the
    team), then ``robot_0`` gets a goal at least 10 m away; its task time counts from then.

    Every argument (numbers, tasks, policy, world, env options) is checked before the first
    episode. Finished episodes are appended to ``<out>/episodes.jsonl`` as they complete; a rerun
    with the same settings skips them (resume after an interruption); the log is removed once
    the results are written. Earlier results (``task_time.json/.csv/.png``) are not replaced
    without ``force``, and ``force`` starts over (no episode of an earlier run is reused).

    Raises:
        ConfigError: a bad argument.
        OutputExistsError: ``out`` is a file, or holds results (or another run's episodes) and
            ``force`` is False.
    """
    seeds = integer_argument("task-time", "seeds", seeds, 1)
    first_seed = integer_argument("task-time", "first_seed", first_seed, 0)
    workers = integer_argument("task-time", "workers", workers, 1)
    if address is not None and (not isinstance(address, str) or not address.strip()):
        raise ConfigError(f"task-time: address must be a Ray address like 'auto', got {address!r}")
    unknown = sorted(set(tasks) - set(TASKS))
    if unknown or not tasks:
        raise ConfigError(f"unknown task(s) {unknown}; tasks are {list(TASKS)}")
    if isinstance(nav_warmup_s, bool) or not isinstance(nav_warmup_s, (int, float)):
        raise ConfigError(f"task-time: nav_warmup_s must be a number, got {nav_warmup_s!r}")
    out = check_out_dir(out, force=True, what="mrexplore task-time")
    check_outputs([out / f for f in RESULT_FILES], force=force, what="mrexplore task-time")
    base = {"world": world, **dict(env_options or {})}
    if Path(policy).is_dir():
        from mrexplore.experiments.trained import observation_options

        # A trained policy sees the observations it was trained on.
        base.update(observation_options(policy))
        if "navigate" in tasks:
            # Navigation drives robot_0 with the goal policy on RobotViews, which a policy
            # acting on observations (and, goal-level, on its own env) cannot share a step with.
            tasks = tuple(t for t in tasks if t != "navigate")
            if not tasks:
                raise ConfigError("task-time: a trained policy folder runs the explore task only")
            print("task-time: a trained policy explores only; the navigate task is skipped")
    seed_list = list(range(first_seed, first_seed + seeds))
    jobs: list[Job] = []
    for task in tasks:
        for team_name, n in (("single", 1), ("multi", 2)):
            opts = {**base, "n_robots": n, "task": task}
            if task == "navigate":
                opts.setdefault("nav_warmup_s", nav_warmup_s)
            # Build the env and the team once now: a bad option fails before any episode runs.
            mrexplore.parallel_env(**opts).close()
            make_team(policy, [f"robot_{i}" for i in range(n)], task)
            jobs += [(task, team_name, seed, opts) for seed in seed_list]
    settings = {
        "world": world,
        "policy": policy,
        "options": {k: v for k, v in base.items() if k != "world"},
        "nav_warmup_s": nav_warmup_s,
    }
    out.mkdir(parents=True, exist_ok=True)
    log_path = out / EPISODE_LOG
    done = _load_log(log_path, settings, force)
    if not log_path.is_file():
        write_text(log_path, json.dumps({"settings": settings}, default=str) + "\n")
    runs: dict[str, dict[str, list[EpisodeResult]]] = {
        t: {"single": [], "multi": []} for t in tasks
    }
    todo = sum(f"{t}/{m}/{s}" not in done for t, m, s, _ in jobs)
    if progress and todo < len(jobs):
        print(f"resuming from {log_path}: {len(jobs) - todo} of {len(jobs)} episodes done")
    bar = tqdm(total=len(jobs), desc="task-time episodes", disable=not progress, unit="ep")
    bar.update(len(jobs) - todo)
    missing = [j for j in jobs if f"{j[0]}/{j[1]}/{j[2]}" not in done]
    results: Iterator[tuple[Job, EpisodeResult]]
    if workers > 1 or address is not None:
        results = _ray_results(policy, missing, workers, address)
    else:
        results = ((job, run_job(policy, job)) for job in missing)
    with log_path.open("a") as log:
        for job, result in results:  # in the order they finish
            key = f"{job[0]}/{job[1]}/{job[2]}"
            done[key] = result
            log.write(json.dumps({"key": key, "result": _episode_to_json(result)}) + "\n")
            log.flush()
            bar.update(1)
    bar.close()
    for task, team_name, seed, _ in jobs:  # in seed order, however they ran
        runs[task][team_name].append(done[f"{task}/{team_name}/{seed}"])
    doc = _document(runs, world, policy, seed_list, base)
    doc["nav_warmup_s"] = nav_warmup_s
    write_text(out / "task_time.json", json.dumps(doc, indent=2, allow_nan=False))
    with atomic_path(out / "task_time.csv") as tmp:
        _write_csv(tmp, runs, seed_list)
    try:
        with atomic_path(out / "task_time.png") as tmp:
            _plot(tmp, runs, doc)
    except ImportError as exc:
        print(f"(no plot: {exc}; install the 'plot' extra: pip install 'mrexplore[plot]')")
    log_path.unlink()  # complete: the results hold every episode
    print(format_table(doc))
    return doc


def _document(
    runs: Mapping[str, Mapping[str, list[EpisodeResult]]],
    world: str,
    policy: str,
    seed_list: list[int],
    options: Mapping[str, Any],
) -> dict[str, Any]:
    doc: dict[str, Any] = {
        "world": world,
        "policy": policy,
        "seeds": seed_list,
        "options": {
            k: v for k, v in options.items() if isinstance(v, (int, float, str, bool, type(None)))
        },
        "units": "simulated seconds",
        "tasks": {},
    }
    for task, teams in runs.items():
        entry: dict[str, Any] = {}
        for team_name, results in teams.items():
            times = [r.task_time_s for r in results]
            merges = [r.first_merge_time_s for r in results if r.first_merge_time_s is not None]
            entry[team_name] = {
                "task_times_s": times,
                **_stats(times),
                "success_rate": float(np.mean([r.success for r in results])) if results else 0.0,
                "final_coverage": [r.coverage for r in results],
                "first_merge_time_s": merges,
                "collisions": [r.collisions for r in results],
                # map accuracy against the truth (evaluation only), per episode: the largest
                # share of contradicting claims in a robot's own-or-fused map (null: none),
                # and the seconds some robot held a transform >= 5 cells off
                "max_fused_contradiction": [
                    r.summary()["max_fused_contradiction"] for r in results
                ],
                "merged_wrongly_s": [r.merged_wrongly_s for r in results],
            }
        s, m = entry["single"]["mean"], entry["multi"]["mean"]
        # JSON has no NaN: a reduction that cannot be computed is null.
        entry["reduction"] = float(1.0 - m / s) if s > 0 and math.isfinite(m) else None
        entry["paper"] = PAPER.get(task)
        doc["tasks"][task] = entry
    return doc


def _write_csv(
    path: Path, runs: Mapping[str, Mapping[str, list[EpisodeResult]]], seeds: list[int]
) -> None:
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(
            [
                "task",
                "team",
                "n_robots",
                "seed",
                "task_time_s",
                "success",
                "coverage",
                "first_merge_time_s",
            ]
        )
        for task, teams in runs.items():
            for team_name, results in teams.items():
                for seed, r in zip(seeds, results, strict=False):
                    w.writerow(
                        [
                            task,
                            team_name,
                            1 if team_name == "single" else 2,
                            seed,
                            f"{r.task_time_s:.2f}",
                            int(r.success),
                            f"{r.coverage:.4f}",
                            "" if r.first_merge_time_s is None else f"{r.first_merge_time_s:.2f}",
                        ]
                    )


def _plot(
    path: Path, runs: Mapping[str, Mapping[str, list[EpisodeResult]]], doc: Mapping[str, Any]
) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(11, 4))
    if "explore" in runs:
        for team_name, colour in (("single", "tab:red"), ("multi", "tab:blue")):
            results = runs["explore"][team_name]
            if not results:
                continue
            t_end = max(r.times_s[-1] for r in results)
            grid = np.linspace(0.0, t_end, 200)
            # After an episode ends its coverage stays at its final value.
            curves = np.array([np.interp(grid, r.times_s, r.coverages) for r in results])
            mean, std = curves.mean(axis=0), curves.std(axis=0)
            label = "1 robot" if team_name == "single" else "2 robots (merged maps)"
            ax0.plot(grid, mean, color=colour, label=label)
            ax0.fill_between(
                grid, np.clip(mean - std, 0, 1), np.clip(mean + std, 0, 1), color=colour, alpha=0.2
            )
        ax0.set_xlabel("time (s)")
        ax0.set_ylabel("coverage")
        ax0.set_title("exploration: coverage vs time (mean, +-1 std)")
        ax0.legend()
    tasks = list(doc["tasks"])
    x = np.arange(len(tasks))
    for k, (team_name, colour) in enumerate((("single", "tab:red"), ("multi", "tab:blue"))):
        means = [doc["tasks"][t][team_name]["mean"] for t in tasks]
        stds = [doc["tasks"][t][team_name]["std"] for t in tasks]
        ax1.bar(
            x + (k - 0.5) * 0.35,
            means,
            0.35,
            yerr=stds,
            color=colour,
            label="1 robot" if k == 0 else "2 robots",
        )
    ax1.set_xticks(x, [f"{t}\n(-{_pct(doc['tasks'][t]['reduction'])})" for t in tasks])
    ax1.set_ylabel("task time (s)")
    ax1.set_title("task time, single vs multi")
    ax1.legend()
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _pct(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.1%}"


def format_table(doc: Mapping[str, Any]) -> str:
    """The results as a text table in the form of the paper's."""
    lines = [
        f"Task time on '{doc['world']}' with policy '{doc['policy']}' over "
        f"{len(doc['seeds'])} seeds (simulated s)",
        f"{'task':<10} {'1 robot':>16} {'2 robots':>16} {'reduction':>10} "
        f"{'success 1/2':>12} | paper 1 -> 2",
    ]
    for task, e in doc["tasks"].items():
        paper = e.get("paper") or {}
        p_txt = (
            f"{paper['single']:.0f} -> {paper['multi']:.0f} s "
            f"(-{1 - paper['multi'] / paper['single']:.0%})"
            if paper
            else "-"
        )
        lines.append(
            f"{task:<10} {e['single']['mean']:>8.1f} +- {e['single']['std']:<5.1f}"
            f"{e['multi']['mean']:>8.1f} +- {e['multi']['std']:<5.1f}"
            f"{_pct(e['reduction']):>10}"
            f"{e['single']['success_rate']:>7.0%}/{e['multi']['success_rate']:.0%} | {p_txt}"
        )
    return "\n".join(lines)
