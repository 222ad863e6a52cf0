"""``scripts/reproduce_paper.sh``, its control flow with a stand-in ``mrexplore`` on PATH (the
real run takes hours): every step runs once, the two groups side by side, a failing step fails
the script, and nothing runs without ``--force``."""

from __future__ import annotations

import os
import re
import subprocess
from pathlib import Path

import pytest

SCRIPT = Path(__file__).resolve().parents[2] / "scripts" / "reproduce_paper.sh"

#: A stand-in for the CLI: logs its arguments, prints what it ran, fails when they contain
#: $FAKE_FAIL_ON.
FAKE = """#!/usr/bin/env bash
echo "$*" >> "$FAKE_LOG"
echo "ran $1 $2"
if [[ -n "${FAKE_FAIL_ON:-}" && "$*" == *"$FAKE_FAIL_ON"* ]]; then
  echo "fake failure: $*" >&2
  exit 3
fi
"""


def _run(
    tmp_path: Path, *args: str, fail_on: str = ""
) -> tuple[subprocess.CompletedProcess[str], list[str]]:
    bin_dir = tmp_path / "bin"
    bin_dir.mkdir(exist_ok=True)
    fake = bin_dir / "mrexplore"
    fake.write_text(FAKE)
    fake.chmod(0o755)
    log = tmp_path / "calls.log"
    env = {**os.environ, "PATH": f"{bin_dir}:{os.environ['PATH']}", "FAKE_LOG": str(log)}
    env["FAKE_FAIL_ON"] = fail_on
    done = subprocess.run(
        ["bash", str(SCRIPT), *args], capture_output=True, text=True, env=env, timeout=120
    )
    calls = log.read_text().splitlines() if log.exists() else []
    return done, calls


def _outputs() -> list[str]:
    """The ``--out`` of every step the script holds, with its variables filled in (``$blocks``,
    a temporary folder, as ``BLOCKS``)."""
    outs = re.findall(r'--out "([^"]+)"', SCRIPT.read_text())
    ev = "docs/results/goal_policy_eval"
    return [
        o.replace("$ev", ev).replace("$out", "docs/results").replace("$blocks", "BLOCKS")
        for o in outs
    ]


def test_every_step_runs_once(tmp_path: Path) -> None:
    done, calls = _run(tmp_path, "--force")
    assert done.returncode == 0, done.stderr
    ran = [m.group(1) for c in calls if (m := re.search(r"--out (\S+)", c))]
    assert len(ran) == len(calls)  # every step names its output
    blocks = {o.rsplit("/", 1)[0] for o in ran if not o.startswith("docs/")}
    assert len(blocks) == 1  # the held-out blocks share one temporary folder
    (folder,) = blocks
    named = [o.replace(folder, "BLOCKS") for o in ran]
    assert sorted(named) == sorted(_outputs()) and len(set(ran)) == len(ran) >= 30
    runs = [c for c in calls if c.startswith("bench merge --case-cache")]
    assert len(runs) == sum(o.startswith("BLOCKS/") or "/merge_" in o for o in named) - 1
    # the combining step comes after its blocks and reads exactly them
    (combine,) = [i for i, c in enumerate(calls) if c.startswith("bench merge --combine")]
    block_steps = [i for i, o in enumerate(named) if o.startswith("BLOCKS/")]
    assert len(block_steps) >= 9 and max(block_steps) < combine
    assert calls[combine].split("--combine ")[1].split(" --out")[0].split() == [
        ran[i] + ".json" for i in block_steps
    ]
    assert named[combine] == "docs/results/merge_heldout"
    # the merge group's output is printed once, when it ends
    assert done.stdout.count("ran bench merge") == len(runs) + 1


@pytest.mark.parametrize("step", ["--seeds 33-42", "--combine", "loop_exact"])
def test_a_failing_step_fails_the_script(tmp_path: Path, step: str) -> None:
    done, calls = _run(tmp_path, "--force", fail_on=step)
    assert done.returncode != 0
    assert any(step in c for c in calls)
    if not step.startswith("loop"):
        assert "a merge step failed" in done.stderr


def test_nothing_runs_without_force(tmp_path: Path) -> None:
    done, calls = _run(tmp_path)
    assert done.returncode == 2 and "--force" in done.stderr
    assert calls == []
