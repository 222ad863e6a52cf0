"""Seeded generators of office floors with two identical rooms ("symmetric worlds").

Why: the seed paper's test world (its Figure 1a, section 3.1) is an office floor whose room-1 and
room-2 look exactly alike, so a map merger matching local features can fuse two partial maps at
the wrong room. These generators build such floors at random, while keeping the floor as a whole
unambiguous (the other rooms differ in size and furniture), so a *correct* merge always exists.

Two layouts:

* :func:`symmetric_office`: one main corridor (2.5-3.0 m) across the floor, rooms on both sides;
  two rooms on the same side are cell-for-cell identical (same size, door, furniture, orientation).
* :func:`twin_wings`: two parallel corridors (north and south wing) joined by a vertical
  connector corridor, with a band of rooms between them; one twin room opens onto the north
  corridor, the other is its 180-degree rotated copy opening onto the south corridor.

Construction (both): a floor is a stack of horizontal bands (room rows and corridors). Each room is
a small bool *template* (walls included) built once, in the canonical orientation (door in the
bottom wall, i.e. the wall at the lowest rows), then stamped with numpy slicing, rotated by 180
degrees for rooms whose door faces up. Furniture are rectangles either flush with a wall or at
least ``clearance`` away from walls and from each other, and never in front of a door, so no
piece of furniture can cut a room in two or leave a pocket a robot cannot enter. Every generated
floor is then checked (:func:`unreachable_free_cells`); a failed floor is redrawn from the same
``rng`` (deterministic). Generation takes a few milliseconds.

All sizes are metres; grids are ``walls[row, col]`` with row 0 the lowest y. Room boxes in
``World.meta`` are ``(col, row, w, h)`` in cells *including* the room's walls.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, ClassVar

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import WorldError
from mrexplore.options import Options, boolean, integer, number, option, optional, positive
from mrexplore.world.world import World

__all__ = [
    "GENERATORS",
    "symmetric_office",
    "twin_wings",
    "unreachable_free_cells",
]

Footprint = tuple[int, int, int, int]  # (col, row, w, h) in cells: where a room was stamped
Rect = tuple[
    int, int, int, int
]  # (row0, col0, h, w) in a room's interior cells, row 0 at the door wall

#: Corridor width range of the paper's world (Eq. 5 uses the most common corridor width, ~3 m).
CORRIDOR_MIN_M = 2.5
CORRIDOR_MAX_M = 3.0
#: Doors at least this wide: a 0.15 m-radius robot passes with room to spare.
DOOR_MIN_M = 0.9
DOOR_MAX_M = 1.2
#: Smallest room interior (either side), metres.
ROOM_MIN_M = 1.8
#: Rooms other than the twins differ in width from the twins by at least this much, metres.
TWIN_WIDTH_GAP_M = 0.4
_MAX_ATTEMPTS = 30


@dataclass(frozen=True)
class GeneratorOptions(Options):
    """The options both generators take (``**options`` of :func:`symmetric_office` and
    :func:`twin_wings`): one default and one range each. None: drawn (widths) or derived from
    the resolution and the robot (walls, clearance, rooms per side)."""

    kind: ClassVar[str] = "generator option"
    error: ClassVar[type[Exception]] = WorldError
    corridor_width_m: float | None = option(
        None, optional(number(CORRIDOR_MIN_M, CORRIDOR_MAX_M, hint=" m"))
    )
    door_width_m: float | None = option(None, optional(number(DOOR_MIN_M, DOOR_MAX_M, hint=" m")))
    wall_cells: int | None = option(None, optional(integer(1)))
    robot_radius_m: float = option(0.15, positive)
    clearance_m: float | None = option(None, optional(positive))
    furniture: bool = option(True, boolean)
    rooms_per_side: int | None = option(None, optional(integer(3)))

    def check_together(self) -> None:
        if 2.0 * self.robot_radius_m + 0.1 > DOOR_MIN_M:
            raise WorldError(
                f"generator option robot_radius_m = {self.robot_radius_m} is too large for "
                f"{DOOR_MIN_M} m doors"
            )
        if self.clearance_m is not None and self.clearance_m < 2.0 * self.robot_radius_m:
            raise WorldError(
                f"generator option clearance_m = {self.clearance_m} is below the robot "
                f"diameter {2 * self.robot_radius_m}"
            )


@dataclass(frozen=True)
class TwinWingsOptions(GeneratorOptions):
    """:func:`twin_wings`' options: as :class:`GeneratorOptions`, with ``rooms_per_side``
    counting the north row, which needs 2 rooms (the connector takes a middle slot)."""

    rooms_per_side: int | None = option(None, optional(integer(2)))


@dataclass(frozen=True)
class _Params:
    """Validated generator settings, in cells where the grid needs cells."""

    res: float  # metres per cell
    t: int  # wall thickness, cells
    robot_r_m: float
    clear: int  # minimum free gap between furniture and anything else (unless flush), cells
    corridor: tuple[int, int]  # inclusive range of corridor widths, cells
    door: tuple[int, int]  # inclusive range of door widths, cells
    furniture: bool

    def cells(self, metres: float) -> int:
        """Metres -> nearest whole number of cells."""
        return round(metres / self.res)


@dataclass(frozen=True)
class _RoomPlan:
    """One room in canonical orientation: interior ``h x w`` cells, door in the bottom wall."""

    h: int
    w: int
    door_c0: int  # first door column, interior coordinates
    door_w: int
    items: tuple[Rect, ...]


# --------------------------------------------------------------------------------------------
# options


def _positive(name: str, value: Any) -> float:
    if isinstance(value, bool) or not isinstance(value, (int, float)):
        raise WorldError(f"option '{name}' must be a number, got {value!r}")
    out = float(value)
    if not math.isfinite(out) or out <= 0.0:
        raise WorldError(f"option '{name}' must be a positive number, got {value!r}")
    return out


def _params(resolution_m: float, o: GeneratorOptions) -> _Params:
    """The options in cells, for a grid of ``resolution_m`` metres per cell."""
    res = _positive("resolution_m", resolution_m)
    if res > 0.25:
        raise WorldError(f"option 'resolution_m' must be at most 0.25 m/cell, got {res}")
    # walls of 2-3 cells, about 0.15 m: thick enough that a ray never slips through diagonally
    t = int(min(3, max(2, round(0.15 / res)))) if o.wall_cells is None else o.wall_cells
    clearance_m = max(0.5, 2.0 * o.robot_radius_m + 0.2) if o.clearance_m is None else o.clearance_m
    clear = math.ceil(clearance_m / res - 1e-9)

    def _range(name: str, value: float | None, lo_m: float, hi_m: float) -> tuple[int, int]:
        if value is None:
            lo, hi = math.ceil(lo_m / res - 1e-9), math.floor(hi_m / res + 1e-9)
        else:
            lo = hi = max(math.ceil(lo_m / res - 1e-9), round(value / res))
        if hi < lo:
            raise WorldError(
                f"resolution {res} m/cell is too coarse for '{name}' in [{lo_m}, {hi_m}] m"
            )
        return lo, hi

    return _Params(
        res=res,
        t=t,
        robot_r_m=o.robot_radius_m,
        clear=clear,
        corridor=_range("corridor_width_m", o.corridor_width_m, CORRIDOR_MIN_M, CORRIDOR_MAX_M),
        door=_range("door_width_m", o.door_width_m, DOOR_MIN_M, DOOR_MAX_M),
        furniture=o.furniture,
    )


def _size_cells(name: str, value_m: float, p: _Params, min_m: float) -> int:
    v = _positive(name, value_m)
    if v < min_m - 1e-9:
        raise WorldError(
            f"option '{name}' = {v} m is too small for this layout; minimum {min_m:.2f} m"
        )
    return round(v / p.res)


# --------------------------------------------------------------------------------------------
# rooms


def _overlap(a: Rect, b: Rect) -> bool:
    return a[0] < b[0] + b[2] and b[0] < a[0] + a[2] and a[1] < b[1] + b[3] and b[1] < a[1] + a[3]


def _grow(r: Rect, m: int) -> Rect:
    return (r[0] - m, r[1] - m, r[2] + 2 * m, r[3] + 2 * m)


def _snap(start: int, length: int, extent: int, clear: int) -> tuple[int, int]:
    """Along one axis: close a gap to a wall below ``clear`` (flush): no narrow pocket remains."""
    if start < clear:
        length += start
        start = 0
    gap = extent - (start + length)
    if 0 < gap < clear:
        length += gap
    return start, length


def _sample_items(
    rng: np.random.Generator,
    h: int,
    w: int,
    door_c0: int,
    door_w: int,
    p: _Params,
    min_items: int = 1,
) -> tuple[Rect, ...]:
    """Furniture rectangles for a room interior of ``h x w`` cells (door in the bottom wall).

    Desks and shelves stand flush against a wall; tables stand free with ``clear`` all round.
    Any two pieces are at least ``clear`` apart, and none enters the zone in front of the door.
    """
    if not p.furniture:
        return ()
    c = p.clear
    # In front of the door: the door's width plus a clearance each side, one metre deep.
    door_zone: Rect = (0, door_c0 - c, max(c, p.cells(1.0)), door_w + 2 * c)
    area_m2 = h * w * p.res * p.res
    # About one piece per 4 m^2 (an office is furnished), at least one, at most eight.
    most = int(np.clip(area_m2 // 4, 1, 8))
    n_target = max(min_items, int(rng.integers(max(1, most // 2), most + 1)))
    items: list[Rect] = []
    for _ in range(12 * n_target):
        if len(items) >= n_target:
            break
        kind = rng.choice(3, p=[0.45, 0.3, 0.25])  # desk, shelf, table
        if kind == 2:  # table, free standing
            th = p.cells(rng.uniform(0.7, 1.2))
            tw = p.cells(rng.uniform(0.8, 2.0))
            if h - 2 * c - th < 0 or w - 2 * c - tw < 0:
                continue
            rect: Rect = (
                int(rng.integers(c, h - c - th + 1)),
                int(rng.integers(c, w - c - tw + 1)),
                th,
                tw,
            )
        else:
            depth_m = rng.uniform(0.6, 0.8) if kind == 0 else rng.uniform(0.3, 0.45)
            length_m = rng.uniform(1.0, 1.8) if kind == 0 else rng.uniform(0.8, 2.4)
            wall = int(rng.integers(4))  # 0 bottom (door wall), 1 top, 2 left, 3 right
            along, across = (w, h) if wall < 2 else (h, w)
            depth = min(p.cells(depth_m), int(0.3 * across))
            length = min(p.cells(length_m), along)
            if depth < 1 or length < 1:
                continue
            start, length = _snap(int(rng.integers(0, along - length + 1)), length, along, c)
            off = 0 if wall in (0, 2) else across - depth
            rect = (off, start, depth, length) if wall < 2 else (start, off, length, depth)
        if _overlap(rect, door_zone) or any(_overlap(_grow(o, c), rect) for o in items):
            continue
        items.append(rect)
    return tuple(items)


def _room_plan(
    rng: np.random.Generator, h: int, w: int, p: _Params, min_items: int = 1
) -> _RoomPlan:
    """A random room: door width and position, then furniture (at least ``min_items`` tried)."""
    door_w = min(int(rng.integers(p.door[0], p.door[1] + 1)), w)
    door_c0 = int(rng.integers(0, w - door_w + 1))
    items = _sample_items(rng, h, w, door_c0, door_w, p, min_items)
    return _RoomPlan(h, w, door_c0, door_w, items)


def _room_template(plan: _RoomPlan, t: int) -> NDArray[np.bool_]:
    """bool (h + 2t, w + 2t): the room with its walls, canonical orientation (door in rows < t)."""
    tpl = np.ones((plan.h + 2 * t, plan.w + 2 * t), dtype=np.bool_)
    tpl[t : t + plan.h, t : t + plan.w] = False
    for r0, c0, rh, rw in plan.items:
        tpl[t + r0 : t + r0 + rh, t + c0 : t + c0 + rw] = True
    tpl[:t, t + plan.door_c0 : t + plan.door_c0 + plan.door_w] = False
    return tpl


def _stamp(
    walls: NDArray[np.bool_], tpl: NDArray[np.bool_], col: int, row: int, flip: bool
) -> Footprint:
    """Write a room template at (col, row); ``flip`` rotates it by 180 degrees (door facing up)."""
    img = np.rot90(tpl, 2) if flip else tpl
    h, w = img.shape
    walls[row : row + h, col : col + w] = img
    return (col, row, w, h)


def _split(
    rng: np.random.Generator,
    interior: int,
    n: int,
    t: int,
    fixed: dict[int, int],
    min_w: int,
    avoid: int | None,
    gap: int,
) -> list[int]:
    """Interior widths of ``n`` rooms side by side filling ``interior`` cells (walls ``t`` between).

    ``fixed`` pins some slots' widths (the twins); the others are random, at least ``min_w``, and
    differ from ``avoid`` by at least ``gap`` cells so that no other room looks like a twin.
    """
    free_slots = [i for i in range(n) if i not in fixed]
    rest = interior - (n - 1) * t - sum(fixed.values())
    for _ in range(200):
        weights = rng.uniform(0.6, 1.4, size=len(free_slots))
        widths = np.floor(weights / weights.sum() * rest).astype(int)
        widths[-1] += rest - int(widths.sum())
        if widths.min() < min_w:
            continue
        if avoid is not None and np.any(np.abs(widths - avoid) < gap):
            continue
        out = [0] * n
        for i, w in fixed.items():
            out[i] = w
        for i, w in zip(free_slots, widths.tolist(), strict=True):
            out[i] = int(w)
        return out
    raise WorldError(f"cannot split {interior * 1.0} cells into {n} distinct rooms")


def _band(
    walls: NDArray[np.bool_],
    rng: np.random.Generator,
    widths: list[int],
    row: int,
    depth: int,
    doors_up: list[bool],
    p: _Params,
    plans: dict[int, _RoomPlan],
    skip: set[int] | None = None,
) -> list[Footprint]:
    """Stamp a row of rooms (interiors ``widths``, ``depth`` rows) whose boxes start at ``row``.

    ``plans`` gives ready plans for some slots (the twins); ``skip`` leaves slots for corridors.
    Returns the boxes (walls included) in slot order; skipped slots get their box too.
    """
    boxes: list[Footprint] = []
    col = 0
    for i, w in enumerate(widths):
        box: Footprint = (col, row, w + 2 * p.t, depth + 2 * p.t)
        if not (skip and i in skip):
            plan = plans.get(i) or _room_plan(rng, depth, w, p)
            box = _stamp(walls, _room_template(plan, p.t), col, row, doors_up[i])
        boxes.append(box)
        col += w + p.t
    return boxes


# --------------------------------------------------------------------------------------------
# checks


def unreachable_free_cells(
    walls: NDArray[np.bool_],
    resolution_m: float,
    start_cell: tuple[int, int],
    robot_radius_m: float = 0.15,
) -> NDArray[np.bool_]:
    """Free cells a disc robot starting at ``start_cell`` = (col, row) can never reach, bool (H, W).

    The robot's centre may stand on cells whose centre is at least ``radius + half a cell`` from
    every wall cell centre (so the disc does not overlap a wall square); those cells connected to
    the start (8-connectivity) are its reachable centres. A free cell counts as reached when it
    lies within ``sqrt(2) * radius + 1 cell`` of a reachable centre: the disc pressed into a
    right-angled corner leaves the corner cell at ``sqrt(2) * radius``, and nothing more than
    corners should be left out. Empty result = every room, gap and corner is accessible.
    """
    free = (~walls).astype(np.uint8)
    r = robot_radius_m / resolution_m
    dist = cv2.distanceTransform(free, cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    centres = (dist >= r + 0.5).astype(np.uint8)
    col, row = start_cell
    if not centres[row, col]:
        return walls == np.False_  # the start itself is blocked: nothing is reachable
    _, labels = cv2.connectedComponents(centres, connectivity=8)
    comp = labels == labels[row, col]
    d2 = cv2.distanceTransform((~comp).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    return np.asarray((free > 0) & (d2 > math.sqrt(2.0) * r + 1.0), dtype=np.bool_)


def _accept(walls: NDArray[np.bool_], p: _Params, start: tuple[int, int]) -> bool:
    return not unreachable_free_cells(walls, p.res, start, p.robot_r_m).any()


# --------------------------------------------------------------------------------------------
# generators


def symmetric_office(
    rng: np.random.Generator,
    width_m: float = 20.0,
    height_m: float = 16.0,
    resolution_m: float = 0.05,
    **options: Any,
) -> World:
    """An office floor like the seed paper's Figure 1a: one corridor, rooms both sides, two twins.

    Layout (row 0 at the bottom): outer wall, a row of rooms with doors facing up, the main
    corridor (2.5-3.0 m wide, across the whole floor), a row of rooms with doors facing down,
    outer wall. Two rooms of the top row, with at least one other room between them, are
    cell-for-cell identical (size, door, furniture, orientation); every other room's width
    differs from theirs by at least 0.4 m and its furniture is drawn independently, so the floor
    as a whole has one correct alignment.

    Args:
        rng: the only source of randomness.
        width_m, height_m: floor size in metres (about 8 m and up; 15-25 m is typical).
        resolution_m: metres per cell.
        **options: ``corridor_width_m`` (fixed width in [2.5, 3.0], default random),
            ``door_width_m`` (in [0.9, 1.2], default random per room), ``wall_cells`` (default 2-3
            cells, ~0.15 m), ``robot_radius_m`` (0.15, for the reachability check),
            ``clearance_m`` (min gap around furniture, default 0.5), ``furniture`` (True),
            ``rooms_per_side`` (rooms in the twins' row, >= 3; default from the width).

    Returns:
        A :class:`World` with ``meta``: ``generator``, ``twin_rooms`` (two boxes (col, row, w, h)
        including walls), ``twin_rotation_deg`` (0), ``corridor_box``, ``corridor_width_m``,
        ``rooms`` (all room boxes), ``options``, ``seed_info``.

    Raises:
        WorldError: a size or option is invalid or too small for the rooms (the message names it).
    """
    o = GeneratorOptions.from_kwargs(**options)
    p = _params(resolution_m, o)
    t = p.t
    min_room = math.ceil(ROOM_MIN_M / p.res)
    min_h_m = (4 * t + 2 * min_room + p.corridor[0]) * p.res
    H = _size_cells("height_m", height_m, p, min_h_m)
    n_opt = o.rooms_per_side
    n_min = 3 if n_opt is None else n_opt
    # Twins at least ROOM_MIN wide, the others wider by the twin gap: the narrowest floor.
    gap = math.ceil(TWIN_WIDTH_GAP_M / p.res)
    min_w_m = (n_min * (min_room + gap) + (n_min + 1) * t) * p.res
    W = _size_cells("width_m", width_m, p, min_w_m)

    inner_w = W - 2 * t
    for attempt in range(1, _MAX_ATTEMPTS + 1):
        walls = np.ones((H, W), dtype=np.bool_)
        cw = int(rng.integers(p.corridor[0], p.corridor[1] + 1))
        bands = H - 4 * t - cw  # interiors of both room rows together
        top = bands // 2 + int(rng.integers(-(bands // 10), bands // 10 + 1))
        top = int(np.clip(top, min_room, bands - min_room))
        bot = bands - top
        if n_opt is None:
            # Rooms about 4.5 m wide, wider when deep, so no room becomes a corridor.
            room_w_m = max(4.5, 0.6 * top * p.res)
            n_top = int(np.clip(round(inner_w * p.res / room_w_m), 3, 6))
        else:
            n_top = n_opt
        # Twins a bit narrower than the average room, so the others can all be wider.
        avg = (inner_w - (n_top - 1) * t) / n_top
        tw = int(np.clip(round(avg * rng.uniform(0.7, 0.9)), min_room, None))
        i = int(rng.integers(0, n_top - 2))
        j = int(rng.integers(i + 2, n_top))
        try:
            w_top = _split(rng, inner_w, n_top, t, {i: tw, j: tw}, min_room, tw, gap)
            n_bot = int(np.clip(n_top + int(rng.integers(-1, 2)), 2, None))
            w_bot = _split(rng, inner_w, n_bot, t, {}, min_room, tw, gap)
        except WorldError:
            continue
        twin = _room_plan(rng, top, tw, p, min_items=3)
        if p.furniture and len(twin.items) < 2:
            continue  # the twins must carry furniture: it is what makes them look alike
        bot_boxes = _band(walls, rng, w_bot, 0, bot, [True] * n_bot, p, {})
        top_row = H - top - 2 * t
        top_boxes = _band(walls, rng, w_top, top_row, top, [False] * n_top, p, {i: twin, j: twin})
        c_row = bot + 2 * t
        walls[c_row : c_row + cw, t : W - t] = False
        start = (W // 2, c_row + cw // 2)
        if not _accept(walls, p, start):
            continue
        return World(
            walls=walls,
            resolution_m=p.res,
            name="symmetric_office",
            meta={
                "generator": "symmetric_office",
                "twin_rooms": [top_boxes[i], top_boxes[j]],
                "twin_rotation_deg": 0,
                "corridor_box": (t, c_row, W - 2 * t, cw),
                "corridor_width_m": cw * p.res,
                "rooms": top_boxes + bot_boxes,
                "options": dict(
                    options, width_m=width_m, height_m=height_m, resolution_m=resolution_m
                ),
                "seed_info": {"attempts": attempt},
            },
        )
    raise WorldError(
        f"symmetric_office: no valid floor after {_MAX_ATTEMPTS} attempts for "
        f"width_m={width_m}, height_m={height_m}; try a larger size"
    )


def twin_wings(
    rng: np.random.Generator,
    width_m: float = 20.0,
    height_m: float = 20.0,
    resolution_m: float = 0.05,
    **options: Any,
) -> World:
    """Two wings (north and south corridors) joined by a connector, twins rotated by 180 degrees.

    Layout (row 0 at the bottom): outer wall, south rooms (doors up), south corridor, a middle
    row of rooms (each door up or down at random) with one slot replaced by a vertical connector
    corridor, north corridor, north rooms (doors down), outer wall. One north room and one south
    room are twins: the south one is the north one rotated by 180 degrees, cell for cell, and at
    a different column, so a merger must consider rotations to be fooled - or to be right.

    Args and options: as :func:`symmetric_office` (``rooms_per_side`` counts the north row).

    Returns:
        A :class:`World`; ``meta`` as :func:`symmetric_office` with ``twin_rotation_deg`` = 180
        (``twin_rooms[1]`` equals ``twin_rooms[0]`` rotated by 180 degrees), ``corridor_box``
        the north corridor, ``corridor_boxes`` all three corridors.

    Raises:
        WorldError: a size or option is invalid or too small (the message names it).
    """
    o = TwinWingsOptions.from_kwargs(**options)
    p = _params(resolution_m, o)
    t = p.t
    min_room = math.ceil(ROOM_MIN_M / p.res)
    min_h_m = (6 * t + 3 * min_room + 2 * p.corridor[0]) * p.res
    H = _size_cells("height_m", height_m, p, min_h_m)
    n_opt = o.rooms_per_side
    n_min = 3 if n_opt is None else max(n_opt, 3)
    gap = math.ceil(TWIN_WIDTH_GAP_M / p.res)
    min_w_m = (n_min * (min_room + gap) + p.corridor[0] + (n_min + 2) * t) * p.res
    W = _size_cells("width_m", width_m, p, min_w_m)
    inner_w = W - 2 * t

    for attempt in range(1, _MAX_ATTEMPTS + 1):
        walls = np.ones((H, W), dtype=np.bool_)
        cw_s = int(rng.integers(p.corridor[0], p.corridor[1] + 1))
        cw_n = int(rng.integers(p.corridor[0], p.corridor[1] + 1))
        bands = H - 6 * t - cw_s - cw_n
        # Both outer rows get the same depth: the twins (one in each) must be equally deep.
        d_o = round(bands * rng.uniform(0.28, 0.36))
        d_m = bands - 2 * d_o
        if min(d_o, d_m) < min_room:
            continue
        room_w_m = max(4.5, 0.6 * d_o * p.res)
        n_side = int(np.clip(round(inner_w * p.res / room_w_m), 2, 6)) if n_opt is None else n_opt
        avg = (inner_w - (n_side - 1) * t) / n_side
        tw = int(np.clip(round(avg * rng.uniform(0.7, 0.9)), min_room, None))
        i_n = int(rng.integers(0, n_side))
        i_s = int(rng.integers(0, n_side))
        n_mid = n_side + 1  # one slot of the middle row is the connector corridor
        conn = int(rng.integers(0, n_mid))
        cwv = int(rng.integers(p.corridor[0], p.corridor[1] + 1))
        try:
            w_n = _split(rng, inner_w, n_side, t, {i_n: tw}, min_room, tw, gap)
            w_s = _split(rng, inner_w, n_side, t, {i_s: tw}, min_room, tw, gap)
            w_m = _split(rng, inner_w, n_mid, t, {conn: cwv}, min_room, tw, gap)
        except WorldError:
            continue
        col_n = t * i_n + sum(w_n[:i_n])
        col_s = t * i_s + sum(w_s[:i_s])
        if abs(col_n - col_s) < tw // 2:
            continue  # twins one above the other would be a too-regular floor
        twin = _room_plan(rng, d_o, tw, p, min_items=3)
        if p.furniture and len(twin.items) < 2:
            continue  # the twins must carry furniture: it is what makes them look alike
        # The same plan stamped flipped (door up) is the 180-degree rotated twin.
        s_boxes = _band(walls, rng, w_s, 0, d_o, [True] * n_side, p, {i_s: twin})
        row_sc = d_o + 2 * t  # first row of the south corridor
        row_m = row_sc + cw_s  # middle boxes start with the wall above the south corridor
        doors_m = [bool(b) for b in rng.integers(0, 2, size=n_mid)]
        m_boxes = _band(walls, rng, w_m, row_m, d_m, doors_m, p, {}, skip={conn})
        row_nc = row_m + d_m + 2 * t
        row_n = row_nc + cw_n
        n_boxes = _band(walls, rng, w_n, row_n, d_o, [False] * n_side, p, {i_n: twin})
        walls[row_sc : row_sc + cw_s, t : W - t] = False
        walls[row_nc : row_nc + cw_n, t : W - t] = False
        cc = m_boxes[conn][0]
        walls[row_sc : row_nc + cw_n, cc + t : cc + t + cwv] = False
        start = (W // 2, row_nc + cw_n // 2)
        if not _accept(walls, p, start):
            continue
        return World(
            walls=walls,
            resolution_m=p.res,
            name="twin_wings",
            meta={
                "generator": "twin_wings",
                "twin_rooms": [n_boxes[i_n], s_boxes[i_s]],
                "twin_rotation_deg": 180,
                "corridor_box": (t, row_nc, W - 2 * t, cw_n),
                "corridor_boxes": [
                    (t, row_nc, W - 2 * t, cw_n),
                    (t, row_sc, W - 2 * t, cw_s),
                    (cc + t, row_sc, cwv, row_nc + cw_n - row_sc),
                ],
                "corridor_width_m": cw_n * p.res,
                "rooms": n_boxes + [b for k, b in enumerate(m_boxes) if k != conn] + s_boxes,
                "options": dict(
                    options, width_m=width_m, height_m=height_m, resolution_m=resolution_m
                ),
                "seed_info": {"attempts": attempt},
            },
        )
    raise WorldError(
        f"twin_wings: no valid floor after {_MAX_ATTEMPTS} attempts for "
        f"width_m={width_m}, height_m={height_m}; try a larger size"
    )


GENERATORS: dict[str, Callable[..., World]] = {
    "symmetric_office": symmetric_office,
    "twin_wings": twin_wings,
}
