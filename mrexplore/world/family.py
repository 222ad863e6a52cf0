"""World families: floors with repeated rooms, drawn from a world seed, split into tune and test.

Why: a merger tuned on a handful of fixed worlds can hold wrong merges on worlds it never saw.
A *family* is a generator of floors with two or more identical rooms in different places;
its worlds are split by **world seed** into a tuning part and a test part, fixed here before any
rule is chosen, so that nothing is tuned on the worlds it is judged on.

The split: world ``index`` of a part is drawn from ``numpy.random.default_rng(seed)`` alone,
with ``seed = PART_FIRST_SEED[part] + index``: the tune part is world seeds 0, 1, 2, ...
(:data:`TUNE_FIRST_SEED`), the test part world seeds 100_000, 100_001, ...
(:data:`TEST_FIRST_SEED`), and further test parts ``test2`` .. ``test99``, world seeds
``k * 100_000``, ..., each kept closed for a rule chosen after the part before it was read; an
index is below :data:`PART_SIZE`, so the parts never share a seed. Nobody tunes on a test part. A
world is named by the spec ``"family:<family>/<part>/<index>"`` (:func:`family_spec`), which
:func:`mrexplore.world.load_world` resolves; its :class:`~mrexplore.world.World` is named
``"<family>/<part>/<index:04d>"``.

Families (:data:`FAMILY_GENERATORS`; also ``"random:<family>"`` specs, a fresh world per
episode from the env's generator):

* :func:`paper_like`: one room template (walls, door, furniture: desks, cupboards, tables as
  blocks) repeated cell for cell in 2 to 4 copies; repeated rooms 3 to 12 m wide; copies
  translated, some turned by 90 or 180 degrees. Layouts: rooms along a corridor (one side or
  both), a hall with rooms around it, two wings (two corridors and a connector), an open plan
  with repeated furniture groups. Doors of the copies at the same or at different offsets;
  sometimes other (non-repeated) rooms; sometimes clutter (small objects in the corridors);
  sometimes real-map noise (speckle cells, slightly rough walls: the copies then differ in a
  few cells, as a real map's would).
* :func:`office_row`: rows of 3 to 8 identical offices along a corridor, sometimes on both
  sides.
* :func:`radial`: floors the same under a turn: 2 to 6 identical wings of rooms round a round
  hall, one every ``360 / n`` degrees (a building with rotational symmetry).

Floors are at most :data:`MAX_LONG_M` x :data:`MAX_SHORT_M` metres (long x short side), so a
2-robot episode stays cheap; every free cell is reachable by the robot from the start area
(checked with :func:`~mrexplore.world.generators.unreachable_free_cells`; the env draws starts
in the largest connected free space, which is then all of it). Room templates and furniture
come from :mod:`mrexplore.world.generators`; rows of rooms around halls from
:mod:`mrexplore.world.floorplans`. Sizes in metres, grids ``walls[row, col]`` with row 0 the
lowest y, boxes ``(col, row, w, h)`` in cells with the walls.

``World.meta`` (tests and evaluation only): ``generator`` (the family), ``layout``, ``copies``
(per copy: ``box``, ``rotation_deg`` of the template, counter-clockwise in the array,
``np.rot90``'s sense), ``twin_rooms`` (the copies' boxes), ``twin_rotation_deg`` (copy 1 against
copy 0), ``doors_differ`` (copies' doors at different offsets: the copies are then identical
but for their door walls), ``rooms`` (every room's box), ``corridor_box`` (the main hall or
corridor; a radial floor's: the square inside its hall, about the centre the floor turns
about), ``start_cell``, ``clutter`` (pieces), ``noise`` (cells changed, or None), ``options``
and ``seed_info``; a radial floor's ``wings``, and its copies' ``rotation_deg`` any multiple
of ``360 / wings`` (boxes of copies not turned by quarter turns bound the turned room).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import WorldError
from mrexplore.grid import map_points
from mrexplore.world.floorplans import Box, Hall, Placed, Slot, hall_floor, rotate_box
from mrexplore.world.generators import (
    ROOM_MIN_M,
    TWIN_WIDTH_GAP_M,
    GeneratorOptions,
    _overlap,
    _Params,
    _params,
    _room_plan,
    _room_template,
    _RoomPlan,
    unreachable_free_cells,
)
from mrexplore.world.world import World

__all__ = [
    "FAMILIES",
    "FAMILY_GENERATORS",
    "FAMILY_PREFIX",
    "MAX_LONG_M",
    "MAX_SHORT_M",
    "PARTS",
    "PART_FIRST_SEED",
    "PART_SIZE",
    "TEST_FIRST_SEED",
    "TUNE_FIRST_SEED",
    "family_seed",
    "family_seeds",
    "family_spec",
    "family_world",
    "office_row",
    "paper_like",
    "parse_family_spec",
    "radial",
]

#: The spec prefix: ``"family:paper_like/test/7"``.
FAMILY_PREFIX = "family:"
#: Worlds per part at most: indices 0 .. PART_SIZE - 1, so the parts' seeds never meet.
PART_SIZE = 100_000
#: First world seed of the tune part (world seeds 0, 1, 2, ...).
TUNE_FIRST_SEED = 0
#: First world seed of the test part (world seeds 100_000, 100_001, ...).
TEST_FIRST_SEED = PART_SIZE
#: The parts of every family, by world seed: ``test<k>`` starts at ``k * PART_SIZE``.
PART_FIRST_SEED: dict[str, int] = {
    "tune": TUNE_FIRST_SEED,
    "test": TEST_FIRST_SEED,
    **{f"test{k}": k * PART_SIZE for k in range(2, 100)},
}
PARTS: tuple[str, ...] = tuple(PART_FIRST_SEED)
#: The parts as error messages name them.
PARTS_TEXT = "tune, test, test2 .. test99"
#: Largest floor, metres: the long side and the short side.
MAX_LONG_M = 35.0
MAX_SHORT_M = 25.0
#: Corridor widths of the families, metres (narrower than the paper's 3 m too).
CORRIDOR_M = (1.5, 3.0)
#: Widths of the repeated rooms of :func:`paper_like` (interior, metres).
REPEATED_WIDTH_M = (3.0, 12.0)
#: Depths of rooms (interior, metres).
ROOM_DEPTH_M = (3.0, 7.0)
#: Wings of :func:`radial`: its floors are the same under a turn of 360 / n degrees.
RADIAL_WINGS = (2, 3, 4, 5, 6)
_MAX_ATTEMPTS = 60


class _Retry(Exception):
    """This draw does not fit (too large, too small, unreachable): draw again."""


@dataclass
class _Floor:
    """A floor as a layout builder leaves it, before global turn, clutter and noise."""

    walls: NDArray[np.bool_]
    hall: Box  # the main free area (col, row, w, h), interior
    placed: list[Placed]
    free_areas: list[Box]  # where clutter may stand (corridors, halls), interior boxes
    facts: dict[str, Any] = field(default_factory=dict)
    # degrees a copy is turned beyond its quarter turns (copy index -> degrees): the wings of
    # a radial floor; its box is then the turned room's bounding box
    copy_deg: dict[int, float] = field(default_factory=dict)


# --------------------------------------------------------------------------------------------
# the split and the specs


def family_seed(part: str, index: int) -> int:
    """The world seed of world ``index`` of ``part`` (see the module doc)."""
    if part not in PART_FIRST_SEED:
        raise WorldError(f"unknown part {part!r}; parts are {PARTS_TEXT}")
    if isinstance(index, bool) or not isinstance(index, (int, np.integer)):
        raise WorldError(f"world index must be an integer, got {index!r}")
    if not 0 <= int(index) < PART_SIZE:
        raise WorldError(f"world index must be in [0, {PART_SIZE}), got {index}")
    return PART_FIRST_SEED[part] + int(index)


def family_seeds(family: str, part: str, n: int) -> list[int]:
    """World seeds of worlds 0 .. n-1 of ``family``'s ``part``."""
    _check_family(family)
    if isinstance(n, bool) or not isinstance(n, (int, np.integer)) or not 0 <= n <= PART_SIZE:
        raise WorldError(f"number of worlds must be an integer in [0, {PART_SIZE}], got {n!r}")
    return [family_seed(part, k) for k in range(int(n))]


def family_spec(family: str, part: str, index: int) -> str:
    """The world spec ``"family:<family>/<part>/<index>"`` (checked)."""
    _check_family(family)
    family_seed(part, index)
    return f"{FAMILY_PREFIX}{family}/{part}/{int(index)}"


def parse_family_spec(spec: str) -> tuple[str, str, int]:
    """``"family:paper_like/test/7"`` -> ``("paper_like", "test", 7)``; a :class:`WorldError`
    naming the bad part otherwise."""
    body = spec[len(FAMILY_PREFIX) :] if spec.startswith(FAMILY_PREFIX) else spec
    bits = body.split("/")
    if len(bits) != 3:
        raise WorldError(
            f"world spec {spec!r}: expected 'family:<family>/<part>/<index>', e.g. "
            f"'family:paper_like/test/7'; families {sorted(FAMILY_GENERATORS)}, parts {PARTS_TEXT}"
        )
    family, part, text = bits
    _check_family(family, spec)
    if part not in PART_FIRST_SEED:
        raise WorldError(f"world spec {spec!r}: unknown part {part!r}; parts are {PARTS_TEXT}")
    if not (text.isascii() and text.isdigit()):
        raise WorldError(
            f"world spec {spec!r}: the world index must be a whole number >= 0, got {text!r}"
        )
    index = int(text)
    if index >= PART_SIZE:
        raise WorldError(f"world spec {spec!r}: the world index must be below {PART_SIZE}")
    return family, part, index


def _check_family(family: str, spec: str | None = None) -> None:
    if family not in FAMILY_GENERATORS:
        where = f"world spec {spec!r}: " if spec else ""
        raise WorldError(
            f"{where}unknown family {family!r}; families are {sorted(FAMILY_GENERATORS)}"
        )


def family_world(family: str, part: str, index: int) -> World:
    """World ``index`` of ``family``'s ``part``: drawn from its world seed alone, named
    ``"<family>/<part>/<index:04d>"``, its seed in ``meta["seed"]``."""
    _check_family(family)
    seed = family_seed(part, index)
    w = FAMILY_GENERATORS[family](np.random.default_rng(seed))
    return replace(w, name=f"{family}/{part}/{int(index):04d}", meta={**w.meta, "seed": seed})


# --------------------------------------------------------------------------------------------
# rooms and rows


def _m(rng: np.random.Generator, lo_m: float, hi_m: float, p: _Params) -> int:
    """A length drawn uniformly in [lo_m, hi_m] metres, in cells."""
    return p.cells(float(rng.uniform(lo_m, hi_m)))


def _copy_templates(
    rng: np.random.Generator, p: _Params, w: int, h: int, n: int, vary_doors: bool
) -> tuple[list[NDArray[np.bool_]], bool]:
    """Templates of ``n`` copies of one furnished room (interior ``h x w`` cells, canonical
    orientation); with ``vary_doors`` the copies after the first get doors at other offsets
    (never in front of furniture). Returns the templates and whether any door differs."""
    plan = _room_plan(rng, h, w, p, min_items=3)
    if p.furniture and len(plan.items) < 2:
        raise _Retry  # the copies must carry furniture: it is what makes them look alike
    plans = [plan]
    c = p.clear
    for _ in range(n - 1):
        q = plan
        if vary_doors:
            for _ in range(10):
                c0 = int(rng.integers(0, w - plan.door_w + 1))
                zone = (0, c0 - c, max(c, p.cells(1.0)), plan.door_w + 2 * c)
                if abs(c0 - plan.door_c0) >= plan.door_w and not any(
                    _overlap(zone, it) for it in plan.items
                ):
                    q = _RoomPlan(plan.h, plan.w, c0, plan.door_w, plan.items)
                    break
        plans.append(q)
    differ = any(q.door_c0 != plan.door_c0 for q in plans)
    return [_room_template(q, p.t) for q in plans], differ


@dataclass(frozen=True)
class _Sizes:
    """Cells of the family's fixed lengths, for one resolution."""

    t: int
    min_room: int
    gap: int
    long: int
    short: int

    @staticmethod
    def of(p: _Params) -> _Sizes:
        return _Sizes(
            t=p.t,
            min_room=math.ceil(ROOM_MIN_M / p.res),
            gap=math.ceil(TWIN_WIDTH_GAP_M / p.res),
            long=round(MAX_LONG_M / p.res),
            short=round(MAX_SHORT_M / p.res),
        )


def _row(
    rng: np.random.Generator,
    p: _Params,
    edge: int,
    copies: list[tuple[int, NDArray[np.bool_]]],
    tw: int,
    depth: int,
    fill: float,
) -> tuple[list[Slot], int] | None:
    """Slots of a row along a side ``edge`` cells long: the given copies (index, template,
    interior ``tw`` wide), then other rooms (each with probability ``fill`` while room is left,
    widths at least the twin gap away from ``tw``, depths up to ``depth``), in random order, at
    a random offset. None when the side stays bare."""
    z = _Sizes.of(p)
    slots = [Slot(tw, depth, tpl, k) for k, tpl in copies]
    used = sum(s.width for s in slots) + max(len(slots) - 1, 0) * z.t
    if used > edge:
        raise _Retry
    rest = edge - used - (z.t if slots else 0)
    for _ in range(12):
        if rest < z.min_room or rng.random() >= fill:
            break
        w = int(rng.integers(z.min_room, min(rest, p.cells(8.0)) + 1))
        if abs(w - tw) < z.gap:
            continue
        d = int(rng.integers(z.min_room, depth + 1))
        plan = _room_plan(rng, d, w, p)
        slots.append(Slot(w, d, _room_template(plan, z.t)))
        rest -= w + z.t
    if not slots:
        return None
    order = rng.permutation(len(slots))
    slots = [slots[int(i)] for i in order]
    length = sum(s.width for s in slots) + (len(slots) - 1) * z.t
    return slots, int(rng.integers(0, edge - length + 1))


def _deal(rng: np.random.Generator, n: int, sides: list[str]) -> dict[str, list[int]]:
    """Copies 0 .. n-1 dealt to ``sides``: each side at least one while copies last, the rest
    at random."""
    order = [sides[int(i)] for i in rng.permutation(len(sides))]
    out: dict[str, list[int]] = {s: [] for s in sides}
    for k in range(n):
        s = order[k] if k < len(order) else sides[int(rng.integers(len(sides)))]
        out[s].append(k)
    return out


def _need(n: int, tw: int, t: int) -> int:
    return n * tw + max(n - 1, 0) * t


# --------------------------------------------------------------------------------------------
# layouts


def _rooms_round_hall(
    rng: np.random.Generator,
    p: _Params,
    sides: list[str],
    tpls: list[NDArray[np.bool_]],
    tw: int,
    th: int,
    min_hall: tuple[int, int],
    fill: float,
    bare: tuple[str, ...] = (),
) -> _Floor:
    """A hall (or corridor: a narrow hall) with the copies dealt to ``sides`` and other rooms
    around it (also on the ``bare`` sides, which get no copy)."""
    z = _Sizes.of(p)
    dealt = _deal(rng, len(tpls), sides)
    need_ns = max([_need(len(dealt.get(s, [])), tw, z.t) for s in "ns"] + [min_hall[0]])
    need_ew = max([_need(len(dealt.get(s, [])), tw, z.t) for s in "ew"] + [min_hall[1]])
    hw = need_ns + _m(rng, 0.0, 8.0, p)
    hh = need_ew + (_m(rng, 0.0, 4.0, p) if any(dealt.get(s) for s in "ew") else 0)
    rows: dict[str, tuple[list[Slot], int]] = {}
    for s in [*sides, *bare]:
        ks = dealt.get(s, [])
        depth = th if ks else _m(rng, *ROOM_DEPTH_M, p)
        r = _row(rng, p, hw if s in "ns" else hh, [(k, tpls[k]) for k in ks], tw, depth, fill)
        if r is not None:
            rows[s] = r
    walls, hall, placed = hall_floor(Hall(hw, hh, rows), z.t)
    return _Floor(walls, hall, placed, [hall])


def _corridor(
    rng: np.random.Generator, p: _Params, tpls: list[NDArray[np.bool_]], tw: int, th: int
) -> _Floor:
    """Rooms along a corridor: copies on one side (other rooms maybe opposite) or both."""
    both = len(tpls) > 1 and rng.random() < 0.5
    cw = _m(rng, *CORRIDOR_M, p)
    sides = ["n", "s"] if both else ["n"]
    bare = () if both else ("s",)
    fill = float(rng.choice([0.0, 0.5, 0.9]))
    f = _rooms_round_hall(rng, p, sides, tpls, tw, th, (p.cells(6.0), cw), fill, bare)
    f.facts["layout"] = "corridor_both_sides" if both else "corridor_one_side"
    return f


def _hall(
    rng: np.random.Generator, p: _Params, tpls: list[NDArray[np.bool_]], tw: int, th: int
) -> _Floor:
    """A hall with rooms around it: copies on 2 to 4 of its sides (turned 90, 180, 270 deg)."""
    n_sides = int(rng.integers(2, min(4, len(tpls)) + 1)) if len(tpls) > 2 else 2
    sides = [str(s) for s in rng.permutation(list("nesw"))[:n_sides]]
    bare = tuple(s for s in "nesw" if s not in sides and rng.random() < 0.5)
    fill = float(rng.choice([0.0, 0.5, 0.9]))
    f = _rooms_round_hall(rng, p, sides, tpls, tw, th, (p.cells(3.0), p.cells(3.0)), fill, bare)
    f.facts["layout"] = "hall"
    return f


def _wings(
    rng: np.random.Generator, p: _Params, tpls: list[NDArray[np.bool_]], tw: int, th: int
) -> _Floor:
    """Two wings: two parallel corridors with rooms on both sides of each, joined at one end by
    a connector corridor; the copies are dealt to the four rows (turned 0 or 180 deg)."""
    z = _Sizes.of(p)
    t = z.t
    rows_named = ["so", "si", "ni", "no"]  # south outer, south inner, north inner, north outer
    chosen = [str(s) for s in rng.permutation(rows_named)[: int(rng.integers(2, 5))]]
    dealt = _deal(rng, len(tpls), chosen)
    cwv = _m(rng, *CORRIDOR_M, p)
    inner_cut = cwv + t  # the inner rows leave the connector's columns
    need = max(
        _need(len(dealt.get(r, [])), tw, t) + (inner_cut if r in ("si", "ni") else 0)
        for r in rows_named
    )
    length = max(need, p.cells(10.0)) + _m(rng, 0.0, 6.0, p)
    fill = float(rng.choice([0.0, 0.5, 0.9]))

    def side_row(name: str, edge: int) -> tuple[list[Slot], int] | None:
        ks = dealt.get(name, [])
        depth = th if ks else _m(rng, *ROOM_DEPTH_M, p)
        return _row(rng, p, edge, [(k, tpls[k]) for k in ks], tw, depth, fill)

    blocks = []
    for outer, inner in (("so", "si"), ("no", "ni")):
        cw = _m(rng, *CORRIDOR_M, p)
        rows: dict[str, tuple[list[Slot], int]] = {}
        out_row = side_row(outer, length)
        in_row = side_row(inner, length - inner_cut)
        if outer == "so":  # the south block: outer row south, inner row north
            if out_row:
                rows["s"] = out_row
            if in_row:
                rows["n"] = (in_row[0], 0)  # flush west: the connector takes the east end
        else:
            if out_row:
                rows["n"] = out_row
            if in_row:
                rows["s"] = (in_row[0], 0)
        blocks.append(hall_floor(Hall(length, cw, rows), t))
    (wa, ha, pa), (wb, hb, pb) = blocks
    width = wa.shape[1]
    walls = np.ones((wa.shape[0] + wb.shape[0] - t, width), dtype=np.bool_)
    walls[: wa.shape[0]] = wa
    off = wa.shape[0] - t
    walls[off:] &= wb
    hb = (hb[0], hb[1] + off, hb[2], hb[3])
    pb = [Placed((b[0], b[1] + off, b[2], b[3]), q.turns, q.copy) for q in pb for b in [q.box]]
    conn: Box = (width - t - cwv, ha[1] + ha[3], cwv, hb[1] - ha[1] - ha[3])
    walls[conn[1] : conn[1] + conn[3], conn[0] : conn[0] + conn[2]] = False
    f = _Floor(walls, ha, pa + pb, [ha, hb, conn])
    f.facts.update(layout="two_wings", corridor_boxes=[ha, hb, conn])
    return f


def _group_template(rng: np.random.Generator, p: _Params) -> NDArray[np.bool_]:
    """A furniture group with its free margin (``clear`` all round), bool: a table, benches on
    one or two of its long sides, sometimes a cupboard at one end; pieces ``clear`` apart."""
    c = p.clear
    th, tw = _m(rng, 0.8, 1.6, p), _m(rng, 1.2, 2.6, p)
    bd = _m(rng, 0.35, 0.45, p)
    pieces: list[tuple[int, int, int, int]] = [(0, 0, th, tw)]  # (row, col, h, w), table at 0
    if rng.random() < 0.8:
        pieces.append((-c - bd, 0, bd, tw))  # bench below
    if rng.random() < 0.6:
        pieces.append((th + c, int(rng.integers(0, tw // 3 + 1)), bd, tw - tw // 3))  # above
    if rng.random() < 0.7:
        ch, cd = _m(rng, 0.8, 1.4, p), _m(rng, 0.4, 0.6, p)
        pieces.append((0, tw + c, ch, cd))  # cupboard at the east end
    r0 = min(q[0] for q in pieces)
    c0 = min(q[1] for q in pieces)
    r1 = max(q[0] + q[2] for q in pieces)
    c1 = max(q[1] + q[3] for q in pieces)
    tpl = np.zeros((r1 - r0 + 2 * c, c1 - c0 + 2 * c), dtype=np.bool_)
    for r, cc, h, w in pieces:
        tpl[r - r0 + c : r - r0 + c + h, cc - c0 + c : cc - c0 + c + w] = True
    return tpl


def _open_plan(rng: np.random.Generator, p: _Params, n: int, _tw: int, _th: int) -> _Floor:
    """An open plan: a large hall with ``n`` copies of one furniture group, each turned by a
    random multiple of 90 degrees; sometimes non-repeated rooms along one or two sides."""
    z = _Sizes.of(p)
    bare = tuple(str(s) for s in rng.permutation(list("nesw"))[: int(rng.integers(0, 3))])
    hw, hh = _m(rng, 14.0, 26.0, p), _m(rng, 10.0, 16.0, p)
    rows: dict[str, tuple[list[Slot], int]] = {}
    for s in bare:
        r = _row(rng, p, hw if s in "ns" else hh, [], 0, _m(rng, *ROOM_DEPTH_M, p), 0.9)
        if r is not None:
            rows[s] = r
    walls, hall, placed = hall_floor(Hall(hw, hh, rows), z.t)
    group = _group_template(rng, p)
    inset = p.cells(0.6)  # away from the hall's walls and doors, beyond the group's margin
    taken: list[Box] = []
    for k in range(n):
        for _ in range(200):
            turns = int(rng.integers(4))
            g = np.rot90(group, turns)
            gh, gw = g.shape
            lo_c, hi_c = hall[0] + inset, hall[0] + hall[2] - inset - gw
            lo_r, hi_r = hall[1] + inset, hall[1] + hall[3] - inset - gh
            if hi_c < lo_c or hi_r < lo_r:
                raise _Retry
            box: Box = (
                int(rng.integers(lo_c, hi_c + 1)),
                int(rng.integers(lo_r, hi_r + 1)),
                gw,
                gh,
            )
            if any(_overlap((b[1], b[0], b[3], b[2]), (box[1], box[0], gh, gw)) for b in taken):
                continue
            walls[box[1] : box[1] + gh, box[0] : box[0] + gw] = g
            taken.append(box)
            placed.append(Placed(box, turns, k))
            break
        else:
            raise _Retry
    # other furniture, each piece drawn on its own: desks and cupboards that repeat nothing
    reserved = _reserved(walls.shape, taken)
    _scatter(rng, walls, [hall], int(rng.integers(2, 9)), (0.5, 1.6), reserved, p)
    f = _Floor(walls, hall, placed, [hall])
    f.facts["layout"] = "open_plan"
    f.facts["copy_kind"] = "furniture_group"
    return f


# --------------------------------------------------------------------------------------------
# floors the same under a turn


def _turn_about_centre(side: int, deg: float) -> NDArray[np.float64]:
    """The 2 x 3 map of (col, row) cells of a ``side`` x ``side`` array turned by ``deg``
    counter-clockwise in the array (as :func:`numpy.rot90`) about its centre cell."""
    c = (side - 1) / 2.0
    return np.asarray(cv2.getRotationMatrix2D((c, c), deg, 1.0), dtype=np.float64)


def _turned(mask: NDArray[np.uint8], deg: float) -> NDArray[np.uint8]:
    """A square ``mask`` (odd side) turned by ``deg`` (:func:`_turn_about_centre`): exact for
    quarter turns, else to the nearest cell."""
    q = deg / 90.0
    if abs(q - round(q)) < 1e-9:
        return np.ascontiguousarray(np.rot90(mask, round(q) % 4))
    rot = _turn_about_centre(mask.shape[0], deg)
    out = cv2.warpAffine(mask, rot, mask.shape[::-1], flags=cv2.INTER_NEAREST)
    return np.asarray(out, dtype=np.uint8)


def _turned_box(box: Box, side: int, deg: float) -> Box:
    """The bounding box of ``box`` (cells of a ``side`` x ``side`` array) turned as
    :func:`_turned` turns the array."""
    T = np.vstack([_turn_about_centre(side, deg), [0.0, 0.0, 1.0]])
    col, row, w, h = box
    corners = np.array(
        [[col, row], [col + w - 1, row], [col, row + h - 1], [col + w - 1, row + h - 1]],
        dtype=np.float64,
    )
    # map_points, not BLAS: the same box on every CPU
    xs, ys = map_points(corners, T)
    c0, c1 = math.floor(float(xs.min()) + 0.5), math.floor(float(xs.max()) + 0.5)
    r0, r1 = math.floor(float(ys.min()) + 0.5), math.floor(float(ys.max()) + 0.5)
    return (c0, r0, c1 - c0 + 1, r1 - r0 + 1)


def _radial_floor(
    rng: np.random.Generator, p: _Params, n: int, tpls: list[NDArray[np.bool_]], tw: int, th: int
) -> _Floor:
    """``n`` identical wings round a round central hall, one every ``360 / n`` degrees: each wing a
    corridor from the hall with the copies in rows on one or both of its sides. The floor is
    the same turned by ``360 / n`` degrees (cell for cell for 2 and 4 wings; for 3, 5 and 6 the
    turned wings are drawn to the nearest cell, so copies differ in a few edge cells)."""
    z = _Sizes.of(p)
    t = z.t
    cw = _m(rng, *CORRIDOR_M, p)
    sides = ["e", "w"] if len(tpls) > 1 and rng.random() < 0.6 else ["e"]
    dealt = _deal(rng, len(tpls), sides)
    # the hall: a disc, wide enough that the wings' corridors meet it apart
    radius = _m(rng, 1.5, 3.0, p)
    if n > 2:
        radius = max(radius, math.ceil((cw / 2 + t + 2) / math.tan(math.pi / n)))
    start = radius - t - 1  # the wing's first row, inside the hall: its mouth opens into it
    need = max(_need(len(ks), tw, t) for ks in dealt.values())
    # widest reach of a wing from its corridor's axis (cells), rooms on the wider side
    reach = cw / 2 + 2 * t + th
    # rooms begin where the wings' rooms cannot meet, and beyond the hall
    clear = max((reach + t + 2) / math.tan(math.pi / n) if n > 2 else 0.0, radius + t + 2)
    off = max(math.ceil(clear - start), radius - start + _m(rng, 0.5, 2.0, p))
    length = off + need + _m(rng, 0.0, 2.0, p)
    rows: dict[str, tuple[list[Slot], int]] = {}
    for s in sides:
        ks = dealt.get(s, [])
        if ks:
            rows[s] = ([Slot(tw, th, tpls[k], k) for k in ks], off)
    wing, corridor, placed = hall_floor(Hall(cw, length, rows), t)
    hc, hr, _, _ = corridor
    wing[:hr, hc : hc + cw] = False  # the mouth
    axis = hc + (cw - 1) // 2
    far = math.hypot(start + wing.shape[0], max(axis, wing.shape[1] - axis))
    side = 2 * (math.ceil(far) + t + 2) + 1
    if side > 2 * max(z.long, z.short):
        raise _Retry
    mid = (side - 1) // 2
    col0, row0 = mid - axis, mid + start
    wing_free = np.zeros((side, side), dtype=np.uint8)
    wing_free[row0 : row0 + wing.shape[0], col0 : col0 + wing.shape[1]] = ~wing
    # the hall: every cell whose centre lies within the hall's radius of the centre cell
    ys, xs = np.ogrid[-mid : side - mid, -mid : side - mid]
    hall = (xs * xs + ys * ys <= radius * radius).astype(np.uint8)
    wings = [_turned(wing_free, 360.0 * k / n) for k in range(n)]
    # neighbouring wings' free cells stay a wall apart (outside the hall)
    near = np.ones((2 * t + 1, 2 * t + 1), np.uint8)
    outside = cv2.dilate(hall, near) == 0
    for i in range(n):
        grown = cv2.dilate(wings[i], near) > 0
        for j in range(i + 1, n):
            if (grown & (wings[j] > 0) & outside).any():
                raise _Retry
    free = hall.astype(bool)
    for turned in wings:
        free |= turned > 0
    rr, cc = np.nonzero(free)
    r0, r1 = int(rr.min()) - t, int(rr.max()) + t + 1
    c0, c1 = int(cc.min()) - t, int(cc.max()) + t + 1
    walls = np.ascontiguousarray(~free[r0:r1, c0:c1])
    per_wing = len(tpls)
    out: list[Placed] = []
    copy_deg: dict[int, float] = {}
    for k in range(n):
        deg = 360.0 * k / n
        for q in placed:
            bc, br, bw, bh = q.box
            tc, tr, w, h = _turned_box((bc + col0, br + row0, bw, bh), side, deg)
            idx = k * per_wing + (q.copy or 0)
            out.append(Placed((tc - c0, tr - r0, w, h), q.turns, idx))
            copy_deg[idx] = deg
    inner = max(1, int(radius / math.sqrt(2.0)) - 1)
    box: Box = (mid - inner - c0, mid - inner - r0, 2 * inner + 1, 2 * inner + 1)
    return _Floor(walls, box, out, [box], {"layout": f"radial_{n}"}, copy_deg)


# --------------------------------------------------------------------------------------------
# finishing: turn, clutter, noise, checks


def _reserved(shape: tuple[int, int], boxes: list[Box]) -> NDArray[np.bool_]:
    out = np.zeros(shape, dtype=np.bool_)
    for c, r, w, h in boxes:
        out[r : r + h, c : c + w] = True
    return out


def _scatter(
    rng: np.random.Generator,
    walls: NDArray[np.bool_],
    areas: list[Box],
    n: int,
    size_m: tuple[float, float],
    reserved: NDArray[np.bool_],
    p: _Params,
) -> int:
    """Up to ``n`` square-ish blocks (sides in ``size_m``) in ``areas`` (interior boxes), each
    with ``clear`` free and unreserved cells all round; written into ``walls``. Returns how
    many stood."""
    c = p.clear
    placed = 0
    for _ in range(20 * n):
        if placed >= n or not areas:
            break
        ac, ar, aw, ah = areas[int(rng.integers(len(areas)))]
        h, w = _m(rng, *size_m, p), _m(rng, *size_m, p)
        if aw < w + 2 * c or ah < h + 2 * c:
            continue
        col = int(rng.integers(ac + c, ac + aw - c - w + 1))
        row = int(rng.integers(ar + c, ar + ah - c - h + 1))
        ring = (slice(row - c, row + h + c), slice(col - c, col + w + c))
        if walls[ring].any() or reserved[ring].any():
            continue
        walls[row : row + h, col : col + w] = True
        reserved[ring] = True
        placed += 1
    return placed


def _start_cell(walls: NDArray[np.bool_], hall: Box) -> tuple[int, int]:
    """(col, row): the cell of the hall farthest from any wall."""
    dist = cv2.distanceTransform((~walls).astype(np.uint8), cv2.DIST_L2, cv2.DIST_MASK_PRECISE)
    c, r, w, h = hall
    sub = dist[r : r + h, c : c + w]
    rr, cc = np.unravel_index(int(np.argmax(sub)), sub.shape)
    return (c + int(cc), r + int(rr))


def _reachable(walls: NDArray[np.bool_], p: _Params, start: tuple[int, int]) -> bool:
    return not unreachable_free_cells(walls, p.res, start, p.robot_r_m).any()


def _noise(
    rng: np.random.Generator, walls: NDArray[np.bool_], p: _Params, start: tuple[int, int]
) -> tuple[NDArray[np.bool_], dict[str, int] | None]:
    """Real-map noise: 3-15 speckle cells in free space and 1-cell bumps on 0.2-1 % of the
    walls' free face. Noise cells near a cell they would cut off are taken back (a real map's
    noise does not close a door), then the rest kept; None when nothing is left."""
    free = ~walls
    face = free & (cv2.dilate(walls.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0)
    speck = np.zeros_like(walls)
    idx = np.flatnonzero(free & ~face)
    speck.flat[rng.choice(idx, size=min(int(rng.integers(3, 16)), idx.size), replace=False)] = True
    bumps = face & (rng.random(walls.shape) < rng.uniform(0.002, 0.01))
    speck[start[1], start[0]] = bumps[start[1], start[0]] = False
    near = np.ones((21, 21), np.uint8)  # take back noise within 10 cells of a cut-off cell
    for _ in range(4):
        out = walls | speck | bumps
        bad = unreachable_free_cells(out, p.res, start, p.robot_r_m) & free
        if not bad.any():
            if not (speck.any() or bumps.any()):
                return walls, None
            return out, {"speckles": int(speck.sum()), "bumps": int(bumps.sum())}
        keep = cv2.dilate(bad.astype(np.uint8), near) == 0
        speck &= keep
        bumps &= keep
    return walls, None


@dataclass(frozen=True)
class _Draw:
    """What a family drew beyond the layout: clutter, noise, the turn of the whole floor."""

    clutter: bool
    noise: bool
    turns: int


def _finish(
    family: str,
    f: _Floor,
    p: _Params,
    rng: np.random.Generator,
    noise_rng: np.random.Generator,
    d: _Draw,
    facts: dict[str, Any],
    attempt: int,
) -> World | None:
    """Size check, clutter, reachability, the floor's turn, noise; the World (None: redraw)."""
    z = _Sizes.of(p)
    walls = f.walls
    if max(walls.shape) > z.long or min(walls.shape) > z.short:
        return None
    room_boxes = [q.box for q in f.placed]
    n_clutter = 0
    if d.clutter:
        reserved = _reserved(walls.shape, room_boxes)
        n_clutter = _scatter(
            rng, walls, f.free_areas, int(rng.integers(2, 9)), (0.2, 0.5), reserved, p
        )
    start = _start_cell(walls, f.hall)
    if not _reachable(walls, p, start):
        return None
    k = d.turns
    shape = (int(walls.shape[0]), int(walls.shape[1]))
    walls = np.ascontiguousarray(np.rot90(walls, k))

    def turn(b: Box) -> Box:
        return rotate_box(b, shape, k)

    sc, sr, _, _ = turn((start[0], start[1], 1, 1))
    start = (sc, sr)
    noise = None
    if d.noise:
        walls, noise = _noise(noise_rng, walls, p, start)
    copies = sorted((q for q in f.placed if q.copy is not None), key=lambda q: q.copy or 0)
    rotations: list[float] = [
        _turn_deg(90 * ((q.turns + k) % 4), f.copy_deg.get(q.copy or 0, 0.0)) for q in copies
    ]
    copy_meta = [
        {"box": turn(q.box), "rotation_deg": deg} for q, deg in zip(copies, rotations, strict=True)
    ]
    extra = {
        key: ([turn(b) for b in v] if key == "corridor_boxes" else v) for key, v in f.facts.items()
    }
    return World(
        walls=walls,
        resolution_m=p.res,
        name=family,
        meta={
            "generator": family,
            **extra,
            **facts,
            "copies": copy_meta,
            "twin_rooms": [turn(q.box) for q in copies],
            "twin_rotation_deg": (rotations[1] - rotations[0]) % 360,
            "rooms": [turn(b) for b in room_boxes],
            "corridor_box": turn(f.hall),
            "start_cell": start,
            "clutter": n_clutter,
            "noise": noise,
            "options": {"resolution_m": p.res},
            "seed_info": {"attempts": attempt},
        },
    )


def _turn_deg(quarter_deg: int, extra_deg: float) -> float:
    """A copy's turn in degrees: whole quarter turns stay ints (as every axis-aligned family
    records them), other turns are rounded to a thousandth of a degree."""
    if extra_deg == 0.0:
        return quarter_deg
    return round((quarter_deg + extra_deg) % 360.0, 3)


def _check_noise(noise: bool | None) -> None:
    if noise is not None and not isinstance(noise, (bool, np.bool_)):
        raise WorldError(f"option 'noise' must be true, false or left out, got {noise!r}")


# --------------------------------------------------------------------------------------------
# the families

_LAYOUTS: dict[str, Callable[..., _Floor]] = {
    "corridor": _corridor,
    "hall": _hall,
    "wings": _wings,
}


def paper_like(
    rng: np.random.Generator, resolution_m: float = 0.05, noise: bool | None = None
) -> World:
    """A floor with one room (or furniture group) repeated cell for cell in 2 to 4 copies.

    Draws, in order: the layout (corridor 35 %, hall 25 %, two wings 20 %, open plan 20 %),
    the number of copies (2, 3, 4), the repeated room (interior 3-12 m wide, 3-7 m deep,
    furnished by :mod:`~mrexplore.world.generators`' desks, cupboards and tables), whether the
    copies' doors sit at different offsets (30 %), other rooms, clutter (40 %), the turn of the
    whole floor (0-3 quarter turns), and real-map noise (25 %, from a stream of its own, so a
    world with ``noise=False`` has the same layout as with noise).

    Args:
        rng: the only source of randomness.
        resolution_m: metres per cell (0.05 by default; at most 0.25).
        noise: force real-map noise on (True) or off (False); None: drawn.

    Returns:
        A :class:`World` with the module doc's ``meta``.

    Raises:
        WorldError: a bad option, or no valid floor after many draws (not seen in practice).
    """
    _check_noise(noise)
    p = _params(resolution_m, GeneratorOptions())
    layout_rng, noise_rng = rng.spawn(2)
    r = layout_rng
    for attempt in range(1, _MAX_ATTEMPTS + 1):
        layout = str(r.choice(["corridor", "hall", "wings", "open_plan"], p=[0.35, 0.25, 0.2, 0.2]))
        n = int(r.choice([2, 3, 4], p=[0.45, 0.35, 0.2]))
        tw, th = _m(r, *REPEATED_WIDTH_M, p), _m(r, *ROOM_DEPTH_M, p)
        vary = bool(r.random() < 0.3)
        draw = _Draw(bool(r.random() < 0.4), bool(r.random() < 0.25), int(r.integers(4)))
        try:
            if layout == "open_plan":
                f = _open_plan(r, p, n, tw, th)
                differ = False
            else:
                tpls, differ = _copy_templates(r, p, tw, th, n, vary)
                f = _LAYOUTS[layout](r, p, tpls, tw, th)
        except _Retry:
            continue
        facts = {"doors_differ": differ, "repeated_size_m": (tw * p.res, th * p.res)}
        if layout == "open_plan":
            facts["repeated_size_m"] = None
        d = replace(draw, noise=draw.noise if noise is None else bool(noise))
        w = _finish("paper_like", f, p, r, noise_rng, d, facts, attempt)
        if w is not None:
            return w
    raise WorldError(f"paper_like: no valid floor after {_MAX_ATTEMPTS} draws")


def office_row(
    rng: np.random.Generator, resolution_m: float = 0.05, noise: bool | None = None
) -> World:
    """Rows of identical offices along a corridor: 3 to 8 offices (2.5-4.5 m wide, 3-5.5 m
    deep) on one side; on the other side (40 %) a second row of identical offices (60 %) or
    other rooms. Clutter 40 %, noise 25 %, the floor turned by 0-3 quarter turns.

    Args, returns and errors as :func:`paper_like`.
    """
    _check_noise(noise)
    p = _params(resolution_m, GeneratorOptions())
    z = _Sizes.of(p)
    layout_rng, noise_rng = rng.spawn(2)
    r = layout_rng
    for attempt in range(1, _MAX_ATTEMPTS + 1):
        n = int(r.integers(3, 9))
        most_m = (MAX_LONG_M - 1.0) / n - 2 * p.t * p.res
        if most_m < 2.5:
            continue
        ow, od = _m(r, 2.5, min(4.5, most_m), p), _m(r, 3.0, 5.5, p)
        vary = bool(r.random() < 0.3)
        draw = _Draw(bool(r.random() < 0.4), bool(r.random() < 0.25), int(r.integers(4)))
        both = bool(r.random() < 0.4)
        n_south = int(r.integers(3, n + 1)) if both and r.random() < 0.6 else 0
        cw = _m(r, *CORRIDOR_M, p)
        fill = float(r.choice([0.0, 0.5, 0.9]))
        try:
            tpls, differ = _copy_templates(r, p, ow, od, n + n_south, vary)
            length = max(_need(n, ow, z.t), _need(n_south, ow, z.t)) + _m(r, 0.0, 4.0, p)
            rows: dict[str, tuple[list[Slot], int]] = {}
            north = _row(r, p, length, list(enumerate(tpls[:n])), ow, od, fill)
            if north is not None:
                rows["n"] = north
            if both:
                south_copies = [(n + k, tpls[n + k]) for k in range(n_south)]
                depth = od if n_south else _m(r, *ROOM_DEPTH_M, p)
                south = _row(r, p, length, south_copies, ow, depth, 0.9 if not n_south else fill)
                if south is not None:
                    rows["s"] = south
            walls, hall, placed = hall_floor(Hall(length, cw, rows), z.t)
        except _Retry:
            continue
        f = _Floor(walls, hall, placed, [hall], {"layout": "office_row"})
        facts = {"doors_differ": differ, "repeated_size_m": (ow * p.res, od * p.res)}
        d = replace(draw, noise=draw.noise if noise is None else bool(noise))
        w = _finish("office_row", f, p, r, noise_rng, d, facts, attempt)
        if w is not None:
            return w
    raise WorldError(f"office_row: no valid floor after {_MAX_ATTEMPTS} draws")


def radial(
    rng: np.random.Generator, resolution_m: float = 0.05, noise: bool | None = None
) -> World:
    """A floor the same under a turn: 2 to 6 identical wings (equally likely) round a round
    central hall, one every ``360 / n`` degrees, each a corridor with copies of one furnished
    room (2.5-4.5 m wide, 2.5-4.5 m deep; 1-4 a wing, 1-3 with 4 wings, 1-2 with 5 or 6) on one
    or both of its sides.
    Which copy a robot stands in cannot be told from its map until it has seen beyond its wing
    (the hall's clutter, when drawn, is the only thing that tells the wings apart). Clutter in
    the hall 40 %, noise 25 %, the floor turned by 0-3 quarter turns.

    Args, returns and errors as :func:`paper_like`; ``meta["copies"]`` boxes of wings turned by
    other than quarter turns are the turned rooms' bounding boxes.
    """
    _check_noise(noise)
    p = _params(resolution_m, GeneratorOptions())
    layout_rng, noise_rng = rng.spawn(2)
    r = layout_rng
    n = int(r.choice(RADIAL_WINGS))  # drawn once: a large n must not be redrawn as a small one
    most = 4 if n <= 3 else 3 if n == 4 else 2
    for attempt in range(1, _MAX_ATTEMPTS + 1):
        per_wing = int(r.integers(1, most + 1))
        tw, th = _m(r, 2.5, 4.5, p), _m(r, 2.5, 4.5, p)
        vary = bool(r.random() < 0.3)
        draw = _Draw(bool(r.random() < 0.4), bool(r.random() < 0.25), int(r.integers(4)))
        try:
            tpls, differ = _copy_templates(r, p, tw, th, per_wing, vary)
            f = _radial_floor(r, p, n, tpls, tw, th)
        except _Retry:
            continue
        facts = {"doors_differ": differ, "repeated_size_m": (tw * p.res, th * p.res), "wings": n}
        d = replace(draw, noise=draw.noise if noise is None else bool(noise))
        w = _finish("radial", f, p, r, noise_rng, d, facts, attempt)
        if w is not None:
            return w
    raise WorldError(f"radial: no valid floor after {_MAX_ATTEMPTS} draws")


#: The families by name: ``generator(rng, resolution_m=0.05, noise=None) -> World``.
FAMILY_GENERATORS: dict[str, Callable[..., World]] = {
    "paper_like": paper_like,
    "office_row": office_row,
    "radial": radial,
}
#: Family names, sorted.
FAMILIES: tuple[str, ...] = tuple(sorted(FAMILY_GENERATORS))
