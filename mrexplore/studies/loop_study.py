"""The in-loop merge study: what merging is worth in an exploration team, against an oracle.

For each world and seed, a team explores to ``target_coverage`` (95 %) within ``max_time_s``
(600 s) with the coordinated-frontier policy, from random start headings, with range and
odometry noise on (:data:`LOOP_ENV_OPTIONS`). Variants (same world, same seed, same start of
``robot_0``):

- ``semantic``: 2 robots, the default merger, through the env's tracker;
- ``oracle``: 2 robots, :class:`~mrexplore.studies.oracle.OracleMerger`: the true
  transform as soon as the two maps share any known cell, through the same tracker (same
  confirmations, re-checks and drops);
- ``none``: 2 robots that never merge;
- ``single``: 1 robot;
- ``seeded`` (asked for by name, not in the default set): 2 robots,
  :class:`~mrexplore.studies.oracle.SeededMerger`: the semantic merger with the true pose
  added to its hypotheses, judged by the same rules. Between ``semantic`` and ``seeded`` lies
  what the search misses; between ``seeded`` and ``oracle``, what the decision rules (and the
  evidence the maps hold) refuse;
- ``sighting`` (asked for by name): 2 robots, the default merger, with sightings on
  (``sighting_range_m`` :data:`SIGHTING_RANGE_M`, the lidar's range): robots that see each
  other measure their relative pose, and the tracker looks near the guess that follows (a
  rendezvous; :mod:`mrexplore.environment.sighting`).
- ``oracle_room`` (asked for by name): 2 robots, the oracle held to a room's worth of evidence:
  the true transform once the maps share :data:`ROOM_EVIDENCE_M2` (20 m^2, the in-loop
  merger's own floor) of known space under it. What a merger could do that needs a room's
  worth of overlap and never misses it: between it and ``oracle`` lies what no merger that must
  tell a room from its twin can take; between ``semantic`` and it, what ours leaves;
- ``oracle_meet`` (asked for by name): 2 robots, the oracle for robots that have met: sightings
  on as in ``sighting``, the tracker's ``rendezvous_only`` on, and the true transform at the
  first attempt after the robots saw each other. What a merger that waits for a meeting could
  do at best, where the maps cannot tell the copies apart (a building the same under a turn):
  between it and ``oracle_room`` lies the price of waiting to meet; between the recipe
  (``sighting`` with ``rendezvous_only``) and it, what the recipe leaves;
- ``verify`` (asked for by name): 2 robots, the default merger, and the team policy
  :data:`VERIFY_POLICY`: before a merge, a frontier whose surroundings the teammate has mapped
  under one of the merger's candidate transforms is worth more (active disambiguation: the
  robot goes where the candidates can be told apart).

Per episode it records whether the maps were merged, the first merge, the task time, whether
the target was reached, whether a transform >= 5 cells off the truth was held at any step, the
seconds it was held (``merged_wrongly_s``) and the largest share of contradicting claims in a
robot's own-or-fused map (``fused_contradiction``): see
:mod:`mrexplore.environment.parallel_env`. Prints a table per world
(:mod:`~mrexplore.studies.loop_report`) and writes ``<out>.json`` and ``<out>.md``.
``--jobs N`` runs episodes in N processes; every episode depends only on its world, variant
and seed, so the results equal a serial run.

``--task navigate`` runs the navigation task instead (the team explores for ``nav_warmup_s``,
120 s, then ``robot_0`` drives to a goal, ``--nav-goal far`` or ``teammate``, while its teammate
keeps exploring; the task time is the time after the warm-up, as in ``mrexplore task-time``):
what the merger buys a robot that must reach a place, against the oracle's.

``--family NAME --part {tune,test} --worlds N`` runs the study on worlds 0 .. N-1 of a world
family's part (:mod:`mrexplore.world.family`: floors with 2 or more identical rooms, split into
a tuning and a test part by world seed), by default with the variants :data:`FAMILY_VARIANTS`
(the merger beside the oracle, the room oracle and never merging); the report adds the
aggregate over all the part's worlds (wrong-merge episodes with the upper 95 % bound of their
rate, merges, task times; :func:`~mrexplore.studies.loop_report.aggregate`). Each world
travels to the worker processes as its spec string (``family:paper_like/tune/3``) and is
rebuilt there from its world seed. Tune rules on the ``tune`` part only.

Run: ``mrexplore bench loop --seeds 20 --jobs 2 --out results/loop_study``;
``mrexplore bench loop --family paper_like --part tune --worlds 20 --seeds 5 --jobs 2
--out results/loop_paper_like_tune``.
"""

from __future__ import annotations

import argparse
import json
import math
import multiprocessing
from collections.abc import Mapping, Sequence
from concurrent.futures import ProcessPoolExecutor, as_completed
from pathlib import Path
from typing import Any

from mrexplore.errors import ConfigError, MrexploreError
from mrexplore.experiments.task_time import NAV_WARMUP_S
from mrexplore.studies.loop_report import (
    MERGER_VARIANTS,
    against,
    aggregate,
    format_tables,
    load_study,
    summarize,
)
from mrexplore.studies.merge_bench import parse_options
from mrexplore.studies.oracle import OracleMerger, SeededMerger

#: The worlds of the study (two symmetric generated floors, two real maps).
WORLDS: tuple[str, ...] = ("symmetric_office", "twin_wings", "tb3_office", "depot")
#: Variants: merger for two robots, or one robot (the default set of the study).
VARIANTS: tuple[str, ...] = ("semantic", "oracle", "none", "single")
#: Every variant the study can run (``seeded`` and ``sighting`` are asked for by name).
ALL_VARIANTS: tuple[str, ...] = (
    *VARIANTS,
    "seeded",
    "sighting",
    "verify",
    "oracle_room",
    "oracle_meet",
)
#: The default variants of a family run (``--family``): the merger, the oracle, the oracle held
#: to a room's worth of evidence, and never merging.
FAMILY_VARIANTS: tuple[str, ...] = ("semantic", "oracle", "oracle_room", "none")
#: Worlds of a family run when ``--worlds`` is not given.
FAMILY_WORLDS = 10
#: Known space (m^2) the ``oracle_room`` variant's oracle waits for under the truth: a room's
#: worth (a match the size of a room may be its twin). A reference, not a rule of the merger.
ROOM_EVIDENCE_M2 = 20.0
#: ``sighting_range_m`` of the ``sighting`` variant: the lidar's default range (metres).
SIGHTING_RANGE_M = 4.0
#: Env options the study sets itself (its flags and its protocol): not for ``--env-options``.
STUDY_SET_KEYS: tuple[str, ...] = (
    "world",
    "merger",
    "max_time_s",
    "task",
    "nav_goal",
    "nav_warmup_s",
    "sighting_range_m",
    "merge_options",
    "aligned_headings",
    "range_noise_m",
    "odom_noise_trans",
    "odom_noise_rot",
    "odom_noise_rot_per_m",
    "target_coverage",
)
POLICY = "coordinated-frontier"
#: The ``verify`` variant's team policy.
VERIFY_POLICY = "coordinated-frontier-verify"
#: Env options of every episode: random start headings, range noise 2 cm (std), odometry
#: translation noise 1 % of the distance, heading noise 0.005 rad per radian turned and
#: 0.001 rad per metre driven (std): moderate drift, about 2 deg of heading after a 600 s run.
LOOP_ENV_OPTIONS: dict[str, Any] = {
    "aligned_headings": False,
    "range_noise_m": 0.02,
    "odom_noise_trans": 0.01,
    "odom_noise_rot": 0.005,
    "odom_noise_rot_per_m": 0.001,
    "target_coverage": 0.95,
}


#: The noise options switched off by ``noise=False`` (exact odometry, the env's default 1 cm
#: range noise): without drift the true transform between start frames is the one right answer,
#: so "wrong merge" means a wrong place, not a map bent by odometry.
NOISE_OFF: dict[str, Any] = {
    "range_noise_m": 0.01,
    "odom_noise_trans": 0.0,
    "odom_noise_rot": 0.0,
    "odom_noise_rot_per_m": 0.0,
}


#: Tasks of the study: exploration (the default) or navigation after a warm-up.
TASKS: tuple[str, ...] = ("explore", "navigate")
#: Where robot_0's navigation goal lies (the env's ``nav_goal``).
NAV_GOALS: tuple[str, ...] = ("far", "teammate")


def family_worlds(family: str, part: str, n: int) -> list[str]:
    """The specs of worlds 0 .. n-1 of ``family``'s ``part`` (``family:<family>/<part>/<k>``);
    a :class:`ConfigError` naming a bad family, part or count."""
    from mrexplore.errors import WorldError
    from mrexplore.world.family import family_seeds, family_spec

    if isinstance(n, bool) or not isinstance(n, int) or n < 1:
        raise ConfigError(f"loop study: --worlds must be an integer >= 1 with --family, got {n!r}")
    try:
        family_seeds(family, part, n)
        return [family_spec(family, part, k) for k in range(n)]
    except WorldError as exc:
        raise ConfigError(f"loop study: {exc}") from exc


def family_block(family: str, part: str, n: int) -> dict[str, Any]:
    """What a family run records of where it was measured: family, part, the worlds' specs,
    world seeds and layouts (the generator's ``layout``: corridor, hall, open plan, ...)."""
    from mrexplore.world.family import family_seeds, family_world

    return {
        "name": family,
        "part": part,
        "specs": family_worlds(family, part, n),
        "world_seeds": family_seeds(family, part, n),
        "layouts": [str(family_world(family, part, k).meta.get("layout", "-")) for k in range(n)],
    }


def study_env_options(
    noise: bool = True, task: str = "explore", nav_goal: str = "far"
) -> dict[str, Any]:
    """The env options shared by every episode of the study."""
    opts = {**LOOP_ENV_OPTIONS, **({} if noise else NOISE_OFF)}
    if task == "navigate":
        opts.update(task="navigate", nav_goal=nav_goal, nav_warmup_s=NAV_WARMUP_S)
    return opts


def episode_options(
    world: str,
    variant: str,
    max_time_s: float,
    noise: bool = True,
    task: str = "explore",
    nav_goal: str = "far",
    merge_options: Mapping[str, Any] | None = None,
    env_options: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """Env options of one episode of ``variant`` (the oracle's merger object not included);
    ``merge_options`` go to the variants that merge with the named semantic merger (its options
    and the tracker's, as the env's ``merge_options``); ``env_options`` (:data:`STUDY_SET_KEYS`
    excluded) go to every variant, ``n_robots`` (the team's size, default 2) to every variant
    but ``single``."""
    opts: dict[str, Any] = {
        **study_env_options(noise, task, nav_goal),
        **(env_options or {}),
        "world": world,
        "max_time_s": float(max_time_s),
    }
    if variant == "single":
        opts["n_robots"] = 1
    else:
        opts.setdefault("n_robots", 2)  # a team of two unless --env-options n_robots says
    opts["merger"] = None if variant in ("none", "single") else "semantic"
    if variant in ("sighting", "oracle_meet"):
        opts["sighting_range_m"] = SIGHTING_RANGE_M
    if variant == "oracle_meet":
        opts["merge_options"] = {"rendezvous_only": True}
    if merge_options and variant in MERGER_VARIANTS:
        opts["merge_options"] = dict(merge_options)
    return opts


def run_loop_episode(
    world: str,
    variant: str,
    seed: int,
    max_time_s: float,
    noise: bool = True,
    task: str = "explore",
    nav_goal: str = "far",
    merge_options: Mapping[str, Any] | None = None,
    env_options: Mapping[str, Any] | None = None,
) -> dict[str, Any]:
    """One episode of the study; a JSON-friendly record (simulated seconds, NaN -> None).
    Upper-case ``merge_options`` are rule constants, set for this episode
    (:func:`~mrexplore.merge.constants.rule_constants`)."""
    from mrexplore.merge.constants import rule_constants, split_constants

    proper, constants = split_constants(merge_options or {})
    with rule_constants(constants):
        return _run_loop_episode(
            world, variant, seed, max_time_s, noise, task, nav_goal, proper or None, env_options
        )


def _run_loop_episode(
    world: str,
    variant: str,
    seed: int,
    max_time_s: float,
    noise: bool,
    task: str,
    nav_goal: str,
    merge_options: Mapping[str, Any] | None,
    env_options: Mapping[str, Any] | None,
) -> dict[str, Any]:
    from mrexplore.experiments.episode import run_episode
    from mrexplore.experiments.task_time import make_team

    opts = episode_options(
        world, variant, max_time_s, noise, task, nav_goal, merge_options, env_options
    )
    oracle: OracleMerger | None = None
    if variant in ("oracle", "oracle_meet"):
        oracle = OracleMerger()
    elif variant == "oracle_room":
        oracle = OracleMerger(min_shared_m2=ROOM_EVIDENCE_M2)
    elif variant == "seeded":
        oracle = SeededMerger()
    if oracle is not None:
        opts["merger"] = oracle
    agents = [f"robot_{k}" for k in range(opts["n_robots"])]
    team = make_team(VERIFY_POLICY if variant == "verify" else POLICY, agents, task)
    envs: list[Any] = []

    def prepare(env: Any) -> None:
        envs.append(env)  # its tracker's drops are read after the run
        if oracle is not None:
            oracle.bind(env)

    r = run_episode(opts, team, seed, prepare=prepare)
    s = r.summary()
    tracker = envs[0].unwrapped.fusion.tracker
    dt_s = float(envs[0].unwrapped.config.dt_s)
    drops = (
        []
        if tracker is None
        else [[d.contradicted_step * dt_s, d.dropped_step * dt_s] for d in tracker.drops]
    )
    return {
        "world": world,
        "variant": variant,
        "seed": int(seed),
        "merged": r.first_merge_time_s is not None,
        "first_merge_time_s": r.first_merge_time_s,
        "task_time_s": r.task_time_s,
        "reached": r.success,
        "coverage": r.coverage,
        "wrong_merge": r.wrong_merge,
        "merged_wrongly_s": r.merged_wrongly_s,
        "max_fused_contradiction": s["max_fused_contradiction"],
        "merges_lost": r.merges_lost,
        # every merge the tracker let go: [first contradiction, drop] (simulated s), and why
        # (DropRecord.cause: contradicted, outranked, moved, sighting)
        "drops_s": drops,
        "drop_causes": [] if tracker is None else [d.cause for d in tracker.drops],
        # what the merging cost: the attempts and re-checks applied (counts, the same on any
        # machine; their CPU is the rollout bench's to measure)
        "merge_attempts": 0 if tracker is None else tracker.work.attempts,
        "merge_rechecks": 0 if tracker is None else tracker.work.rechecks,
    }


def _run_task(
    task: tuple[str, str, int, float, bool, str, str, dict[str, Any] | None, dict[str, Any] | None],
) -> dict[str, Any]:
    import cv2

    cv2.setNumThreads(1)  # one core per process: --jobs decides the parallelism
    return run_loop_episode(*task)


def validate(
    worlds: Sequence[str],
    seeds: int,
    first_seed: int,
    variants: Sequence[str],
    max_time_s: float,
    jobs: int,
    task: str = "explore",
    nav_goal: str = "far",
    merge_options: Mapping[str, Any] | None = None,
    env_options: Mapping[str, Any] | None = None,
) -> None:
    """Check every option before any work; a bad one is a :class:`ConfigError` naming it."""
    from mrexplore.world import load_world

    if not worlds:
        raise ConfigError("loop study: --worlds is empty")
    for w in worlds:
        try:
            load_world(w)
        except MrexploreError as exc:
            raise ConfigError(f"loop study: bad world {w!r}: {exc}") from exc
    if isinstance(seeds, bool) or not isinstance(seeds, int) or seeds < 1:
        raise ConfigError(f"loop study: --seeds must be an integer >= 1, got {seeds!r}")
    if isinstance(first_seed, bool) or not isinstance(first_seed, int) or first_seed < 0:
        raise ConfigError(f"loop study: --first-seed must be an integer >= 0, got {first_seed!r}")
    if not variants:
        raise ConfigError(f"loop study: --variants is empty; choose from {list(ALL_VARIANTS)}")
    bad = [v for v in variants if v not in ALL_VARIANTS]
    if bad:
        raise ConfigError(
            f"loop study: unknown variant(s) {bad}; variants are {list(ALL_VARIANTS)}"
        )
    if len(set(variants)) != len(variants) or len(set(worlds)) != len(worlds):
        raise ConfigError("loop study: a world or variant is listed twice")
    if not (isinstance(max_time_s, (int, float)) and math.isfinite(max_time_s) and max_time_s > 0):
        raise ConfigError(f"loop study: --max-time-s must be a positive number, got {max_time_s!r}")
    if isinstance(jobs, bool) or not isinstance(jobs, int) or jobs < 1:
        raise ConfigError(f"loop study: --jobs must be an integer >= 1, got {jobs!r}")
    if task not in TASKS:
        raise ConfigError(f"loop study: --task must be one of {list(TASKS)}, got {task!r}")
    if nav_goal not in NAV_GOALS:
        raise ConfigError(
            f"loop study: --nav-goal must be one of {list(NAV_GOALS)}, got {nav_goal!r}"
        )
    if merge_options:
        from mrexplore.merge.constants import split_constants
        from mrexplore.merge.fusion import FusionStage

        try:  # the tracker checks every name and value, as the env would at its first reset
            proper, _ = split_constants(merge_options)
            FusionStage(
                ["a", "b"], "semantic", merge_options=proper, resolution_m=0.05, sightings=True
            )
        except ConfigError as exc:
            raise ConfigError(f"loop study: --merge-options: {exc}") from exc
        blind = [v for v in variants if v in MERGER_VARIANTS and v != "sighting"]
        # given, not followed from the sightings this check's stage has
        if proper.get("rendezvous_only") is True and blind:
            raise ConfigError(
                f"loop study: --merge-options rendezvous_only=true merges only robots that saw "
                f"each other; of the variants it applies to, only 'sighting' has sightings "
                f"(drop {blind})"
            )
    if env_options:
        from mrexplore.environment.config import EnvConfig

        taken = sorted(set(env_options) & set(STUDY_SET_KEYS))
        if taken:
            raise ConfigError(
                f"loop study: --env-options: {taken} are set by the study itself "
                f"(its own flags or its protocol: {list(STUDY_SET_KEYS)})"
            )
        try:  # every name and value, as the env would check them
            EnvConfig.from_kwargs(**{**study_env_options(True, task, nav_goal), **env_options})
        except ConfigError as exc:
            raise ConfigError(f"loop study: --env-options: {exc}") from exc
        if "n_robots" in env_options and env_options["n_robots"] < 2:
            raise ConfigError(
                f"loop study: --env-options n_robots is the team's size (the 'single' variant "
                f"is one robot anyway): need >= 2, got {env_options['n_robots']!r}"
            )
    if task == "navigate" and max_time_s <= NAV_WARMUP_S:
        raise ConfigError(
            f"loop study: --max-time-s ({max_time_s}) must exceed the navigation warm-up "
            f"({NAV_WARMUP_S} s)"
        )


def run_study(
    worlds: Sequence[str] = WORLDS,
    seeds: int = 20,
    first_seed: int = 1000,
    variants: Sequence[str] = VARIANTS,
    max_time_s: float = 600.0,
    jobs: int = 1,
    progress: bool = True,
    noise: bool = True,
    task: str = "explore",
    nav_goal: str = "far",
    merge_options: Mapping[str, Any] | None = None,
    env_options: Mapping[str, Any] | None = None,
    reuse: Mapping[str, Mapping[str, Any]] | None = None,
    family: tuple[str, str] | None = None,
) -> dict[str, Any]:
    """Run every (world, variant, seed) episode of ``task``; returns the JSON document.

    ``merge_options``: options of the semantic merger and its tracker for the variants that
    use them (:data:`MERGER_VARIANTS`), e.g. ``{"min_common_m2": 10.0}``: a rule's ablation.
    ``env_options``: env options for every variant beyond the study's own (not those of
    :data:`STUDY_SET_KEYS`), e.g. ``{"map_l_occ": 2.6}``: the mapper's.

    ``reuse``: other studies' documents by file name; an episode one of them holds is taken
    from it instead of run again. An episode depends only on its world, variant, seed, the
    study's settings and the code, worlds and maps, which must all be the same (each document
    records a digest of the last: :func:`reusable`). The document records how many episodes
    came from each file.

    With ``jobs > 1`` the episodes run in that many processes (spawned, so no state is shared);
    the records come back in the serial order, identical to a serial run.

    ``family``: (family, part) when ``worlds`` are that part's worlds 0 .. N-1 (their specs,
    :func:`family_worlds`): the document then records them (``family``: name, part, specs,
    world seeds) and the aggregate over all of them (``aggregate``).
    """
    if family is not None and list(worlds) != family_worlds(*family, len(worlds)):
        raise ConfigError(
            f"loop study: the worlds of a {family[0]} {family[1]} run must be its worlds 0 .. "
            f"{len(worlds) - 1}, in order"
        )
    validate(
        worlds,
        seeds,
        first_seed,
        variants,
        max_time_s,
        jobs,
        task,
        nav_goal,
        merge_options,
        env_options,
    )
    mo = dict(merge_options) if merge_options else None
    eo = dict(env_options) if env_options else None
    settings = study_settings(noise, task, nav_goal, max_time_s, mo, eo)
    seed_list = list(range(first_seed, first_seed + seeds))
    tasks = [
        (w, v, s, float(max_time_s), bool(noise), task, nav_goal, mo, eo)
        for w in worlds
        for v in variants
        for s in seed_list
    ]
    records: list[dict[str, Any] | None] = [None] * len(tasks)
    taken = reusable(settings, reuse or {})
    reused = {name: 0 for name in reuse or {}}
    for k, t in enumerate(tasks):
        if t[:3] in taken:
            name, records[k] = taken[t[:3]]
            reused[name] += 1
    idle = [name for name, n in reused.items() if n == 0]
    if idle:  # a file given to be reused that cannot be is a mistake
        raise ConfigError(
            f"loop study: --reuse {idle[0]!r} holds no episode of this run's worlds, variants "
            "and seeds (or an earlier --reuse file holds them all)"
        )
    todo = [k for k, r in enumerate(records) if r is None]
    from tqdm import tqdm

    bar = tqdm(total=len(todo), desc="loop episodes", disable=not progress, unit="ep")
    if jobs == 1:
        for k in todo:
            records[k] = run_loop_episode(*tasks[k])
            bar.update(1)
    else:
        ctx = multiprocessing.get_context("spawn")
        with ProcessPoolExecutor(max_workers=jobs, mp_context=ctx) as pool:
            futures = {pool.submit(_run_task, tasks[k]): k for k in todo}
            for fut in as_completed(futures):
                records[futures[fut]] = fut.result()
                bar.update(1)
    bar.close()
    episodes = [r for r in records if r is not None]
    return {
        **settings,
        "extra_env_options": eo or {},
        **({"reused": reused} if reused else {}),
        "worlds": list(worlds),
        "variants": list(variants),
        "seeds": seed_list,
        "units": "simulated seconds",
        "episodes": episodes,
        "summary": summarize(episodes, worlds, variants),
        **(
            {
                "family": (block := family_block(*family, len(worlds))),
                "aggregate": aggregate(
                    episodes, variants, dict(zip(block["specs"], block["layouts"], strict=True))
                ),
            }
            if family is not None
            else {}
        ),
    }


def study_settings(
    noise: bool,
    task: str,
    nav_goal: str,
    max_time_s: float,
    merge_options: Mapping[str, Any] | None,
    env_options: Mapping[str, Any] | None,
) -> dict[str, Any]:
    """What, beside world, variant and seed, decides an episode: the code, worlds and maps
    (:func:`~mrexplore.studies.provenance.source_digest`), the policy, every env option and
    the merger's options, as the study's document records them."""
    from mrexplore.studies.provenance import source_digest

    return {
        "source_digest": source_digest(),
        "policy": POLICY,
        "env_options": {
            **study_env_options(noise, task, nav_goal),
            **(env_options or {}),
            "max_time_s": float(max_time_s),
        },
        "merge_options": dict(merge_options or {}),
    }


def _differences(part: str, there: Any, here: Mapping[str, Any]) -> list[str]:
    """``part``'s options that differ between a saved study (``there``) and this run, compared
    as JSON (so ``true`` is not ``1``)."""
    if not isinstance(there, Mapping):
        return [f"{part} is not a mapping there"]
    return [
        f"{part} {k}: {there.get(k)!r} there, {here.get(k)!r} here"
        for k in sorted(set(here) | set(there))
        if json.dumps(there.get(k)) != json.dumps(here.get(k))
    ]


def reusable(
    settings: Mapping[str, Any], docs: Mapping[str, Mapping[str, Any]]
) -> dict[tuple[str, str, int], tuple[str, dict[str, Any]]]:
    """The episodes of ``docs`` (studies by file name) that a run with ``settings`` may take:
    (world, variant, seed) -> (file name, record); the first file that holds one wins.

    A study made by other code, worlds or maps (its ``source_digest``) or with other settings is
    a :class:`ConfigError` naming the difference, and so is a malformed episode.
    """
    taken: dict[tuple[str, str, int], tuple[str, dict[str, Any]]] = {}
    for name, doc in docs.items():
        if doc.get("source_digest") != settings["source_digest"]:
            raise ConfigError(
                f"loop study: --reuse {name!r} was made by other code, worlds or maps (or "
                "before studies recorded theirs): its episodes may differ from a run now"
            )
        differ = [
            *_differences("env_options", doc.get("env_options", {}), settings["env_options"]),
            *_differences("merge_options", doc.get("merge_options", {}), settings["merge_options"]),
        ]
        if doc.get("policy") != settings["policy"]:
            differ.insert(0, f"policy {doc.get('policy')!r} there, {settings['policy']!r} here")
        if differ:
            raise ConfigError(
                f"loop study: --reuse {name!r} was made with other settings: {'; '.join(differ)}"
            )
        for e in doc["episodes"]:
            try:
                key = (e["world"], e["variant"], e["seed"])
            except (KeyError, TypeError) as exc:
                raise ConfigError(
                    f"loop study: --reuse {name!r} holds an episode without world, variant and seed"
                ) from exc
            taken.setdefault(key, (name, e))
    return taken


def _worlds_and_variants(
    worlds: Sequence[str] | None,
    variants: Sequence[str] | None,
    family: str | None,
    part: str | None,
) -> tuple[list[str], list[str], tuple[str, str] | None]:
    """The run's world specs, variants and (family, part) from the CLI's flags: the four fixed
    worlds and :data:`VARIANTS` by default; with ``--family``, worlds 0 .. N-1 of ``--part``
    (``--worlds N``) and :data:`FAMILY_VARIANTS`."""
    if family is None:
        if part is not None:
            raise ConfigError("loop study: --part needs --family")
        return list(worlds or WORLDS), list(variants or VARIANTS), None
    if part is None:
        raise ConfigError("loop study: --family needs --part tune or --part test")
    if worlds is None:
        n = FAMILY_WORLDS
    elif len(worlds) == 1 and worlds[0].isascii() and worlds[0].isdigit():
        n = int(worlds[0])
    else:
        raise ConfigError(
            f"loop study: with --family, --worlds is how many worlds (one integer >= 1), got "
            f"{' '.join(worlds)!r}"
        )
    return family_worlds(family, part, n), list(variants or FAMILY_VARIANTS), (family, part)


def main(argv: Sequence[str] | None = None) -> int:
    """CLI: ``mrexplore bench loop [--worlds ..] [--family F --part P [--worlds N]] [--seeds N]
    [--first-seed S] [--variants ..]
    [--max-time-s T] [--jobs N] [--task T] [--nav-goal G] [--out STEM] [--force]``; returns the
    exit code."""
    p = argparse.ArgumentParser(
        prog="mrexplore bench loop", description=__doc__.split("\n\n")[0] if __doc__ else None
    )
    p.add_argument(
        "--worlds",
        nargs="+",
        default=None,
        help="worlds (default: all four); with --family, how many of the part's worlds "
        f"(default {FAMILY_WORLDS})",
    )
    p.add_argument(
        "--family",
        default=None,
        help="run on a world family's worlds instead (paper_like, office_row, radial): worlds 0 .. "
        "N-1 of --part",
    )
    p.add_argument(
        "--part",
        default=None,
        help="with --family: tune (world seeds 0, 1, ...), test (100000, ...) or test2 .. "
        "test99 (k * 100000, ...: each kept for a rule chosen after the part before it was "
        "read); tune rules on tune only",
    )
    p.add_argument("--seeds", type=int, default=20, help="seeds per world (default 20)")
    p.add_argument("--first-seed", type=int, default=1000, help="first seed (default 1000)")
    p.add_argument(
        "--variants",
        nargs="+",
        default=None,
        help=f"of {list(ALL_VARIANTS)} (default: {list(VARIANTS)}; with --family "
        f"{list(FAMILY_VARIANTS)})",
    )
    p.add_argument("--max-time-s", type=float, default=600.0, help="truncation, simulated s")
    p.add_argument("--jobs", type=int, default=1, help="episodes in this many processes")
    p.add_argument("--out", default="results/loop_study", help="writes OUT.json and OUT.md")
    p.add_argument("--force", action="store_true", help="overwrite existing outputs")
    p.add_argument(
        "--task",
        default="explore",
        help=f"of {list(TASKS)} (default explore); navigate: {NAV_WARMUP_S:.0f} s of "
        "exploring, then robot_0 drives to a goal",
    )
    p.add_argument(
        "--nav-goal", default="far", help=f"navigate: of {list(NAV_GOALS)} (default far)"
    )
    p.add_argument(
        "--merge-options",
        default="",
        metavar="K=V,K=V",
        help="options of the semantic merger and its tracker for the variants "
        f"{list(MERGER_VARIANTS)}, e.g. min_common_m2=10,confirmations=3, and their rule "
        "constants in upper case, e.g. OUTRANKED_DROP=false (a rule's ablation)",
    )
    p.add_argument(
        "--env-options",
        default="",
        metavar="K=V,K=V",
        help="env options for every variant beyond the study's own, e.g. map_l_occ=2.6 "
        "(the mapper's) or n_robots=3 (teams of three; 'single' stays one robot)",
    )
    p.add_argument(
        "--against",
        default=None,
        metavar="JSON",
        help="another study's JSON (e.g. docs/results/loop_study.json): also print this run "
        "minus that one on the same seeds, per world and variant (paired task time, first "
        "merges), and record it",
    )
    p.add_argument(
        "--reuse",
        nargs="+",
        default=[],
        metavar="JSON",
        help="studies made with the same settings by the same code, worlds and maps (each "
        "records a digest of them): their episodes of this run's worlds, variants and seeds "
        "are taken instead of run again (a study made otherwise is refused)",
    )
    p.add_argument(
        "--noise",
        choices=("on", "off"),
        default="on",
        help="range and odometry noise (default on); off: exact odometry, so a merge error "
        "against the truth is a wrong place, not drift",
    )
    args = p.parse_args(list(argv) if argv is not None else None)
    stem = Path(args.out)
    outputs = [Path(f"{stem}.json"), Path(f"{stem}.md")]
    try:
        worlds, variants, family = _worlds_and_variants(
            args.worlds, args.variants, args.family, args.part
        )
        merge_options = parse_options(args.merge_options, flag="--merge-options")
        env_options = parse_options(args.env_options, flag="--env-options")
        other = None if args.against is None else load_study(args.against)
        if len({Path(f).resolve() for f in args.reuse}) < len(args.reuse):
            raise ConfigError("loop study: a --reuse file is given twice")
        reuse = {f: load_study(f, "--reuse") for f in args.reuse}
        validate(
            worlds,
            args.seeds,
            args.first_seed,
            variants,
            args.max_time_s,
            args.jobs,
            args.task,
            args.nav_goal,
            merge_options,
            env_options,
        )
        if other is not None:
            planned = {
                (w, v, s)
                for w in worlds
                for v in variants
                for s in range(args.first_seed, args.first_seed + args.seeds)
            }
            theirs = {(e.get("world"), e.get("variant"), e.get("seed")) for e in other["episodes"]}
            if not planned & theirs:
                raise ConfigError(
                    f"loop study: --against {args.against!r} holds no episode of this run's "
                    "worlds, variants and seeds: nothing to pair"
                )
        existing = [str(f) for f in outputs if f.exists()]
        if existing and not args.force:
            raise ConfigError(f"loop study: {existing} exist; pass --force to overwrite")
        doc = run_study(
            worlds,
            args.seeds,
            args.first_seed,
            variants,
            args.max_time_s,
            args.jobs,
            noise=args.noise == "on",
            task=args.task,
            nav_goal=args.nav_goal,
            merge_options=merge_options,
            env_options=env_options,
            reuse=reuse,
            family=family,
        )
        if other is not None:
            doc["against"] = against(doc, other, str(args.against))
    except ConfigError as exc:
        print(f"mrexplore bench loop: error: {exc}")
        return 2
    text = format_tables(doc)
    print(text)
    stem.parent.mkdir(parents=True, exist_ok=True)
    outputs[0].write_text(json.dumps(doc, indent=1, allow_nan=False))
    outputs[1].write_text(format_tables(doc, markdown=True) + "\n")
    print(f"wrote {outputs[0]} and {outputs[1]}")
    return 0
