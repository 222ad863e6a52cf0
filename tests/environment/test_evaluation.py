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


def test_compiled_merge_errors_equal_the_numpy_path(monkeypatch: pytest.MonkeyPatch) -> None:
    """The compiled sampling of a pair's merge error gives the numpy path's figures bit for
    bit: on the maps of a noisy rollout, for the true transform and for wrong ones."""
    import numpy as np

    import mrexplore
    from mrexplore import kernels
    from mrexplore.grid import chain, make_transform

    if not kernels.HAVE_NUMBA:
        pytest.skip("numba not installed")
    env = mrexplore.parallel_env(
        world="small_office", n_robots=3, odom_noise_trans=0.02, odom_noise_rot=0.01
    )
    env.reset(seed=5)
    rng = np.random.default_rng(0)
    checked = 0
    for step in range(120):
        env.step({a: int(rng.integers(4)) for a in env.agents})
        if step % 20 != 19:
            continue
        monitor = env.episode.truth
        sim = env.episode.sim
        for i in range(3):
            for j in range(3):
                if i == j:
                    continue
                T_true = sim.true_transform(i, j)
                wrong = chain(make_transform(0.3, 7.5, -3.25), T_true)
                for T in (T_true, wrong):
                    figures = []
                    for use in (True, False):
                        monkeypatch.setattr(kernels, "USE_NUMBA", use)
                        monitor._errors.clear()
                        figures.append(monitor._pair_error(i, j, T))
                    assert figures[0] == figures[1]
                    assert figures[0] is not None
                    checked += 1
    assert checked == 6 * 6 * 2
