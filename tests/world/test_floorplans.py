"""Floor-plan primitives: boxes follow np.rot90, rows face the hall, rooms land where recorded."""

from __future__ import annotations

import numpy as np
import pytest

from mrexplore.world.floorplans import SIDE_TURNS, Hall, Slot, build_row, hall_floor, rotate_box


@pytest.mark.parametrize("k", range(4))
@pytest.mark.parametrize(
    "box",
    [
        (0, 0, 1, 1),  # the corner cell
        (2, 1, 3, 2),  # a box inside
        (4, 3, 3, 2),  # touching the far corner
    ],
)
def test_rotate_box_follows_rot90(box: tuple[int, int, int, int], k: int) -> None:
    a = np.zeros((5, 7), dtype=bool)
    c, r, w, h = box
    a[r : r + h, c : c + w] = True
    rot = np.rot90(a, k)
    c2, r2, w2, h2 = rotate_box(box, a.shape, k)
    expect = np.zeros_like(rot)
    expect[r2 : r2 + h2, c2 : c2 + w2] = True
    np.testing.assert_array_equal(rot, expect)


def _room(width: int, depth: int, t: int, door: int) -> np.ndarray:
    tpl = np.ones((depth + 2 * t, width + 2 * t), dtype=bool)
    tpl[t:-t, t:-t] = False
    tpl[:t, t + door : t + door + 2] = False  # door in the bottom wall
    tpl[t + 1, t + 1] = True  # a marker in one corner, so turns show
    return tpl


def test_build_row_shares_walls() -> None:
    t = 1
    slots = [Slot(4, 3, _room(4, 3, t, 1), 0), Slot(2, 2, None), Slot(4, 3, _room(4, 3, t, 1), 1)]
    sub, boxes = build_row(slots, t)
    assert sub.shape == (3 + 2 * t, 4 + 2 + 4 + 2 * t + 2 * t)
    assert boxes == [(0, 0, 6, 5), (5, 0, 4, 4), (8, 0, 6, 5)]
    assert sub[:, 5:9].all()  # the solid slot, with the walls either side


@pytest.mark.parametrize("side", list(SIDE_TURNS))
def test_rooms_on_every_side_open_onto_the_hall(side: str) -> None:
    t = 1
    tpl = _room(4, 3, t, 1)
    hall = Hall(8, 6, {side: ([Slot(4, 3, tpl, 0)], 1)})
    floor, (hc, hr, hw, hh), placed = hall_floor(hall, t)
    assert not floor[hr : hr + hh, hc : hc + hw].any()
    assert floor[0].all() and floor[-1].all() and floor[:, 0].all() and floor[:, -1].all()
    (room,) = placed
    assert room.turns == SIDE_TURNS[side]
    c, r, w, h = room.box
    np.testing.assert_array_equal(floor[r : r + h, c : c + w], np.rot90(tpl, room.turns))
    # the door cells touch the hall: free cells of the room's box next to a hall cell
    grow = np.zeros_like(floor)
    grow[hr - 1 : hr + hh + 1, hc - 1 : hc + hw + 1] = True
    box = np.zeros_like(floor)
    box[r : r + h, c : c + w] = True
    assert (~floor & box & grow).sum() == 2 * t
