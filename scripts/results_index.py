"""Write ``docs/results/index.md``: one row per study of ``docs/results/``, read from its files.

Each study is the set of files one command wrote: ``NAME.json`` with its ``NAME.md`` / ``.csv`` /
``.png`` beside it, or a folder holding one JSON file (``goal_policy_eval/office/eval.json``). Per
study the index gives what it measures (read from the JSON's own fields: policy, variants, worlds,
families, methods, options, seeds), the command that made it (the line of
``scripts/reproduce_paper.sh`` that writes it, when there is one), a headline figure (computed from
the JSON, never typed in) and its files. Nothing in the index is written by hand, so after a study
is added or regenerated, run

    python scripts/results_index.py            # rewrites docs/results/index.md in place
    python scripts/results_index.py --check    # exit 1 if the index is out of date

The file is replaced atomically (written beside it, then renamed), so a reader never sees half an
index. ``tests/test_results_index.py`` fails when the committed index differs from a fresh one.
"""

from __future__ import annotations

import argparse
import json
import os
import re
import shlex
import sys
import tempfile
from collections.abc import Iterable, Mapping, Sequence
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
RESULTS = ROOT / "docs" / "results"
INDEX_NAME = "index.md"
REPRODUCE = ROOT / "scripts" / "reproduce_paper.sh"
#: Variables of reproduce_paper.sh, as the paths they stand for (relative to the repository);
#: BLOCKS is the temporary folder where the blocks of a combined study are run.
SCRIPT_VARS = {
    "$out": "docs/results",
    "$ev": "docs/results/goal_policy_eval",
    "$blocks": "BLOCKS",
}
SIDE_FILES = (".md", ".csv", ".png")

HEADER = """# Results index

Every study committed in `docs/results/`, one row each: what it measures, the command that made it,
a headline figure and its files. **Generated** by `python scripts/results_index.py` from the JSON
files themselves (the figures are computed from them, not typed in): do not edit by hand; run the
script again after adding or regenerating a study (a test checks that this page is up to date).
`scripts/reproduce_paper.sh --force` regenerates every study whose command is given; figures
other than timings come out the same on any machine with the pinned versions. What the studies
mean, and the caveats that go with them: [Experiments](../guide/experiments.md) and
[The merger](../guide/merger.md#measured-what-it-merges-and-what-it-refuses).

| study | what it measures | command | headline | files |
|---|---|---|---|---|
"""


# --- reading ----------------------------------------------------------------------------------


def studies(results: Path) -> list[tuple[str, Path, list[Path]]]:
    """``(name, json_path, files)`` for each study under ``results``, sorted by name."""
    found: list[tuple[str, Path, list[Path]]] = []
    for path in sorted(results.rglob("*.json")):
        rel = path.relative_to(results)
        if len(rel.parts) == 1:
            name = path.stem
            files = [path] + [
                path.with_suffix(s) for s in SIDE_FILES if path.with_suffix(s).exists()
            ]
        else:
            name = "/".join(rel.parts[:-1])
            files = sorted(p for p in path.parent.iterdir() if p.is_file())
        found.append((name, path, files))
    return sorted(found, key=lambda t: t[0])


def script_commands(script: Path) -> dict[str, str]:
    """Output path (repository-relative, no suffix) -> the command of ``script`` that writes it.

    Joins continued lines, expands the script's path variables and its ``bench_merge`` helper,
    and leaves out the options that only say where and how to write (``--force``,
    ``--case-cache``)."""
    if not script.exists():
        return {}
    text = script.read_text().replace("\\\n", " ")
    commands: dict[str, str] = {}
    for line in text.splitlines():
        words = line.strip()
        if "--out" not in words or not words.startswith(("mrexplore ", "bench_merge ")):
            continue
        try:
            argv = shlex.split(words, posix=True)
        except ValueError:  # pragma: no cover - an unbalanced quote in the script
            continue
        argv = [_expand(a) for a in argv]
        if argv[0] == "bench_merge":
            argv = ["mrexplore", "bench", "merge", *argv[1:]]
        out = argv[argv.index("--out") + 1]
        kept: list[str] = []
        skip = False
        for a in argv:
            if skip:
                skip = False
                continue
            if a == "--force":
                continue
            if a == "--case-cache":
                skip = True
                continue
            kept.append(a)
        commands[out] = shlex.join(kept)
    return commands


def _expand(word: str) -> str:
    for var, value in SCRIPT_VARS.items():
        word = word.replace(var, value)
    return word


# --- describing -------------------------------------------------------------------------------


def _seeds(seeds: Iterable[int]) -> str:
    """``[1, 2, 3, 7]`` -> ``"1-3, 7"``."""
    values = sorted(set(seeds))
    if not values:
        return "-"
    runs: list[str] = []
    start = prev = values[0]
    for v in [*values[1:], None]:
        if v is not None and v == prev + 1:
            prev = v
            continue
        runs.append(str(start) if start == prev else f"{start}-{prev}")
        if v is not None:
            start = prev = v
    return ", ".join(runs)


def _options(options: Mapping[str, Any]) -> str:
    return ", ".join(f"{k}={v}" for k, v in options.items())


def _pct(x: float) -> str:
    return f"{100 * x:+.1f} %"


def _unique(values: Iterable[str]) -> list[str]:
    return list(dict.fromkeys(values))


_FAMILY_WORLD = re.compile(r"(family:[^/]+/[^/]+/)(\d+)$")


def _worlds(worlds: Sequence[str]) -> str:
    """World names, a family part's consecutive worlds as one range.

    >>> _worlds(["family:f/test/0", "family:f/test/1", "family:f/test/2", "depot"])
    'family:f/test/0-2 (3 worlds), depot'
    """
    out: list[str] = []
    run: list[tuple[str, int]] = []

    def flush() -> None:
        if len(run) > 2:
            out.append(f"{run[0][0]}{run[0][1]}-{run[-1][1]} ({len(run)} worlds)")
        else:
            out.extend(f"{prefix}{i}" for prefix, i in run)
        run.clear()

    for name in worlds:
        m = _FAMILY_WORLD.match(name)
        if m and run and run[-1][0] == m.group(1) and run[-1][1] + 1 == int(m.group(2)):
            run.append((m.group(1), int(m.group(2))))
            continue
        flush()
        if m:
            run.append((m.group(1), int(m.group(2))))
        else:
            out.append(name)
    flush()
    return ", ".join(out)


def describe_loop(doc: Mapping[str, Any]) -> tuple[str, str]:
    worlds = list(doc["worlds"])
    what = (
        f"in-loop merging: team `{doc['policy']}`, variants {', '.join(doc['variants'])}; "
        f"worlds {_worlds(worlds)}; seeds {_seeds(doc['seeds'])}"
    )
    extra = {**doc.get("env_options", {}), **doc.get("extra_env_options", {})}
    if extra:
        what += f"; env {_options(extra)}"
    if doc.get("merge_options"):
        what += f"; merger {_options(doc['merge_options'])}"
    summary = doc["summary"]
    parts: list[str] = []
    for variant in doc["variants"]:
        if variant in ("oracle", "none", "single"):
            continue
        rows = [summary[w][variant] for w in worlds if variant in summary.get(w, {})]
        merged = sum(int(r["merged"]) for r in rows)
        episodes = sum(int(r["episodes"]) for r in rows)
        wrong = sum(int(r["wrong_merge_episodes"]) for r in rows)
        part = f"{variant}: merged {merged}/{episodes}, wrong {wrong}"
        vs = [r.get("vs_oracle") for r in rows]
        if "oracle" in doc["variants"] and all(v is not None for v in vs):
            part += "; task time vs oracle " + " / ".join(_pct(float(v)) for v in vs)
        parts.append(part)
    if not parts:  # only baselines: their task times
        for variant in doc["variants"]:
            rows = [summary[w][variant] for w in worlds]
            times = " / ".join(f"{float(r['task_time_mean_s']):.1f}" for r in rows)
            parts.append(f"{variant}: task time {times} s")
    return what, "; ".join(parts)


_SEED = re.compile(r"\(seed (\d+)\)")


def describe_merge(doc: Mapping[str, Any]) -> tuple[str, str]:
    rows = doc["rows"]
    families = _unique(r["family"] for r in rows)
    methods = _unique(
        r["method"] if r["detector"] in ("-", r["method"]) else f"{r['method']} ({r['detector']})"
        for r in rows
    )
    variants = _unique(r["options"] for r in rows if r["options"] != "-")
    seeds = {int(m.group(1)) for r in rows for c in r["cases"] if (m := _SEED.search(c["case"]))}
    # a combined study's rows carry their block (``seeds``): its families' cases add up
    blocks = _unique(str(r.get("seeds", "")) for r in rows)
    per_family = {
        f: sum(
            max(
                (int(r["n"]) for r in rows if r["family"] == f and r.get("seeds", "") == b),
                default=0,
            )
            for b in blocks
        )
        for f in families
    }
    what = (
        f"one-shot merges: families {', '.join(f'{f} ({n})' for f, n in per_family.items())}; "
        f"methods {', '.join(methods)}"
    )
    if doc.get("blocks"):
        what += (
            f"; {len(doc['blocks'])} blocks of seeds, a row per block and variant: "
            + "; ".join(
                f"{b['seeds']} ({', '.join(b['variants']) or 'default only'})"
                for b in doc["blocks"]
            )
        )
    elif variants:
        what += f"; variants {'; '.join(variants)}"
    what += f"; seeds {_seeds(seeds) if seeds else '0'}"
    parts: list[str] = []
    for method in _unique(r["method"] for r in rows):
        detectors = _unique(r["detector"] for r in rows if r["method"] == method)
        for det in detectors:
            default = [
                r
                for r in rows
                if r["method"] == method and r["detector"] == det and r["options"] == "-"
            ]
            if not default:
                continue
            n = sum(int(r["n"]) for r in default)
            correct = sum(int(r["correct"]) for r in default)
            wrong = sum(int(r["wrong"]) for r in default)
            refused = sum(int(r["refused"]) for r in default)
            label = method if det in ("-", method) else f"{method} ({det})"
            parts.append(f"{label}: {correct} correct, {wrong} wrong, {refused} refused of {n}")
    return what, "; ".join(parts)


def describe_task_time(doc: Mapping[str, Any]) -> tuple[str, str]:
    what = (
        f"task time, 1 robot against 2: world `{doc['world']}`, policy `{doc['policy']}`, "
        f"tasks {', '.join(doc['tasks'])}; seeds {_seeds(doc['seeds'])}; "
        f"options {_options(doc.get('options', {}))}"
    )
    parts = []
    for task, t in doc["tasks"].items():
        multi = t["multi"]
        part = (
            f"{task}: {float(t['single']['mean']):.1f} s -> {float(multi['mean']):.1f} s "
            f"({-100 * float(t['reduction']):+.1f} %)"
        )
        if "wrong_merge_episodes" in multi:  # files made before wrong merges were reported lack it
            n = len(multi["task_times_s"])
            part += (
                f", merged {multi['merged_episodes']}/{n}, "
                f"wrong {multi['wrong_merge_episodes']}/{n}"
            )
        parts.append(part)
    # the mode without its advice to the table's reader ("... (see the wrong column)")
    merging = f"merging {doc['merging'].split(' (')[0]}: " if doc.get("merging") else ""
    return what, merging + "; ".join(parts)


def describe_eval(doc: Mapping[str, Any]) -> tuple[str, str]:
    env = doc["env"]
    worlds = ", ".join(f"`{w}`" for w in doc.get("worlds", {})) or f"`{env.get('world')}`"
    what = (
        f"a trained policy against the planners: `{doc['policy_folder']}` on "
        f"{worlds}, {env.get('n_robots')} robots, to {env.get('target_coverage')} "
        f"coverage within {env.get('max_time_s')} s; seeds {_seeds(doc['seeds'])}; "
        f"actions {doc.get('trained_actions')}"
    )
    base = doc.get("paired_baseline")
    parts = []
    for name, paired in doc.get("paired", {}).items():
        key = "time_to_0.95" if "time_to_0.95" in paired else next(iter(paired), None)
        if key is None:
            continue
        p = paired[key]
        parts.append(
            f"{name} minus {base}, {key.replace('_', ' ')}: {float(p['mean']):+.1f} s "
            f"[{float(p['ci_low']):+.1f}, {float(p['ci_high']):+.1f}] (n {p['n']})"
        )
    return what, "; ".join(parts)


def describe_env_bench(doc: Mapping[str, Any]) -> tuple[str, str]:
    rows = {k: v for k, v in doc.items() if k != "machine"}
    what = "env speed, CPU time of the stepping thread (a timing: machine- and load-dependent): "
    what += "; ".join(rows)
    parts = []
    machine = doc.get("machine")
    if isinstance(machine, dict):
        load = machine.get("load")
        parts.append(
            f"machine: {machine.get('usable_cores')} cores"
            + ("" if not load else f", load {float(load[0]):.2f} before")
        )
    for name, row in rows.items():
        if "robot_steps_per_s" in row and "p99_ms" in row:
            parts.append(
                f"{name}: {float(row['robot_steps_per_s']):,.0f} robot-steps/s, "
                f"p99 {float(row['p99_ms']):.2f} ms"
            )
        elif "process_ms" in row and "max_over_p50" in row:
            merge = (
                ""
                if "merge_ms" not in row
                else f" ({float(row['merge_ms']):.2f} in {row['merge_attempts']} merge attempts)"
            )
            parts.append(
                f"{name}: {float(row['process_ms']):.2f} ms of process CPU per step{merge}, the "
                f"slowest step {float(row['max_over_p50']):.2f}x the median"
            )
        elif "single" in row:
            for key, label in (("batched_threads", "threads"), ("batched_processes", "processes")):
                if key in row:
                    parts.append(
                        f"{name}, {row['num_envs']} worlds in {label}: "
                        f"{float(row[key]['wall_ratio']):.2f}x the single envs in wall time"
                    )
    return what, "; ".join(parts)


def _is_env_bench(doc: Mapping[str, Any]) -> bool:
    """Is ``doc`` a ``mrexplore bench env --json`` file (rows keyed by setting, a machine)?"""
    rows = [v for k, v in doc.items() if k != "machine"]
    return bool(rows) and all(
        isinstance(v, dict) and ("robot_steps_per_s" in v or "process_ms" in v or "single" in v)
        for v in rows
    )


def describe(doc: Any) -> tuple[str, str]:
    """``(what it measures, headline)`` of one study's JSON document."""
    if isinstance(doc, dict):
        if "summary" in doc and "variants" in doc:
            return describe_loop(doc)
        if "rows" in doc:
            return describe_merge(doc)
        if "tasks" in doc and "world" in doc:
            return describe_task_time(doc)
        if "policy_folder" in doc:
            return describe_eval(doc)
        if _is_env_bench(doc):
            return describe_env_bench(doc)
        return "keys: " + ", ".join(map(str, doc)), "-"
    return type(doc).__name__, "-"  # pragma: no cover - every study is a JSON object


# --- writing ----------------------------------------------------------------------------------


def _cell(text: str) -> str:
    return text.replace("|", "\\|").replace("\n", " ")


def render(results: Path = RESULTS, script: Path = REPRODUCE) -> str:
    """The index page for the studies under ``results``."""
    commands = script_commands(script)
    lines = [HEADER]
    for name, json_path, files in studies(results):
        what, headline = describe(json.loads(json_path.read_text()))
        # reproduce_paper.sh writes to docs/results/...: key the study as if it lived there
        inside = Path(SCRIPT_VARS["$out"]) / json_path.relative_to(results)
        rel = inside.with_suffix("").as_posix()
        folder = inside.parent.as_posix()
        command = commands.get(rel)
        if command is None and folder in commands:
            # a command that writes into a folder: a study's own folder, or files named after
            # the command's verb (``mrexplore task-time --out docs/results`` -> task_time.json)
            verb = commands[folder].split()[1].replace("-", "_")
            if json_path.parent != results or json_path.stem == verb:
                command = commands[folder]
        links = ", ".join(
            f"[{p.relative_to(results).as_posix()}]({p.relative_to(results).as_posix()})"
            for p in files
        )
        cmd = _command_cell(command, commands) if command else "not in `scripts/reproduce_paper.sh`"
        lines.append(
            f"| **{_cell(name)}** | {_cell(what)} | {_cell(cmd)} | {_cell(headline)} | {links} |\n"
        )
    return "".join(lines)


def _command_cell(command: str, commands: Mapping[str, str]) -> str:
    """The command column: a combining step (``--combine A.json B.json ...``) is shown after the
    commands that write its blocks, so the cell says everything that makes the study."""
    argv = shlex.split(command)
    if "--combine" not in argv:
        return f"`{command}`"
    inputs: list[str] = []
    for a in argv[argv.index("--combine") + 1 :]:
        if a.startswith("--"):
            break
        inputs.append(a)
    made = [commands.get(a.removesuffix(".json")) for a in inputs]
    steps = [f"`{c}`" for c in made if c is not None]
    folder = " (BLOCKS: a temporary folder)" if any("BLOCKS/" in a for a in inputs) else ""
    return "; ".join(steps) + f"; then `{command}`{folder}" if steps else f"`{command}`"


def write_atomic(path: Path, text: str) -> None:
    """Replace ``path`` by ``text`` at once: a temporary file beside it, then a rename."""
    fd, tmp = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    try:
        with os.fdopen(fd, "w") as f:
            f.write(text)
        os.replace(tmp, path)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise


def main(argv: Sequence[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--results", type=Path, default=RESULTS, help="folder of the studies")
    p.add_argument("--check", action="store_true", help="exit 1 if the index is out of date")
    args = p.parse_args(argv)
    results: Path = args.results.resolve()
    index = results / INDEX_NAME
    text = render(results)
    if args.check:
        if not index.exists() or index.read_text() != text:
            print(
                f"results_index: {index} is out of date; run scripts/results_index.py",
                file=sys.stderr,
            )
            return 1
        return 0
    write_atomic(index, text)
    print(f"results_index: wrote {index} ({len(studies(results))} studies)")
    return 0


if __name__ == "__main__":
    sys.exit(main())
