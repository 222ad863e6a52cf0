"""The truth monitor's bookkeeping (evaluation only)."""

from __future__ import annotations

import pytest

from mrexplore.environment.evaluation import ERROR_REFRESH_STEPS, TruthMonitor


@pytest.mark.parametrize("n", [2, 3, 4, 8])
def test_merge_error_refreshes_spread_over_the_period(n: int) -> None:
    """Each ordered pair refreshes its merge error on its own phase, spread evenly, so the
    pairs' refreshes do not pile up in one step."""
    monitor = TruthMonitor.__new__(TruthMonitor)  # the phase needs only the agents
    monitor.agents = [f"robot_{k}" for k in range(n)]
    pairs = [(i, j) for i in range(n) for j in range(n) if i != j]
    phases = [monitor._refresh_phase(i, j) for i, j in pairs]
    assert all(0 <= p < ERROR_REFRESH_STEPS for p in phases)
    per_step = [phases.count(p) for p in range(ERROR_REFRESH_STEPS)]
    assert max(per_step) == -(-len(pairs) // ERROR_REFRESH_STEPS)  # as even as it can be
    if n == 2:
        assert phases == [0, ERROR_REFRESH_STEPS // 2]
