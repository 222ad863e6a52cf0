"""Every script of ``examples/`` runs as a user would run it (a subprocess, from another folder)
and prints what its docstring promises."""

from __future__ import annotations

import os
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
EXAMPLES = ROOT / "examples"
#: script -> a text its output must contain
EXPECTED = {
    "train_policy.py": "trained 256 steps",
    "measure_team_gain.py": "wrong_merge=",
    "reuse_merger.py": "wrapper: merged True",
}


def test_every_example_is_tested_short_and_documented() -> None:
    scripts = sorted(p.name for p in EXAMPLES.glob("*.py"))
    assert scripts == sorted(EXPECTED)
    for name in scripts:
        text = (EXAMPLES / name).read_text()
        assert text.startswith('"""'), f"{name}: start with a docstring saying what it shows"
        assert len(text.splitlines()) <= 40, f"{name}: keep an example under 40 lines"


@pytest.mark.parametrize("name", sorted(EXPECTED))
def test_example_runs(name: str, tmp_path: Path) -> None:
    env = {**os.environ, "MPLBACKEND": "Agg"}
    done = subprocess.run(
        [sys.executable, str(EXAMPLES / name)],
        cwd=tmp_path,
        env=env,
        capture_output=True,
        text=True,
        timeout=300,
        check=False,
    )
    assert done.returncode == 0, done.stderr[-3000:]
    assert EXPECTED[name] in done.stdout, done.stdout[-3000:]
    assert not list(tmp_path.iterdir()), "an example leaves no files behind"
