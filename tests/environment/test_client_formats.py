"""What every RL client needs from the env: observation layouts and dtypes, flat fixed infos,
plain pickling, and RLlib's ``render(mode)`` call."""

from __future__ import annotations

import pickle
from typing import Any

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test

import mrexplore
from mrexplore.environment.infos import INFO_KEYS, UNKNOWN_INFO
from mrexplore.errors import ConfigError

SMALL: dict[str, Any] = {"world": "small_office", "max_time_s": 60.0}


def _run(steps: int, seed: int = 0, **options: Any) -> list[dict[str, np.ndarray]]:
    penv = mrexplore.parallel_env(**{**SMALL, **options})
    obs, _ = penv.reset(seed=seed)
    rng = np.random.default_rng(1)
    out = [obs]
    for _ in range(steps):
        obs, *_ = penv.step({a: int(rng.integers(4)) for a in penv.agents})
        out.append(obs)
    return out


@pytest.mark.parametrize(
    ("layout", "dtype", "shape", "np_dtype", "high"),
    [
        ("chw", "uint8", (8, 64, 64), np.uint8, 255),
        ("hwc", "uint8", (64, 64, 8), np.uint8, 255),
        ("chw", "float32", (8, 64, 64), np.float32, 1.0),
        ("hwc", "float32", (64, 64, 8), np.float32, 1.0),
    ],
)
def test_layouts_and_dtypes_are_the_default_observation_rearranged(
    layout: str, dtype: str, shape: tuple[int, ...], np_dtype: type, high: float
) -> None:
    penv = mrexplore.parallel_env(**SMALL, obs_layout=layout, obs_dtype=dtype)
    space = penv.observation_space("robot_0")
    assert space.shape == shape and space.dtype == np_dtype and float(space.high.max()) == high
    ref = _run(30)
    got = _run(30, obs_layout=layout, obs_dtype=dtype)
    for r, g in zip(ref, got, strict=True):
        for a in r:
            assert space.contains(g[a])
            expect = r[a] if layout == "chw" else r[a].transpose(1, 2, 0)
            if dtype == "float32":
                expect = expect.astype(np.float32) / 255.0
            np.testing.assert_array_equal(g[a], expect)
            assert g[a].flags.c_contiguous
    # the state stacks robots on the channel axis, first or last
    penv.reset(seed=0)
    state = penv.state()
    assert penv.state_space.contains(state)
    assert state.shape == ((16, 64, 64) if layout == "chw" else (64, 64, 16))


def test_a_full_white_pixel_is_exactly_one_in_float32() -> None:
    # 255 / 255 must be 1.0, not 1.0000001 (outside the Box [0, 1]).
    penv = mrexplore.parallel_env(**SMALL, obs_dtype="float32")
    obs, _ = penv.reset(seed=0)
    assert float(obs["robot_0"].max()) == 1.0  # the robot disk is 255 in the default format


def test_float_layout_passes_the_pettingzoo_api_test() -> None:
    parallel_api_test(
        mrexplore.parallel_env(**SMALL, obs_layout="hwc", obs_dtype="float32"), num_cycles=50
    )


@pytest.mark.parametrize(
    ("option", "value", "words"),
    [
        ("obs_layout", "HWC", "obs_layout must be 'chw'"),
        ("obs_layout", "nhwc", "RLlib"),
        ("obs_dtype", "float64", "obs_dtype must be 'uint8'"),
        ("obs_dtype", np.float32, "obs_dtype"),
        ("info_extra", "yes", "info_extra must be True or False"),
    ],
)
def test_bad_format_options_are_refused_at_construction(
    option: str, value: Any, words: str
) -> None:
    with pytest.raises(ConfigError, match=words):
        mrexplore.parallel_env(**SMALL, **{option: value})


def _check_info(info: dict[str, Any], extra: bool = False) -> None:
    keys = (*INFO_KEYS, "extra") if extra else INFO_KEYS
    assert tuple(info) == keys
    for k in INFO_KEYS:
        v = info[k]
        assert type(v) in (bool, int, float), (k, v)  # plain numbers: one dtype per key
        assert v == v, (k, "NaN compares unequal to itself: checkers take it as non-determinism")
        if type(v) is float:
            assert v >= 0.0 or v == UNKNOWN_INFO, (k, v)


@pytest.mark.parametrize("task", ["explore", "navigate"])
def test_infos_have_the_same_flat_numeric_keys_on_every_step(task: str) -> None:
    penv = mrexplore.parallel_env(**SMALL, task=task, n_robots=2, max_cycles=60)
    _, infos = penv.reset(seed=2)
    for i in infos.values():
        _check_info(i)
        assert i["score"] == UNKNOWN_INFO and i["merge_error_cells"] == UNKNOWN_INFO
        assert i["collided"] is False and i["TimeLimit.truncated"] is False
    rng = np.random.default_rng(0)
    seen_types: dict[str, set[type]] = {k: set() for k in INFO_KEYS}
    while penv.agents:
        _, _, _, truncs, infos = penv.step({a: int(rng.integers(4)) for a in penv.agents})
        for a, i in infos.items():
            _check_info(i)
            assert i["TimeLimit.truncated"] is truncs[a]
            for k in INFO_KEYS:
                seen_types[k].add(type(i[k]))
    # one Python type per key over the whole episode (merged or not, truncated or not)
    assert all(len(t) == 1 for t in seen_types.values()), seen_types


def test_merge_error_fields_once_merged_and_extra_on_request() -> None:
    from mrexplore.environment.infos import merge_error_of
    from mrexplore.studies.oracle import OracleMerger

    oracle = OracleMerger()  # the true transform through the tracker: merged after 2.5 s
    penv = mrexplore.parallel_env(**SMALL, info_extra=True, merger=oracle)
    oracle.bind(penv)
    _, infos = penv.reset(seed=0)
    _check_info(infos["robot_0"], extra=True)
    assert infos["robot_0"]["extra"]["merge_error"] is None
    rng = np.random.default_rng(5)
    while penv.agents and not infos["robot_0"]["merged"]:
        acts = {a: int(rng.choice(4, p=[0.7, 0.15, 0.15, 0.0])) for a in penv.agents}
        _, _, _, _, infos = penv.step(acts)
        _check_info(infos["robot_0"], extra=True)
    i = infos["robot_0"]
    assert i["merged"], "the oracle should merge within the episode"
    assert 0.0 <= i["score"] <= 1.0 and i["first_merge_time_s"] >= 0.0
    assert i["merge_error_cells"] >= 0.0 and i["merge_error_deg"] >= 0.0
    # the flat keys and the nested extra agree
    assert i["extra"]["merge_error"] == merge_error_of(i)
    assert set(i["extra"]["merge_errors"]) == {"robot_1"}


def test_plain_pickle_round_trips_a_running_env() -> None:
    penv = mrexplore.parallel_env(**SMALL, render_mode="rgb_array")
    fresh = pickle.loads(pickle.dumps(penv))
    assert fresh.possible_agents == penv.possible_agents
    penv.reset(seed=4)
    for _ in range(20):
        penv.step({a: 0 for a in penv.agents})
    penv.render()
    copy = pickle.loads(pickle.dumps(penv))
    rng = np.random.default_rng(9)
    for _ in range(30):
        acts = {a: int(rng.integers(4)) for a in penv.agents}
        o1, r1, t1, u1, i1 = penv.step(acts)
        o2, r2, t2, u2, i2 = copy.step(acts)
        assert all(np.array_equal(o1[a], o2[a]) for a in o1)
        assert (r1, t1, u1, i1) == (r2, t2, u2, i2)


def test_human_mode_env_pickles_without_its_window() -> None:
    penv = mrexplore.parallel_env(**SMALL, render_mode="human")
    assert penv.window is not None
    penv.window._figure = (lambda: None, None)  # stands for a matplotlib window: not picklable
    copy = pickle.loads(pickle.dumps(penv))
    assert copy.window is not None and copy.window._figure is None
    assert penv.window._figure is not None


def test_render_accepts_rllibs_positional_mode_and_nothing_else() -> None:
    penv = mrexplore.parallel_env(**SMALL, render_mode="rgb_array")
    penv.reset(seed=0)
    assert penv.render(None).shape == penv.render().shape  # RLlib passes its own None
    assert penv.render("rgb_array").ndim == 3
    with pytest.raises(ConfigError, match="render mode is set when the env is built"):
        penv.render("human")
