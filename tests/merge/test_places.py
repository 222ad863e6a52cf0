"""Places: rooms and corridors cut at their narrow passages, and evidence beyond one of them."""

from __future__ import annotations

import numpy as np
import pytest

from mrexplore.grid import FREE, OCCUPIED, UNKNOWN
from mrexplore.merge import merge_maps
from mrexplore.merge.common import MapCodes, translation
from mrexplore.merge.places import beyond_places, segment_places

#: Twin room boxes of :func:`paper_floor` (first and last column of each, walls included).
TWIN_COLS = ((3, 130), (263, 390))


def paper_floor() -> np.ndarray:
    """The seed paper's scene, fully known (160 x 420 cells): a corridor along the bottom, two
    cell-for-cell identical rooms above it (table, cupboard, bench, a door at the same offset),
    a different room between them and a narrow one at the end, two objects in the corridor."""
    m = np.full((160, 420), FREE, np.int8)
    m[:3, :] = m[-3:, :] = m[:, :3] = m[:, -3:] = OCCUPIED
    m[97:100, :] = OCCUPIED  # rooms (rows 3-96) above, corridor (rows 100-156) below
    for c0, _ in TWIN_COLS:
        m[3:100, c0 + 124 : c0 + 127] = OCCUPIED
        m[3:100, c0 : c0 + 3] = OCCUPIED
        m[97:100, c0 + 20 : c0 + 40] = FREE  # door
        m[40:55, c0 + 40 : c0 + 70] = OCCUPIED  # table
        m[6:14, c0 + 90 : c0 + 118] = OCCUPIED  # cupboard
        m[80:86, c0 + 80 : c0 + 110] = OCCUPIED  # bench
    m[30:34, 150:240] = OCCUPIED  # the middle room differs
    m[97:100, 200:218] = FREE
    m[120:126, 60:66] = OCCUPIED
    m[130:136, 330:340] = OCCUPIED
    return m


def seen(m: np.ndarray, *boxes: tuple[int, int, int, int]) -> np.ndarray:
    """``m`` known only inside the boxes (r0, r1, c0, c1), unknown elsewhere."""
    out = np.full(m.shape, UNKNOWN, np.int8)
    for r0, r1, c0, c1 in boxes:
        out[r0:r1, c0:c1] = m[r0:r1, c0:c1]
    return out


def test_rooms_and_corridor_are_places_and_furniture_is_not() -> None:
    m = paper_floor()
    places = segment_places(m)
    labels = places.labels
    room_1, room_2 = labels[25, 20], labels[25, 283]
    corridor = labels[110, 150]
    assert len({room_1, room_2, corridor}) == 3 and 0 not in (room_1, room_2, corridor)
    # the floor around the table and beside the bench belongs to the room (wide openings)
    assert labels[60, 60] == room_1 and labels[90, 75] == room_1 and labels[70, 110] == room_1
    assert (labels[m == OCCUPIED] == 0).all()


def test_places_do_not_depend_on_the_scale() -> None:
    m = paper_floor()
    small = segment_places(m[:, :265])
    large = segment_places(np.kron(m[:, :265], np.ones((2, 2), np.int8)))
    assert small.count == large.count
    assert np.allclose(large.peaks[1:], 2 * small.peaks[1:], rtol=0.2)


def test_nothing_free_is_no_place() -> None:
    places = segment_places(np.full((20, 30), UNKNOWN, np.int8))
    assert places.count == 0 and not places.labels.any()


def test_a_twin_room_on_its_twin_is_not_pinned_beyond_the_room() -> None:
    m = paper_floor()
    (a0, a1), (b0, b1) = TWIN_COLS
    # each robot saw its own room and the corridor in front of its door
    a = seen(m, (0, 100, a0, a1), (97, 130, a0 + 10, a0 + 60))
    b = seen(m, (0, 100, b0, b1), (97, 130, b0 + 10, b0 + 60))
    wrong = translation(a0 - b0, 0)  # b's room laid on a's: they agree cell for cell
    support_a, support_b = beyond_places(a, b, MapCodes(a), MapCodes(b), wrong)
    assert max(support_a, support_b) < 10.0


def test_agreement_in_a_second_place_pins_the_pose() -> None:
    m = paper_floor()
    a = seen(m, (0, 158, 0, 200))  # room 1, the middle room's edge, the corridor's end
    b = seen(m, (40, 158, 0, 160))
    support_a, support_b = beyond_places(a, b, MapCodes(a), MapCodes(b), translation(0, 0))
    assert min(support_a, support_b) > 50.0


@pytest.mark.parametrize("place_test", [True, False])
def test_the_merger_waits_while_the_evidence_lies_in_one_room(place_test: bool) -> None:
    m = paper_floor()
    (a0, a1), (b0, b1) = TWIN_COLS
    a = seen(m, (0, 100, a0, a1), (97, 130, a0 + 10, a0 + 60))
    b = seen(m, (0, 100, b0, b1), (97, 130, b0 + 10, b0 + 60))
    res = merge_maps(a, b, place_test=place_test, room_match_m2=0.0)
    if place_test:
        assert not res.matched and "twin" in res.reason
    else:  # without the test, nothing else stops it: the twin is merged, 260 cells off
        assert res.matched and res.transform is not None
        assert abs(res.transform[0, 2] - (a0 - b0)) < 2
