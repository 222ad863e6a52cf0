"""The episode runner's bookkeeping of map quality (evaluation only)."""

from __future__ import annotations

from mrexplore.experiments.episode import _MapQuality


def _infos(*merged: bool) -> dict[str, dict[str, object]]:
    none = {"merge_error_cells": -1.0, "merge_error_deg": -1.0, "merge_error_drift_cells": -1.0}
    return {f"robot_{k}": {"merged": m, **none} for k, m in enumerate(merged)}


def test_merges_lost_counts_each_drop_of_each_robot() -> None:
    q = _MapQuality()
    assert q.merges_lost == 0
    for step in [(False, False), (True, True), (True, True), (False, False), (True, False)]:
        q.add(_infos(*step))
    assert q.merges_lost == 1  # both dropped once; robot_0 merged again and still is
    q.add(_infos(False, False))
    assert q.merges_lost == 2  # robot_0 lost its merge a second time
    q.add(_infos(False, False))
    assert q.merges_lost == 2  # staying unmerged is not a new loss
