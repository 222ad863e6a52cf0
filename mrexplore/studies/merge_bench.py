"""The merge benchmark: a table like the seed paper's Table 1, with the truth known.

For every method x detector, over seeded cases from the symmetric worlds and from real maps
(:mod:`mrexplore.studies.merge_cases`), it counts:

- **correct**: accepted and the mean displacement of b's known cells (estimate vs truth) < 2 cells;
- **WRONG**: accepted, yet >= 5 cells off: a wrong merge;
- **imprecise**: accepted, between 2 and 5 cells off;
- **refused**: not matched;
- **correct >= 30 %** / **>= 40 %** / **>= 50 %**: correct among the cases whose true overlap
  (share of b's known cells on a's known cells) is at least 30 % / 40 % / 50 %;
- **median ms**: median time of one ``merge_maps`` call, wall clock and process CPU time (OpenCV
  is limited to one thread, numpy's FFT and reductions are single-threaded, so CPU time is the
  one-core cost; on a shared machine it is the steadier figure).

Run: ``mrexplore bench merge --n 30 --out results/merge_bench``; ``--tracker`` also times
:class:`~mrexplore.merge.MapMergeTracker` per step.
``--seeds 0-9,12`` pools the cases of several seeds per family (one seed's 30 cases say little
about a rate; the README's table is seed 0's).
``--combine A.json B.json ... --out STEM`` runs nothing: it writes one study file from several
runs, each a block of seeds (held-out seeds opened one block at a time), every row kept as its
run wrote it and labelled with its block's ``seeds`` (:func:`combine_blocks`).
"""

from __future__ import annotations

import argparse
import json
import re
import sys
import time
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

import numpy as np

from mrexplore.errors import ConfigError, MrexploreError
from mrexplore.io_safety import check_outputs, write_text
from mrexplore.merge import MapMergeTracker, merge_maps
from mrexplore.merge.semantic import DEMOTED_OPTIONS
from mrexplore.studies.case_cache import cached_cases, check_cache_dir
from mrexplore.studies.merge_cases import (
    LIDAR_NOISE,
    MergeCase,
    aliased_cases,
    large_cases,
    lidar_cases,
    noisy_real_cases,
    real_cases,
    symmetric_cases,
)
from mrexplore.truth import merge_error

#: (method, detector, options) run by default; detector None = the method has none to choose.
#: The orb baseline runs twice: with m-explore's default confidence threshold (1.0) and with
#: its ROS 2 port's (0.6).
DEFAULT_CONFIGS: tuple[tuple[str, str | None, dict[str, Any]], ...] = (
    ("semantic", None, {}),
    ("paper", "harris", {}),
    ("paper", "shi-tomasi", {}),
    ("paper", "fast", {}),
    ("paper", "sift", {}),
    ("orb", "orb", {}),
    ("orb", "orb", {"min_confidence": 0.6}),
    ("orb", "sift", {}),
)
#: Diagnostic configurations, run only when named in ``methods``: ``seeded`` is the semantic
#: merger with the true pose handed in as one more hypothesis (``extra_hypotheses``), judged by
#: the same rules. Where the default refuses and ``seeded`` merges, the search missed the truth;
#: where both refuse, the decision rules did (the in-loop study has the same variant). The truth
#: reaches a merger only here and in the oracle of the loop study.
DIAGNOSTIC_CONFIGS: tuple[tuple[str, str | None, dict[str, Any]], ...] = (
    ("seeded", None, {}),
    ("guided", None, {}),
)
#: ``guided``: the semantic merger given a :class:`~mrexplore.merge.PosePrior`, a rough guess
#: drawn around the true pose (b's centre moved up to ``GUIDE_SHIFT_CELLS`` in a random
#: direction, turned up to ``GUIDE_TURN_DEG`` either way; seeded by the case's name), with a
#: region of ``GUIDE_RADIUS_CELLS`` and ``GUIDE_REGION_DEG``: what a user who knows roughly
#: where the maps overlap (a rendezvous, GPS, known start poses) gets.
GUIDE_SHIFT_CELLS, GUIDE_TURN_DEG = 20.0, 5.0
GUIDE_RADIUS_CELLS, GUIDE_REGION_DEG = 40.0, 10.0
CORRECT_CELLS = 2.0
WRONG_CELLS = 5.0


def classify(case: MergeCase, matched: bool, transform: np.ndarray | None) -> tuple[str, float]:
    """("correct" | "imprecise" | "wrong" | "refused", error in cells (inf when refused)).

    Both thresholds are widened by ``case.meta["drift_cells"]`` (lidar cases with odometry
    noise: how far drift alone moves a perfect merge off the start-frame truth; 0 otherwise).
    """
    if not matched or transform is None:
        return "refused", float("inf")
    measured = merge_error(np.asarray(transform), case.T_ab, case.b)
    err = float("inf") if measured is None else measured[0]
    drift = float(case.meta.get("drift_cells", 0.0))
    if err < CORRECT_CELLS + drift:
        return "correct", err
    if err >= WRONG_CELLS + drift:
        return "wrong", err
    return "imprecise", err


def guide(case: MergeCase) -> Any:
    """The ``guided`` method's :class:`~mrexplore.merge.PosePrior` for ``case``: the true pose
    moved and turned at random within :data:`GUIDE_SHIFT_CELLS` and :data:`GUIDE_TURN_DEG`
    about b's known centre (seeded by the case's name: the same guess on every run)."""
    import math
    import zlib

    from mrexplore.grid import UNKNOWN, chain, map_points
    from mrexplore.merge import PosePrior
    from mrexplore.merge.common import translation
    from mrexplore.merge.semantic import _turn_about

    rng = np.random.default_rng(zlib.crc32(case.name.encode()))
    rows, cols = np.nonzero(case.b != UNKNOWN)
    if rows.size == 0:
        rows, cols = np.array([case.b.shape[0] / 2]), np.array([case.b.shape[1] / 2])
    centre = np.array([[cols.mean(), rows.mean()]], dtype=np.float64)
    T = np.asarray(case.T_ab, dtype=np.float64)
    cx, cy = (float(v[0]) for v in map_points(centre, T))
    ang, dist = rng.uniform(0.0, 2.0 * math.pi), GUIDE_SHIFT_CELLS * math.sqrt(rng.uniform())
    about = _turn_about(rng.uniform(-GUIDE_TURN_DEG, GUIDE_TURN_DEG), cx, cy)
    guess = chain(translation(dist * math.cos(ang), dist * math.sin(ang)), about, T)
    return PosePrior(guess, GUIDE_RADIUS_CELLS, GUIDE_REGION_DEG)


def _refused_best_error(case: MergeCase, res: Any) -> float | None:
    """For a refusal: how far (cells, as :func:`classify` measures) the pose the merger judged
    and refused (``evidence.best``) lies from the truth; None when it judged none.

    A refusal whose judged pose was the truth is one where the search found the truth and a
    rule held it back (rightly, when a rival explains the maps as well); one whose judged pose
    lay elsewhere refused a wrong pose. Evaluation only: the truth never reaches the merger."""
    ev = getattr(res, "evidence", None)
    if ev is None or ev.best is None:
        return None
    _, err = classify(case, True, np.asarray(ev.best.transform, dtype=np.float64))
    return round(err, 2) if np.isfinite(err) else None


#: The semantic merger's rule constants a ``--semantic-variant`` may set (upper case).
_CONSTANTS = frozenset(DEMOTED_OPTIONS.values())


def evaluate(
    cases: Sequence[MergeCase], method: str, detector: str | None, **options: Any
) -> dict[str, Any]:
    """Run one method x detector over ``cases``; returns one table row (plus per-case records).

    Upper-case ``options`` (``SLACK_CELLS=0``) are constants of the semantic merger's rules
    (:data:`mrexplore.merge.semantic.DEMOTED_OPTIONS`), set for this row only: an ablation."""
    constants = {k: v for k, v in options.items() if k in _CONSTANTS}
    if constants:
        from mrexplore.merge import semantic

        saved = {k: getattr(semantic, k) for k in constants}
        try:
            for k, v in constants.items():
                setattr(semantic, k, v)
            row = evaluate(
                cases, method, detector, **{k: v for k, v in options.items() if k not in constants}
            )
        finally:
            for k, v in saved.items():
                setattr(semantic, k, v)
        row["options"] = ",".join(f"{k}={v}" for k, v in options.items())
        return row
    kw = dict(options)
    if detector is not None:
        kw["detector"] = detector
    counts = {"correct": 0, "wrong": 0, "imprecise": 0, "refused": 0}
    times, cpu, records = [], [], []
    big = big_ok = forty = forty_ok = half = half_ok = 0
    for c in cases:
        t_cpu = time.process_time()
        extra: dict[str, Any] = {}
        diagnostic = method in ("seeded", "guided")
        if method == "semantic" or diagnostic:
            extra["resolution_m"] = c.resolution_m
        if method == "seeded":
            extra["extra_hypotheses"] = [np.asarray(c.T_ab, dtype=np.float64)]
        if method == "guided":
            extra["prior"] = guide(c)
        res = merge_maps(c.a, c.b, method="semantic" if diagnostic else method, **extra, **kw)
        cpu.append(time.process_time() - t_cpu)
        kind, err = classify(c, res.matched, res.transform)
        counts[kind] += 1
        times.append(res.time_s)
        if c.overlap >= 0.3:
            big += 1
            big_ok += kind == "correct"
        if c.overlap >= 0.4:
            forty += 1
            forty_ok += kind == "correct"
        if c.overlap >= 0.5:
            half += 1
            half_ok += kind == "correct"
        records.append(
            {
                "case": c.name,
                "overlap": round(c.overlap, 3),
                "kind": kind,
                "error_cells": None if not np.isfinite(err) else round(err, 2),
                "best_error_cells": _refused_best_error(c, res) if kind == "refused" else None,
                "drift_cells": round(float(c.meta.get("drift_cells", 0.0)), 2),
                "score": round(res.score, 3),
                "reason": res.reason,
                "ms": round(res.time_s * 1e3, 1),
            }
        )
    return {
        "method": method,
        "detector": detector or "-",
        "n": len(cases),
        **counts,
        "correct_overlap30": f"{big_ok}/{big}",
        "correct_overlap40": f"{forty_ok}/{forty}",
        "correct_overlap50": f"{half_ok}/{half}",
        "options": ",".join(f"{k}={v}" for k, v in options.items()) or "-",
        "median_ms": round(float(np.median(times)) * 1e3, 1) if times else float("nan"),
        "median_cpu_ms": round(float(np.median(cpu)) * 1e3, 1) if cpu else float("nan"),
        "cases": records,
    }


#: Case families: generated symmetric worlds, real-map crops, noisy non-Manhattan real-map crops
#: (overlap >= 0.4), our simulator's own-frame lidar maps with noise, large maps (500-900
#: cells a side: the merger's large-map rules), crops of repetitive real maps that do not
#: overlap (aliased: the right answer is a refusal).
FAMILIES: tuple[str, ...] = ("symmetric", "real", "noisy", "lidar", "large", "aliased")


def make_cases(
    family: str,
    n: int,
    seed: int,
    lidar_options: Mapping[str, Any] | None = None,
    cache_dir: Path | None = None,
) -> list[MergeCase]:
    """``n`` cases of ``family`` (one of :data:`FAMILIES`), seeded; ``lidar_options``: env
    options of the ``lidar`` family's episodes beyond its noise (e.g. the mapper's
    ``map_l_occ``). With ``cache_dir``, read from or saved to that cache
    (:mod:`mrexplore.studies.case_cache`: the same cases, made once per code)."""
    if family not in FAMILIES:
        raise ConfigError(f"unknown case family {family!r}; choose from {FAMILIES}")
    if cache_dir is not None:
        options = lidar_options if family == "lidar" else None
        return cached_cases(
            cache_dir, family, n, seed, options, lambda: make_cases(family, n, seed, options)
        )
    if family == "symmetric":
        return symmetric_cases(n, seed)
    if family == "real":
        return real_cases(n, seed)
    if family == "noisy":
        return noisy_real_cases(n, seed)
    if family == "lidar":
        return lidar_cases(n, seed, env_options={**LIDAR_NOISE, **(lidar_options or {})})
    if family == "large":
        return large_cases(n, seed)
    return aliased_cases(n, seed)


def run_bench(
    n_cases: int,
    methods: Sequence[str] | None = None,
    detectors: Sequence[str] | None = None,
    seed: int = 0,
    families: Sequence[str] = ("symmetric", "real"),
    configs: Sequence[tuple[str, str | None, dict[str, Any]]] | None = None,
    seeds: Sequence[int] | None = None,
    lidar_options: Mapping[str, Any] | None = None,
    case_cache: Path | None = None,
) -> list[dict[str, Any]]:
    """Rows ``{family, method, detector, n, correct, wrong, imprecise, refused,
    correct_overlap30, median_ms, cases}`` for every configuration and family.

    ``methods``/``detectors`` filter :data:`DEFAULT_CONFIGS` (None = all), and a method of
    :data:`DIAGNOSTIC_CONFIGS` named in ``methods`` is added; ``configs`` replaces them all.
    ``n_cases`` cases per family, seeded by ``seed``; or, with ``seeds``, ``n_cases`` per family
    and seed, pooled (case names then end in `` (seed S)``). ``lidar_options``: see
    :func:`make_cases`; recorded in the lidar rows (``lidar_options``). ``case_cache``: a
    directory where the cases are saved and read back (:func:`make_cases`); the rows are the
    same with it or without.
    """
    if n_cases < 1:
        raise ConfigError(f"run_bench: n_cases must be >= 1, got {n_cases}")
    known_methods = {m for m, _, _ in DEFAULT_CONFIGS + DIAGNOSTIC_CONFIGS}
    known_detectors = {d for _, d, _ in DEFAULT_CONFIGS if d is not None}
    bad = sorted(set(methods or ()) - known_methods)
    if bad:
        raise ConfigError(
            f"run_bench: unknown method(s) {bad}; choose from {sorted(known_methods)}"
        )
    bad = sorted(set(detectors or ()) - known_detectors)
    if bad:
        raise ConfigError(
            f"run_bench: unknown detector(s) {bad}; choose from {sorted(known_detectors)}"
        )
    unknown_families = sorted(set(families) - set(FAMILIES))
    if unknown_families:
        raise ConfigError(f"run_bench: unknown family {unknown_families} {FAMILIES}")
    cfgs = (
        list(configs)
        if configs is not None
        else [
            (m, d, o)
            for m, d, o in DEFAULT_CONFIGS
            if (methods is None or m in methods)
            and (detectors is None or d is None or d in detectors)
        ]
        + [c for c in DIAGNOSTIC_CONFIGS if methods is not None and c[0] in methods]
    )
    rows: list[dict[str, Any]] = []
    for fam in families:
        if seeds is None:
            cases = make_cases(fam, n_cases, seed, lidar_options, case_cache)
        else:
            cases = [
                replace(c, name=f"{c.name} (seed {s})")
                for s in seeds
                for c in make_cases(fam, n_cases, s, lidar_options, case_cache)
            ]
        for m, d, o in cfgs:
            row = evaluate(cases, m, d, **o)
            row["family"] = fam
            if fam == "lidar" and lidar_options:
                row["lidar_options"] = dict(lidar_options)
            rows.append(row)
    return rows


COLUMNS = (
    "method",
    "detector",
    "options",
    "correct",
    "wrong",
    "imprecise",
    "refused",
    "correct_overlap30",
    "correct_overlap40",
    "correct_overlap50",
    "median_ms",
    "median_cpu_ms",
)
HEADERS = (
    "method",
    "detector",
    "options",
    "correct",
    "WRONG",
    "imprecise",
    "refused",
    "correct (overlap>=30%)",
    "correct (overlap>=40%)",
    "correct (overlap>=50%)",
    "median ms (wall)",
    "median ms (CPU)",
)


def seeded_summary(
    default: dict[str, Any], seeded: dict[str, Any], min_overlap: float = 0.4
) -> str:
    """One sentence pairing the default semantic row with a ``seeded`` or ``guided`` row of the
    same cases: of the default's refusals at ``min_overlap`` or more, how many the true pose
    handed in (or the rough guess) turns into correct merges, how many into imprecise or wrong
    ones, how many stay refused, and how many of the default's correct merges are lost."""
    pairs = [
        (d, s)
        for d, s in zip(default["cases"], seeded["cases"], strict=True)
        if d["overlap"] >= min_overlap
    ]
    refused = [(d, s) for d, s in pairs if d["kind"] == "refused"]
    rescued = sum(s["kind"] == "correct" for _, s in refused)
    other = sum(s["kind"] in ("imprecise", "wrong") for _, s in refused)
    lost = sum(d["kind"] == "correct" and s["kind"] != "correct" for d, s in pairs)
    if seeded["method"] == "guided":
        lead = (
            f"With a rough guess of the pose (`guided`: within {GUIDE_SHIFT_CELLS:g} cells and "
            f"{GUIDE_TURN_DEG:g} degrees of the truth)"
        )
        why, still = "", ""
    else:
        lead = "With the true pose handed in (`seeded`)"
        why, still = " (the search missed the truth)", " (the rules refuse the truth too)"
    return (
        f"{lead}, at overlap >= {min_overlap:.0%}: of the default's {len(refused)} refusals, "
        f"{rescued} become correct merges{why}, {other} imprecise or wrong, "
        f"{len(refused) - rescued - other} stay refused{still}; {lost} of its correct merges "
        "are not correct with it."
    )


def to_markdown(rows: Sequence[dict[str, Any]]) -> str:
    """One Markdown table per family (with :func:`seeded_summary` when it holds a ``seeded``
    row beside the default one). Rows of a combined file (:func:`combine_blocks`) get a
    ``seeds`` column first, and each family a line totalling the default rows of its blocks."""
    blocked = any("seeds" in r for r in rows)
    columns = ("seeds", *COLUMNS) if blocked else COLUMNS
    headers = ("seeds", *HEADERS) if blocked else HEADERS
    out = []
    for fam in dict.fromkeys(r["family"] for r in rows):
        sel = [r for r in rows if r["family"] == fam]
        n = sel[0]["n"] if sel else 0
        lo = sel[0].get("lidar_options") if sel else None
        with_ = "; maps made with " + ",".join(f"{k}={v}" for k, v in lo.items()) if lo else ""
        each = " in each row" if blocked else ""
        out.append(f"### {fam} ({n} cases{each}{with_})\n")
        out.append("| " + " | ".join(headers) + " |")
        out.append("|" + "---|" * len(headers))
        for r in sel:
            out.append("| " + " | ".join(str(r[c]) for c in columns) + " |")
        for block in dict.fromkeys(r.get("seeds") for r in sel):
            here = [r for r in sel if r.get("seeds") == block]
            default = [r for r in here if r["method"] == "semantic" and r["options"] == "-"]
            overlapping = default and any(c["overlap"] >= 0.4 for c in default[0]["cases"])
            for other in [r for r in here if r["method"] in ("seeded", "guided")]:
                if overlapping and other["options"] == "-":
                    out.append("")
                    out.append(seeded_summary(default[0], other))
        if blocked:
            out.append("")
            out.append(_block_totals(sel))
        out.append("")
    return "\n".join(out)


def _block_totals(rows: Sequence[Mapping[str, Any]]) -> str:
    """One sentence: the default semantic rows of one family, added up over their blocks."""
    default = [r for r in rows if r["method"] == "semantic" and r["options"] == "-"]
    if not default:
        return "No default semantic row in these blocks."
    total = {k: sum(int(r[k]) for r in default) for k in ("n", "correct", "wrong", "imprecise")}
    refused = sum(int(r["refused"]) for r in default)
    at40 = [str(r["correct_overlap40"]).partition("/") for r in default]
    got, of = sum(int(a) for a, _, _ in at40), sum(int(b) for _, _, b in at40)
    return (
        f"The default (`-`) over its {len(default)} blocks: {total['correct']} correct, "
        f"{total['wrong']} WRONG, {total['imprecise']} imprecise, {refused} refused of "
        f"{total['n']}; correct at overlap >= 40 %: {got}/{of}."
    )


def format_seeds(seeds: Iterable[int]) -> str:
    """Seeds as ranges, the form :func:`parse_seeds` reads.

    >>> format_seeds([14, 13, 15, 22, 30, 31])
    '13-15,22,30-31'
    """
    runs: list[list[int]] = []
    for v in sorted(set(seeds)):
        if runs and v == runs[-1][1] + 1:
            runs[-1][1] = v
        else:
            runs.append([v, v])
    return ",".join(str(a) if a == b else f"{a}-{b}" for a, b in runs)


#: Every bench case's name ends with the seed that made it: ``"nav2/depot.yaml#3 (seed 73)"``.
_CASE_SEED = re.compile(r"\(seed (\d+)\)\s*$")


def block_seeds(rows: Sequence[Mapping[str, Any]]) -> list[int]:
    """The seeds of a run's cases, read from the cases' names (sorted, each once)."""
    found = {
        int(m.group(1)) for r in rows for c in r["cases"] if (m := _CASE_SEED.search(c["case"]))
    }
    return sorted(found)


def combine_blocks(blocks: Sequence[tuple[str, Mapping[str, Any]]]) -> dict[str, Any]:
    """One study from several runs of the bench on disjoint seeds (blocks), in the order given.

    Every row of every block is kept as its run wrote it (figures, timings, cases), with a
    ``seeds`` field first naming its block (``"13-22"``, read from the case names); the rows'
    ``options`` already name the variant. ``blocks`` in the result lists each block's seeds,
    families and variants. The blocks may differ in families and variants (each ran what it
    was opened for); they may not share a seed, hold timings a row cannot carry (``--sizes``,
    ``--tracker``) or be combined files already.

    Args:
        blocks: ``(name, document)`` per run, the name (its file) used in error messages.

    Raises:
        ConfigError: a document that is not a bench result with per-case records, or one of
            the conditions above.
    """
    if not blocks:
        raise ConfigError("--combine: give the JSON files of the blocks")
    rows: list[dict[str, Any]] = []
    listed: list[dict[str, Any]] = []
    owner: dict[int, str] = {}
    for name, doc in blocks:
        if not isinstance(doc, Mapping) or not isinstance(doc.get("rows"), list):
            raise ConfigError(f"--combine: {name} is not a merge bench result (no 'rows')")
        extra = sorted(k for k in doc if k not in ("rows", "blocks"))
        if "blocks" in doc or any("seeds" in r for r in doc["rows"]):
            raise ConfigError(f"--combine: {name} is a combined file already; give its blocks")
        if extra:
            raise ConfigError(
                f"--combine: {name} holds {', '.join(extra)}, which a combined file would drop; "
                "give runs made without --sizes and --tracker"
            )
        missing = sorted(
            {c for r in doc["rows"] for c in (*COLUMNS, "family", "cases") if c not in r}
        )
        if not doc["rows"] or missing:
            raise ConfigError(
                f"--combine: {name} has no rows"
                if not doc["rows"]
                else f"--combine: the rows of {name} lack {', '.join(missing)}"
            )
        seeds = block_seeds(doc["rows"])
        if not seeds:
            raise ConfigError(f"--combine: no '(seed N)' in the case names of {name}")
        shared = sorted(s for s in seeds if s in owner)
        if shared:
            raise ConfigError(
                f"--combine: {name} and {owner[shared[0]]} share seeds {format_seeds(shared)}; "
                "a block may be counted once"
            )
        owner.update(dict.fromkeys(seeds, name))
        label = format_seeds(seeds)
        rows += [{"seeds": label, **r} for r in doc["rows"]]
        listed.append(
            {
                "seeds": label,
                "families": list(dict.fromkeys(r["family"] for r in doc["rows"])),
                "variants": [
                    o for o in dict.fromkeys(r["options"] for r in doc["rows"]) if o != "-"
                ],
            }
        )
    return {"blocks": listed, "rows": rows}


def combined_markdown(doc: Mapping[str, Any]) -> str:
    """The Markdown of a :func:`combine_blocks` result: what a row is, the blocks, the tables."""
    lines = [
        f"{len(doc['blocks'])} blocks of seeds, each one run of `mrexplore bench merge`; a row is "
        "one block (`seeds`) run with one variant of the merger (`options`; `-` is the default). "
        "Every figure is its block's own, as its run wrote it.",
        "",
        "| seeds | families | variants beside the default |",
        "|---|---|---|",
    ]
    for b in doc["blocks"]:
        variants = "; ".join(b["variants"]) or "-"
        lines.append(f"| {b['seeds']} | {', '.join(b['families'])} | {variants} |")
    return "\n".join(lines) + "\n\n" + to_markdown(doc["rows"])


def size_timing(sizes: Sequence[int], n: int = 10, seed: int = 0) -> list[dict[str, Any]]:
    """The semantic merger's CPU time (this thread) by map size: for each size S, ``n`` pairs of
    S x S crops (the second rotated at random, borders damaged) of generated office floors
    (``symmetric_office`` at 0.05 m/cell, 1.6 S cells wide, fully known: walls 100, free 0),
    merged with the default options. Reports the median and the outcome counts.
    """
    from mrexplore.studies.merge_cases import real_map_case
    from mrexplore.world import symmetric_office

    out = []
    for size in sizes:
        rng = np.random.default_rng([seed, size])
        cpu, outcomes = [], {"correct": 0, "imprecise": 0, "wrong": 0, "refused": 0}
        for k in range(n):
            side_m = round(1.6 * size * 0.05, 1)
            world = symmetric_office(rng, width_m=side_m, height_m=side_m)
            full = np.where(world.walls, 100, 0).astype(np.int8)
            case = real_map_case(full, rng, crop=(size, size), name=f"office{size}#{k}")
            t0 = time.thread_time()
            res = merge_maps(case.a, case.b)
            cpu.append(time.thread_time() - t0)
            outcomes[classify(case, res.matched, res.transform)[0]] += 1
        out.append(
            {
                "size": int(size),
                "n": int(n),
                "median_cpu_ms": round(float(np.median(cpu)) * 1e3, 1),
                "max_cpu_ms": round(float(np.max(cpu)) * 1e3, 1),
                **outcomes,
            }
        )
    return out


def tracker_timing(
    n_steps: int = 200, canvas: int = 1500, known: int = 400, seed: int = 0
) -> dict[str, float]:
    """Time ``MapMergeTracker.update`` + ``fused`` for 2 robots on steps without a merge attempt.

    Two ``canvas`` x ``canvas`` maps with a ``known`` x ``known`` known area cut from a real map,
    merged once (truth-free: the merger finds it), then each step a few cells change in both
    maps (as a lidar update would) and both fused maps are read.
    """
    from mrexplore.studies.merge_cases import load_real_map

    rng = np.random.default_rng(seed)
    full = load_real_map("nav2/depot.yaml")
    h, w = full.shape
    k = min(known, h, w)
    maps = []
    for off in (0, 40):
        m = np.full((canvas, canvas), -1, dtype=np.int8)
        sub = full[:k, off : off + min(k, w - 40)]
        r0 = (canvas - sub.shape[0]) // 2
        c0 = (canvas - sub.shape[1]) // 2
        m[r0 : r0 + sub.shape[0], c0 : c0 + sub.shape[1]] = sub
        maps.append(m)
    tr = MapMergeTracker(2, merge_every=10**9, recheck_every=0)
    tr.update(maps, step=0)
    merged = tr.merged(0)
    times, cpu = [], []
    for step in range(1, n_steps + 1):
        for m in maps:  # a small local change, as one lidar update
            r, c = (int(x) for x in rng.integers(canvas // 2 - 50, canvas // 2 + 50, size=2))
            m[r, c] = 0 if m[r, c] != 0 else 100
        t0, c0 = time.perf_counter(), time.process_time()
        tr.update(maps, step=step)
        tr.fused(0)
        tr.fused(1)
        times.append(time.perf_counter() - t0)
        cpu.append(time.process_time() - c0)
    return {
        "merged": float(merged),
        "median_ms": float(np.median(times) * 1e3),
        "p95_ms": float(np.percentile(times, 95) * 1e3),
        "median_cpu_ms": float(np.median(cpu) * 1e3),
    }


def parse_seeds(text: str) -> list[int]:
    """``"0-9,12"`` -> ``[0, 1, ..., 9, 12]``: comma-separated seeds (>= 0) and inclusive ranges,
    each seed once, in the order given.

    >>> parse_seeds("0-2,12")
    [0, 1, 2, 12]
    """
    out: list[int] = []
    for part in text.split(","):
        lo, sep, hi = part.strip().partition("-")
        try:
            first = int(lo)
            last = int(hi) if sep else first
        except ValueError:
            raise ConfigError(
                f"--seeds: {part.strip()!r} is not a seed or a range like 0-9 (in {text!r})"
            ) from None
        if first < 0 or last < first:
            raise ConfigError(f"--seeds: {part.strip()!r} must be seeds >= 0, low-high")
        out += [s for s in range(first, last + 1) if s not in out]
    return out


def parse_options(text: str, flag: str = "--semantic-variant") -> dict[str, Any]:
    """``"k=v,k=v"`` -> options; values are read as int, float, true/false, else text.

    >>> parse_options("slack_cells=0,min_score=0.95,paper_candidates=true")
    {'slack_cells': 0, 'min_score': 0.95, 'paper_candidates': True}
    """
    out: dict[str, Any] = {}
    for part in filter(None, (x.strip() for x in text.split(","))):
        key, sep, raw = part.partition("=")
        if not sep or not key:
            raise ConfigError(f"{flag}: expected k=v pairs, got {part!r}")
        value: Any = raw
        if raw.lower() in ("true", "false"):
            value = raw.lower() == "true"
        else:
            for cast in (int, float):
                try:
                    value = cast(raw)
                    break
                except ValueError:
                    continue
        out[key] = value
    return out


def main(argv: Sequence[str] | None = None) -> int:
    """CLI: ``merge_bench [--n N] [--seed S] [--methods m,..] [--families f,..] [--out STEM]
    [--tracker]``; returns the exit code."""
    p = argparse.ArgumentParser(prog="mrexplore bench merge", description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--n", type=int, default=30, help="cases per family (default 30; 0: only --sizes/--tracker)"
    )
    p.add_argument("--seed", type=int, default=0)
    p.add_argument(
        "--seeds",
        default=None,
        metavar="S,S-S",
        help="pool the cases of these seeds per family, e.g. 0-9,12 (replaces --seed)",
    )
    p.add_argument(
        "--methods",
        default=None,
        help="comma list of semantic,paper,orb (default all) and the diagnostic seeded (the "
        "semantic merger with the true pose among its hypotheses: search misses vs rule "
        "refusals) and guided (given a rough guess of the pose, a PosePrior)",
    )
    p.add_argument("--detectors", default=None, help="comma list filter of detectors")
    p.add_argument("--families", default="symmetric,real")
    p.add_argument("--out", default=None, help="write STEM.json and STEM.md")
    p.add_argument("--tracker", action="store_true", help="also time the tracker per step")
    p.add_argument(
        "--sizes",
        default=None,
        metavar="S,S",
        help="also time the semantic merger on S x S map pairs (e.g. 500,1000), CPU time",
    )
    p.add_argument("--force", action="store_true", help="replace existing STEM.json/STEM.md")
    p.add_argument(
        "--semantic-variant",
        action="append",
        default=[],
        metavar="K=V,K=V",
        help="also run the semantic merger with these options (repeatable; an ablation row); "
        "upper-case names set the merger's rule constants for the row (SLACK_CELLS=0)",
    )
    p.add_argument(
        "--lidar-options",
        default="",
        metavar="K=V,K=V",
        help="env options of the lidar family's episodes beyond its noise, e.g. map_l_occ=2.6 "
        "(the mapper's): its maps, as the merger then sees them",
    )
    p.add_argument(
        "--case-cache",
        default=None,
        metavar="DIR",
        help="save the cases here and read them back in later runs of the same code, worlds "
        "and maps (making the lidar and symmetric cases is most of a run's time); a directory "
        "of your own, made if missing (it holds pickles)",
    )
    p.add_argument(
        "--combine",
        nargs="+",
        default=None,
        metavar="BLOCK.json",
        help="run nothing: write --out as one study of these runs (blocks of seeds), every row "
        "kept and labelled with its block's seeds",
    )
    args = p.parse_args(list(argv) if argv is not None else None)
    if args.combine is not None:
        return _combine_main(p, args)
    import cv2

    cv2.setNumThreads(1)  # one core, as the targets are stated
    try:
        if args.out:
            stem = Path(args.out)
            check_outputs(
                [stem.with_suffix(".json"), stem.with_suffix(".md")],
                force=args.force,
                what="mrexplore bench merge",
            )
        methods = args.methods.split(",") if args.methods else None
        detectors = args.detectors.split(",") if args.detectors else None
        configs = None
        if args.semantic_variant:
            variants = [parse_options(v) for v in args.semantic_variant]
            probe = np.full((4, 4), -1, dtype=np.int8)
            for opts in variants:  # a misspelt option fails now, not after the cases are made
                bad = sorted(k for k in opts if k.isupper() and k not in _CONSTANTS)
                if bad:
                    raise ConfigError(
                        f"--semantic-variant: {bad} are not constants of the semantic merger; "
                        f"known: {sorted(_CONSTANTS)}"
                    )
                merge_maps(
                    probe,
                    probe,
                    method="semantic",
                    **{k: v for k, v in opts.items() if k not in _CONSTANTS},
                )
            configs = (
                [
                    (m, d, o)
                    for m, d, o in DEFAULT_CONFIGS
                    if (methods is None or m in methods)
                    and (detectors is None or d is None or d in detectors)
                ]
                + [c for c in DIAGNOSTIC_CONFIGS if methods is not None and c[0] in methods]
                + [("semantic", None, o) for o in variants]
            )
        # --n 0: only the extra timings (--sizes, --tracker), no table
        if args.n == 0 and not (args.sizes or args.tracker):
            raise ConfigError("--n 0 runs only --sizes or --tracker: give one of them")
        seeds = None if args.seeds is None else parse_seeds(args.seeds)
        case_cache = None if args.case_cache is None else check_cache_dir(args.case_cache)
        lidar_options = parse_options(args.lidar_options, flag="--lidar-options")
        if lidar_options:
            from mrexplore.environment.config import EnvConfig

            if "lidar" not in args.families.split(","):
                raise ConfigError("--lidar-options: the lidar family is not among --families")
            try:  # every name and value, as the episodes' env would check them
                EnvConfig.from_kwargs(**{**LIDAR_NOISE, **lidar_options})
            except ConfigError as exc:
                raise ConfigError(f"--lidar-options: {exc}") from exc
        rows = (
            run_bench(
                args.n,
                methods=methods,
                detectors=detectors,
                seed=args.seed,
                families=args.families.split(","),
                configs=configs,
                seeds=seeds,
                lidar_options=lidar_options,
                case_cache=case_cache,
            )
            if args.n != 0
            else []
        )
    except MrexploreError as e:
        print(f"mrexplore bench merge: error: {e}", file=sys.stderr)
        return 2
    md = to_markdown(rows) if rows else ""
    if md:
        print(md)
    extra: dict[str, Any] = {}
    if args.sizes:
        extra["sizes"] = size_timing([int(s) for s in args.sizes.split(",")], seed=args.seed)
        for row in extra["sizes"]:
            print(
                f"semantic merge, {row['size']} x {row['size']} cells, {row['n']} pairs: median "
                f"{row['median_cpu_ms']} ms CPU (max {row['max_cpu_ms']}); correct "
                f"{row['correct']}, refused {row['refused']}, imprecise {row['imprecise']}, "
                f"wrong {row['wrong']}"
            )
    if args.tracker:
        extra["tracker"] = tracker_timing()
        print(f"tracker update+fused, 2 robots, 1500x1500 canvases: {extra['tracker']}")
    if args.out:
        stem = Path(args.out)
        stem.parent.mkdir(parents=True, exist_ok=True)
        write_text(stem.with_suffix(".json"), json.dumps({"rows": rows, **extra}, indent=1))
        write_text(stem.with_suffix(".md"), md + "\n")
        print(f"wrote {stem.with_suffix('.json')} and {stem.with_suffix('.md')}")
    return 0


#: Options that make cases: meaningless beside --combine, which runs none.
_RUN_OPTIONS = (
    "n", "seed", "seeds", "methods", "detectors", "families", "tracker", "sizes",
    "semantic_variant", "lidar_options", "case_cache",
)  # fmt: skip


def _combine_main(p: argparse.ArgumentParser, args: argparse.Namespace) -> int:
    """``--combine``: read the blocks, check them, write ``--out`` (.json and .md)."""
    try:
        given = [o for o in _RUN_OPTIONS if getattr(args, o) != p.get_default(o)]
        if given:
            flags = ", ".join("--" + o.replace("_", "-") for o in given)
            raise ConfigError(f"--combine runs no cases: drop {flags}")
        if not args.out:
            raise ConfigError("--combine needs --out STEM (the study file to write)")
        stem = Path(args.out)
        outputs = [stem.with_suffix(".json"), stem.with_suffix(".md")]
        check_outputs(outputs, inputs=args.combine, force=args.force, what="--out")
        blocks = []
        for f in args.combine:
            try:
                blocks.append((f, json.loads(Path(f).read_text())))
            except (OSError, ValueError) as exc:
                raise ConfigError(f"--combine: cannot read {f}: {exc}") from exc
        doc = combine_blocks(blocks)
    except MrexploreError as e:
        print(f"mrexplore bench merge: error: {e}", file=sys.stderr)
        return 2
    stem.parent.mkdir(parents=True, exist_ok=True)
    write_text(outputs[0], json.dumps(doc, indent=1))
    write_text(outputs[1], combined_markdown(doc) + "\n")
    print(
        f"wrote {outputs[0]} and {outputs[1]} "
        f"({len(doc['blocks'])} blocks, {len(doc['rows'])} rows)"
    )
    return 0
