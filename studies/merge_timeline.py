"""Where the first merge waits: every in-loop merge attempt against the truth.

Runs loop-study episodes of the ``semantic`` variant (``mrexplore bench loop``'s settings:
coordinated frontiers, random headings, noise on) with ``merge_latency_steps`` 0, so that each
attempt is decided in the step that starts it, and logs every attempt of every pair through
:attr:`mrexplore.merge.MapMergeTracker.attempt_observer`: the merger's reason, its best pose's
error against the truth (the largest displacement of the corners of robot j's known box, cells),
and the known space the two maps share under the true transform (m^2). The truth is read by this
script only (evaluation); nothing of it reaches the merger.

Per world it prints, as medians over the episodes (an episode that never gets there counts at
the time limit): when the maps first share known space under the truth, when that reaches 10 and
20 m^2, when the merger's best pose is the truth (within ``--truth-cells``) with 20 m^2 shared,
the first attempt the merger accepted, and the merge; then, per band of true shared space, in how
many attempts the best pose was the truth; then the evidence: in how many episodes the maps ever
shared 10 and 20 m^2 under the truth before the merge (a merger that needs a room's worth of
overlap cannot merge the others), and how long the merge waited once they shared 20 m^2.

``--replay K=V,...`` (repeatable) replays the tracker's confirmation rule (``confirmations``,
``confirm_tol_cells``, ``confirm_growth``) over the logged attempts: the first merge it would
have made, exactly, since nothing a robot sees before the first merge depends on that rule (the
attempts, their answers and the remembered rivals are the same). It first replays the run's own
settings and says whether that reproduces every logged first merge.

    python studies/merge_timeline.py --worlds symmetric_office twin_wings --seeds 20 \\
        --first-seed 3000 --json timeline.json --replay confirmations=1
"""

from __future__ import annotations

import argparse
import json
import statistics
import sys
from pathlib import Path
from typing import Any

import numpy as np

from mrexplore.errors import ConfigError
from mrexplore.experiments.episode import run_episode
from mrexplore.experiments.task_time import make_team
from mrexplore.grid import UNKNOWN, Transform, known_bbox, map_points
from mrexplore.merge.common import warp_into
from mrexplore.merge.tracker import AttemptRecord, MapMergeTracker
from mrexplore.studies.loop_study import POLICY, episode_options, validate
from mrexplore.studies.merge_bench import parse_options

#: Tracker options ``--replay`` can change (the confirmation rule), with their checks.
REPLAY_KEYS = ("confirmations", "confirm_tol_cells", "confirm_growth")

#: Bands of true shared space (m^2) of the per-band count.
BANDS_M2 = (0.0, 10.0, 20.0, 30.0, 40.0)


def corner_error(T1: Transform, T2: Transform, box: tuple[int, int, int, int]) -> float:
    """Largest distance (cells) between the corners of ``box`` (r0, r1, c0, c1) under two poses."""
    r0, r1, c0, c1 = box
    corners = np.array([[c0, r0], [c1, r0], [c0, r1], [c1, r1]], dtype=np.float64)
    (x1, y1), (x2, y2) = map_points(corners, T1), map_points(corners, T2)
    return float(np.hypot(x1 - x2, y1 - y2).max())


def run_one(
    world: str,
    seed: int,
    max_time_s: float,
    merge_options: dict[str, Any],
    env_options: dict[str, Any] | None = None,
    noise: bool = True,
) -> dict[str, Any]:
    """One episode; its attempts with the truth beside them (simulated seconds). Per attempt
    also what the tracker judged (remembered rivals still standing, too little wall) and, when
    the merger accepted, its pose and robot j's known box (canvas cells), for :func:`replay`."""
    opts = episode_options(
        world,
        "semantic",
        max_time_s,
        noise=noise,
        merge_options=merge_options,
        env_options=env_options,
    )
    opts["merge_latency_steps"] = 0
    attempts: list[dict[str, Any]] = []
    holder: dict[str, Any] = {}

    def observe(rec: AttemptRecord) -> None:
        sim = holder["env"].sim
        mi, mj = sim.maps[rec.i].to_int8(), sim.maps[rec.j].to_int8()
        T_true = sim.true_transform(rec.i, rec.j)
        shared = np.count_nonzero((mi != UNKNOWN) & (warp_into(mj, T_true, mi.shape) != UNKNOWN))
        box = known_bbox(mj)
        err = None
        if rec.best is not None and box is not None:
            err = corner_error(rec.best, T_true, box)
        attempts.append(
            {
                "t_s": rec.step * sim.config.robot.dt_s,
                "pair": [rec.i, rec.j],
                "shared_m2": float(shared) * sim.resolution_m**2,
                "best_error_cells": err,
                "accepted_by_merger": rec.T is not None,
                "reason": rec.result.reason,
                "pending": rec.pending,
                "merged": rec.merged,
                "standing": rec.standing,
                "thin": rec.thin,
                "overlap_cells": int(rec.result.overlap_cells),
                "T": None if rec.T is None else np.asarray(rec.T, dtype=float).tolist(),
                "box": None if box is None else [int(v) for v in box],
            }
        )

    def prepare(env: Any) -> None:
        holder["env"] = env
        env.fusion.tracker.attempt_observer = observe

    team = make_team(POLICY, ["robot_0", "robot_1"], "explore")
    r = run_episode(opts, team, seed, prepare=prepare)
    return {
        "world": world,
        "seed": seed,
        "first_merge_time_s": r.first_merge_time_s,
        "task_time_s": r.task_time_s,
        "wrong_merge": r.wrong_merge,
        "attempts": attempts,
    }


def _same(T1: Any, T2: Any, box: list[int] | None, tol: float) -> bool:
    """The tracker's test: two poses put robot j's known box's corners within ``tol`` cells."""
    if box is None:
        return False
    r0, r1, c0, c1 = box
    return corner_error(np.asarray(T1), np.asarray(T2), (r0, r1, c0, c1)) <= tol


def replay(
    episode: dict[str, Any],
    confirmations: int = 2,
    confirm_tol_cells: float = 2.0,
    confirm_growth: float = 0.0,
) -> tuple[float | None, float | None]:
    """The first merge (s) the tracker's confirmation rule with these settings would have made
    from the episode's logged attempts, and the merged pose's error against the truth (corner
    cells); (None, None) when it never merges. As :class:`MapMergeTracker` decides (with
    ``keep_run_on_refusal`` off): an attempt the merger refused, or whose pose a remembered
    rival still explains, or that rests on too little wall, breaks the run; an agreeing one on
    as much evidence (times ``1 + confirm_growth``) extends it."""
    pending: tuple[Any, int, int] | None = None
    for a in episode["attempts"]:
        if a["T"] is None or a["standing"] or a["thin"]:
            pending = None
            continue
        evidence, count = a["overlap_cells"], 1
        if pending is not None and _same(pending[0], a["T"], a["box"], confirm_tol_cells):
            if evidence < pending[2] * (1.0 + confirm_growth):
                continue
            count = pending[1] + 1
        if count >= confirmations:
            return float(a["t_s"]), a["best_error_cells"]
        pending = (a["T"], count, evidence)
    return None, None


def replay_lines(
    episodes: list[dict[str, Any]], settings: dict[str, Any], limit: float
) -> list[str]:
    """The printed lines of ``--replay``: whether the run's own settings reproduce its first
    merges, then per world the replayed settings against the run."""
    mismatch = [
        f"{e['world']} {e['seed']}"
        for e in episodes
        if replay(e, **settings["run"])[0] != e["first_merge_time_s"]
    ]
    lines = [
        f"replay of the run's own rule ({settings['run']}): "
        + ("reproduces every first merge" if not mismatch else f"differs in {mismatch}")
    ]
    for world in dict.fromkeys(e["world"] for e in episodes):
        eps = [e for e in episodes if e["world"] == world]
        got = [replay(e, **settings["replay"]) for e in eps]
        t = [limit if g[0] is None else g[0] for g in got]
        run = [limit if e["first_merge_time_s"] is None else e["first_merge_time_s"] for e in eps]
        errs = [g[1] for g in got if g[1] is not None]
        lines.append(
            f"{world}, replayed {settings['replay']}: merged {sum(g[0] is not None for g in got)}"
            f"/{len(eps)} (run: {sum(e['first_merge_time_s'] is not None for e in eps)}), "
            f"median first merge {statistics.median(t):.1f} s (run: {statistics.median(run):.1f}),"
            f" mean {statistics.mean(t):.1f} s (run: {statistics.mean(run):.1f}), earlier in "
            f"{sum(a < b for a, b in zip(t, run, strict=True))}, later in "
            f"{sum(a > b for a, b in zip(t, run, strict=True))}; largest error of a merged pose "
            f"{max(errs, default=0.0):.1f} cells"
        )
    return lines


def evidence_line(eps: list[dict[str, Any]]) -> str:
    """How many episodes' maps ever shared 10 and 20 m^2 under the truth before the merge, and
    how long the merge then waited after 20 m^2 (median over the merged episodes that did)."""
    ever = {
        m2: sum(any(a["shared_m2"] >= m2 for a in e["attempts"]) for e in eps) for m2 in (10, 20)
    }
    waits = []
    for e in eps:
        t20 = next((a["t_s"] for a in e["attempts"] if a["shared_m2"] >= 20), None)
        if e["first_merge_time_s"] is not None and t20 is not None:
            waits.append(e["first_merge_time_s"] - t20)
    merged = sum(e["first_merge_time_s"] is not None for e in eps)
    wait = f"{statistics.median(waits):.1f} s (mean {statistics.mean(waits):.1f})" if waits else "-"
    return (
        f"  evidence: the maps shared >= 10 m^2 under the truth in {ever[10]}/{len(eps)} episodes,"
        f" >= 20 m^2 in {ever[20]}, merged {merged}; after 20 m^2 the merge waited a median {wait}"
    )


def _first(attempts: list[dict[str, Any]], cond: Any, limit: float) -> float:
    return next((a["t_s"] for a in attempts if cond(a)), limit)


def summarize(episodes: list[dict[str, Any]], limit: float, truth_cells: float) -> list[str]:
    """The printed lines: per world, the medians and the per-band counts."""

    def near(a: dict[str, Any]) -> bool:
        return a["best_error_cells"] is not None and a["best_error_cells"] <= truth_cells

    lines = []
    for world in dict.fromkeys(e["world"] for e in episodes):
        eps = [e for e in episodes if e["world"] == world]
        cols = {
            "shared > 0": lambda a: a["shared_m2"] > 0,
            ">= 10 m^2": lambda a: a["shared_m2"] >= 10,
            ">= 20 m^2": lambda a: a["shared_m2"] >= 20,
            "truth best, >= 20 m^2": lambda a: a["shared_m2"] >= 20 and near(a),
            "first match": lambda a: a["accepted_by_merger"],
        }
        meds = {
            k: statistics.median(_first(e["attempts"], c, limit) for e in eps)
            for k, c in cols.items()
        }
        merged = statistics.median(
            e["first_merge_time_s"] if e["first_merge_time_s"] is not None else limit for e in eps
        )
        wrong = sum(bool(e["wrong_merge"]) for e in eps)
        lines.append(
            f"{world} ({len(eps)} episodes, {wrong} wrong): medians "
            + ", ".join(f"{k} {v:.1f} s" for k, v in meds.items())
            + f", merged {merged:.1f} s"
        )
        bands = []
        for lo, hi in zip(BANDS_M2, (*BANDS_M2[1:], float("inf")), strict=True):
            sel = [
                a
                for e in eps
                for a in e["attempts"]
                if lo <= a["shared_m2"] < hi and a["shared_m2"] > 0 and not a["merged"]
            ]
            bands.append(f"{lo:g}-{hi:g} m^2: {sum(near(a) for a in sel)}/{len(sel)}")
        lines.append("  attempts before the merge, best pose the truth: " + "; ".join(bands))
        lines.append(evidence_line(eps))
    return lines


def replay_settings(asked: dict[str, Any], merge_options: dict[str, Any]) -> dict[str, Any] | None:
    """The run's confirmation settings and the replayed ones (``None`` without ``--replay``),
    checked as the tracker checks them; a :class:`ConfigError` naming a key it cannot replay."""
    if not asked:
        return None
    bad = [k for k in asked if k not in REPLAY_KEYS]
    if bad:
        raise ConfigError(f"--replay can change {list(REPLAY_KEYS)} only, not {bad}")
    if merge_options.get("keep_run_on_refusal"):
        raise ConfigError("--replay follows the tracker with keep_run_on_refusal off")
    # the run's settings: the tracker's, built with the run's options (its defaults otherwise)
    given = {k: merge_options[k] for k in REPLAY_KEYS if k in merge_options}
    tracker = MapMergeTracker(2, **given)
    run = {k: getattr(tracker.options, k) for k in REPLAY_KEYS}
    MapMergeTracker(2, **{**run, **asked})  # the tracker's own checks of the values
    return {"run": run, "replay": {**run, **asked}}


def main(argv: list[str] | None = None) -> int:
    """Parse, check every option at the door, run, print; returns the exit code."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0] if __doc__ else None)
    ap.add_argument("--worlds", nargs="+", default=["symmetric_office", "twin_wings"])
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--first-seed", type=int, default=3000)
    ap.add_argument("--max-time-s", type=float, default=600.0)
    ap.add_argument("--merge-options", default="", metavar="K=V,K=V")
    ap.add_argument(
        "--env-options", default="", metavar="K=V,K=V", help="as mrexplore bench loop's"
    )
    ap.add_argument("--noise", default="on", help="on or off, as mrexplore bench loop's")
    ap.add_argument("--truth-cells", type=float, default=15.0, help="best pose = truth within")
    ap.add_argument(
        "--replay",
        action="append",
        default=[],
        metavar="K=V,K=V",
        help="replay the tracker's confirmation rule with these settings (repeatable) "
        f"({', '.join(REPLAY_KEYS)})",
    )
    ap.add_argument("--json", default=None, help="write every attempt here")
    ap.add_argument("--force", action="store_true", help="overwrite an existing --json")
    args = ap.parse_args(argv)
    try:
        mo = parse_options(args.merge_options, flag="--merge-options")
        eo = parse_options(args.env_options, flag="--env-options")
        validate(
            args.worlds,
            args.seeds,
            args.first_seed,
            ["semantic"],
            args.max_time_s,
            1,
            merge_options=mo,
            env_options=eo,
        )
        if args.noise not in ("on", "off"):
            raise ConfigError(f"--noise is on or off, got {args.noise!r}")
        if not args.truth_cells > 0:
            raise ConfigError(f"--truth-cells must be positive, got {args.truth_cells}")
        replays = [replay_settings(parse_options(r, flag="--replay"), mo) for r in args.replay]
        if args.json and Path(args.json).exists() and not args.force:
            raise ConfigError(f"{args.json} exists; pass --force to overwrite")
    except ConfigError as exc:
        print(f"merge_timeline: error: {exc}", file=sys.stderr)
        return 2
    episodes = []
    for world in args.worlds:
        for seed in range(args.first_seed, args.first_seed + args.seeds):
            ep = run_one(world, seed, args.max_time_s, mo, eo, noise=args.noise == "on")
            print(
                f"{world} {seed}: first merge {ep['first_merge_time_s']}, "
                f"{len(ep['attempts'])} attempts",
                flush=True,
            )
            episodes.append(ep)
    print("\n".join(summarize(episodes, args.max_time_s, args.truth_cells)))
    for replayed in replays:
        if replayed is not None:
            print("\n".join(replay_lines(episodes, replayed, args.max_time_s)))
    if args.json:
        Path(args.json).write_text(
            json.dumps({"merge_options": mo, "env_options": eo, "episodes": episodes})
        )
        print(f"wrote {args.json}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
