"""``mrexplore --version`` prints the installed package's version, the one pyproject.toml sets."""

from __future__ import annotations

import sys
from pathlib import Path

import pytest

import mrexplore
from mrexplore.cli import main

if sys.version_info >= (3, 11):
    import tomllib
else:  # pragma: no cover - CI runs 3.11
    import tomli as tomllib

ROOT = Path(__file__).resolve().parents[1]
VERSION = tomllib.loads((ROOT / "pyproject.toml").read_text())["project"]["version"]


def test_version_flag_prints_the_package_version(capsys: pytest.CaptureFixture[str]) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["--version"])
    assert exit_info.value.code == 0
    assert capsys.readouterr().out.strip() == f"mrexplore {VERSION}"


def test_module_version_matches_pyproject() -> None:
    assert mrexplore.__version__ == VERSION


def test_citation_and_changelog_name_the_version() -> None:
    assert f'version: "{VERSION}"' in (ROOT / "CITATION.cff").read_text()
    assert (ROOT / "LICENSE").read_text().lstrip().startswith("Apache License")
    changelog = (ROOT / "CHANGELOG.md").read_text()
    assert "## [Unreleased]" in changelog and f"## [{VERSION}]" in changelog
