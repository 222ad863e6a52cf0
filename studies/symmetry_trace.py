"""Would a map's copies of itself have told a held merge from its rivals? Loop episodes replayed
to see when a self-match of either robot's map, moved onto the held pose, stands as a rival.

    python studies/symmetry_trace.py docs/results/loop_radial_test2.json [--which wrong]
        [--variant semantic] [--every 20] [--limit N]

For each episode of ``--variant`` in a committed loop-study file (``--which wrong``: those that
held a wrong merge; ``merged``: those that merged and never held a wrong one), the episode is
replayed with the file's settings and, from its first wrong step (or first merge), every
``--every`` steps: each robot's own map is searched against itself with the in-loop semantic
merger; every pose other than the identity that the merger would take for a second copy of
the map (``min_overlap`` of its wall samples on its known cells, ``MIN_OVERLAP_CELLS`` in all,
agreeing at ``min_score``) is a *self-match* S (a shifted or turned copy of a place: a repeat,
or the floor's symmetry). The held pose T of robot_1's map in robot_0's then has the rivals
``S_0 T`` and ``T S_1``; one *stands* when it lies ``FAR_CELLS`` from T and the merger's own
test (:func:`~mrexplore.merge.semantic.stands_as_rival`) says the two maps cannot tell it from
T. Printed per episode: the first wrong (or merged) step, the first step a rival stood (the
self-match's turn), and the seconds a wrong merge was held before it. Ground truth is read only
to find the steps; nothing is written.
"""

from __future__ import annotations

import argparse
import json
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mrexplore.experiments.episode import run_episode
from mrexplore.experiments.task_time import make_team
from mrexplore.grid import chain, invert_transform
from mrexplore.merge.common import Verifier
from mrexplore.merge.fusion import IN_LOOP_SEMANTIC_OPTIONS
from mrexplore.merge.semantic import (
    FAR_CELLS,
    MIN_OVERLAP_CELLS,
    SemanticOptions,
    merge_semantic,
    stands_as_rival,
    turn_between_deg,
)
from mrexplore.studies.loop_study import POLICY, episode_options
from mrexplore.truth import transform_error

Transform = NDArray[np.float64]


def self_matches(grid: NDArray[np.int8], options: dict[str, Any]) -> list[Transform]:
    """Poses (3x3, the map's cells -> its cells) other than the identity under which the merger
    would take ``grid`` for a second copy of itself."""
    o = SemanticOptions()
    evidence = merge_semantic(grid, grid, **options).evidence
    walls = np.argwhere(grid >= 65)[:, ::-1].astype(np.float64)
    out = []
    for pose in () if evidence is None else evidence.hypotheses:
        a = pose.agreement
        if a.share < o.min_overlap or a.overlap < MIN_OVERLAP_CELLS or a.score < o.min_score:
            continue
        if transform_error(pose.transform, np.eye(3), walls[:: max(1, len(walls) // 2000)])[0] < 1:
            continue  # the identity
        out.append(pose.transform)
    return out


def standing_rival(
    map0: NDArray[np.int8], map1: NDArray[np.int8], T: Transform, options: dict[str, Any]
) -> float | None:
    """The turn (degrees) of the first self-match whose moved pose stands against ``T`` (robot_1's
    cells -> robot_0's), or None."""
    o = SemanticOptions()
    verify = Verifier(map0, map1)
    held = verify(T)
    rivals = [(chain(S, T), S) for S in self_matches(map0, options)]
    rivals += [(chain(T, invert_transform(S)), S) for S in self_matches(map1, options)]
    for R, S in rivals:
        if transform_error(R, T, verify.points_b)[0] < FAR_CELLS:
            continue
        if stands_as_rival(held, verify(R), verify.cells_per_sample, o):
            return round(turn_between_deg(S, np.eye(3)), 1)
    return None


def trace(record: dict[str, Any], doc: dict[str, Any], which: str, every: int) -> dict[str, Any]:
    """Replay one episode; the first wrong (or merged) step and the first with a standing rival."""
    env_opts = {k: v for k, v in doc["env_options"].items() if k != "max_time_s"}
    opts = episode_options(
        record["world"],
        record["variant"],
        float(doc["env_options"]["max_time_s"]),
        merge_options=doc.get("merge_options") or None,
        env_options={**env_opts, **(doc.get("extra_env_options") or {})},
    )
    merge_options = {**IN_LOOP_SEMANTIC_OPTIONS, "resolution_m": 0.05}
    agents = [f"robot_{k}" for k in range(opts["n_robots"])]
    team = make_team(POLICY, agents, "explore")
    box: dict[str, Any] = {}
    found: dict[str, Any] = {"start": None, "stood": None, "turn": None, "dt_s": None}

    def on_step(step: int) -> None:
        env = box["env"].unwrapped
        ep = env.episode
        if ep is None or ep.truth is None or found["stood"] is not None:
            return
        T = ep.transforms.get(agents[0], {}).get(agents[1])
        started = ep.truth.wrong_s.sum() > 0 if which == "wrong" else T is not None
        if not started or T is None:
            return
        if found["start"] is None:
            found["start"], found["dt_s"] = step, float(env.config.dt_s)
        if (step - found["start"]) % every:
            return
        maps = [np.array(env.local_map(a)) for a in agents[:2]]
        turn = standing_rival(maps[0], maps[1], np.asarray(T, dtype=np.float64), merge_options)
        if turn is not None:
            found["stood"], found["turn"] = step, turn

    seed = int(record["seed"])
    run_episode(opts, team, seed, on_step=on_step, prepare=lambda e: box.update(env=e))
    return found


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("results", help="a loop-study JSON file (docs/results/loop_*.json)")
    p.add_argument("--variant", default="semantic")
    p.add_argument("--which", choices=["wrong", "merged"], default="wrong")
    p.add_argument("--every", type=int, default=20, help="steps between checks")
    p.add_argument("--limit", type=int, default=0, help="at most this many episodes (0: all)")
    args = p.parse_args()
    with open(args.results) as f:
        doc = json.load(f)
    eps = [
        e
        for e in doc["episodes"]
        if e["variant"] == args.variant
        and (e["wrong_merge"] if args.which == "wrong" else e["merged"] and not e["wrong_merge"])
    ]
    eps = eps[: args.limit] if args.limit else eps
    print(
        f"{args.results}, variant {args.variant}, {len(eps)} episodes that "
        f"{'held a wrong merge' if args.which == 'wrong' else 'merged, never wrongly'}; "
        f"self-match rivals of the held pose checked every {args.every} steps from the first "
        f"{'wrong' if args.which == 'wrong' else 'merged'} step"
    )
    at_start = later = never = 0
    held_before, held_all = 0.0, 0.0
    for e in eps:
        f = trace(e, doc, args.which, args.every)
        start, sym = f["start"], f["stood"]
        if sym is None:
            never += 1
        elif sym == start:
            at_start += 1
        else:
            later += 1
        line = f"{e['world']} seed {e['seed']}: from step {start}, a rival stood at {sym}"
        if sym is not None:
            line += f" (a self-match turned {f['turn']} deg)"
        if args.which == "wrong":
            held_all += e["merged_wrongly_s"]
            gap = (
                e["merged_wrongly_s"]
                if sym is None
                else min(e["merged_wrongly_s"], (sym - start) * f["dt_s"])
            )
            held_before += gap
            line += f"; held wrongly {e['merged_wrongly_s']} s, {gap:.2f} s of it before"
        print(line, flush=True)
    print(
        f"a rival stood at the first check: {at_start}, later: {later}, never: {never} "
        f"(of {len(eps)})"
    )
    if args.which == "wrong":
        print(f"seconds held wrongly: {held_all:.2f}, before a rival stood: {held_before:.2f}")


if __name__ == "__main__":
    main()
