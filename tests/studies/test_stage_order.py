"""``studies/stage_order.py``: the two orders sense the same worlds alike (so only their timing
differs), and the measurement returns a figure per order and round."""

from __future__ import annotations

import numpy as np

from tests.helpers import load_study


def test_the_orders_leave_the_same_maps() -> None:
    script = load_study("stage_order")
    a, b = script.stepped_sims(2, steps=3), script.stepped_sims(2, steps=3)
    script.orders(a, np.random.default_rng(1))["world-major"]()
    script.orders(b, np.random.default_rng(1))["stage-major"]()
    for sa, sb in zip(a, b, strict=True):
        for ma, mb in zip(sa.maps, sb.maps, strict=True):
            assert np.array_equal(ma.to_int8(), mb.to_int8())
        assert np.array_equal(sa.observed, sb.observed)


def test_a_figure_per_order_and_round() -> None:
    res = load_study("stage_order").measure(2, rounds=2)
    assert set(res) == {"world-major", "stage-major", "one world N times"}
    assert all(len(v) == 2 and min(v) > 0 for v in res.values())
