#!/usr/bin/env python
"""Draw a new user's first map with numpy, as a person would: the seed paper's scene.

Usage: ``python scripts/user_twin_rooms.py [--out DIR] [--force]``

A corridor along the bottom and two cell-for-cell identical rooms above it (6 x 4.5 m each,
the same table, cupboard, bench and door), two small things in the corridor, 0.05 m/cell,
written as a map_server YAML and PGM (``their.yaml``, ``their.pgm``) in ``--out`` (default
``docs/results/user_twin_rooms``). It is what issue 47's new user drew, rebuilt from its
description: the map on which two robots that each map one room agree perfectly under the
pose that lays one room on the other. ``scripts/reproduce_paper.sh`` measures merging on it
(``mrexplore task-time`` and ``mrexplore bench loop --worlds <their.yaml>``).
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

import cv2
import numpy as np
from numpy.typing import NDArray

ROOT = Path(__file__).resolve().parents[1]

RESOLUTION_M = 0.05
#: map_server's grey levels: occupied, free.
OCCUPIED, FREE = 0, 254
WALL_CELLS = 3

YAML = """image: their.pgm
resolution: 0.05
origin: [0.0, 0.0, 0.0]
negate: 0
occupied_thresh: 0.65
free_thresh: 0.196
mode: trinary
"""


def cells(m: float) -> int:
    """Metres to cells."""
    return round(m / RESOLUTION_M)


def draw() -> NDArray[np.uint8]:
    """The map as a map_server image (H, W) uint8: 0 occupied, 254 free."""
    g = np.full((cells(8.5), cells(16.5)), OCCUPIED, np.uint8)
    h, w = g.shape
    t = WALL_CELLS

    def block(r0: int, r1: int, c0: int, c1: int, value: int = OCCUPIED) -> None:
        g[r0:r1, c0:c1] = value

    corridor_top = h - t - cells(2.4)
    block(corridor_top, h - t, t, w - t, FREE)  # the corridor, 2.4 m wide
    room_w, room_h = cells(6.0), cells(4.5)
    room_top = corridor_top - t - room_h
    for left in (cells(1.0), cells(9.0)):  # the two rooms, identical cell for cell
        block(room_top, corridor_top - t, left, left + room_w, FREE)
        door = left + cells(1.0)
        block(corridor_top - t, corridor_top, door, door + cells(0.9), FREE)
        block(room_top + cells(1.5), room_top + cells(2.5), left + cells(2.5), left + cells(4.0))
        block(room_top, room_top + cells(0.6), left + cells(4.5), left + cells(5.8))
        block(room_top + cells(3.6), room_top + cells(4.0), left + cells(3.5), left + cells(5.5))
    # two small things in the corridor, one in front of each room, not at the same offsets
    block(h - t - cells(1.2), h - t - cells(0.8), cells(4.0), cells(4.4))
    block(h - t - cells(1.8), h - t - cells(1.3), cells(12.5), cells(13.0))
    return g


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--out", type=Path, default=ROOT / "docs" / "results" / "user_twin_rooms")
    ap.add_argument("--force", action="store_true", help="overwrite an existing map")
    args = ap.parse_args(argv)
    yaml_path, pgm_path = args.out / "their.yaml", args.out / "their.pgm"
    existing = [p for p in (yaml_path, pgm_path) if p.exists()]
    if existing and not args.force:
        print(f"error: {existing[0]} exists; give --force to overwrite it", file=sys.stderr)
        return 2
    args.out.mkdir(parents=True, exist_ok=True)
    if not cv2.imwrite(str(pgm_path), draw()):
        print(f"error: could not write {pgm_path}", file=sys.stderr)
        return 1
    yaml_path.write_text(YAML)
    print(f"wrote {yaml_path} and {pgm_path}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
