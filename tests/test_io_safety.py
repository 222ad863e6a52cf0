"""The one helper every command writes through: refuse, then write atomically."""

from __future__ import annotations

from pathlib import Path

import pytest

from mrexplore.errors import OutputExistsError
from mrexplore.io_safety import atomic_path, check_out_dir, check_outputs, write_text


def test_interrupted_write_leaves_the_old_file_and_no_temporary(tmp_path: Path) -> None:
    target = tmp_path / "r.json"
    target.write_text("old")
    with pytest.raises(RuntimeError), atomic_path(target) as tmp:
        assert tmp.suffix == ".json" and tmp.parent == tmp_path
        tmp.write_text("half")
        raise RuntimeError("interrupted")
    assert target.read_text() == "old"
    assert [p.name for p in tmp_path.iterdir()] == ["r.json"]
    write_text(target, "new")
    assert target.read_text() == "new"


def test_check_outputs(tmp_path: Path) -> None:
    inp = tmp_path / "in.yaml"
    inp.write_text("x")
    with pytest.raises(OutputExistsError, match="input"):
        check_outputs([tmp_path / "sub" / ".." / "in.yaml"], inputs=[inp])
    with pytest.raises(OutputExistsError, match="already exists"):
        check_outputs([inp])
    check_outputs([inp], inputs=[inp], force=True)
    check_outputs([tmp_path / "new.yaml"], inputs=[inp])
    with pytest.raises(OutputExistsError, match="folder"):
        check_outputs([tmp_path], force=True)


def test_check_out_dir(tmp_path: Path) -> None:
    check_out_dir(tmp_path / "new")
    check_out_dir(tmp_path)  # empty
    (tmp_path / "f").write_text("x")
    with pytest.raises(OutputExistsError, match="not empty"):
        check_out_dir(tmp_path)
    check_out_dir(tmp_path, force=True)
    with pytest.raises(OutputExistsError, match="existing file"):
        check_out_dir(tmp_path / "f", force=True)
    with pytest.raises(OutputExistsError, match="input"):
        check_out_dir(tmp_path, force=True, protect=[tmp_path])
