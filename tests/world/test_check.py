"""``mrexplore world check``: tiny hand-made maps, one problem each, and the task-time warning."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

from mrexplore.cli import main
from mrexplore.errors import ConfigError, MapFileNotFoundError
from mrexplore.experiments.task_time import _warn_map
from mrexplore.grid import OCCUPIED
from mrexplore.world import write_map_yaml
from mrexplore.world.check import check_map, warn_map


def _room(rows: int = 40, cols: int = 60) -> np.ndarray:
    """A walled empty room (int8, free inside, 1-cell walls)."""
    grid = np.zeros((rows, cols), np.int8)
    grid[[0, -1], :] = OCCUPIED
    grid[:, [0, -1]] = OCCUPIED
    return grid


def _write(tmp_path: Path, grid: np.ndarray, resolution_m: float = 0.05) -> Path:
    return write_map_yaml(tmp_path / "m.yaml", grid, resolution_m=resolution_m)


def test_a_walled_room_is_usable(tmp_path: Path) -> None:
    found = check_map(_write(tmp_path, _room()))
    assert found.ok, found.problems
    assert found.shape == (40, 60)
    assert found.has_walls and found.parts == []
    # 38 x 58 free cells of 0.05 m; all reachable by a 0.15 m robot in an empty room
    assert found.free_m2 == pytest.approx(38 * 58 * 0.0025)
    assert found.reachable_m2 == pytest.approx(found.free_m2)
    assert (found.radius_m, found.max_range_m) == (0.15, 4.0)  # the env's defaults
    assert "60 x 40 cells, 3 x 2 m at 0.05 m/cell" in found.report()


def test_no_walls_is_a_problem(tmp_path: Path) -> None:
    found = check_map(_write(tmp_path, np.zeros((40, 60), np.int8)))
    assert not found.has_walls
    assert [p for p in found.problems if p.startswith("no walls")]


def test_two_disconnected_parts(tmp_path: Path) -> None:
    grid = _room(40, 81)
    grid[:, 40] = OCCUPIED  # a wall with no door: two rooms of 38 x 39 cells
    found = check_map(_write(tmp_path, grid))
    assert len(found.parts) == 1
    assert found.parts[0] == pytest.approx(38 * 39 * 0.0025)
    assert found.reachable_m2 == pytest.approx(38 * 39 * 0.0025)
    assert [p for p in found.problems if "never reach" in p]


def test_a_small_unreached_speck_is_a_note(tmp_path: Path) -> None:
    grid = _room(40, 60)
    grid[5:8, 40:43] = OCCUPIED
    grid[6, 41] = 0  # one free cell inside a block: out of reach, too small to matter
    found = check_map(_write(tmp_path, grid))
    assert found.ok, found.problems
    assert found.parts == [pytest.approx(0.0025)]
    assert [n for n in found.notes if "never reach" in n]


def test_half_a_metre_per_cell_is_too_coarse(tmp_path: Path) -> None:
    found = check_map(_write(tmp_path, _room(), resolution_m=0.5))
    text = " ".join(found.problems)
    assert "too coarse for the robot" in text  # 0.6 cells across a 0.3 m robot
    assert "too coarse for the lidar" in text  # 4 m = 8 cells
    assert check_map(found.path, radius_m=1.0, max_range_m=10.0).ok


def test_cli_exit_codes(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    good = _write(tmp_path, _room())
    assert main(["world", "check", str(good)]) == 0
    assert "usable" in capsys.readouterr().out
    coarse = write_map_yaml(tmp_path / "coarse.yaml", _room(), resolution_m=0.5)
    assert main(["world", "check", str(coarse)]) == 1
    out = capsys.readouterr().out
    assert "problem: too coarse for the lidar" in out and "not usable: 2 problem(s)" in out
    assert main(["world", "check", str(tmp_path / "missing.yaml")]) == 2
    assert "map YAML not found" in capsys.readouterr().err
    assert main(["world", "check", "--radius-m", "0", str(good)]) == 2


def test_bad_inputs(tmp_path: Path) -> None:
    with pytest.raises(MapFileNotFoundError):
        check_map(tmp_path / "missing.yaml")
    with pytest.raises(ConfigError, match="max_range_m"):
        check_map(_write(tmp_path, _room()), max_range_m=-1.0)


def test_task_time_prints_the_same_lines(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    coarse = _write(tmp_path, _room(), resolution_m=0.5)
    _warn_map(str(coarse), {})
    out = capsys.readouterr().out.splitlines()
    assert out == [f"task-time: {coarse}: {line}" for line in warn_map(coarse)]
    assert out and all("problem: too coarse" in line for line in out)
    _warn_map("symmetric_office", {})  # a shipped name: nothing printed
    assert capsys.readouterr().out == ""
