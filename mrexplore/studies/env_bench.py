"""``mrexplore bench env``: environment steps per second, per team size, with latencies.

Steps the PettingZoo env with seeded random actions and measures the **CPU time of the stepping
thread** (``time.thread_time``), so the figures hold on a machine shared with other work (wall
time would count the other processes' turns). Per setting it prints env steps/s, robot-steps/s
(steps/s x robots), and the p50 / p99 / max CPU time of one ``step()``. Episodes that end are
reset (not timed).

The last two columns: steps per second of the whole process's CPU time, which also counts the
merge worker thread and the threads OpenCV spreads some calls over (the stepping thread's time
does not), and steps per second of wall time, which also counts the time the stepping thread
waits for a merge attempt that outlasts its latency (``merge_latency_steps``) and other
processes' turns on a shared machine: what a training loop sees, and the noisiest figure.

``--batched 1,8,32`` adds the batched env (:func:`mrexplore.vector_env`, 2 robots on
``symmetric_office``, merging on, default options) at each number of worlds N: batched steps
per second, world-steps/s and robot-steps/s, p50 / p99 / max CPU time of one batched step (all
N worlds, auto-resets included), and robot-steps per second of the process's CPU time (the
shared merge worker thread included) and of wall time. Every row takes the same number of batched
steps (``--batched-steps``, 200) after 20 untimed ones, and world k draws its actions from a
stream seeded ``seed + k`` as :func:`measure` does: each world is timed over the same steps of
the same trajectory whatever N (world 0's is the per-env row's with ``--steps 200``), since a
step's cost changes along an episode (maps grow, merges happen) and with where the robots go.
``--evaluate 1,0`` applies to these rows too. The batched env steps its worlds on all usable
cores (``num_threads``), so its stepping thread's CPU time is only the caller's share.

``--side-by-side 32`` (single vs batched, the figures to quote): N single envs, each stepped
alone in turn, and the batched env of the same N worlds (``symmetric_office``, 2 robots, merging
on, the same seeds and actions), stepped in alternation, ``--rounds`` rounds of
``--round-steps`` steps of every world, so the machine's load falls on them alike; the batched
env once on one thread (the worlds one after the other, as before it had threads) and once on
every core. Per row: robot-steps per second of the stepping thread's CPU time
(``time.thread_time``), of the whole process's CPU time (``time.process_time``: pool threads and
the merge worker included) and of wall time, the cores used (process CPU / wall) and the
robot-steps/s in wall time as a ratio to the single envs'. Each timed span ends when the merge
attempts it started have finished, so no row's merge work is counted in another's. World k acts
as in ``--batched``. With ``--team coordinated-frontier`` every world is driven by that team,
its decisions (``team.act`` on every robot's view; in the batched rows on the stepping threads,
:meth:`~mrexplore.environment.batched.BatchedExploreEnv.map_worlds`) timed with the steps: a
realistic rollout. The machine's core count and load are printed: on a
shared machine the wall ratio is a ratio under contention.

``--rollout coordinated-frontier`` (:func:`measure_rollout`): one env (``symmetric_office``, 2
robots, merging on) driven by that team for ``--steps`` steps, the team's decisions (views
included) timed with the steps: process CPU per step (the merge worker and OpenCV's threads
too), the stepping thread's, the policy's and the env step's, the policy's share of the process
CPU, and p50 / p99 / max of one step's stepping-thread CPU with the slowest step over the
median; then the merge worker's CPU per step (``merge``), the attempts and re-checks it applied
(``attempts``: 31+2) and the wall time per step (which also holds the waits for a merge attempt
still running when its result is due). One row per ``--merge-latency-steps`` value;
``--env-options merge_every=20`` sets other env options of these rows.
``studies/speed_vs_checkout.py --rollout coordinated-frontier`` runs it on two trees side by
side.

Settings: ``symmetric_office`` (0.05 m/cell, 360 beams, 4 m, merging on) for ``--robots``
(default 1, 2, 4, 8), and two robots on the Explore-Bench-sized world (250 x 250 cells,
0.1 m/cell, 3 m). ``--breakdown`` also times the stages of the default 2-robot step through the
env's ``stage_timer`` (``act``: move + lidar + own maps; ``merge``: fusion stage; ``observe``:
observation images; ``other``: reward, termination, infos).

:func:`measure` uses only the public API (``parallel_env``, ``reset``, ``step``), so the same
harness times an older checkout: ``scripts/bench_env_vs.py`` runs it on two trees in turn and
prints the ratios measured side by side.
"""

from __future__ import annotations

import argparse
import functools
import json
import os
import time
from collections import defaultdict
from collections.abc import Callable, Sequence
from typing import Any

import numpy as np

import mrexplore
from mrexplore.environment.parallel_env import STEP_STAGES
from mrexplore.errors import ConfigError
from mrexplore.io_safety import check_outputs, write_text

#: The settings of the printed table: (label, env options without n_robots).
DEFAULT_WORLD: dict[str, Any] = {"world": "symmetric_office"}
EXPLORE_BENCH_WORLD: dict[str, Any] = {"world": "symmetric_office_coarse", "max_range_m": 3.0}


#: The step's stages timed with ``--breakdown`` (the env's ``stage_timer`` names them).
STAGES = STEP_STAGES


_WARM = False


def warm_merging() -> None:
    """Compile (or load from numba's on-disk cache) the kernels of a merging run, untimed, once
    per process: a short merging episode (``small_office``, the coordinated-frontier team, 240
    steps; it merges). numba compiles a kernel at its first call, the merger's in the merge
    worker, so on a fresh checkout the first timed row to merge would count seconds of
    compiling in its process CPU. Public API only, as :func:`measure` (it times other trees)."""
    global _WARM
    if _WARM:
        return
    from mrexplore.policies import make_team_policy

    env = mrexplore.parallel_env(world="small_office", merge_latency_steps=0, max_time_s=60.0)
    try:
        env.reset(seed=0)
        team = make_team_policy("coordinated-frontier", env.possible_agents)
        team.reset(np.random.default_rng(0))
        for _ in range(240):
            if not env.agents:
                break
            env.step(team.act({a: env.robot_view(a) for a in env.agents}))
    finally:
        env.close()
    _WARM = True


def measure(
    steps: int = 2000,
    seed: int = 0,
    warmup: int = 20,
    breakdown: bool = False,
    **options: Any,
) -> dict[str, Any]:
    """Step ``parallel_env(**options)`` ``steps`` times with random actions (after
    :func:`warm_merging` and ``warmup`` untimed steps); returns CPU-time figures.

    Returns a dict: ``steps``, ``episodes``, ``cpu_s`` (stepping thread), ``steps_per_s``,
    ``robot_steps_per_s``, ``p50_ms`` / ``p99_ms`` / ``max_ms`` (CPU time of one ``step()``),
    ``steps_per_process_cpu_s``, ``wall_s`` and ``steps_per_wall_s``, and with ``breakdown``
    ``ms_per_step`` by stage.
    """
    warm_merging()
    penv = mrexplore.parallel_env(**options)
    acc: dict[str, float] = defaultdict(float)
    if breakdown:
        if not hasattr(penv, "stage_timer"):
            raise ConfigError("--breakdown needs an env with a stage_timer (this checkout's)")

        def tell(stage: str, seconds: float) -> None:
            acc[stage] += seconds

        penv.stage_timer = tell
    rng = np.random.default_rng(seed)
    penv.reset(seed=seed)
    n_act = int(penv.action_space(penv.possible_agents[0]).n)
    n_robots = len(penv.possible_agents)
    episodes = 1
    lat = np.zeros(steps, dtype=np.float64)
    proc = wall = 0.0
    for k in range(-warmup, steps):
        if not penv.agents:
            penv.reset()
            episodes += 1
        actions = {a: int(rng.integers(n_act)) for a in penv.agents}
        if k == 0:
            acc.clear()
        w0 = time.perf_counter()
        p0 = time.process_time()
        t0 = time.thread_time()
        penv.step(actions)
        if k >= 0:
            lat[k] = time.thread_time() - t0
            proc += time.process_time() - p0
            wall += time.perf_counter() - w0
    total = float(lat.sum())
    out: dict[str, Any] = {
        "options": dict(options),
        "n_robots": n_robots,
        "steps": steps,
        "episodes": episodes,
        "cpu_s": total,
        "steps_per_s": steps / total,
        "robot_steps_per_s": steps * n_robots / total,
        # all threads of the process (OpenCV spreads some calls over worker threads)
        "process_cpu_s": proc,
        "steps_per_process_cpu_s": steps / proc,
        "wall_s": wall,
        "steps_per_wall_s": steps / wall,
        "p50_ms": 1000.0 * float(np.percentile(lat, 50)),
        "p99_ms": 1000.0 * float(np.percentile(lat, 99)),
        "max_ms": 1000.0 * float(lat.max()),
    }
    if breakdown:
        parts = {k: acc[k] for k in STAGES}
        parts["other"] = total - sum(parts.values())
        out["ms_per_step"] = {k: 1000.0 * v / steps for k, v in parts.items()}
    return out


def measure_batched(
    num_envs: int,
    steps: int = 200,
    seed: int = 0,
    warmup: int = 20,
    **options: Any,
) -> dict[str, Any]:
    """Step ``vector_env(num_envs, **options)`` (a team) ``steps`` times with seeded random
    actions after ``warmup`` untimed steps; CPU-time figures of one batched step.

    Returns a dict: ``num_envs``, ``n_robots``, ``num_threads`` (the threads that stepped the
    worlds; ``options`` may set it), ``steps`` (batched), ``episodes_ended``,
    ``cpu_s`` (stepping thread), ``batch_steps_per_s``, ``world_steps_per_s``,
    ``robot_steps_per_s``, ``p50_ms`` / ``p99_ms`` / ``max_ms`` (one batched step),
    ``process_cpu_s`` and ``robot_steps_per_process_cpu_s`` (all threads: the merge worker too),
    ``wall_s`` and ``robot_steps_per_wall_s``.
    """
    from mrexplore.environment.batched import BatchedExploreEnv

    warm_merging()
    venv = BatchedExploreEnv(num_envs, **options)
    try:
        # World k draws its actions from its own stream seeded seed + k, one robot at a time
        # as measure() does: world 0 gets the actions of measure()'s env and world k the same
        # actions whatever N, so rows time the same trajectories (a step's cost depends on
        # where the robots go).
        rngs = [np.random.default_rng(seed + k) for k in range(venv.num_envs)]
        venv.reset(seed=seed)
        n_act = int(venv.single_action_space.n)
        r = venv.n_robots
        lat = np.zeros(steps, dtype=np.float64)
        proc = wall = 0.0
        ended = 0
        for k in range(-warmup, steps):
            actions = np.array([[int(g.integers(n_act)) for _ in range(r)] for g in rngs])
            w0 = time.perf_counter()
            p0 = time.process_time()
            t0 = time.thread_time()
            out = venv.step(actions)
            if k >= 0:
                lat[k] = time.thread_time() - t0
                proc += time.process_time() - p0
                wall += time.perf_counter() - w0
                ended += int(np.count_nonzero(out[2][:, 0] | out[3][:, 0]))
    finally:
        venv.close()
    total = float(lat.sum())
    robot_steps = steps * venv.num_envs * venv.n_robots
    return {
        "options": dict(options),
        "num_envs": venv.num_envs,
        "n_robots": venv.n_robots,
        "num_threads": venv.num_threads,
        "steps": steps,
        "episodes_ended": ended,
        "cpu_s": total,
        "batch_steps_per_s": steps / total,
        "world_steps_per_s": steps * venv.num_envs / total,
        "robot_steps_per_s": robot_steps / total,
        "process_cpu_s": proc,
        "robot_steps_per_process_cpu_s": robot_steps / proc,
        "wall_s": wall,
        "robot_steps_per_wall_s": robot_steps / wall,
        "p50_ms": 1000.0 * float(np.percentile(lat, 50)),
        "p99_ms": 1000.0 * float(np.percentile(lat, 99)),
        "max_ms": 1000.0 * float(lat.max()),
    }


def measure_rollout(
    steps: int = 1000,
    seed: int = 0,
    team: str = "coordinated-frontier",
    warmup: int = 20,
    **options: Any,
) -> dict[str, Any]:
    """A realistic rollout: ``parallel_env(**options)`` driven by the team policy ``team``
    (its decisions on every robot's view, views included) for ``steps`` steps after ``warmup``
    untimed ones; episodes that end are reset with the team (not timed).

    Returns a dict: ``steps``, ``episodes``, per step in ms ``process_ms`` (process CPU: the
    merge worker and OpenCV's threads too), ``thread_ms`` (stepping thread: decisions + step),
    ``policy_ms`` and ``env_ms`` (stepping thread), ``policy_share`` (policy / process CPU),
    ``p50_ms`` / ``p99_ms`` / ``max_ms`` of one step's stepping-thread CPU (decisions + step),
    ``max_over_p50``, the slowest step over the median, and that step's ``max_policy_ms`` and
    ``max_env_ms``; ``wall_ms`` per step (what a user waits: also the stepping thread's waits
    for a merge attempt still running when its result is due); the merge work of the timed
    steps (:attr:`~mrexplore.merge.MapMergeTracker.work`): ``merge_attempts`` and
    ``merge_rechecks`` applied, ``merge_ms`` their CPU per step (0 without a merger).
    """
    from mrexplore.merge import MergeWork
    from mrexplore.policies import make_team_policy

    warm_merging()
    penv = mrexplore.parallel_env(**options)
    policy = make_team_policy(team, penv.possible_agents)
    penv.reset(seed=seed)
    policy.reset(np.random.default_rng(seed))
    tracker = penv.unwrapped.fusion.tracker
    decide = np.zeros(steps)
    step = np.zeros(steps)
    proc = wall = 0.0
    episodes = 1
    done = MergeWork()  # the work of episodes reset during the timed steps

    def work() -> MergeWork:
        return done + (MergeWork() if tracker is None else tracker.work)

    try:
        for k in range(-warmup, steps):
            if k == 0:
                start = work()
            if not penv.agents:
                done = work()
                penv.reset()
                policy.reset(np.random.default_rng([seed, episodes]))
                episodes += 1
            w0 = time.perf_counter()
            p0 = time.process_time()
            t0 = time.thread_time()
            actions = policy.act({a: penv.robot_view(a) for a in penv.agents})
            t1 = time.thread_time()
            penv.step(actions)
            t2 = time.thread_time()
            if k >= 0:
                decide[k], step[k] = t1 - t0, t2 - t1
                proc += time.process_time() - p0
                wall += time.perf_counter() - w0
        end = work()
    finally:
        penv.close()
    lat = decide + step
    p50 = float(np.percentile(lat, 50))
    return {
        "options": dict(options),
        "team": team,
        "steps": steps,
        "episodes": episodes,
        "process_ms": 1000.0 * proc / steps,
        "thread_ms": 1000.0 * float(lat.sum()) / steps,
        "policy_ms": 1000.0 * float(decide.sum()) / steps,
        "env_ms": 1000.0 * float(step.sum()) / steps,
        "policy_share": float(decide.sum()) / proc,
        "p50_ms": 1000.0 * p50,
        "p99_ms": 1000.0 * float(np.percentile(lat, 99)),
        "max_ms": 1000.0 * float(lat.max()),
        "max_over_p50": float(lat.max()) / p50,
        # the slowest step's parts: decisions and env step
        "max_policy_ms": 1000.0 * float(decide[int(np.argmax(lat))]),
        "max_env_ms": 1000.0 * float(step[int(np.argmax(lat))]),
        "wall_ms": 1000.0 * wall / steps,
        "merge_attempts": end.attempts - start.attempts,
        "merge_rechecks": end.rechecks - start.rechecks,
        "merge_ms": 1000.0 * (end.cpu_s - start.cpu_s) / steps,
    }


ROLLOUT_HEADER = (
    f"{'realistic rollout (ms of CPU per step)':<66} {'process':>8} {'thread':>7} "
    f"{'policy':>7} {'env':>6} {'policy/proc':>11} {'p50':>6} {'p99':>6} {'max':>6} {'max/p50':>7}"
    f" {'merge':>6} {'attempts':>8} {'wall':>6}"
)


def rollout_row(label: str, r: dict[str, Any]) -> str:
    """One printed line of a result of :func:`measure_rollout` (``-`` for the merge work and
    wall time of a result made before they were measured)."""
    merge = "-" if "merge_ms" not in r else f"{r['merge_ms']:.3f}"
    attempts = "-" if "merge_attempts" not in r else f"{r['merge_attempts']}+{r['merge_rechecks']}"
    wall = "-" if "wall_ms" not in r else f"{r['wall_ms']:.3f}"
    return (
        f"{label:<66} {r['process_ms']:>8.3f} {r['thread_ms']:>7.3f} {r['policy_ms']:>7.3f} "
        f"{r['env_ms']:>6.3f} {100 * r['policy_share']:>10.1f}% {r['p50_ms']:>6.2f} "
        f"{r['p99_ms']:>6.2f} {r['max_ms']:>6.2f} {r['max_over_p50']:>6.2f}x"
        f" {merge:>6} {attempts:>8} {wall:>6}"
    )


def _machine() -> dict[str, Any]:
    """The machine's cores and load averages now (1, 5, 15 min; None where the OS has none)."""
    from mrexplore.environment.batched import usable_cores

    try:
        load: list[float] | None = [round(v, 2) for v in os.getloadavg()]
    except OSError:  # not available on this OS
        load = None
    return {"cores": os.cpu_count(), "usable_cores": usable_cores(), "load": load}


def _load_line(when: str, machine: dict[str, Any] | None = None) -> str:
    """The machine's cores and load average (the context of every wall-time figure)."""
    m = _machine() if machine is None else machine
    load = "unknown" if m["load"] is None else " ".join(f"{v:.2f}" for v in m["load"])
    return f"machine: {m['cores']} cores ({m['usable_cores']} usable); load average {when}: {load}"


class _Driver:
    """What acts in one world: seeded random actions (one stream per world, one draw per robot
    as :func:`measure` does) or a team policy on the robots' views (reset with each episode)."""

    def __init__(self, env: Any, seed: int, team: str | None) -> None:
        self.env = env
        self.rng = np.random.default_rng(seed)
        self.team: Any = None
        if team is not None:
            from mrexplore.policies import make_team_policy

            self.team = make_team_policy(team, env.possible_agents)
            self.reset()

    def reset(self) -> None:
        if self.team is not None:
            self.team.reset(np.random.default_rng([int(self.rng.integers(2**31)), 1]))

    def act(self) -> list[int]:
        agents = self.env.possible_agents
        if self.team is None:
            return [int(self.rng.integers(4)) for _ in agents]
        acts = self.team.act({a: self.env.robot_view(a) for a in agents})
        return [int(acts[a]) for a in agents]


class _Clock:
    """Stepping-thread CPU, process CPU and wall seconds summed over timed spans."""

    def __init__(self) -> None:
        self.thread = self.process = self.wall = 0.0

    def span(self, fn: Callable[[], Any], envs: Sequence[Any] = (), workers: Any = None) -> Any:
        """Time ``fn()`` and then the wait for the merge attempts it started in ``envs``, so
        that one span's merge work is not counted in the next one's (whichever row that is);
        ``workers``: a :class:`ProcessBatchedEnv` whose worker processes' CPU (after the same
        wait) is counted as the process's."""
        before = 0.0 if workers is None else workers.worker_cpu_s()
        w0, p0, t0 = time.perf_counter(), time.process_time(), time.thread_time()
        out = fn()
        for env in envs:
            tracker = env.unwrapped.fusion.tracker
            if tracker is not None:
                tracker.wait_idle()
        after = 0.0 if workers is None else workers.worker_cpu_s()
        self.thread += time.thread_time() - t0
        self.process += time.process_time() - p0 + after - before
        self.wall += time.perf_counter() - w0
        return out


def side_by_side(
    num_envs: int,
    rounds: int = 4,
    steps_per_round: int = 25,
    seed: int = 0,
    team: str | None = None,
    merger: Any = "semantic",
    warmup: int = 5,
    **options: Any,
) -> dict[str, Any]:
    """Single envs and the batched env of ``num_envs`` worlds (on one thread, then on every
    usable core) stepped in alternation, ``rounds`` x ``steps_per_round`` steps of every world
    after ``warmup`` untimed ones; ``team`` None: random actions, else a team policy name whose
    decisions are timed with the steps.

    The single row steps the same worlds as the batched rows (world k seeded ``seed + k``, the
    same actions), each by its own :func:`mrexplore.parallel_env` stepped alone: in a round,
    world 0's env takes its ``steps_per_round`` steps, then world 1's, ... (each with its own
    merge worker, as one env has). So all rows do the same work and differ only in how it is
    stepped. Each timed span ends when the merge attempts its steps started have finished
    (:meth:`~mrexplore.merge.MapMergeTracker.wait_idle`): the merge workers run beside the
    stepping, and without the wait a row's last attempts would be counted in the next row's
    process CPU and wall time.

    With random actions a fourth row steps the batched env in worker processes, one per usable
    core (``vector_env(num_workers=...)``, :mod:`mrexplore.environment.processes`): its process
    CPU is the parent's and the workers' together (a team's decisions need the robots' views,
    which stay in the workers, so the team rows have no such row).

    Returns a dict: ``num_envs``, ``team``, ``cores``, ``threads`` and per row (``single``,
    ``batched_1_thread``, ``batched_threads``, with random actions ``batched_processes``) the
    robot-steps, ``thread_s``, ``process_s``, ``wall_s``, robot-steps per second of each,
    ``cores_used`` and ``wall_ratio`` (robot-steps/s in wall time / the single envs').
    """
    from mrexplore.environment.batched import BatchedExploreEnv, usable_cores
    from mrexplore.environment.processes import ProcessBatchedEnv

    warm_merging()
    opts = {**DEFAULT_WORLD, "n_robots": 2, "merger": merger, **options}
    cores = usable_cores()
    singles: list[Any] = []
    batches: dict[str, BatchedExploreEnv] = {}
    try:
        singles.extend(mrexplore.parallel_env(**opts) for _ in range(num_envs))
        batches["batched_1_thread"] = BatchedExploreEnv(num_envs, num_threads=1, **opts)
        batches["batched_threads"] = BatchedExploreEnv(num_envs, num_threads=cores, **opts)
        if team is None:
            batches["batched_processes"] = ProcessBatchedEnv(num_envs, num_workers=cores, **opts)
        for k, env in enumerate(singles):
            env.reset(seed=seed + k)
        drivers: dict[str, list[_Driver]] = {
            "single": [_Driver(e, seed + k, team) for k, e in enumerate(singles)]
        }
        for name, b in batches.items():
            b.reset(seed=seed)
            # random actions need only the robots' count: the single envs stand in for worlds
            # that live in worker processes
            hosts = singles if isinstance(b, ProcessBatchedEnv) else b.envs
            drivers[name] = [_Driver(e, seed + k, team) for k, e in enumerate(hosts)]

        def run_single(steps: int) -> None:
            for env, d in zip(singles, drivers["single"], strict=True):
                for _ in range(steps):  # this world's env stepped alone
                    env.step(dict(zip(env.possible_agents, d.act(), strict=True)))
                    if not env.agents:
                        env.reset()
                        d.reset()

        def run_batch(name: str) -> Callable[[int], None]:
            def run(steps: int) -> None:
                ds, b = drivers[name], batches[name]
                for _ in range(steps):
                    if isinstance(b, ProcessBatchedEnv):  # random actions (no team row)
                        acts = [d.act() for d in ds]
                    else:  # the decisions on the stepping threads (a team's planning is nogil)
                        acts = b.map_worlds(lambda k, _env: ds[k].act())
                    _, _, terms, truncs, _ = b.step(np.array(acts))
                    for k in np.flatnonzero(terms[:, 0] | truncs[:, 0]):
                        ds[k].reset()  # the world was reset in the step (same-step auto-reset)

            return run

        runs: dict[str, Callable[[int], None]] = {
            "single": run_single,
            **{name: run_batch(name) for name in batches},
        }
        clocks = {name: _Clock() for name in runs}
        envs: dict[str, Sequence[Any]] = {"single": singles}
        workers: dict[str, Any] = {}
        for name, b in batches.items():
            if isinstance(b, ProcessBatchedEnv):
                envs[name], workers[name] = (), b
            else:
                envs[name] = b.envs
        for name, run in runs.items():
            _Clock().span(functools.partial(run, warmup), envs[name], workers.get(name))
        for _ in range(rounds):
            for name, run in runs.items():  # in alternation: the load falls on all alike
                clocks[name].span(
                    functools.partial(run, steps_per_round), envs[name], workers.get(name)
                )
    finally:
        for env in singles:
            env.close()
        for b in batches.values():
            b.close()
    n = rounds * steps_per_round * num_envs * 2
    out: dict[str, Any] = {
        "num_envs": num_envs,
        "team": team or "random",
        "cores": cores,
        "threads": batches["batched_threads"].num_threads,
        "workers": getattr(batches.get("batched_processes"), "num_workers", None),
        "rounds": rounds,
        "steps_per_round": steps_per_round,
    }
    for name, c in clocks.items():
        out[name] = {
            "robot_steps": n,
            "thread_s": c.thread,
            "process_s": c.process,
            "wall_s": c.wall,
            "robot_steps_per_thread_s": n / c.thread,
            "robot_steps_per_process_s": n / c.process,
            "robot_steps_per_wall_s": n / c.wall,
            "cores_used": c.process / c.wall,
        }
    base = out["single"]["robot_steps_per_wall_s"]
    for name in clocks:
        out[name]["wall_ratio"] = out[name]["robot_steps_per_wall_s"] / base
    return out


def side_by_side_header(num_envs: int, rounds: int, steps: int, merger: Any) -> str:
    """The title and column names of the side-by-side table."""
    return (
        f"single vs batched, side by side ({num_envs} worlds, {rounds} rounds x {steps} steps "
        f"of each, in alternation; symmetric_office, 2 robots, merger {merger}; robot-steps "
        f"per second of:)\n"
        f"{'driver, env':<52} {'thread CPU':>10} {'process CPU':>11} {'wall':>8} "
        f"{'cores used':>10} {'wall vs single':>14}"
    )


def side_by_side_lines(r: dict[str, Any]) -> list[str]:
    """The printed rows of a result of :func:`side_by_side`."""
    labels = {
        "single": f"{r['num_envs']} single envs, each stepped alone",
        "batched_1_thread": f"batched, {r['num_envs']} worlds, 1 thread",
        "batched_threads": f"batched, {r['num_envs']} worlds, {r['threads']} threads",
        "batched_processes": f"batched, {r['num_envs']} worlds, {r.get('workers')} processes",
    }
    lines = []
    for name, label in labels.items():
        if name not in r:
            continue
        x = r[name]
        lines.append(
            f"{r['team'] + ', ' + label:<52} {x['robot_steps_per_thread_s']:>10.0f} "
            f"{x['robot_steps_per_process_s']:>11.0f} {x['robot_steps_per_wall_s']:>8.0f} "
            f"{x['cores_used']:>10.2f} {x['wall_ratio']:>13.2f}x"
        )
    return lines


BATCHED_HEADER = (
    f"{'batched env, 2 robots, symmetric_office (stepping thread)':<58} {'batch/s':>8} "
    f"{'world-st/s':>10} {'robot-st/s':>10} {'p50 ms':>7} {'p99 ms':>7} {'max ms':>7} "
    f"{'robot-st/proc-s':>15} {'robot-st/wall-s':>15}"
)


def batched_row(label: str, r: dict[str, Any]) -> str:
    """One printed line of a result of :func:`measure_batched`."""
    return (
        f"{label:<58} {r['batch_steps_per_s']:>8.1f} {r['world_steps_per_s']:>10.0f} "
        f"{r['robot_steps_per_s']:>10.0f} {r['p50_ms']:>7.2f} {r['p99_ms']:>7.2f} "
        f"{r['max_ms']:>7.1f} {r['robot_steps_per_process_cpu_s']:>15.0f} "
        f"{r['robot_steps_per_wall_s']:>15.0f}"
    )


def row(label: str, r: dict[str, Any]) -> str:
    """One printed line of a result of :func:`measure`."""
    return (
        f"{label:<56} {r['steps_per_s']:>8.0f} {r['robot_steps_per_s']:>9.0f} "
        f"{r['p50_ms']:>7.2f} {r['p99_ms']:>7.2f} {r['max_ms']:>7.1f} "
        f"{r['steps_per_process_cpu_s']:>10.0f} {r['steps_per_wall_s']:>10.0f}"
    )


HEADER = (
    f"{'setting (CPU time of the stepping thread)':<56} {'steps/s':>8} {'robot-st/s':>9} "
    f"{'p50 ms':>7} {'p99 ms':>7} {'max ms':>7} {'st/proc-s':>10} {'st/wall-s':>10}"
)


def settings(robots: Sequence[int], merger: Any) -> list[tuple[str, dict[str, Any]]]:
    """The (label, options) pairs of the table."""
    out = [
        (f"symmetric_office, {n} robot{'s' if n > 1 else ''}", {**DEFAULT_WORLD, "n_robots": n})
        for n in robots
    ]
    out.append(("Explore-Bench-sized (0.1 m, 3 m), 2 robots", {**EXPLORE_BENCH_WORLD}))
    for _, opts in out:
        opts["merger"] = merger
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """Print env steps/s, robot-steps/s and step latencies per team size (see the module doc)."""
    p = argparse.ArgumentParser(prog="mrexplore bench env", description=__doc__)
    p.add_argument("--steps", type=int, default=2000, help="timed steps per setting (>= 1)")
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--robots", default="1,2,4,8", help="team sizes, comma-separated")
    p.add_argument("--merger", default="semantic", help='a merge method, or "none"')
    p.add_argument(
        "--merge-latency-steps",
        default=None,
        help="comma-separated values of the env's merge_latency_steps, each measured in turn "
        "(default: the env's default, 8); e.g. 0,8 puts in-step and off-path merging side by side",
    )
    p.add_argument(
        "--evaluate",
        default=None,
        help="comma-separated values of the env's evaluate option (1 or 0), each measured in "
        "turn (default: the env's, 1); 1,0 puts the truth monitor on and off side by side",
    )
    p.add_argument(
        "--batched",
        default=None,
        help="comma-separated numbers of worlds N for the batched env (vector_env, 2 robots, "
        "symmetric_office), e.g. 1,8,32; each row takes --batched-steps batched steps",
    )
    p.add_argument(
        "--batched-steps",
        type=int,
        default=200,
        help="batched steps per --batched row, the same for every N (default 200)",
    )
    p.add_argument(
        "--batched-only",
        action="store_true",
        help="with --batched, --side-by-side or --rollout: skip the per-env table",
    )
    p.add_argument(
        "--side-by-side",
        type=int,
        default=None,
        metavar="N",
        help="single env vs the batched env of N worlds (2 robots) on one thread and on every "
        "core, stepped in alternation; prints robot-steps/s of the stepping thread, process CPU "
        "and wall, and the wall ratio batched / single",
    )
    p.add_argument("--rounds", type=int, default=4, help="--side-by-side: rounds (default 4)")
    p.add_argument(
        "--round-steps",
        type=int,
        default=25,
        help="--side-by-side: steps of each env per round (default 25)",
    )
    p.add_argument(
        "--team",
        default="random",
        help="--side-by-side: comma-separated drivers, 'random' and/or a team policy name "
        "(e.g. random,coordinated-frontier)",
    )
    p.add_argument(
        "--rollout",
        default=None,
        metavar="TEAM",
        help="a realistic rollout per team policy (comma-separated, e.g. coordinated-frontier): "
        "symmetric_office, 2 robots, --steps steps; prints process and stepping-thread CPU per "
        "step, the policy's share and the slowest step over the median",
    )
    p.add_argument(
        "--env-options",
        default=None,
        metavar="K=V,K=V",
        help="env options of the --rollout rows, e.g. merge_every=20 or world=small_office "
        "(each row names them; default: symmetric_office, 2 robots)",
    )
    p.add_argument("--breakdown", action="store_true", help="also time the stages (2 robots)")
    p.add_argument("--json", default=None, help="also write the figures to this JSON file")
    p.add_argument("--force", action="store_true", help="replace an existing --json file")
    args = p.parse_args(argv)
    if args.steps < 1:
        raise ConfigError(f"bench env: --steps must be at least 1, got {args.steps}")
    if args.seed < 0:
        raise ConfigError(f"bench env: --seed must be an integer >= 0, got {args.seed}")
    try:
        robots = [int(v) for v in args.robots.split(",") if v.strip()]
    except ValueError:
        raise ConfigError(f"bench env: --robots must be integers, got {args.robots!r}") from None
    if not robots or min(robots) < 1:
        raise ConfigError(f"bench env: --robots must be integers >= 1, got {args.robots!r}")
    latencies: list[int | None] = [None]
    if args.merge_latency_steps is not None:
        try:
            latencies = [int(v) for v in args.merge_latency_steps.split(",") if v.strip()]
        except ValueError:
            latencies = []
        if not latencies or min(v for v in latencies if v is not None) < 0:
            raise ConfigError(
                "bench env: --merge-latency-steps must be integers >= 0, "
                f"got {args.merge_latency_steps!r}"
            )
    evaluates: list[bool | None] = [None]
    if args.evaluate is not None:
        words = [v.strip() for v in args.evaluate.split(",") if v.strip()]
        if not words or any(w not in ("0", "1") for w in words):
            raise ConfigError(f"bench env: --evaluate must be 1 and/or 0, got {args.evaluate!r}")
        evaluates = [w == "1" for w in words]
    batched: list[int] = []
    if args.batched is not None:
        try:
            batched = [int(v) for v in args.batched.split(",") if v.strip()]
        except ValueError:
            batched = []
        if not batched or min(batched) < 1:
            raise ConfigError(
                f"bench env: --batched must be integers >= 1 (worlds), got {args.batched!r}"
            )
    if args.batched_steps < 1:
        raise ConfigError(
            f"bench env: --batched-steps must be at least 1, got {args.batched_steps}"
        )
    if args.batched_only and not batched and args.side_by_side is None and args.rollout is None:
        raise ConfigError("bench env: --batched-only needs --batched, --side-by-side or --rollout")
    if args.side_by_side is not None and args.side_by_side < 1:
        raise ConfigError(
            f"bench env: --side-by-side must be an integer >= 1 (worlds), got {args.side_by_side}"
        )
    if args.rounds < 1 or args.round_steps < 1:
        raise ConfigError(
            f"bench env: --rounds and --round-steps must be at least 1, got {args.rounds} "
            f"and {args.round_steps}"
        )
    teams: list[str | None] = []
    for word in (w.strip() for w in args.team.split(",") if w.strip()):
        if word != "random":
            from mrexplore.policies import POLICIES

            if word not in POLICIES:
                raise ConfigError(
                    f"bench env: --team must name 'random' or a team policy "
                    f"({', '.join(sorted(POLICIES))}), got {word!r}"
                )
        teams.append(None if word == "random" else word)
    if not teams:
        raise ConfigError(f"bench env: --team names no driver, got {args.team!r}")
    rollouts = [w.strip() for w in (args.rollout or "").split(",") if w.strip()]
    if args.rollout is not None:
        from mrexplore.policies import POLICIES

        if not rollouts or any(w not in POLICIES for w in rollouts):
            raise ConfigError(
                f"bench env: --rollout must name team policies ({', '.join(sorted(POLICIES))}), "
                f"got {args.rollout!r}"
            )
    if args.json:
        check_outputs([args.json], force=args.force, what="mrexplore bench env")
    merger = None if args.merger.lower() == "none" else args.merger
    rollout_options: dict[str, Any] = {}
    if args.env_options is not None:
        from mrexplore.studies.merge_bench import parse_options

        if args.rollout is None:
            raise ConfigError("bench env: --env-options applies to the --rollout rows: give one")
        rollout_options = parse_options(args.env_options, flag="--env-options")
        # a bad name or value fails here, before any row is measured
        mrexplore.parallel_env(**{**DEFAULT_WORLD, "merger": merger, **rollout_options}).close()
    print(
        f"mrexplore bench env: {args.steps} random-action steps per setting, seed {args.seed}, "
        f"merger {merger}; figures are CPU time of the stepping thread"
    )
    before = _machine()
    print(_load_line("before", before))
    results: dict[str, Any] = {}
    if not args.batched_only:
        print(HEADER)
    for latency in latencies if not args.batched_only else []:
        for label, opts in settings(robots, merger):
            if latency is not None:
                label = f"{label}, latency {latency}"
                opts = {**opts, "merge_latency_steps": latency}
            for evaluate in evaluates:  # side by side: on and off for one setting in a row
                name, o = label, opts
                if evaluate is not None:
                    name, o = f"{label}, evaluate {int(evaluate)}", {**opts, "evaluate": evaluate}
                r = measure(args.steps, args.seed, **o)
                results[name] = r
                print(row(name, r), flush=True)
    if batched:
        print(BATCHED_HEADER)
    for n in batched:
        for evaluate in evaluates:
            name = f"batched, N = {n} worlds x 2 robots, merger {merger}"
            b_opts: dict[str, Any] = {**DEFAULT_WORLD, "n_robots": 2, "merger": merger}
            if evaluate is not None:
                name = f"{name}, evaluate {int(evaluate)}"
                b_opts["evaluate"] = evaluate
            b_steps = args.batched_steps
            r = measure_batched(n, b_steps, args.seed, **b_opts)
            results[name] = r
            print(batched_row(name, r), flush=True)
    if rollouts:
        print(ROLLOUT_HEADER)
    for team in rollouts:
        for latency in latencies:
            r_opts: dict[str, Any] = {**DEFAULT_WORLD, "merger": merger, **rollout_options}
            n = int(r_opts.get("n_robots", 2))
            name = f"{team}, {r_opts['world']}, {n} robot{'s' * (n > 1)}, merger {merger}"
            others = {k: v for k, v in rollout_options.items() if k not in ("world", "n_robots")}
            if others:
                name += ", " + ", ".join(f"{k}={v}" for k, v in others.items())
            if latency is not None:
                name = f"{name}, latency {latency}"
                r_opts["merge_latency_steps"] = latency
            r = measure_rollout(args.steps, args.seed, team, **r_opts)
            results[f"rollout, {name}"] = r
            print(rollout_row(name, r), flush=True)
    if args.breakdown:
        r = measure(args.steps, args.seed, breakdown=True, **{**DEFAULT_WORLD, "merger": merger})
        ms = r["ms_per_step"]
        print(
            "stages, symmetric_office, 2 robots (ms per step): "
            f"act (move+sense+map) {ms['act']:.3f} | merge {ms['merge']:.3f} | "
            f"observe {ms['observe']:.3f} | other (reward, infos) {ms['other']:.3f}"
        )
        results["breakdown"] = r
    if args.side_by_side is not None:
        print(side_by_side_header(args.side_by_side, args.rounds, args.round_steps, merger))
        for team in teams:
            r = side_by_side(
                args.side_by_side,
                rounds=args.rounds,
                steps_per_round=args.round_steps,
                seed=args.seed,
                team=team,
                merger=merger,
            )
            results[f"side by side, {team or 'random'}"] = r
            for line in side_by_side_lines(r):
                print(line, flush=True)
        print(_load_line("after"))
    if args.json:
        results["machine"] = {**before, "load_after": _machine()["load"]}
        write_text(args.json, json.dumps(results, indent=2))
    return 0


if __name__ == "__main__":  # pragma: no cover
    raise SystemExit(main())
