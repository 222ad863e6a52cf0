"""``scripts/user_twin_rooms.py``: a new user's first map, the committed copy, and no overwrite."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from mrexplore.world import load_world
from tests.helpers import load_script

COMMITTED = Path(__file__).resolve().parents[1] / "docs" / "results" / "user_twin_rooms"


def test_the_two_rooms_are_the_same_cell_for_cell() -> None:
    script = load_script("user_twin_rooms")
    g = script.draw()
    free = g == script.FREE
    a, b = script.cells(1.0), script.cells(9.0)
    rows = slice(0, g.shape[0] - script.cells(2.4) - 2 * script.WALL_CELLS)  # above the corridor
    width = script.cells(6.0)
    room_a, room_b = free[rows, a : a + width], free[rows, b : b + width]
    assert room_a.any() and np.array_equal(room_a, room_b)


def test_the_committed_map_is_what_the_script_draws(tmp_path: Path) -> None:
    script = load_script("user_twin_rooms")
    assert script.main(["--out", str(tmp_path)]) == 0
    assert (tmp_path / "their.yaml").read_text() == (COMMITTED / "their.yaml").read_text()
    assert (tmp_path / "their.pgm").read_bytes() == (COMMITTED / "their.pgm").read_bytes()
    world = load_world(str(tmp_path / "their.yaml"))
    assert world.resolution_m == 0.05


def test_an_existing_map_is_not_overwritten_without_force(tmp_path: Path) -> None:
    script = load_script("user_twin_rooms")
    (tmp_path / "their.yaml").write_text("mine")
    assert script.main(["--out", str(tmp_path)]) == 2
    assert (tmp_path / "their.yaml").read_text() == "mine"
    assert script.main(["--out", str(tmp_path), "--force"]) == 0
    assert (tmp_path / "their.yaml").read_text() != "mine"
