"""``studies/step_split.py``: a figure per order and part, the kernels inside the step, and the
kernels put back afterwards."""

from __future__ import annotations

import mrexplore.kernels.scoring as scoring
from tests.helpers import load_study


def test_a_figure_per_order_and_part_and_the_kernels_restored() -> None:
    script = load_study("step_split")
    before = scoring.score_region
    res = script.measure(2, rounds=2, steps=3)
    assert scoring.score_region is before
    assert set(res["us_per_world_step"]) == {"alone", "in turn"}
    for parts in res["us_per_world_step"].values():
        assert set(parts) == {"step", *script.KERNELS}
        assert parts["sensing"] > 0 and parts["views"] > 0
        assert sum(parts[k] for k in script.KERNELS) < parts["step"]
