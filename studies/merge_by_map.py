"""Where one-shot merges are refused: bench results per source map, and the refusals' reasons.

Reads the JSON files of ``mrexplore bench merge`` (each case records its source map, overlap,
outcome and the merger's reason) and prints, for one method's default rows (``semantic`` unless
``--method``), per family and source map: the pairs with overlap >= ``--min-overlap`` (0.4), how
many were merged correctly, wrongly and refused, and the refusals grouped by the first words of
their reason (the text up to its first figure or parenthesis). Methods that run with several
detectors (``paper``, ``orb``) need ``--detector``. Cases of several files add up, so the seeds the
rules were chosen on and every held-out block can be pooled:

    python studies/merge_by_map.py docs/results/merge_seeds.json docs/results/merge_heldout.json

A refusal at high overlap is a merge the evidence may have allowed; the reasons say which rule
(ambiguity between look-alike places, consistency, shared space, ...) and the source maps where.
Files that record the pose each refusal judged (``best_error_cells``, written since 2026-11-27)
also say in how many refusals that pose was the truth: the search found it and a rule held it
back (rightly, when a rival explains the maps as well: the truth won the ranking by chance).
Reads only; writes nothing.
"""

from __future__ import annotations

import argparse
import json
import re
import sys
from collections import Counter, defaultdict
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

from mrexplore.studies.merge_bench import CORRECT_CELLS

#: The first figure or parenthesis of a reason ends its fixed words ("best hypothesis agrees only
#: 0.94 < 0.97" -> "best hypothesis agrees only").
_FIGURE = re.compile(r"[\d(]")


def reason_kind(reason: str) -> str:
    """The fixed first words of a merger's reason (up to its first figure or parenthesis).

    >>> reason_kind("best hypothesis agrees only 0.94 < 0.97 (raw index 0.91)")
    'best hypothesis agrees only'
    >>> reason_kind("ambiguous: best 1.000 vs 0.990 for a pose 40 cells away")
    'ambiguous: best'
    """
    m = _FIGURE.search(reason)
    return (reason[: m.start()] if m else reason).strip().rstrip(":;,")


def source_map(case_name: str) -> str:
    """The source of a bench case from its name (``"nav2/depot.yaml#3 (seed 5)"`` -> the
    part before ``#``).

    >>> source_map("nav2/depot.yaml@noisy#12 (seed 83)")
    'nav2/depot.yaml@noisy'
    """
    return case_name.split("#", 1)[0].strip()


def _detector(row: Mapping[str, Any]) -> str | None:
    d = row.get("detector")
    return None if d in (None, "-", "") else str(d)


def tally(
    docs: Iterable[Mapping[str, Any]],
    method: str,
    min_overlap: float,
    detector: str | None = None,
) -> dict[tuple[str, str], dict[str, Any]]:
    """Per (family, source map): ``pairs``, ``correct``, ``wrong``, ``imprecise``, ``refused``
    among the cases with overlap >= ``min_overlap`` of ``method``'s default rows with
    ``detector`` (None: rows that name none), ``reasons`` (a Counter of :func:`reason_kind`
    over the refusals), and of the refusals whose judged pose the file records
    (``best_error_cells``; ``judged``), those where that pose was the truth (``truth_refused``:
    within the bench's :data:`~mrexplore.studies.merge_bench.CORRECT_CELLS` plus the
    case's drift): the search found the truth and a rule held it back."""
    out: dict[tuple[str, str], dict[str, Any]] = defaultdict(
        lambda: {
            "pairs": 0,
            "correct": 0,
            "wrong": 0,
            "imprecise": 0,
            "refused": 0,
            "reasons": Counter(),
            "judged": 0,
            "truth_refused": 0,
        }
    )
    for doc in docs:
        for row in doc["rows"]:
            if row["method"] != method or row.get("options") not in ("-", "", None):
                continue
            if _detector(row) != detector:
                continue
            for case in row["cases"]:
                if case["overlap"] < min_overlap:
                    continue
                t = out[(row["family"], source_map(case["case"]))]
                t["pairs"] += 1
                t[case["kind"]] += 1
                if case["kind"] == "refused":
                    t["reasons"][reason_kind(case["reason"])] += 1
                    best = case.get("best_error_cells")
                    if best is not None:  # files written since the field exists
                        t["judged"] += 1
                        t["truth_refused"] += best < CORRECT_CELLS + case.get("drift_cells", 0.0)
    return dict(out)


def format_tally(t: Mapping[tuple[str, str], Mapping[str, Any]], min_overlap: float) -> str:
    """The table as printed: one line per family and source map, then its refusals."""
    lines = [f"pairs with overlap >= {min_overlap:g}: correct / pairs, wrong, imprecise, refused"]
    for (family, src), r in sorted(t.items()):
        share = r["correct"] / r["pairs"] if r["pairs"] else 0.0
        lines.append(
            f"{family:10s} {src:34s} {r['correct']:5d} / {r['pairs']:5d} ({share:4.0%})"
            f"  wrong {r['wrong']}, imprecise {r['imprecise']}, refused {r['refused']}"
            + (
                f" (the refused pose was the truth in {r['truth_refused']} of {r['judged']})"
                if r["judged"]
                else ""
            )
        )
        for kind, n in r["reasons"].most_common():
            lines.append(f"{'':12s}{n:5d}  {kind}")
    return "\n".join(lines)


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0] if __doc__ else None)
    p.add_argument("files", nargs="+", help="merge bench JSON files (their cases add up)")
    p.add_argument("--method", default="semantic", help="the method's rows (default semantic)")
    p.add_argument("--detector", default=None, help="the detector's rows (methods that use one)")
    p.add_argument("--min-overlap", type=float, default=0.4, help="overlap floor (default 0.4)")
    args = p.parse_args(argv)
    if not 0.0 <= args.min_overlap <= 1.0:
        print(f"error: --min-overlap must lie in [0, 1], got {args.min_overlap}", file=sys.stderr)
        return 2
    docs = []
    for f in args.files:
        try:
            doc = json.loads(Path(f).read_text())
            if not isinstance(doc, dict) or not isinstance(doc.get("rows"), list):
                raise ValueError("not a merge bench JSON (no 'rows')")
            if any("cases" not in row for row in doc["rows"]):
                raise ValueError("its rows hold no per-case records ('cases')")
        except (OSError, ValueError) as exc:
            print(f"error: {f!r} cannot be read as a merge bench result: {exc}", file=sys.stderr)
            return 2
        docs.append(doc)
    detectors = sorted(
        {str(_detector(r)) for d in docs for r in d["rows"] if r["method"] == args.method}
    )
    t = tally(docs, args.method, args.min_overlap, args.detector)
    if not t:
        print(
            f"error: no {args.method!r} default rows with detector {args.detector!r} in these "
            f"files (their detectors: {', '.join(detectors) or 'none'}; name one with --detector)",
            file=sys.stderr,
        )
        return 2
    print(format_tally(t, args.min_overlap))
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
