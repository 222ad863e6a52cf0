"""The single- versus multi-robot task-time experiment (the seed paper's headline result).

For each seed, the single-robot and the two-robot episode start ``robot_0`` at the same place
(same world, same seed), for the exploration task and for the navigation task. Task times are
simulated seconds. Writes ``task_time.json``, ``task_time.csv`` and ``task_time.png`` and prints a
table like the paper's.

Two exploration times come from every exploration episode (the env runs with
``coverage_mode="held"`` and :class:`CoverageClock` ends it once both are known):

- *observed*: the team's sensors together have seen ``target_coverage`` of the reachable free
  space (the env's default ``coverage_mode="observed"``): a wrong merge costs no time;
- *held*: some robot holds that share in its own-or-fused map at the true place: knowledge
  placed by a wrong merge does not count, so a wrong merge costs time, as it would a real team.

Until the observed target is reached the episode is the one an ``observed`` env would run (the
coverage mode is evaluation only: nothing of it reaches a robot). Wrong merges (a transform
>= 5 cells off the truth beyond drift, :mod:`mrexplore.environment.evaluation`) are counted over
the whole episode and shown in the table, CSV, JSON and plot.
"""

from __future__ import annotations

import csv
import json
import logging
import math
import statistics
from collections.abc import Iterator, Mapping, Sequence
from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import Any

import numpy as np
from numpy.typing import NDArray
from tqdm import tqdm

import mrexplore
from mrexplore.environment.task import Task
from mrexplore.errors import ConfigError, OutputExistsError
from mrexplore.experiments.episode import EpisodeResult, run_episode
from mrexplore.io_safety import atomic_path, check_out_dir, check_outputs, write_text
from mrexplore.options import integer_argument
from mrexplore.sim import Simulation
from mrexplore.types import RobotView

#: The seed paper's figures (Durdu & Korkmaz 2019, section 4): seconds. Measured in its own
#: simulation, on a world like :data:`PAPER_WORLD`: shown only for that world.
PAPER = {"explore": {"single": 105.0, "multi": 65.0}, "navigate": {"single": 125.0, "multi": 85.0}}
#: The shipped world built like the seed paper's (two identical rooms off one corridor, its
#: Figure 1a): the only world on which the table shows :data:`PAPER`.
PAPER_WORLD = "symmetric_office"
TASKS = ("explore", "navigate")
#: The teams of the experiment: name in the results -> number of robots.
TEAMS: dict[str, int] = {"single": 1, "multi": 2}
#: Env options the experiment sets itself (an ``env_options`` key among them is refused).
OWN_OPTIONS = ("n_robots", "task", "coverage_mode")
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


class CoverageClock(Task):
    """Exploration timed under both coverages in one episode (the env in
    ``coverage_mode="held"``, so the ``coverage`` it is handed is the held one).

    The episode ends once both the held coverage and the observed team coverage
    (:meth:`mrexplore.sim.Simulation.coverage`) have reached ``target_coverage``, or at the time
    limit. It records the simulated second each first reached the target and the observed curve
    until then: the run an ``observed`` env would have made (nothing a robot sees depends on the
    coverage mode).

    Attributes:
        observed_time_s: simulated s when the observed coverage first reached the target (None:
            not yet).
        held_time_s: the same for the held coverage.
        observed_curve: ``(time_s, observed coverage)`` from reset until ``observed_time_s``.
    """

    name = "explore"

    def __init__(self) -> None:
        super().__init__()
        self.observed_time_s: float | None = None
        self.held_time_s: float | None = None
        self.observed_curve: list[tuple[float, float]] = []

    def reset(
        self,
        sim: Simulation,
        goal_rng: np.random.Generator,
        start_rng: np.random.Generator,
        starts: NDArray[np.float64] | None,
    ) -> None:
        super().reset(sim, goal_rng, start_rng, starts)
        self.observed_time_s = None
        self.held_time_s = None
        self.observed_curve = [(float(sim.time_s), float(sim.coverage()))]

    def terminated(self, sim: Simulation, coverage: float) -> bool:
        """Done when both coverages reached ``target_coverage`` (``coverage``: the held one)."""
        target = self.config.target_coverage
        now = float(sim.time_s)
        if self.observed_time_s is None:
            observed = float(sim.coverage())
            self.observed_curve.append((now, observed))
            if observed >= target:
                self.observed_time_s = now
        if self.held_time_s is None and coverage >= target:
            self.held_time_s = now
        return self.observed_time_s is not None and self.held_time_s is not None


@dataclass
class TaskTimeEpisode(EpisodeResult):
    """One episode of the experiment: :class:`EpisodeResult` with the observed coverage's
    figures (``task_time_s``, ``success``, ``coverage``, ``times_s``, ``coverages``: what an
    ``observed`` env reports), and the held coverage's beside them. The map-accuracy fields
    (``wrong_merge``, ``merged_wrongly_s``, ``max_fused_contradiction``) cover the whole run.

    Attributes:
        held_task_time_s: simulated s until some robot held ``target_coverage`` correctly placed
            (the time limit if never); None for navigation, which ends at the goal whatever the
            coverage (a wrong merge already costs the robot that plans on it).
        held_success: the held target was reached (None for navigation).
        held_times_s, held_coverages: the held coverage curve (simulated s, share), one entry
            per simulator step; empty for navigation.
    """

    held_task_time_s: float | None = None
    held_success: bool | None = None
    held_times_s: list[float] = field(default_factory=list)
    held_coverages: list[float] = field(default_factory=list)

    @property
    def held_wrong_merge(self) -> bool:
        """Some robot held a wrong transform at some step (flag or seconds, s > 0)."""
        return self.wrong_merge or self.merged_wrongly_s > 0.0


def timed_episode(run: EpisodeResult, clock: CoverageClock | None) -> TaskTimeEpisode:
    """The experiment's record of ``run``: with ``clock`` (an exploration episode run under it),
    the observed figures from the clock and the run's curve as the held one; without, the run
    as it is (navigation)."""
    base = {f.name: getattr(run, f.name) for f in fields(EpisodeResult)}
    base.update(frames=[], merge_frame=None)
    if clock is None:
        return TaskTimeEpisode(**base)
    end_s = float(run.task_time_s)
    held_ok = clock.held_time_s is not None
    obs_ok = clock.observed_time_s is not None
    times = [t for t, _ in clock.observed_curve]
    covs = [c for _, c in clock.observed_curve]
    base.update(
        task_time_s=clock.observed_time_s if obs_ok else end_s,
        success=obs_ok,
        coverage=covs[-1] if covs else run.coverage,
        times_s=times,
        coverages=covs,
    )
    return TaskTimeEpisode(
        **base,
        held_task_time_s=clock.held_time_s if held_ok else end_s,
        held_success=held_ok,
        held_times_s=list(run.times_s),
        held_coverages=list(run.coverages),
    )


def _stats(xs: Sequence[float]) -> dict[str, float]:
    return {
        "mean": float(statistics.fmean(xs)) if xs else 0.0,
        "std": float(statistics.pstdev(xs)) if len(xs) > 1 else 0.0,
    }


EPISODE_LOG = "episodes.jsonl"
RESULT_FILES = ("task_time.json", "task_time.csv", "task_time.png")


def _episode_to_json(r: TaskTimeEpisode) -> dict[str, Any]:
    return {
        **r.summary(),
        "times_s": r.times_s,
        "coverages": r.coverages,
        "held_task_time_s": r.held_task_time_s,
        "held_success": r.held_success,
        "held_times_s": r.held_times_s,
        "held_coverages": r.held_coverages,
    }


def _episode_from_json(d: Mapping[str, Any]) -> TaskTimeEpisode:
    held_time = d.get("held_task_time_s")
    held_ok = d.get("held_success")
    return TaskTimeEpisode(
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
        merges_lost=int(d.get("merges_lost", 0)),
        held_task_time_s=None if held_time is None else float(held_time),
        held_success=None if held_ok is None else bool(held_ok),
        held_times_s=[float(x) for x in d.get("held_times_s", [])],
        held_coverages=[float(x) for x in d.get("held_coverages", [])],
    )


def _load_log(path: Path, settings: Mapping[str, Any], force: bool) -> dict[str, TaskTimeEpisode]:
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
    done: dict[str, TaskTimeEpisode] = {}
    for line in lines[1:]:
        try:
            rec = json.loads(line)
            done[rec["key"]] = _episode_from_json(rec["result"])
        except (ValueError, KeyError, TypeError):
            continue  # a line cut by an interruption: that episode runs again
    return done


#: One episode of the experiment: (task, team name, seed, env options).
Job = tuple[str, str, int, dict[str, Any]]


def run_job(policy: str, job: Job) -> TaskTimeEpisode:
    """Run one episode of the experiment (a fresh team policy; the same in every process).
    An exploration episode runs under a fresh :class:`CoverageClock` (both coverages timed)."""
    task, _, seed, opts = job
    n = int(opts["n_robots"])
    team = make_team(policy, [f"robot_{i}" for i in range(n)], task)
    clock = CoverageClock() if task == "explore" else None
    if clock is not None:
        opts = {**opts, "task": clock, "coverage_mode": "held"}
    return timed_episode(run_episode(opts, team, seed), clock)


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
) -> Iterator[tuple[Job, TaskTimeEpisode]]:
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


def _warn_map(world: Any, options: Mapping[str, Any]) -> None:
    """Print ``mrexplore world check``'s problems and notes when ``world`` is a map file."""
    if not isinstance(world, (str, Path)) or Path(world).suffix.lower() not in (".yaml", ".yml"):
        return
    if not Path(world).is_file():
        return  # the env names the missing file
    from mrexplore.world.check import warn_map

    for line in warn_map(world, options.get("radius_m"), options.get("max_range_m")):
        print(f"task-time: {world}: {line}")


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
    Exploration episodes give two task times, observed and held (see the module doc).

    ``env_options`` go to every episode's env, except :data:`OWN_OPTIONS`, which the
    experiment sets itself (refused: a ConfigError names the option).

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
    own = sorted(set(env_options or {}) & set(OWN_OPTIONS))
    if own:
        raise ConfigError(
            f"task-time: env option(s) {own} are set by the experiment itself (team sizes "
            "1 and 2, the tasks of --tasks, exploration timed under both coverage modes)"
        )
    base = {"world": world, **dict(env_options or {})}
    _warn_map(world, base)
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
        for team_name, n in TEAMS.items():
            opts = {**base, "n_robots": n, "task": task}
            if task == "navigate":
                opts.setdefault("nav_warmup_s", nav_warmup_s)
            else:
                opts["coverage_mode"] = "held"  # run_job's CoverageClock reads both
            # Build the env and the team once now: a bad option fails before any episode runs.
            mrexplore.parallel_env(**opts).close()
            make_team(policy, [f"robot_{i}" for i in range(n)], task)
            jobs += [(task, team_name, seed, opts) for seed in seed_list]
    settings = {
        "world": world,
        "policy": policy,
        "options": {k: v for k, v in base.items() if k != "world"},
        "nav_warmup_s": nav_warmup_s,
        # a log of episodes timed under the observed coverage only is not reused
        "coverage_modes": ["observed", "held"],
    }
    out.mkdir(parents=True, exist_ok=True)
    log_path = out / EPISODE_LOG
    done = _load_log(log_path, settings, force)
    if not log_path.is_file():
        write_text(log_path, json.dumps({"settings": settings}, default=str) + "\n")
    runs: dict[str, dict[str, list[TaskTimeEpisode]]] = {
        t: {team_name: [] for team_name in TEAMS} for t in tasks
    }
    todo = sum(f"{t}/{m}/{s}" not in done for t, m, s, _ in jobs)
    if progress and todo < len(jobs):
        print(f"resuming from {log_path}: {len(jobs) - todo} of {len(jobs)} episodes done")
    bar = tqdm(total=len(jobs), desc="task-time episodes", disable=not progress, unit="ep")
    bar.update(len(jobs) - todo)
    missing = [j for j in jobs if f"{j[0]}/{j[1]}/{j[2]}" not in done]
    results: Iterator[tuple[Job, TaskTimeEpisode]]
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


def is_paper_world(world: Any) -> bool:
    """Whether ``world`` is :data:`PAPER_WORLD`, by name or as the path of its shipped YAML."""
    if world == PAPER_WORLD:
        return True
    if not isinstance(world, (str, Path)) or not str(world).lower().endswith((".yaml", ".yml")):
        return False
    from mrexplore.world.registry import envs_dir

    try:
        return Path(world).resolve() == (envs_dir() / f"{PAPER_WORLD}.yaml").resolve()
    except OSError:
        return False


def team_label(n_robots: int) -> str:
    """``"1 robot"``, ``"2 robots"``, ..."""
    return f"{n_robots} robot" if n_robots == 1 else f"{n_robots} robots"


def _median(xs: Sequence[float]) -> float | None:
    return float(statistics.median(xs)) if xs else None


def _team_entry(results: Sequence[TaskTimeEpisode], n_robots: int) -> dict[str, Any]:
    """One team's figures over its episodes (simulated seconds, shares in [0, 1]; None where
    there is nothing to summarise)."""
    times = [r.task_time_s for r in results]
    merges = [r.first_merge_time_s for r in results if r.first_merge_time_s is not None]
    held = [r.held_task_time_s for r in results]
    held_times = (
        [float(t) for t in held if t is not None] if all(t is not None for t in held) else []
    )
    contradictions = [r.summary()["max_fused_contradiction"] for r in results]
    known = [float(c) for c in contradictions if c is not None]
    wrong_s = [r.merged_wrongly_s for r in results]
    return {
        "n_robots": n_robots,
        "task_times_s": times,
        **_stats(times),
        "success_rate": float(np.mean([r.success for r in results])) if results else 0.0,
        # held coverage: the share some robot holds correctly placed (null: navigation)
        "held_task_times_s": held_times if held_times else None,
        "held_mean": _stats(held_times)["mean"] if held_times else None,
        "held_std": _stats(held_times)["std"] if held_times else None,
        "held_success_rate": (
            float(np.mean([bool(r.held_success) for r in results])) if held_times else None
        ),
        "final_coverage": [r.coverage for r in results],
        "first_merge_time_s": merges,
        "merged_episodes": len(merges),
        "first_merge_median_s": _median(merges),
        "collisions": [r.collisions for r in results],
        # map accuracy against the truth (evaluation only), per episode: the largest
        # share of contradicting claims in a robot's own-or-fused map (null: none),
        # and the seconds some robot held a transform >= 5 cells off
        "max_fused_contradiction": contradictions,
        "max_fused_contradiction_max": max(known) if known else None,
        "wrong_merge": [r.held_wrong_merge for r in results],
        "wrong_merge_episodes": sum(r.held_wrong_merge for r in results),
        "merged_wrongly_s": wrong_s,
        "merged_wrongly_sum_s": float(sum(wrong_s)),
        "merged_wrongly_max_s": float(max(wrong_s, default=0.0)),
    }


def _reduction(single: float | None, multi: float | None) -> float | None:
    """``1 - multi / single`` (JSON has no NaN: None when it cannot be computed)."""
    if single is None or multi is None or not single > 0 or not math.isfinite(multi):
        return None
    return float(1.0 - multi / single)


def wrong_merge_warning(doc: Mapping[str, Any]) -> str | None:
    """One line saying how many episodes held a wrong merge and that their teams' times include
    them, and, when the teams merged from the maps alone, how to merge only robots that met;
    None when no episode held one."""
    parts: list[str] = []
    wrong = total = 0
    for task, entry in doc["tasks"].items():
        for team_name in TEAMS:
            e = entry.get(team_name)
            if not e:
                continue
            n = len(e["task_times_s"])
            total += n
            k = int(e["wrong_merge_episodes"])
            if k:
                wrong += k
                parts.append(
                    f"{task} {team_label(int(e['n_robots']))}: {k} of {n}, "
                    f"{e['merged_wrongly_sum_s']:.1f} s merged wrongly"
                )
    if not wrong:
        return None
    hint = ""
    if doc.get("merging") == merging_mode({}):  # the teams merged from the maps alone
        hint = (  # the documented path for look-alike rooms (docs/guide/merger.md)
            "; on floors with repeated rooms let the robots see each other "
            "(--sighting-range-m 4, or sighting_range_m=4.0): only robots that have met merge"
        )
    return (
        f"WARNING: {wrong} of {total} episodes held a wrong merge ({'; '.join(parts)}); "
        "those teams' task times include them (the observed time does not charge a wrong merge, "
        f"the held time does){hint}"
    )


def merging_mode(options: Mapping[str, Any]) -> str:
    """How the teams merged, in words, from the env options of the run: never, from the maps
    alone, or with sightings (only robots that have met, unless ``rendezvous_only`` is off)."""
    if "merger" in options and options["merger"] is None:
        return "none (the robots never merge)"
    sight = options.get("sighting_range_m")
    if sight is None:
        return "from the maps alone (look-alike rooms may be merged wrongly: see the wrong column)"
    rendezvous = (options.get("merge_options") or {}).get("rendezvous_only")
    if rendezvous is False:
        return (
            f"maps and sightings within {sight:g} m; the maps alone may merge robots that never "
            "met (rendezvous_only off)"
        )
    return f"only robots that have met (sightings within {sight:g} m, rendezvous_only)"


def _document(
    runs: Mapping[str, Mapping[str, Sequence[TaskTimeEpisode]]],
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
        "merging": merging_mode(options),
        "units": "simulated seconds",
        "coverage_modes": {
            "observed": "task_times_s: the team's sensors together saw target_coverage",
            "held": "held_task_times_s: some robot holds target_coverage at the true place in "
            "its own-or-fused map (a wrong merge costs time); exploration only",
        },
        "paper_world": PAPER_WORLD,
        "tasks": {},
    }
    paper = is_paper_world(world)
    for task, teams in runs.items():
        entry: dict[str, Any] = {
            team_name: _team_entry(results, TEAMS[team_name])
            for team_name, results in teams.items()
        }
        single, multi = entry["single"], entry["multi"]
        entry["reduction"] = _reduction(single["mean"], multi["mean"])
        entry["held_reduction"] = _reduction(single["held_mean"], multi["held_mean"])
        entry["paper"] = PAPER.get(task) if paper else None
        doc["tasks"][task] = entry
    doc["wrong_merge_warning"] = wrong_merge_warning(doc)
    return doc


CSV_COLUMNS = (
    "task",
    "team",
    "n_robots",
    "seed",
    "task_time_s",
    "success",
    "coverage",
    "first_merge_time_s",
    "held_task_time_s",
    "held_success",
    "wrong_merge",
    "merged_wrongly_s",
    "max_fused_contradiction",
)


def _opt(x: float | None, fmt: str) -> str:
    return "" if x is None else format(x, fmt)


def _write_csv(
    path: Path, runs: Mapping[str, Mapping[str, Sequence[TaskTimeEpisode]]], seeds: list[int]
) -> None:
    """One row per episode (:data:`CSV_COLUMNS`; empty where not defined)."""
    with path.open("w", newline="") as f:
        w = csv.writer(f)
        w.writerow(CSV_COLUMNS)
        for task, teams in runs.items():
            for team_name, results in teams.items():
                for seed, r in zip(seeds, results, strict=False):
                    c = r.summary()["max_fused_contradiction"]
                    w.writerow(
                        [
                            task,
                            team_name,
                            TEAMS[team_name],
                            seed,
                            f"{r.task_time_s:.2f}",
                            int(r.success),
                            f"{r.coverage:.4f}",
                            _opt(r.first_merge_time_s, ".2f"),
                            _opt(r.held_task_time_s, ".2f"),
                            "" if r.held_success is None else int(r.held_success),
                            int(r.held_wrong_merge),
                            f"{r.merged_wrongly_s:.2f}",
                            _opt(c, ".4f"),
                        ]
                    )


#: Colours of the teams in the plot.
_COLOURS = {"single": "tab:red", "multi": "tab:blue"}


def _plot(
    path: Path,
    runs: Mapping[str, Mapping[str, Sequence[TaskTimeEpisode]]],
    doc: Mapping[str, Any],
) -> None:
    """Coverage curves (observed solid, held dashed) and task-time bars (observed solid, held
    hatched); a team that held a wrong merge gets a red marker and its count over its bars, and
    each task's label says how often the team merged and merged wrongly."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (ax0, ax1) = plt.subplots(1, 2, figsize=(12, 4.5))
    if "explore" in runs:
        for team_name, colour in _COLOURS.items():
            results = runs["explore"][team_name]
            if not results:
                continue
            label = team_label(TEAMS[team_name])
            for mode, style in (("observed", "-"), ("held", "--")):
                curves_in = [
                    (r.times_s, r.coverages)
                    if mode == "observed"
                    else (r.held_times_s, r.held_coverages)
                    for r in results
                ]
                curves_in = [(t, c) for t, c in curves_in if t]
                if not curves_in:
                    continue
                t_end = max(t[-1] for t, _ in curves_in)
                grid = np.linspace(0.0, t_end, 200)
                # After an episode ends its coverage stays at its final value.
                curves = np.array([np.interp(grid, t, c) for t, c in curves_in])
                mean, std = curves.mean(axis=0), curves.std(axis=0)
                ax0.plot(grid, mean, style, color=colour, label=f"{label}, {mode}")
                if mode == "observed":
                    ax0.fill_between(
                        grid,
                        np.clip(mean - std, 0, 1),
                        np.clip(mean + std, 0, 1),
                        color=colour,
                        alpha=0.2,
                    )
        ax0.set_xlabel("time (s)")
        ax0.set_ylabel("coverage")
        ax0.set_title("exploration: coverage vs time (mean, +-1 std)")
        ax0.legend(fontsize=8)
    tasks = list(doc["tasks"])
    x = np.arange(len(tasks))
    width = 0.2
    wrong_marked = False
    for k, (team_name, colour) in enumerate(_COLOURS.items()):
        for m, mode in enumerate(("observed", "held")):
            offset = (2 * k + m - 1.5) * width
            for j, task in enumerate(tasks):
                e = doc["tasks"][task][team_name]
                mean = e["mean"] if mode == "observed" else e["held_mean"]
                if mean is None:
                    continue
                std = e["std"] if mode == "observed" else e["held_std"]
                first = j == 0 or (
                    mode == "held"
                    and all(doc["tasks"][t][team_name]["held_mean"] is None for t in tasks[:j])
                )
                ax1.bar(
                    x[j] + offset,
                    mean,
                    width,
                    yerr=[[min(std, mean)], [std]],  # a time is never below 0 s
                    color=colour,
                    alpha=1.0 if mode == "observed" else 0.45,
                    hatch=None if mode == "observed" else "//",
                    label=f"{team_label(TEAMS[team_name])}, {mode}" if first else None,
                )
                n_wrong = int(e["wrong_merge_episodes"])
                if n_wrong:
                    y = (mean + std) * 1.04 + 1.0
                    ax1.plot(
                        x[j] + offset,
                        y,
                        marker="v",
                        linestyle="none",
                        color="red",
                        markersize=8,
                        label=None if wrong_marked else "held a wrong merge",
                    )
                    wrong_marked = True
                    if mode == "observed":
                        ax1.annotate(
                            f"wrong merge {n_wrong}/{len(e['task_times_s'])}",
                            (x[j] + offset, y),
                            xytext=(0, 7),
                            textcoords="offset points",
                            ha="center",
                            va="bottom",
                            fontsize=7,
                            color="red",
                        )
    ax1.set_xticks(x, [_tick_label(doc, t) for t in tasks])
    ax1.set_ylabel("task time (s)")
    ax1.set_title("task time, 1 vs 2 robots (observed solid, held hatched)")
    ax1.margins(y=0.15)  # room for the wrong-merge markers
    ax1.legend(fontsize=8, loc="best")
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)


def _tick_label(doc: Mapping[str, Any], task: str) -> str:
    """A task's label under its bars: the reduction, and how often the team merged and merged
    wrongly (said when none did too, so a plot without a wrong-merge marker is not read as
    unchecked)."""
    t = doc["tasks"][task]
    multi = t["multi"]
    n = len(multi["task_times_s"])
    return (
        f"{task}\n(-{_pct(t['reduction'])} observed)\n"
        f"{team_label(TEAMS['multi'])} merged {multi['merged_episodes']}/{n}, "
        f"wrong merge {multi['wrong_merge_episodes']}/{n}"
    )


def _pct(x: float | None) -> str:
    return "n/a" if x is None else f"{x:.1%}"


def _mean_std(mean: float | None, std: float | None) -> str:
    return "-" if mean is None or std is None else f"{mean:.1f} +- {std:.1f}"


#: The table's columns: (heading, width).
_COLUMNS = (
    ("task", 9),
    ("team", 10),
    ("observed s", 14),
    ("held s", 14),
    ("done o/h", 10),
    ("merged", 7),
    ("1st merge s", 12),
    ("wrong", 6),
    ("wrongly s sum/max", 18),
    ("contradict", 11),
)


def _row(cells: Sequence[str]) -> str:
    """One line of the table: the task and team left-aligned, the figures right-aligned."""
    out = ""
    for k, ((_, w), c) in enumerate(zip(_COLUMNS, cells, strict=False)):
        out += f"{c:<{w}}" if k < 2 else f"{c:>{w}}"
    return out.rstrip()


def format_table(doc: Mapping[str, Any]) -> str:
    """The results as a text table, one row per task and team size, then a legend, the seed
    paper's figures (on :data:`PAPER_WORLD` only) and the wrong-merge warning, if any."""
    lines = [
        f"Task time on '{doc['world']}' with policy '{doc['policy']}' over "
        f"{len(doc['seeds'])} seeds (simulated s)",
        *([f"merging: {doc['merging']}"] if doc.get("merging") else []),
        _row([h for h, _ in _COLUMNS]),
    ]
    for task, e in doc["tasks"].items():
        for team_name in TEAMS:
            t = e.get(team_name)
            if not t:
                continue
            n = len(t["task_times_s"])
            alone = int(t["n_robots"]) == 1
            held_rate = t["held_success_rate"]
            contra = t["max_fused_contradiction_max"]
            lines.append(
                _row(
                    [
                        task,
                        team_label(int(t["n_robots"])),
                        _mean_std(t["mean"], t["std"]),
                        _mean_std(t["held_mean"], t["held_std"]),
                        f"{t['success_rate']:.0%}/"
                        + ("-" if held_rate is None else f"{held_rate:.0%}"),
                        "-" if alone else f"{t['merged_episodes']}/{n}",
                        "-"
                        if t["first_merge_median_s"] is None
                        else f"{t['first_merge_median_s']:.1f}",
                        "-" if alone else f"{t['wrong_merge_episodes']}/{n}",
                        "-"
                        if alone
                        else f"{t['merged_wrongly_sum_s']:.1f}/{t['merged_wrongly_max_s']:.1f}",
                        "-" if contra is None else f"{contra:.1%}",
                    ]
                )
            )
        lines.append(
            _row([task, "reduction", _pct(e.get("reduction")), _pct(e.get("held_reduction"))])
        )
    lines.append(
        "observed: the team's sensors together saw the target share; held: some robot holds it "
        "at the true place in its own-or-fused map (a wrong merge costs time; exploration only)"
    )
    lines.append(
        "over each whole episode (until both targets or the time limit): merged: episodes "
        "merged; 1st merge: median; wrong: episodes that held a transform >= 5 cells off the "
        "truth, for wrongly s seconds; contradict: the largest share of a robot's map "
        "contradicting the truth"
    )
    papers = [(t, e["paper"]) for t, e in doc["tasks"].items() if e.get("paper")]
    if papers:
        lines.append(
            "seed paper (its own simulation, on a world like this one): "
            + ", ".join(
                f"{t} {p['single']:.0f} -> {p['multi']:.0f} s (-{1 - p['multi'] / p['single']:.0%})"
                for t, p in papers
            )
        )
    warning = doc.get("wrong_merge_warning")
    if warning:
        lines.append(warning)
    return "\n".join(lines)
