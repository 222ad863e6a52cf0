"""Hand-made maps for the merge tests (small, so the whole folder runs in seconds)."""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path
from typing import Any

import numpy as np
import pytest

from mrexplore.grid import FREE, OCCUPIED, UNKNOWN, invert_transform
from mrexplore.merge.common import translation
from mrexplore.studies.merge_cases import rotate_map

# The real TurtleBot3 office map (ROBOTIS, Apache-2.0) ships in envs/ as tb3_office.
ENVS = Path(__file__).resolve().parents[2] / "envs"


def two_rooms() -> np.ndarray:
    """A fully known 120 x 260 floor: two identical rooms side by side (their walls at columns 0,
    130 and 259, a door between them, the same furniture in each), so a crop of one room fits
    the other 130 cells along."""
    a = np.zeros((120, 260), np.int8)
    a[0, :] = a[-1, :] = a[:, 0] = a[:, -1] = a[:, 130] = OCCUPIED
    a[50:70, 130] = FREE  # the door
    for c0 in (0, 130):
        a[30:40, c0 + 30 : c0 + 70] = OCCUPIED
        a[80:100, c0 + 90 : c0 + 95] = OCCUPIED
    return a


def look_alike_canvases() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Robot 0's canvas holds both rooms of :func:`two_rooms`, robot 1's only the left one:
    ``(canvas_0, canvas_1, T_01)``, ``T_01`` the true transform (robot 1's cells -> robot 0's).
    Alone, the maps cannot tell the left room from the right one."""
    a = two_rooms()
    canvas_0 = np.full((200, 400), UNKNOWN, dtype=np.int8)
    canvas_0[40:160, 60:320] = a
    canvas_1 = np.full((200, 200), UNKNOWN, dtype=np.int8)
    canvas_1[30:150, 20:151] = a[:, :131]
    T_01 = np.array([[1.0, 0.0, 40.0], [0.0, 1.0, 10.0], [0.0, 0.0, 1.0]])
    return canvas_0, canvas_1, T_01


def twin_world() -> tuple[np.ndarray, list[tuple[int, int, int, int]]]:
    """A fully known 110 x 190 floor: a corridor along the bottom with asymmetric clutter, and
    above it two cell-for-cell identical rooms (same size, door, furniture) plus a different
    room between them. Returns (map, twin boxes (r0, r1, c0, c1) including their walls)."""
    m = np.full((110, 190), FREE, dtype=np.int8)
    m[0:2, :] = OCCUPIED
    m[-2:, :] = OCCUPIED
    m[:, 0:2] = OCCUPIED
    m[:, -2:] = OCCUPIED
    m[40:42, :] = OCCUPIED  # wall between corridor (rows 2-39) and rooms (rows 42-107)
    # corridor clutter, deliberately not symmetric
    m[10:16, 30:33] = OCCUPIED
    m[22:26, 95:110] = OCCUPIED
    m[8:30, 160:163] = OCCUPIED
    m[30:33, 60:66] = OCCUPIED
    boxes = [(40, 110, 10, 60), (40, 110, 120, 170)]
    for r0, r1, c0, c1 in boxes:
        m[r0:r1, c0 : c0 + 2] = OCCUPIED
        m[r0:r1, c1 - 2 : c1] = OCCUPIED
        m[40:42, c0 + 10 : c0 + 22] = FREE  # door
        m[70:80, c0 + 12 : c0 + 20] = OCCUPIED  # a table
        m[95:99, c0 + 30 : c0 + 46] = OCCUPIED  # a shelf
        m[55:58, c0 + 35 : c0 + 38] = OCCUPIED  # a bin
    # the middle room is different
    m[60:64, 80:100] = OCCUPIED
    m[85:107, 105:108] = OCCUPIED
    return m, boxes


@pytest.fixture(scope="session")
def twins() -> tuple[np.ndarray, list[tuple[int, int, int, int]]]:
    return twin_world()


def _cut(
    m: np.ndarray, r0: int, r1: int, c0: int, c1: int, keep: np.ndarray | None = None
) -> np.ndarray:
    """Crop ``m[r0:r1, c0:c1]``; cells outside ``keep`` (same crop, bool) become unknown."""
    out = m[r0:r1, c0:c1].copy()
    if keep is not None:
        out[~keep] = UNKNOWN
    return out


@pytest.fixture(scope="session")
def cut() -> Callable[..., np.ndarray]:
    """The crop helper as a fixture (test folders are not packages)."""
    return _cut


@pytest.fixture(scope="session")
def office_pair() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Two overlapping crops of the real TurtleBot3 office map, b rotated by 37 degrees.

    Returns (a, b, T_ab truth)."""
    from mrexplore.world.map_io import read_map_yaml

    full = read_map_yaml(ENVS / "tb3_office.yaml").grid
    ra, ca, rb, cb = 60, 150, 110, 210
    a = full[ra : ra + 190, ca : ca + 190].copy()
    mb = full[rb : rb + 190, cb : cb + 160]
    b, T_rot = rotate_map(mb, np.radians(37.0))
    T_ab = translation(cb - ca, rb - ra) @ invert_transform(T_rot)
    return a, b, T_ab


def merge_with(a: np.ndarray, b: np.ndarray, **kw: Any) -> Any:
    """:func:`~mrexplore.merge.merge_maps` with the semantic merger's rule constants given by
    their former option names (``object_hull_free=0``) set for this call only: a test of that
    rule, on or off. The other keywords are options, as ``merge_maps`` takes them."""
    from mrexplore.merge import merge_maps, semantic

    with pytest.MonkeyPatch.context() as mp:
        for name in [k for k in kw if k in semantic.DEMOTED_OPTIONS]:
            mp.setattr(semantic, semantic.DEMOTED_OPTIONS[name], kw.pop(name))
        return merge_maps(a, b, **kw)
