"""Every ```python example of README.md runs, as written, from the repository root."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
ALL_BLOCKS = re.findall(r"```python\n(.*?)```", (ROOT / "README.md").read_text(), re.S)
# The RL-library recipes ("# recipe: <client>") run in tests/clients/, with their own checks and
# markers (RLlib and TorchRL take ~30 s each).
BLOCKS = [b for b in ALL_BLOCKS if not b.startswith("# recipe:")]


def test_readme_has_python_examples() -> None:
    assert len(BLOCKS) >= 3


@pytest.mark.parametrize("index", range(len(BLOCKS)))
def test_readme_example_runs(index: int, monkeypatch: pytest.MonkeyPatch) -> None:
    # Each block on its own (a fresh namespace): an example must carry its own imports.
    monkeypatch.chdir(ROOT)
    code = compile(BLOCKS[index], f"README.md python block {index}", "exec")
    exec(code, {"__name__": f"readme_{index}"})
