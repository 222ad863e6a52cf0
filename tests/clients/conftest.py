"""The RL-library recipes of docs/guide/training.md, as written: ``recipe(name)`` runs the block
that starts with ``# recipe: <name>`` from the repository root and returns its namespace."""

from __future__ import annotations

import re
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

ROOT = Path(__file__).resolve().parents[2]
GUIDE = ROOT / "docs" / "guide" / "training.md"


def recipe_source(name: str) -> str:
    """The guide's block of recipe ``name`` (exactly one must exist)."""
    text = GUIDE.read_text()
    blocks = re.findall(r"```python\n(# recipe: (\w+)\n.*?)```", text, re.S)
    found = [code for code, tag in blocks if tag == name]
    assert len(found) == 1, f"{GUIDE.name} has {len(found)} blocks '# recipe: {name}'"
    return found[0]


@pytest.fixture
def recipe(monkeypatch: pytest.MonkeyPatch) -> Callable[[str], dict[str, Any]]:
    def run(name: str) -> dict[str, Any]:
        monkeypatch.chdir(ROOT)
        ns: dict[str, Any] = {"__name__": f"recipe_{name}"}
        exec(compile(recipe_source(name), f"{GUIDE.name} recipe {name}", "exec"), ns)
        return ns

    return run
