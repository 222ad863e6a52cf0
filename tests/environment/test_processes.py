"""The batched env in worker processes (``vector_env(num_workers=...)``): the same run as the
batched env on one thread, bit for bit; bad input at the door; errors of a worker raised."""

from __future__ import annotations

import subprocess
import sys
from typing import Any

import numpy as np
import pytest

import mrexplore
from mrexplore.environment.batched import BatchedExploreEnv
from mrexplore.environment.processes import ProcessBatchedEnv, _blocks
from mrexplore.errors import ConfigError, MrexploreError
from tests.helpers import assert_same

WORLD = "small_office"


def _same_infos(a: dict[str, Any], b: dict[str, Any], where: str) -> None:
    assert sorted(a) == sorted(b), where
    for key, v in b.items():
        if key == "final_obs":
            for x, y in zip(a[key], v, strict=True):
                assert (x is None and y is None) or np.array_equal(x, y), f"{where} {key}"
        elif key == "final_info":
            _same_infos(a[key], v, f"{where} final")
        else:
            assert a[key].dtype == v.dtype, f"{where} {key}"
            assert_same(a[key], v, f"{where} {key}")


def test_worker_processes_give_the_run_of_one_thread_bit_for_bit() -> None:
    """5 worlds in 2 workers (blocks of 3 and 2), merging on, random actions over several
    episodes: observations, rewards, flags and infos (final ones of the auto-resets too) equal
    the one-thread batched env's at every step."""
    n, seed = 5, 11
    opts = {
        "world": WORLD,
        "n_robots": 2,
        "max_cycles": 40,
        "merge_every": 5,
        "merge_options": {"place_test": False},
    }
    procs = mrexplore.vector_env(num_envs=n, num_workers=2, **opts)
    assert isinstance(procs, ProcessBatchedEnv) and procs.worker_sizes == [3, 2]
    ref = BatchedExploreEnv(n, num_threads=1, **opts)
    try:
        obs, infos = procs.reset(seed=seed)
        r_obs, r_infos = ref.reset(seed=seed)
        np.testing.assert_array_equal(obs, r_obs)
        _same_infos(infos, r_infos, "reset")
        rng = np.random.default_rng(0)
        resets = 0
        scored = False
        for t in range(100):
            act = rng.integers(0, 4, size=(n, 2))
            out, r_out = procs.step(act), ref.step(act)
            for x, y in zip(out[:4], r_out[:4], strict=True):
                np.testing.assert_array_equal(x, y, err_msg=f"step {t}")
            _same_infos(out[4], r_out[4], f"step {t}")
            resets += int(np.sum(r_out[4].get("_final_obs", 0)))
            scored |= bool((r_out[4]["score"] != -1.0).any())
        assert resets >= n  # auto-resets were exercised, in both workers
        assert scored  # merge attempts ran and reached the infos
        # seed=None goes on with each world's own stream, as the batched env does
        np.testing.assert_array_equal(procs.reset()[0], ref.reset()[0])
    finally:
        procs.close()
        ref.close()
    procs.close()  # closing twice is harmless


def test_blocks_are_contiguous_and_even() -> None:
    assert _blocks(5, 2) == [(0, 3), (3, 2)]
    assert _blocks(4, 4) == [(0, 1), (1, 1), (2, 1), (3, 1)]
    assert _blocks(32, 3) == [(0, 11), (11, 11), (22, 10)]


@pytest.mark.parametrize("bad", [0, -1, 1.5, True, "2"])
def test_bad_num_workers_is_a_config_error_naming_it(bad: Any) -> None:
    with pytest.raises(ConfigError, match="num_workers"):
        mrexplore.vector_env(num_envs=2, world=WORLD, num_workers=bad)


def test_bad_options_are_refused_before_any_worker_starts() -> None:
    with pytest.raises(ConfigError, match="no_such_option"):
        mrexplore.vector_env(num_envs=2, world=WORLD, num_workers=2, no_such_option=1)
    with pytest.raises(ConfigError, match="num_threads and num_workers"):
        mrexplore.vector_env(num_envs=2, world=WORLD, num_workers=2, num_threads=2)
    with pytest.raises(ConfigError, match="num_workers is for teams"):
        mrexplore.vector_env(num_envs=2, world=WORLD, n_robots=1, num_workers=2)

    class LocalMerger:  # a class inside a function does not pickle
        def merge(self, a: Any, b: Any) -> Any:
            raise AssertionError("never called")

    with pytest.raises(ConfigError, match="must pickle"):
        mrexplore.vector_env(num_envs=2, world=WORLD, num_workers=2, merger=LocalMerger())


def test_what_a_process_cannot_do_says_so() -> None:
    venv = mrexplore.vector_env(num_envs=2, world=WORLD, max_cycles=3, num_workers=2)
    try:
        assert venv.num_workers == 2
        with pytest.raises(ConfigError, match="map_worlds"):
            venv.map_worlds(lambda k, env: k)
        with pytest.raises(AttributeError, match="worker processes"):
            _ = venv.envs
        with pytest.raises(RuntimeError, match="before reset"):
            venv.step(np.zeros((2, 2), dtype=np.int64))
        venv.reset(seed=0)
        with pytest.raises(ValueError, match="shape"):
            venv.step(np.zeros((3, 2), dtype=np.int64))
        assert venv.worker_cpu_s() > 0.0
        with pytest.raises(RuntimeError, match="unknown command"):  # a worker's error, raised
            venv._all("no-such-command", [None, None])
        venv.step(np.zeros((2, 2), dtype=np.int64))  # the workers go on after it
    finally:
        venv.close()
    with pytest.raises(RuntimeError, match="closed"):
        venv.reset(seed=0)


def test_a_script_without_the_main_guard_is_told_what_to_do(tmp_path: Any) -> None:
    script = tmp_path / "unguarded.py"
    script.write_text(
        "import mrexplore\n"
        f"venv = mrexplore.vector_env(num_envs=2, world={WORLD!r}, max_cycles=3, num_workers=2)\n"
        "venv.close()\n"
    )
    run = subprocess.run([sys.executable, str(script)], capture_output=True, text=True)
    assert run.returncode != 0
    last = run.stderr.strip().splitlines()[-1]
    assert last.startswith("mrexplore.errors.MrexploreError: a worker process died"), last
    assert 'if __name__ == "__main__":' in last


def test_a_worker_killed_mid_run_is_a_clear_error() -> None:
    venv = mrexplore.vector_env(num_envs=2, world=WORLD, max_cycles=3, num_workers=2)
    try:
        venv.reset(seed=0)
        venv._procs[0].kill()
        venv._procs[0].join()
        with pytest.raises(MrexploreError, match=r"a worker process died \(exit code -9\)$"):
            venv.step(np.zeros((2, 2), dtype=np.int64))
    finally:
        venv.close()
