"""``mrexplore merge a.yaml b.yaml -o out.yaml``: files in, files out, exit codes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrexplore.errors import MapFileError
from mrexplore.experiments.merge_files import main, merge_files
from mrexplore.world.map_io import read_map_yaml, write_map_yaml


@pytest.fixture()
def files(tmp_path: Path, office_pair) -> tuple[Path, Path, Path]:  # type: ignore[no-untyped-def]
    a, b, _ = office_pair
    pa = write_map_yaml(tmp_path / "a.yaml", a, 0.05, (-1.0, 2.0, 0.0))
    pb = write_map_yaml(tmp_path / "b.yaml", b, 0.05)
    pc = write_map_yaml(tmp_path / "c.yaml", b, 0.10)
    return pa, pb, pc


def test_merge_writes_map_and_figure(files, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    pa, pb, _ = files
    out = tmp_path / "out" / "merged.yaml"
    assert main([str(pa), str(pb), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "score" in text and "rotation" in text
    merged = read_map_yaml(out)
    a = read_map_yaml(pa)
    assert out.with_suffix(".png").exists()
    # a's cells keep their world coordinates: origin shifted by the canvas offset
    res = merge_files(pa, pb, tmp_path / "again.yaml")
    dc, dr = res.offset
    np.testing.assert_allclose(merged.origin_m[:2], (-1.0 - dc * 0.05, 2.0 - dr * 0.05))
    window = merged.grid[dr : dr + a.grid.shape[0], dc : dc + a.grid.shape[1]]
    known = a.grid != -1
    assert np.all(window[known] >= a.grid[known])


def test_refusal_exit_code_and_message(files, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    pa, pb, _ = files
    rc = main(
        [str(pa), str(pb), "-o", str(tmp_path / "m.yaml"), "--method", "orb", "--detector", "orb"]
    )
    out = capsys.readouterr().out
    assert rc in (0, 1)
    if rc == 1:
        assert "no reliable match found" in out and not (tmp_path / "m.yaml").exists()


@pytest.mark.parametrize(
    ("which", "extra"),
    [
        ("c", []),  # resolutions differ (0.05 vs 0.10)
        ("missing", []),  # no such file
        ("b", ["--method", "nope"]),  # unknown method
        ("b", ["--detector", "akaze"]),  # absent from this OpenCV
    ],
)
def test_bad_input_exit_code_2(files, tmp_path: Path, which: str, extra: list[str], capsys) -> None:  # type: ignore[no-untyped-def]
    pa, pb, pc = files
    other = {"b": pb, "c": pc, "missing": tmp_path / "none.yaml"}[which]
    assert main([str(pa), str(other), "-o", str(tmp_path / "m.yaml"), *extra]) == 2
    assert "error:" in capsys.readouterr().err


def test_different_resolutions_raise(files, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    pa, _, pc = files
    with pytest.raises(MapFileError, match="resolutions"):
        merge_files(pa, pc, tmp_path / "m.yaml")
