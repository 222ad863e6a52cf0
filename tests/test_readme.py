"""Every ```python example of README.md and of the guides (docs/guide/*.md) runs, as written,
from the repository root; the README stays short and links to pages that exist."""

from __future__ import annotations

import re
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
PAGES = [ROOT / "README.md", *sorted((ROOT / "docs" / "guide").glob("*.md"))]


def _blocks(page: Path) -> list[str]:
    return re.findall(r"```python\n(.*?)```", page.read_text(), re.S)


# The RL-library recipes ("# recipe: <client>", in docs/guide/training.md) run in tests/clients/,
# with their own checks and markers (RLlib and TorchRL take ~30 s each).
EXAMPLES = [
    (page.relative_to(ROOT).as_posix(), i, code)
    for page in PAGES
    for i, code in enumerate(_blocks(page))
    if not code.startswith("# recipe:")
]
README = (ROOT / "README.md").read_text()


def test_readme_has_python_examples() -> None:
    assert sum(1 for name, _, _ in EXAMPLES if name == "README.md") >= 3


def test_readme_is_short_and_keeps_the_ci_commands() -> None:
    assert len(README.splitlines()) < 200
    assert "python -m pytest -q" in README  # .ci/run runs it
    assert 'pip install -c requirements/constraints.txt -e ".[all]"' in README
    assert "pip install torch==2.13.0" in README


def test_readme_links_point_to_files() -> None:
    for target in re.findall(r"\]\(([^)#\s]+)(?:#[^)]*)?\)", README):
        if "://" not in target:
            assert (ROOT / target).exists(), target


@pytest.mark.parametrize(
    ("page", "index", "code"), EXAMPLES, ids=[f"{p}:{i}" for p, i, _ in EXAMPLES]
)
def test_example_runs(page: str, index: int, code: str, monkeypatch: pytest.MonkeyPatch) -> None:
    # Each block on its own (a fresh namespace): an example must carry its own imports.
    monkeypatch.chdir(ROOT)
    exec(compile(code, f"{page} python block {index}", "exec"), {"__name__": f"example_{index}"})
