"""Floor-plan primitives for the world families: rows of rooms around a free hall, rotated.

A *row* is a strip of rooms side by side in the canonical orientation of
:mod:`mrexplore.world.generators` (doors in the bottom wall, the wall at the lowest rows),
built once as a bool array and pasted next to a free rectangle (a *hall*: a corridor is a
narrow hall) after rotating it with :func:`numpy.rot90` by ``k`` quarter turns, so that its
door wall faces the hall. Rotating a row rotates every room in it the same way: a room
template stamped in rows on different sides of a hall appears turned by 90, 180 or 270 degrees,
cell for cell.

Quarter turns ``k`` and the side of the hall a row stands on (row 0 is the lowest y)::

    k = 0  north of the hall (door wall at the row's lowest rows)
    k = 1  east  (door wall at its lowest columns)
    k = 2  south (door wall at its highest rows)
    k = 3  west  (door wall at its highest columns)

Pasting ANDs the row into the floor (``floor &= row``): a paste only frees cells, never walls
off a corridor; neighbouring rows meet on wall cells only. Boxes are ``(col, row, w, h)`` in
cells, walls included, as in ``World.meta``.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

__all__ = [
    "SIDE_TURNS",
    "Box",
    "Hall",
    "Placed",
    "Slot",
    "build_row",
    "hall_floor",
    "paste",
    "rotate_box",
]

Box = tuple[int, int, int, int]  # (col, row, w, h) in cells, walls included

#: Quarter turns (np.rot90's k) of a row standing on each side of a hall, doors facing it.
SIDE_TURNS: dict[str, int] = {"n": 0, "e": 1, "s": 2, "w": 3}


@dataclass(frozen=True)
class Slot:
    """One place in a row: a room template (canonical orientation), or solid wall.

    ``width`` and ``depth`` are the interior cells along and across the row; ``tpl`` is bool
    ``(depth + 2t, width + 2t)`` (None: solid); ``copy`` the index of the repeated room it is
    a copy of (None: a room drawn on its own, or solid).
    """

    width: int
    depth: int
    tpl: NDArray[np.bool_] | None
    copy: int | None = None


@dataclass(frozen=True)
class Placed:
    """A room as it ended up on the floor: its box, its turn against the template, its copy."""

    box: Box
    turns: int  # quarter turns (np.rot90's k) of the template
    copy: int | None


@dataclass(frozen=True)
class Hall:
    """A free rectangle (col, row, w, h) in cells, interior only, and the rows along its sides:
    side (``"n"``, ``"e"``, ``"s"``, ``"w"``) -> (slots, offset along the side in cells)."""

    w: int
    h: int
    rows: dict[str, tuple[list[Slot], int]]


def rotate_box(box: Box, shape: tuple[int, int], k: int) -> Box:
    """Where ``box`` (col, row, w, h) of an array of ``shape`` (H, W) lands in ``np.rot90(a, k)``.

    One quarter turn sends cell (row r, col c) to (row W - 1 - c, col r).
    """
    c, r, w, h = box
    H, W = shape
    for _ in range(k % 4):
        c, r, w, h = r, W - c - w, h, w
        H, W = W, H
    return (c, r, w, h)


def build_row(slots: list[Slot], t: int) -> tuple[NDArray[np.bool_], list[Box]]:
    """The row of ``slots`` side by side (neighbours share a wall ``t`` thick), bool
    ``(max depth + 2t, sum of widths + (n - 1) t + 2t)``; rooms shallower than the deepest
    leave solid wall behind them. Returns the array and each slot's box in it."""
    length = sum(s.width for s in slots) + (len(slots) - 1) * t
    depth = max(s.depth for s in slots)
    sub = np.ones((depth + 2 * t, length + 2 * t), dtype=np.bool_)
    boxes: list[Box] = []
    col = 0
    for s in slots:
        box: Box = (col, 0, s.width + 2 * t, s.depth + 2 * t)
        if s.tpl is not None:
            if s.tpl.shape != (box[3], box[2]):
                raise ValueError(f"template shape {s.tpl.shape} does not fit slot {box}")
            sub[: box[3], col : col + box[2]] = s.tpl
        boxes.append(box)
        col += s.width + t
    return sub, boxes


def paste(
    floor: NDArray[np.bool_], sub: NDArray[np.bool_], k: int, col: int, row: int
) -> NDArray[np.bool_]:
    """AND ``np.rot90(sub, k)`` into ``floor`` with its lower-left cell at (col, row); returns the
    rotated array. Raises ValueError when it does not fit."""
    rot = np.rot90(sub, k)
    h, w = rot.shape
    if col < 0 or row < 0 or row + h > floor.shape[0] or col + w > floor.shape[1]:
        raise ValueError(f"a {w} x {h} row does not fit at ({col}, {row}) in {floor.shape}")
    floor[row : row + h, col : col + w] &= rot
    return rot


def hall_floor(hall: Hall, t: int) -> tuple[NDArray[np.bool_], Box, list[Placed]]:
    """A floor: the hall (free), rows of rooms on some of its sides, an outer wall ``t`` thick.

    Each side's row (slots and offset along the side) must fit the side's length (the hall's
    ``w`` for ``n`` / ``s``, ``h`` for ``e`` / ``w``). Returns the floor, bool (H, W) with
    ``True`` = wall; the hall's interior box; every room slot (not solid ones) as placed.
    """
    built = {side: build_row(slots, t) for side, (slots, _) in hall.rows.items()}
    ext = {s: (built[s][0].shape[0] if s in built else t) for s in SIDE_TURNS}
    W = ext["w"] + hall.w + ext["e"]
    H = ext["s"] + hall.h + ext["n"]
    floor = np.ones((H, W), dtype=np.bool_)
    hc, hr = ext["w"], ext["s"]
    floor[hr : hr + hall.h, hc : hc + hall.w] = False
    placed: list[Placed] = []
    for side, (sub, boxes) in built.items():
        slots, off = hall.rows[side]
        k = SIDE_TURNS[side]
        d, length = sub.shape  # depth across the side, length along it (walls included)
        edge = hall.w if side in "ns" else hall.h
        if off < 0 or off + length - 2 * t > edge:
            raise ValueError(f"row on side {side!r} ({length - 2 * t} cells) overruns the hall")
        at = {
            "n": (hc - t + off, hr + hall.h),
            "s": (hc - t + off, hr - d),
            "e": (hc + hall.w, hr - t + off),
            "w": (hc - d, hr - t + off),
        }[side]
        paste(floor, sub, k, *at)
        for s, b in zip(slots, boxes, strict=True):
            if s.tpl is None:
                continue
            c, r, w, h = rotate_box(b, sub.shape, k)
            placed.append(Placed((c + at[0], r + at[1], w, h), k, s.copy))
    return floor, (hc, hr, hall.w, hall.h), placed
