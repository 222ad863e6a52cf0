"""The API reference (docs/api/, built by mkdocs in CI) names every public module of the package."""

from __future__ import annotations

import ast
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
API = ROOT / "docs" / "api"
PACKAGE = ROOT / "mrexplore"


def _is_alias(path: Path) -> bool:
    """A module kept only so old imports work (its docstring says where it moved)."""
    doc = ast.get_docstring(ast.parse(path.read_text())) or ""
    return doc.startswith("Moved to")


def test_every_subpackage_has_an_api_page_with_its_modules() -> None:
    text = {p.name: p.read_text() for p in API.glob("*.md")}
    for init in sorted(PACKAGE.glob("*/__init__.py")):
        name = init.parent.name
        page = text.get(f"{name}.md", "")
        assert f"::: mrexplore.{name}\n" in page, f"add docs/api/{name}.md (::: mrexplore.{name})"
        assert "show_submodules: true" in page, f"docs/api/{name}.md: show its submodules"
        # a filter may hide private names only: every public submodule is on the page
        assert "!^" not in page.replace('"!^_"', ""), f"docs/api/{name}.md hides a module"


def test_every_top_level_module_is_in_the_api_reference() -> None:
    text = "".join(p.read_text() for p in API.glob("*.md"))
    for path in sorted(PACKAGE.glob("*.py")):
        if path.name.startswith("_") or _is_alias(path):
            continue
        assert f"::: mrexplore.{path.stem}\n" in text, f"add ::: mrexplore.{path.stem} to docs/api"


def test_every_guide_and_api_page_is_in_the_nav() -> None:
    nav = (ROOT / "mkdocs.yml").read_text()
    for page in [*(ROOT / "docs" / "guide").glob("*.md"), *API.glob("*.md")]:
        assert page.relative_to(ROOT / "docs").as_posix() in nav, page
