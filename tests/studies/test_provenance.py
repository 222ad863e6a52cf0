"""The source digest: the same for the same files, another for a changed file of any tree."""

from __future__ import annotations

from pathlib import Path

import pytest

from mrexplore.studies import provenance


def test_the_digest_follows_every_file_of_every_tree(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    trees = {label: tmp_path / label for label in ("code", "envs", "maps")}
    for label, root in trees.items():
        root.mkdir()
        (root / ("a.py" if label == "code" else "a.pgm")).write_text(label)
    monkeypatch.setattr(provenance, "_inputs", lambda: list(trees.items()))

    def digest() -> str:
        provenance.source_digest.cache_clear()
        return provenance.source_digest()

    first = digest()
    assert digest() == first
    (trees["maps"] / "a.pgm").write_text("one pixel changed")
    changed = digest()
    assert changed != first
    (trees["code"] / "notes.txt").write_text("not code")  # only .py files count in the code tree
    assert digest() == changed
    (trees["envs"] / "new.yaml").write_text("a new world")
    assert digest() != changed
    provenance.source_digest.cache_clear()
