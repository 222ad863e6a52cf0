"""The env's parts: an injected task, the old names that stay importable, option coercion."""

from __future__ import annotations

import warnings

import pytest

import mrexplore
from mrexplore.environment.task import Task
from mrexplore.errors import ConfigError
from mrexplore.sim import Simulation

SMALL = {"world": "small_office", "n_robots": 2, "merger": None}


class QuickTask(Task):
    """Done after three steps, one point per step: a task the env does not know."""

    name = "quick"

    def terminated(self, sim: Simulation, coverage: float) -> bool:
        return sim.steps >= 3

    def reward(self, gain: float, sim: Simulation, resolution_m: float) -> float:
        return 1.0


def test_an_injected_task_decides_reward_and_termination() -> None:
    task = QuickTask()
    penv = mrexplore.parallel_env(**SMALL, task=task)
    assert penv.task is task and task.config is penv.config
    penv.reset(seed=0)
    for k in range(3):
        _, rewards, terms, _, _ = penv.step({a: 3 for a in penv.agents})
        assert rewards["robot_0"] == 1.0
        assert terms["robot_0"] == (k == 2)
    assert penv.agents == []


def test_a_task_that_is_not_one_is_refused() -> None:
    with pytest.raises(ConfigError, match="option task must be 'explore' or 'navigate'"):
        mrexplore.parallel_env(**SMALL, task=object())


def test_the_old_kernel_switch_still_switches(monkeypatch: pytest.MonkeyPatch) -> None:
    from mrexplore import kernels, sensors

    monkeypatch.setattr(kernels, "USE_NUMBA", kernels.USE_NUMBA)  # restored afterwards
    with warnings.catch_warnings(record=True) as caught:
        warnings.simplefilter("always")
        sensors.USE_NUMBA = False
    assert kernels.USE_NUMBA is False and not kernels.enabled()
    assert any(issubclass(w.category, DeprecationWarning) for w in caught)


def test_an_int_given_for_a_float_option_is_stored_as_a_float() -> None:
    cfg = mrexplore.parallel_env(**SMALL, comm_range_m=5, max_range_m=4).config
    assert type(cfg.comm_range_m) is float and type(cfg.max_range_m) is float
    assert type(cfg.n_robots) is int


def test_an_injected_radio_and_viewer_are_used() -> None:
    import numpy as np

    from mrexplore.environment.radio import Radio

    class Deaf(Radio):
        """Nobody ever hears anybody."""

        def update_links(self, true_xy):  # type: ignore[no-untyped-def]
            self.links = np.zeros((len(self.agents), len(self.agents)), dtype=bool)
            return self.links

    seen = []
    penv = mrexplore.parallel_env(
        world="small_office",
        n_robots=2,
        merger=None,
        render_mode="rgb_array",
        radio=Deaf(["robot_0", "robot_1"]),
        viewer=lambda snap: seen.append(snap.time_s) or np.zeros((2, 2, 3), np.uint8),
    )
    penv.reset(seed=0)
    penv.step({a: 3 for a in penv.agents})
    assert penv.robot_view("robot_0").in_range == frozenset()
    assert penv.render().shape == (2, 2, 3) and seen == [0.25]
    with pytest.raises(ConfigError, match="radio: its agents"):
        mrexplore.parallel_env(**SMALL, radio=Radio(["a", "b"]))


def test_evaluate_false_changes_no_observation_reward_or_end() -> None:
    """The truth monitor only writes evaluation infos: without it the rollout is the same, the
    evaluation-only infos are -1.0 (nothing of the truth reaches a robot either way)."""
    import numpy as np

    opts = {"world": "small_office", "n_robots": 2, "merge_every": 5, "merge_latency_steps": 0}
    runs = []
    for evaluate in (True, False):
        penv = mrexplore.parallel_env(**opts, evaluate=evaluate)
        obs, infos = penv.reset(seed=4)
        rng = np.random.default_rng(4)
        trace = [np.concatenate([obs[a].ravel() for a in penv.agents])]
        for _ in range(60):
            obs, rew, term, trunc, infos = penv.step({a: int(rng.integers(4)) for a in penv.agents})
            trace.append(np.concatenate([obs[a].ravel() for a in sorted(obs)]))
            trace.append(np.array([rew["robot_0"], term["robot_0"], trunc["robot_0"]]))
            trace.append(np.array([infos["robot_0"]["coverage"], infos["robot_0"]["merged"]]))
        runs.append((trace, infos["robot_0"]))
    (with_truth, info_t), (without, info_f) = runs
    assert all(np.array_equal(x, y) for x, y in zip(with_truth, without, strict=True))
    for key in ("merge_error_cells", "fused_contradiction", "merged_wrongly_s"):
        assert info_f[key] == -1.0
    assert info_t["fused_contradiction"] >= 0.0
    with pytest.raises(ConfigError, match="evaluate=True"):
        mrexplore.parallel_env(**opts, evaluate=False, coverage_mode="held")


def test_a_stage_timer_is_told_every_stage_and_changes_nothing() -> None:
    import numpy as np

    from mrexplore.environment.parallel_env import STEP_STAGES

    told: list[tuple[str, float]] = []
    opts = {"world": "small_office", "n_robots": 2}
    timed = mrexplore.parallel_env(stage_timer=lambda s, sec: told.append((s, sec)), **opts)
    plain = mrexplore.parallel_env(**opts)
    runs = []
    for env in (timed, plain):
        obs, _ = env.reset(seed=3)
        rng = np.random.default_rng(0)
        trace = []
        for _ in range(6):
            obs, rew, _, _, infos = env.step({a: int(rng.integers(4)) for a in env.agents})
            trace.append((obs, rew, infos))
        runs.append(trace)
    for (o1, r1, i1), (o2, r2, i2) in zip(*runs, strict=True):
        assert r1 == r2 and i1 == i2
        assert all(np.array_equal(o1[a], o2[a]) for a in o1)
    assert [s for s, _ in told] == list(STEP_STAGES) * 6  # step()'s stages only, in order
    assert all(isinstance(sec, float) and sec >= 0.0 for _, sec in told)
    assert plain.stage_timer is None
    with pytest.raises(ConfigError, match="stage_timer"):
        mrexplore.parallel_env(stage_timer="yes", **opts)
