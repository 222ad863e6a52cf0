"""``mrexplore bench merge --combine``: several runs (blocks of seeds) become one study file
whose rows are the runs' rows unchanged, each labelled with its block's seeds."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

from mrexplore.cli import main
from mrexplore.errors import ConfigError
from mrexplore.studies.merge_bench import (
    COLUMNS,
    combine_blocks,
    combined_markdown,
    format_seeds,
    parse_seeds,
)

RESULTS = Path(__file__).resolve().parents[2] / "docs" / "results"


def _row(family: str, seeds: list[int], options: str = "-", wrong: int = 0) -> dict[str, Any]:
    """A bench row with one case per seed, as ``run_bench`` writes them."""
    n = len(seeds)
    row: dict[str, Any] = {c: 0 for c in COLUMNS}
    row.update(
        method="semantic",
        detector="-",
        options=options,
        n=n,
        correct=n - wrong,
        wrong=wrong,
        refused=0,
        correct_overlap40=f"{n - wrong}/{n}",
        family=family,
        cases=[
            {"case": f"{family}#{i} (seed {s})", "overlap": 0.5, "kind": "correct"}
            for i, s in enumerate(seeds)
        ],
    )
    return row


def _block(seeds: list[int], *variants: str, families: tuple[str, ...] = ("symmetric",)) -> dict:
    return {"rows": [_row(f, seeds, o) for f in families for o in ("-", *variants)]}


def test_rows_are_kept_in_order_and_labelled_with_their_block() -> None:
    a = _block([13, 14, 15], "min_wall_area_m2=0")
    b = _block([33, 34], "slide_test=True", families=("symmetric", "aliased"))
    doc = combine_blocks([("a.json", a), ("b.json", b)])
    assert [r["seeds"] for r in doc["rows"]] == ["13-15"] * 2 + ["33-34"] * 4
    # every figure and case as its run wrote it; only the label is new
    assert [{k: v for k, v in r.items() if k != "seeds"} for r in doc["rows"]] == [
        *a["rows"],
        *b["rows"],
    ]
    assert doc["blocks"] == [
        {"seeds": "13-15", "families": ["symmetric"], "variants": ["min_wall_area_m2=0"]},
        {"seeds": "33-34", "families": ["symmetric", "aliased"], "variants": ["slide_test=True"]},
    ]
    md = combined_markdown(doc)
    assert "| seeds | method |" in md and "| 33-34 | semantic | - | slide_test=True |" in md
    # the default rows of a family add up over its blocks
    assert "The default (`-`) over its 2 blocks: 5 correct, 0 WRONG" in md
    assert "of 5; correct at overlap >= 40 %: 5/5." in md


@pytest.mark.parametrize(
    ("docs", "words"),
    [
        ([("x.json", [])], "x.json is not a merge bench result"),
        ([("x.json", {"rows": []})], "x.json has no rows"),
        ([("a.json", _block([1, 2])), ("b.json", _block([2, 3]))], "share seeds 2"),
        ([("c.json", combine_blocks([("a", _block([1]))]))], "is a combined file already"),
        ([("t.json", {**_block([1]), "tracker": {}})], "t.json holds tracker"),
        ([("n.json", {"rows": [{"family": "symmetric", "cases": []}]})], "rows of n.json lack"),
        (
            [("s.json", {"rows": [{**_row("symmetric", [1]), "cases": [{"case": "x#0"}]}]})],
            "no '(seed N)' in the case names of s.json",
        ),
    ],
)
def test_bad_blocks_are_refused_naming_the_file(docs: list[Any], words: str) -> None:
    with pytest.raises(ConfigError) as err:
        combine_blocks(docs)
    assert words in str(err.value)


def test_format_seeds_is_read_back_by_parse_seeds() -> None:
    seeds = [0, 1, 2, 5, 7, 8, 113, 114]
    assert format_seeds(reversed(seeds)) == "0-2,5,7-8,113-114"
    assert parse_seeds(format_seeds(seeds)) == seeds


def test_cli_combines_refuses_to_overwrite_and_runs_nothing(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    a, b = tmp_path / "a.json", tmp_path / "b.json"
    a.write_text(json.dumps(_block([1, 2])))
    b.write_text(json.dumps(_block([3])))
    out = tmp_path / "study"
    assert main(["bench", "merge", "--combine", str(a), str(b), "--out", str(out)]) == 0
    doc = json.loads(out.with_suffix(".json").read_text())
    assert [r["seeds"] for r in doc["rows"]] == ["1-2", "3"]
    assert out.with_suffix(".md").read_text() == combined_markdown(doc) + "\n"
    capsys.readouterr()
    # an existing study is kept without --force
    assert main(["bench", "merge", "--combine", str(a), "--out", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err
    assert json.loads(out.with_suffix(".json").read_text()) == doc
    # options that make cases mean nothing here
    assert main(["bench", "merge", "--combine", str(a), "--seeds", "1", "--out", "x"]) == 2
    assert "--combine runs no cases: drop --seeds" in capsys.readouterr().err
    assert main(["bench", "merge", "--combine", str(a)]) == 2
    assert "--combine needs --out" in capsys.readouterr().err


def test_the_committed_held_out_study_is_one_file_of_disjoint_blocks() -> None:
    doc = json.loads((RESULTS / "merge_heldout.json").read_text())
    labels = [b["seeds"] for b in doc["blocks"]]
    assert len(labels) >= 9 and [r["seeds"] for r in doc["rows"]] == [
        label for label in labels for r in doc["rows"] if r["seeds"] == label
    ]
    seeds = [s for label in labels for s in parse_seeds(label)]
    assert len(seeds) == len(set(seeds))
    assert (RESULTS / "merge_heldout.md").read_text() == combined_markdown(doc) + "\n"
    assert not list(RESULTS.glob("merge_heldout[0-9]*"))
