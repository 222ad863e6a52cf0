"""The single- versus multi-robot task-time experiment (the seed paper's headline result).

For each seed, the single-robot and the two-robot episode start ``robot_0`` at the same place
(same world, same seed), for the exploration task and for the navigation task. Task times are
simulated seconds. Writes ``task_time.json``, ``task_time.csv`` and ``task_time.png`` and prints a
table like the paper's.
"""

from __future__ import annotations

import csv
import json
import math
import statistics
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from tqdm import tqdm

from mrexplore.environment.view import RobotView
from mrexplore.errors import ConfigError
from mrexplore.experiments.episode import EpisodeResult, run_episode

#: The seed paper's figures (Durdu & Korkmaz 2019, section 4): seconds.
PAPER = {"explore": {"single": 105.0, "multi": 65.0}, "navigate": {"single": 125.0, "multi": 85.0}}
TASKS = ("explore", "navigate")


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
        from mrexplore.experiments.trained import TrainedTeamPolicy

        team: Any = TrainedTeamPolicy.load(policy, agents)
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


def run_task_time(
    world: str = "symmetric_office",
    seeds: int = 20,
    policy: str = "coordinated-frontier",
    out: str | Path = "results",
    first_seed: int = 0,
    tasks: Sequence[str] = TASKS,
    env_options: Mapping[str, Any] | None = None,
    progress: bool = True,
    nav_warmup_s: float = 120.0,
) -> dict[str, Any]:
    """Run the experiment and write the result files; returns the JSON document.

    Navigation episodes first explore for ``nav_warmup_s`` (the same for one robot and for the
    team), then ``robot_0`` gets a goal at least 10 m away; its task time counts from then.
    """
    if seeds < 1:
        raise ConfigError(f"task-time needs at least 1 seed, got {seeds}")
    unknown = sorted(set(tasks) - set(TASKS))
    if unknown:
        raise ConfigError(f"unknown task(s) {unknown}; tasks are {list(TASKS)}")
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    base = {"world": world, **dict(env_options or {})}
    if Path(policy).is_dir():
        from mrexplore.experiments.trained import observation_options

        # A trained policy sees the observations it was trained on.
        base.update(observation_options(policy))
    runs: dict[str, dict[str, list[EpisodeResult]]] = {
        t: {"single": [], "multi": []} for t in tasks
    }
    seed_list = list(range(first_seed, first_seed + seeds))
    total = len(seed_list) * len(tasks) * 2
    bar = tqdm(total=total, desc="task-time episodes", disable=not progress, unit="ep")
    for task in tasks:
        for team_name, n in (("single", 1), ("multi", 2)):
            for seed in seed_list:
                opts = {**base, "n_robots": n, "task": task}
                if task == "navigate":
                    opts.setdefault("nav_warmup_s", nav_warmup_s)
                agents = [f"robot_{i}" for i in range(n)]
                team = make_team(policy, agents, task)
                runs[task][team_name].append(run_episode(opts, team, seed))
                bar.update(1)
    bar.close()
    doc = _document(runs, world, policy, seed_list, base)
    doc["nav_warmup_s"] = nav_warmup_s
    (out / "task_time.json").write_text(json.dumps(doc, indent=2, allow_nan=False))
    _write_csv(out / "task_time.csv", runs, seed_list)
    try:
        _plot(out / "task_time.png", runs, doc)
    except ImportError as exc:
        print(f"(no plot: {exc}; install the 'plot' extra: pip install 'mrexplore[plot]')")
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
