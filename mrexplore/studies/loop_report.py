"""The loop study's figures: per-world summaries, paired comparisons and the printed tables.

:func:`summarize` turns a study's episodes into the per-world, per-variant figures its JSON
holds; :func:`against` compares a run with another study's episodes of the same seeds;
:func:`format_tables` prints them (text, or markdown for ``<out>.md``); :func:`load_study`
reads a study's JSON with a clear error. Running the study is
:mod:`mrexplore.studies.loop_study`'s job.
"""

from __future__ import annotations

import json
import math
import statistics
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

from mrexplore.errors import ConfigError

__all__ = [
    "MERGER_VARIANTS",
    "against",
    "aggregate",
    "binomial_upper_bound",
    "format_tables",
    "load_study",
    "summarize",
]

#: The variants that merge with the env's named semantic merger: the study's ``--merge-options``
#: apply to them (and the tables' heading says so).
MERGER_VARIANTS: tuple[str, ...] = ("semantic", "sighting", "verify")


def _median(xs: Sequence[float]) -> float | None:
    return float(statistics.median(xs)) if xs else None


def summarize(
    episodes: Sequence[Mapping[str, Any]], worlds: Sequence[str], variants: Sequence[str]
) -> dict[str, dict[str, dict[str, Any]]]:
    """Per world and variant: episodes, share merged, median first merge, mean and std of the
    task time, share reached, wrong-merge episodes, seconds merged wrongly, the largest fused
    contradiction, merges lost (summed; None for records made before they were counted), the
    mean task time relative to the oracle's, the paired difference to the oracle's task time
    on the same seeds (mean, 95 % CI, s; None without an oracle), and the share of the
    oracle's gain a merging variant takes: ``(base - variant) / (base - oracle)`` in mean task time,
    against never merging (``gain_vs_none``) and against one robot (``gain_vs_single``); None
    when a variant is missing or the oracle gains nothing."""
    from mrexplore.experiments.evaluate import paired

    out: dict[str, dict[str, dict[str, Any]]] = {}
    for w in worlds:
        out[w] = {}
        for v in variants:
            eps = [e for e in episodes if e["world"] == w and e["variant"] == v]
            times = [float(e["task_time_s"]) for e in eps]
            merges = [float(e["first_merge_time_s"]) for e in eps if e["merged"]]
            contr = [
                float(e["max_fused_contradiction"])
                for e in eps
                if e["max_fused_contradiction"] is not None
            ]
            out[w][v] = {
                "episodes": len(eps),
                "merged": sum(bool(e["merged"]) for e in eps),
                "median_first_merge_s": _median(merges),
                "task_time_mean_s": float(statistics.fmean(times)) if times else None,
                "task_time_std_s": float(statistics.pstdev(times)) if len(times) > 1 else 0.0,
                "reached": sum(bool(e["reached"]) for e in eps),
                "wrong_merge_episodes": sum(bool(e["wrong_merge"]) for e in eps),
                "merged_wrongly_s": float(sum(float(e["merged_wrongly_s"]) for e in eps)),
                "max_fused_contradiction": max(contr) if contr else None,
                "merges_lost": (
                    sum(int(e["merges_lost"]) for e in eps)
                    if all("merges_lost" in e for e in eps)
                    else None
                ),
            }
        oracle = out[w].get("oracle", {}).get("task_time_mean_s")
        by_seed = (
            {
                (e["variant"], e["seed"]): float(e["task_time_s"])
                for e in episodes
                if e["world"] == w and e["variant"] in variants
            }
            if "oracle" in variants
            else {}
        )
        for v in variants:
            m = out[w][v]["task_time_mean_s"]
            out[w][v]["vs_oracle"] = float(m / oracle - 1.0) if oracle and m is not None else None
            for base in ("none", "single"):
                b = out[w].get(base, {}).get("task_time_mean_s")
                share = None
                merging = v not in ("oracle", "none", "single")  # what a merger takes
                if merging and b is not None and oracle and m is not None:
                    share = float((b - m) / (b - oracle)) if b != oracle else None
                out[w][v][f"gain_vs_{base}"] = share
            seeds = sorted(s for (v2, s) in by_seed if v2 == v and ("oracle", s) in by_seed)
            out[w][v]["minus_oracle_s"] = (
                paired([by_seed[(v, s)] for s in seeds], [by_seed[("oracle", s)] for s in seeds])
                if seeds and v != "oracle"
                else None
            )
        for v in SEMANTIC_OPTION_VARIANTS:
            if v in variants and "semantic" in variants:
                out[w][v]["minus_semantic"] = _against_semantic(
                    [e for e in episodes if e["world"] == w], v
                )
    return out


#: Variants the study pairs with ``semantic`` when both ran (it prints each one's paired
#: difference): the semantic merger with one option or diagnostic, and the oracle held to a
#: room's worth of evidence (``oracle_room``: what ours leaves of what such a merger could take).
SEMANTIC_OPTION_VARIANTS: tuple[str, ...] = ("seeded", "sighting", "verify", "oracle_room")


def _compare_pairs(
    pairs: Sequence[tuple[Mapping[str, Any], Mapping[str, Any]]],
) -> dict[str, Any]:
    """Episodes ``(a, b)`` of the same world and seed: the paired task-time difference a - b
    (mean, 95 % CI, s), in how many pairs a's first merge came earlier / later than b's (never
    merging counts as latest), and how many of each reached the target."""
    from mrexplore.experiments.evaluate import paired

    def first(e: Mapping[str, Any]) -> float:
        return float(e["first_merge_time_s"]) if e["merged"] else math.inf

    return {
        "task_time_s": paired(
            [float(a["task_time_s"]) for a, _ in pairs], [float(b["task_time_s"]) for _, b in pairs]
        ),
        "first_merge_earlier": sum(first(a) < first(b) for a, b in pairs),
        "first_merge_later": sum(first(a) > first(b) for a, b in pairs),
        "episodes": len(pairs),
        "reached": [
            sum(bool(a["reached"]) for a, _ in pairs),
            sum(bool(b["reached"]) for _, b in pairs),
        ],
    }


def _against_semantic(episodes: Sequence[Mapping[str, Any]], variant: str) -> dict[str, Any]:
    """``variant`` against ``semantic`` on the (world, seed) episodes both ran
    (:func:`_compare_pairs`)."""
    runs = {(e["world"], e["variant"], e["seed"]): e for e in episodes}
    keys = sorted((w, s) for (w, v, s) in runs if v == variant and (w, "semantic", s) in runs)
    return _compare_pairs([(runs[(w, variant, s)], runs[(w, "semantic", s)]) for w, s in keys])


def binomial_upper_bound(k: int, n: int, confidence: float = 0.95) -> float | None:
    """One-sided upper ``confidence`` bound of a rate seen ``k`` times in ``n`` trials (exact,
    Clopper-Pearson): the rate p at which ``k`` or fewer in ``n`` has probability
    ``1 - confidence``; 1.0 when ``k == n``, None without trials. 0 in 20 gives 0.139 (about
    the rule of three, 3 / n)."""
    if n <= 0:
        return None
    if not 0 <= k <= n:
        raise ValueError(f"binomial_upper_bound: need 0 <= k <= n, got k={k}, n={n}")
    if k == n:
        return 1.0
    alpha = 1.0 - confidence

    def cdf(p: float) -> float:  # P(X <= k) for X ~ Binomial(n, p), summed in log space
        lp, lq = math.log(p), math.log1p(-p)
        return sum(
            math.exp(
                math.lgamma(n + 1)
                - math.lgamma(i + 1)
                - math.lgamma(n - i + 1)
                + i * lp
                + (n - i) * lq
            )
            for i in range(k + 1)
        )

    lo, hi = k / n, 1.0  # cdf falls from >= 1/2-ish at k/n to 0 at 1: bisect for alpha
    for _ in range(100):
        mid = 0.5 * (lo + hi)
        if mid <= 0.0 or cdf(mid) > alpha:
            lo = mid
        else:
            hi = mid
    return hi


def aggregate(
    episodes: Sequence[Mapping[str, Any]],
    variants: Sequence[str],
    layouts: Mapping[str, str] | None = None,
) -> dict[str, Any]:
    """Over all worlds of a family run, per variant: episodes, merged, reached, episodes that
    ever held a wrong merge with the upper 95 % bound of that rate
    (:func:`binomial_upper_bound`), the mean task time (s), and with ``oracle_room`` beside it
    the episodes merged of those the room oracle merged; ``semantic`` against ``oracle_room``
    and ``none`` (when they ran): its mean task time relative to theirs, the paired difference
    (mean, 95 % CI, s), and the episodes one merged and the other did not. With ``layouts``
    (world spec -> the generator's layout) naming two or more, the same per layout
    (``by_layout``)."""
    out = _per_variant(episodes, variants)
    if layouts and len(set(layouts.values())) > 1:
        out["by_layout"] = {
            lay: _per_variant([e for e in episodes if layouts.get(e["world"]) == lay], variants)[
                "variants"
            ]
            for lay in sorted(set(layouts.values()))
        }
    return out


#: The references a run's merging variants are measured against when it ran them (or, with
#: ``--against``, when the other run did): variant -> (its name in the text, the key of the
#: episodes merged of those it merged, the key of the mean task time relative to it).
REFERENCES: dict[str, tuple[str, str, str]] = {
    "oracle_room": ("room oracle", "merged_where_room_oracle_merged", "vs_room_oracle"),
    "oracle_meet": ("meeting oracle", "merged_where_oracle_meet_merged", "vs_oracle_meet"),
}


def _where_reference_merged(
    runs: Mapping[tuple[str, str, int], Mapping[str, Any]], variant: str, ref: str
) -> tuple[int, int] | None:
    """(episodes ``variant`` merged among those ``ref`` merged, those) on the same world and
    seed (``runs``: (world, variant, seed) -> episode); None without ``ref`` episodes."""
    if not any(v == ref for _, v, _ in runs):
        return None
    keys = [(w, s) for (w, v, s), e in runs.items() if v == ref and e["merged"]]
    both = sum(bool(runs[(w, variant, s)]["merged"]) for w, s in keys if (w, variant, s) in runs)
    return both, len(keys)


def _against_reference(
    mine: Sequence[Mapping[str, Any]],
    theirs: Sequence[Mapping[str, Any]],
    variant: str,
    ref: str,
) -> dict[str, Any]:
    """``variant`` of ``mine`` against ``ref`` of ``theirs`` (a reference of
    :data:`REFERENCES`) on the (world, seed) episodes both ran: the episodes it merged of those
    the reference merged, and its mean task time relative to the reference's (keys named in
    :data:`REFERENCES`; empty when they share no episode)."""
    ours = {(e["world"], e["seed"]): e for e in mine if e["variant"] == variant}
    other = {(e["world"], e["seed"]): e for e in theirs if e["variant"] == ref}
    keys = sorted(set(ours) & set(other))
    if not keys:
        return {}
    runs = {(w, variant, s): ours[(w, s)] for w, s in keys}
    runs.update({(w, ref, s): other[(w, s)] for w, s in keys})
    share = _where_reference_merged(runs, variant, ref)
    t_ours = sum(float(ours[k]["task_time_s"]) for k in keys) / len(keys)
    t_ref = sum(float(other[k]["task_time_s"]) for k in keys) / len(keys)
    _, share_key, vs_key = REFERENCES[ref]
    return {share_key: share, vs_key: t_ours / t_ref - 1.0}


def _per_variant(episodes: Sequence[Mapping[str, Any]], variants: Sequence[str]) -> dict[str, Any]:
    """:func:`aggregate` of one set of episodes (all the run's, or one layout's)."""
    out: dict[str, Any] = {"variants": {}, "semantic_against": {}}
    runs = {(e["world"], e["variant"], e["seed"]): e for e in episodes}
    for v in variants:
        eps = [e for e in episodes if e["variant"] == v]
        wrong = sum(bool(e["wrong_merge"]) for e in eps)
        times = [float(e["task_time_s"]) for e in eps]
        firsts = [float(e["first_merge_time_s"]) for e in eps if e["merged"]]
        # how long a dropped merge stood contradicted (records without drops: none counted)
        recovery = [d[1] - d[0] for e in eps for d in e.get("drops_s", ())]
        causes: dict[str, int] = {}
        for c in (c for e in eps for c in e.get("drop_causes", ())):
            causes[c] = causes.get(c, 0) + 1
        out["variants"][v] = {
            "episodes": len(eps),
            "merged": sum(bool(e["merged"]) for e in eps),
            "first_merge_median_s": _median(firsts),
            "reached": sum(bool(e["reached"]) for e in eps),
            "wrong_merge_episodes": wrong,
            "wrong_merge_upper95": binomial_upper_bound(wrong, len(eps)),
            "merged_wrongly_s": float(sum(float(e["merged_wrongly_s"]) for e in eps)),
            "drops": len(recovery),
            "drop_causes": dict(sorted(causes.items())),
            "contradiction_to_drop_max_s": max(recovery) if recovery else None,
            "task_time_mean_s": float(statistics.fmean(times)) if times else None,
            **_merge_work(eps),
        }
        for ref in REFERENCES:
            if ref in variants and v not in ("none", "single", ref):
                d = _against_reference(episodes, episodes, v, ref)
                out["variants"][v].update(
                    {k: list(x) if isinstance(x, tuple) else x for k, x in d.items()}
                )
    if "semantic" in variants:
        sem = out["variants"]["semantic"]["task_time_mean_s"]
        for base in ("oracle_room", "none"):
            if base not in variants:
                continue
            keys = sorted((w, s) for (w, v, s) in runs if v == "semantic" and (w, base, s) in runs)
            pairs = [(runs[(w, "semantic", s)], runs[(w, base, s)]) for w, s in keys]
            b = out["variants"][base]["task_time_mean_s"]
            out["semantic_against"][base] = {
                **_compare_pairs(pairs),
                "relative_task_time": float(sem / b - 1.0) if sem is not None and b else None,
                "merged_only_semantic": sum(
                    bool(a["merged"]) and not c["merged"] for a, c in pairs
                ),
                "merged_only_" + base: sum(not a["merged"] and bool(c["merged"]) for a, c in pairs),
            }
    return out


def _merge_work(eps: Sequence[Mapping[str, Any]]) -> dict[str, float | None]:
    """Mean merge attempts and re-checks per episode (None for records made before the loop
    study counted them)."""
    keys = ("merge_attempts", "merge_rechecks")
    if not eps or not all(k in e for e in eps for k in keys):
        return {f"{k}_mean": None for k in keys}
    return {f"{k}_mean": float(statistics.fmean(float(e[k]) for e in eps)) for k in keys}


def _work_text(variants: Mapping[str, Mapping[str, Any]]) -> str | None:
    """One line: each merging variant's mean merge attempts and re-checks per episode."""
    parts = [
        f"{v} {s['merge_attempts_mean']:.1f} attempts, {s['merge_rechecks_mean']:.1f} re-checks"
        for v, s in variants.items()
        if v not in ("none", "single") and s.get("merge_attempts_mean") is not None
    ]
    return "merge work, mean per episode: " + "; ".join(parts) if parts else None


def _where(doc: Mapping[str, Any]) -> str:
    """Where a study was measured: the family, part and world seeds (a family run) or the
    worlds, and the episode seeds."""
    seeds = doc["seeds"]
    ep = f"episode seeds {seeds[0]}-{seeds[-1]}" if seeds else "no episode seeds"
    fam = doc.get("family")
    if fam:
        ws = fam["world_seeds"]
        return (
            f"family {fam['name']}, {fam['part']} part, worlds 0-{len(ws) - 1} "
            f"(world seeds {ws[0]}-{ws[-1]}), {ep}"
        )
    return f"worlds {', '.join(doc['worlds'])}, {ep}"


def _aggregate_lines(doc: Mapping[str, Any], markdown: bool) -> list[str]:
    """The family run's aggregate table and the semantic merger against its bases."""
    agg = doc["aggregate"]
    cols = (
        "variant",
        "episodes",
        "merged",
        "1st merge med",
        "reached",
        "wrong",
        "wrong rate <= (95 %)",
        "wrong s",
        "dropped",
        "contradicted s (max)",
        "task time mean",
        "merged where room oracle merged",
    )
    body = []
    for v, s in agg["variants"].items():
        up = s["wrong_merge_upper95"]
        mean = s["task_time_mean_s"]
        merging = v not in ("none", "single")
        first = s.get("first_merge_median_s")
        held = s.get("contradiction_to_drop_max_s")
        body.append(
            (
                v,
                str(s["episodes"]),
                f"{s['merged']}/{s['episodes']}" if merging else "-",
                "-" if first is None else f"{first:.1f} s",
                f"{s['reached']}/{s['episodes']}",
                str(s["wrong_merge_episodes"]) if merging else "-",
                "-" if up is None or not merging else f"{up:.1%}",
                f"{s.get('merged_wrongly_s', 0.0):.1f}" if merging else "-",
                _drops_text(s) if merging else "-",
                "-" if held is None else f"{held:.1f}",
                "-" if mean is None else f"{mean:.1f} s",
                _share_text(s.get("merged_where_room_oracle_merged")),
            )
        )
    title = f"All worlds ({_where(doc)}):"
    lines = [f"### {title}" if markdown else title]
    lines += _table(cols, body, markdown)
    work = _work_text(agg["variants"])
    if work is not None:
        lines += ["", work]
    lines += _layout_lines(doc, markdown)
    refs = [x for v, s in agg["variants"].items() for x in _reference_texts(v, s)]
    if refs:
        lines += ["", f"Against the references ({_where(doc)}; the same worlds and seeds):"]
        lines += [f"- {x}" if markdown else f"  {x}" for x in refs]
    for base, d in agg["semantic_against"].items():
        rel = d["relative_task_time"]
        lines += [
            "",
            f"semantic against {base} ({_where(doc)}), paired over {d['episodes']} episodes: "
            f"mean task time {'-' if rel is None else f'{rel:+.1%}'}, difference "
            f"{_paired_text(d['task_time_s'])}; merged by semantic only in "
            f"{d['merged_only_semantic']}, by {base} only in {d['merged_only_' + base]}; first "
            f"merge earlier in {d['first_merge_earlier']}, later in {d['first_merge_later']}",
        ]
    lines.append(
        "wrong rate <=: the one-sided upper 95 % bound (exact binomial, Clopper-Pearson) of the "
        "share of episodes that ever held a wrong merge; wrong s: seconds merged wrongly, "
        "summed; dropped: merges the tracker let go, in brackets those not for the grown maps' "
        "contradiction (outranked: the maps single out another place, un-merged; moved: ... "
        "and the pair moved there; sighting: the robots were seen elsewhere); contradicted s: "
        "the longest a dropped merge stood contradicted before the drop; merged where room "
        "oracle merged: of the episodes the room oracle merged, those the variant merged too."
    )
    return lines


def _share_text(pair: Sequence[int] | None) -> str:
    """``[k, n]`` -> ``"k/n (share)"``; ``"-"`` for None or n = 0."""
    if not pair or not pair[1]:
        return "-"
    return f"{pair[0]}/{pair[1]} ({pair[0] / pair[1]:.0%})"


def _layout_lines(doc: Mapping[str, Any], markdown: bool) -> list[str]:
    """The aggregate per layout of the family's worlds (``by_layout``), when it has one: where
    the merger waits and where it errs."""
    by = doc["aggregate"].get("by_layout")
    if not by:
        return []
    fam = doc["family"]
    count = {lay: fam["layouts"].count(lay) for lay in by}
    cols = (
        "layout",
        "worlds",
        "variant",
        "merged",
        "wrong",
        "task time mean",
        "merged where room oracle merged",
    )
    body = []
    for lay, variants in by.items():
        for v, s in variants.items():
            merging = v not in ("none", "single")
            mean = s["task_time_mean_s"]
            body.append(
                (
                    lay,
                    str(count[lay]),
                    v,
                    f"{s['merged']}/{s['episodes']}" if merging else "-",
                    str(s["wrong_merge_episodes"]) if merging else "-",
                    "-" if mean is None else f"{mean:.1f} s",
                    _share_text(s.get("merged_where_room_oracle_merged")),
                )
            )
    title = f"By layout ({_where(doc)}):"
    return ["", f"### {title}" if markdown else title, *_table(cols, body, markdown)]


def _drops_text(s: Mapping[str, Any]) -> str:
    """The dropped column: the count, then the causes other than contradiction (when the
    records name them)."""
    other = {c: n for c, n in s.get("drop_causes", {}).items() if c != "contradicted"}
    if not other:
        return str(s.get("drops", 0))
    return f"{s.get('drops', 0)} ({', '.join(f'{n} {c}' for c, n in other.items())})"


def _table(cols: Sequence[str], body: Sequence[Sequence[str]], markdown: bool) -> list[str]:
    if markdown:
        return [
            "",
            "| " + " | ".join(cols) + " |",
            "|" + "---|" * len(cols),
            *("| " + " | ".join(r) + " |" for r in body),
        ]
    widths = [max(len(c), *(len(r[k]) for r in body)) for k, c in enumerate(cols)]
    return ["  ".join(x.ljust(widths[k]) for k, x in enumerate(r)).rstrip() for r in (cols, *body)]


def _paired_text(p: Mapping[str, Any] | None) -> str:
    if p is None:
        return "-"
    if p.get("ci_low") is None:
        return f"{p['mean']:+.1f} s"
    return f"{p['mean']:+.1f} s [{p['ci_low']:+.1f}, {p['ci_high']:+.1f}]"


def _gain_text(s: Mapping[str, Any]) -> str:
    shares = [s.get("gain_vs_none"), s.get("gain_vs_single")]
    if all(x is None for x in shares):
        return "-"
    return " / ".join("-" if x is None else f"{x:.0%}" for x in shares)


def _against_semantic_text(variant: str, d: Mapping[str, Any], where: str = "") -> str:
    return (
        f"{where + ': ' if where else ''}{variant} minus semantic, paired over "
        f"{d['episodes']} episodes: task time {_paired_text(d['task_time_s'])}; first merge "
        f"earlier in {d['first_merge_earlier']}, later in {d['first_merge_later']}"
    )


def load_study(path: str | Path, flag: str = "--against") -> dict[str, Any]:
    """A loop study's JSON given with ``flag`` (``--against``, ``--reuse``); a
    :class:`ConfigError` naming the problem when it cannot be read or is not one."""
    f = Path(path)
    try:
        doc = json.loads(f.read_text())
    except (OSError, ValueError) as exc:
        raise ConfigError(f"loop study: {flag} {str(f)!r} cannot be read: {exc}") from exc
    if not (isinstance(doc, dict) and isinstance(doc.get("episodes"), list)):
        raise ConfigError(f"loop study: {flag} {str(f)!r} is not a loop study's JSON")
    return doc


def against(doc: Mapping[str, Any], other: Mapping[str, Any], label: str) -> dict[str, Any]:
    """This run against another study's episodes of the same (world, variant, seed): per world
    and variant, and per variant over all worlds, the paired task-time difference (this minus
    that: :func:`_compare_pairs`); under ``references``, each variant against the other run's
    references (:data:`REFERENCES`) on the same seeds. ``label`` names the other run (its
    file)."""
    theirs = {(e["world"], e["variant"], e["seed"]): e for e in other["episodes"]}
    per: dict[str, dict[str, Any]] = {}
    pooled: dict[str, Any] = {}
    refs: dict[str, dict[str, Any]] = {}
    for v in doc["variants"]:
        all_pairs = []
        for w in doc["worlds"]:
            pairs = [
                (e, theirs[(w, v, e["seed"])])
                for e in doc["episodes"]
                if e["world"] == w and e["variant"] == v and (w, v, e["seed"]) in theirs
            ]
            if pairs:
                per.setdefault(w, {})[v] = _compare_pairs(pairs)
                all_pairs += pairs
        if all_pairs:
            pooled[v] = _compare_pairs(all_pairs)
        for ref in REFERENCES:
            d = _against_reference(doc["episodes"], other["episodes"], v, ref)
            if d:
                refs.setdefault(v, {}).update(d)
    return {
        "file": label,
        "env_options": dict(other.get("env_options", {})),
        "per_world": per,
        "all_worlds": pooled,
        "references": refs,
    }


def _against_text(a: Mapping[str, Any]) -> list[str]:
    lines = [f"Against {a['file']} (the same seeds; this run minus that one, paired):"]
    rows = [(w, v, d) for w, by in a["per_world"].items() for v, d in by.items()]
    rows += [("all worlds", v, d) for v, d in a["all_worlds"].items()]
    for w, v, d in rows:
        lines.append(
            f"  {w}, {v}: task time {_paired_text(d['task_time_s'])} over {d['episodes']} "
            f"episodes; first merge earlier in {d['first_merge_earlier']}, later in "
            f"{d['first_merge_later']}; reached {d['reached'][0]} vs {d['reached'][1]}"
        )
    # older runs kept the references among the pooled pairs
    for v, d in a.get("references", a["all_worlds"]).items():
        lines += [f"  all worlds, {x}" for x in _reference_texts(v, d, "that run's ")]
    return lines


def _reference_texts(variant: str, d: Mapping[str, Any], whose: str = "the ") -> list[str]:
    """One line per reference of :data:`REFERENCES` that ``d`` (a variant's figures) was
    measured against: the episodes merged of those the reference merged, the mean task time."""
    lines = []
    for name, share_key, vs_key in REFERENCES.values():
        if d.get(share_key) and d.get(vs_key) is not None:
            both, n = d[share_key]
            lines.append(
                f"{variant} against {whose}{name}: merged in {both} of the {n} episodes it "
                f"merged ({100.0 * both / max(n, 1):.0f}%); mean task time "
                f"{100.0 * d[vs_key]:+.1f}%"
            )
    return lines


def format_tables(doc: Mapping[str, Any], markdown: bool = False) -> str:
    """One table per world (text as printed, or markdown); a family run's tables name each
    world's seed and end with the aggregate over all its worlds (:func:`aggregate`)."""
    n = len(doc["seeds"])
    o = doc["env_options"]
    if o.get("task") == "navigate":
        what = (
            f"explore {o['nav_warmup_s']:.0f} s, then robot_0 drives to a goal "
            f"(nav_goal {o['nav_goal']}) within {o['max_time_s']:.0f} s; task time = the time "
            "after the warm-up (simulated s)"
        )
    else:
        what = f"explore to {o['target_coverage']:.0%} within {o['max_time_s']:.0f} s (simulated s)"
    head = (
        f"In-loop study: policy {doc['policy']}, {n} seeds from {doc['seeds'][0]}, random "
        f"headings, range noise {o['range_noise_m']} m, odometry noise {o['odom_noise_trans']} "
        f"/ {o['odom_noise_rot']} rad/rad / {o['odom_noise_rot_per_m']} rad/m; {what}"
    )
    if doc.get("extra_env_options"):
        opts = ",".join(f"{k}={v}" for k, v in doc["extra_env_options"].items())
        head += f"; env options {opts} (every variant"
        head += ", but 'single' is one robot)" if "n_robots" in doc["extra_env_options"] else ")"
    if doc.get("merge_options"):
        opts = ",".join(f"{k}={v}" for k, v in doc["merge_options"].items())
        head += f"; merger options {opts} (variants {', '.join(MERGER_VARIANTS)})"
    if any(doc.get("reused", {}).values()):
        took = ", ".join(f"{n} from {f}" for f, n in doc["reused"].items() if n)
        head += f"; episodes taken from studies of the same settings: {took}"
    fam = doc.get("family")
    if fam:
        head += f"; measured on {_where(doc)}"
    cols = (
        "variant",
        "merged",
        "1st merge med",
        "task time mean +- std",
        "reached",
        "wrong",
        "wrong s",
        "max contr",
        "lost",
        "vs oracle",
        "minus oracle, paired [95% CI]",
        "oracle's gain taken",
    )
    lines = [head, ""]
    seeds = doc["seeds"]
    for w, rows in doc["summary"].items():
        where = w
        if fam:  # every table says where it was measured
            ws = fam["world_seeds"][fam["specs"].index(w)] if w in fam["specs"] else "?"
            where = f"{w} (world seed {ws}; episode seeds {seeds[0]}-{seeds[-1]})"
        body = []
        for v, s in rows.items():
            two = v != "single"
            med = s["median_first_merge_s"]
            mean = s["task_time_mean_s"]
            body.append(
                (
                    v,
                    f"{s['merged']}/{s['episodes']}" if two else "-",
                    "-" if med is None else f"{med:.1f} s",
                    "-" if mean is None else f"{mean:.1f} +- {s['task_time_std_s']:.1f} s",
                    f"{s['reached']}/{s['episodes']}",
                    str(s["wrong_merge_episodes"]) if two else "-",
                    f"{s['merged_wrongly_s']:.1f}" if two else "-",
                    "-"
                    if s["max_fused_contradiction"] is None
                    else f"{s['max_fused_contradiction']:.3f}",
                    "-" if s.get("merges_lost") is None or not two else str(s["merges_lost"]),
                    "-" if s["vs_oracle"] is None else f"{s['vs_oracle']:+.1%}",
                    _paired_text(s.get("minus_oracle_s")),
                    _gain_text(s),
                )
            )
        if markdown:
            lines += [f"### {where}", "", "| " + " | ".join(cols) + " |"]
            lines.append("|" + "---|" * len(cols))
            lines += ["| " + " | ".join(r) + " |" for r in body]
        else:
            widths = [max(len(c), *(len(r[k]) for r in body)) for k, c in enumerate(cols)]
            lines.append(f"{where}:")
            for r in (cols, *body):
                lines.append("  ".join(x.ljust(widths[k]) for k, x in enumerate(r)).rstrip())
        for v, s in rows.items():
            d = s.get("minus_semantic")
            if d is not None:
                lines += ["", _against_semantic_text(v, d)]
        lines.append("")
    if doc.get("aggregate"):
        lines += [*_aggregate_lines(doc, markdown), ""]
    if doc.get("against"):
        text = _against_text(doc["against"])
        lines += [text[0], "", *(f"- {x.strip()}" for x in text[1:])] if markdown else text
        lines.append("")
    ran = doc.get("variants", ())
    for v in SEMANTIC_OPTION_VARIANTS:
        if v in ran and "semantic" in ran:
            lines += [
                _against_semantic_text(v, _against_semantic(doc["episodes"], v), "all worlds"),
                "",
            ]
    lines.append(
        "merged: episodes whose maps were merged; wrong: episodes in which a robot held a "
        "transform >= 5 cells off the truth, beyond what odometry drift explains, at some step; "
        "wrong s: seconds merged wrongly, summed "
        "over episodes; max contr: largest share of a robot's own-or-fused map contradicting the "
        "truth; lost: times a robot's merge was dropped by a re-check, summed over episodes; "
        "vs oracle: mean task time relative to the oracle's; minus oracle: the task time minus "
        "the oracle's on the same seed, mean and 95 % confidence interval (Student's t), s; "
        "oracle's gain taken: (base - variant) / (base - oracle) in mean task time, against "
        "never merging / against one robot."
    )
    return "\n".join(lines)
