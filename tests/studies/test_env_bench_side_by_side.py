"""``mrexplore bench env --side-by-side``: single vs batched rows, on a tiny run (not timed)."""

from __future__ import annotations

import json
from pathlib import Path

import pytest

from mrexplore.cli import main
from mrexplore.errors import ConfigError


def test_side_by_side_prints_single_and_batched_rows_with_the_cores(
    tmp_path: Path,
    capsys,  # type: ignore[no-untyped-def]
) -> None:
    out_json = tmp_path / "s.json"
    args = ["bench", "env", "--side-by-side", "2", "--batched-only", "--rounds", "1"]
    args += ["--round-steps", "2", "--team", "random,coordinated-frontier"]
    assert main([*args, "--json", str(out_json)]) == 0
    out = capsys.readouterr().out
    assert "cores" in out and "load average" in out
    assert "thread CPU" in out and "process CPU" in out and "wall vs single" in out
    for team in ("random", "coordinated-frontier"):
        assert f"{team}, 2 single envs, each stepped alone" in out
        assert f"{team}, batched, 2 worlds, 1 thread" in out
    r = json.loads(out_json.read_text())["side by side, coordinated-frontier"]
    # every row: 1 round x 2 steps x 2 worlds x 2 robots
    assert r["num_envs"] == 2 and r["single"]["robot_steps"] == 8
    assert r["batched_1_thread"]["robot_steps"] == r["batched_threads"]["robot_steps"] == 8
    assert r["single"]["wall_ratio"] == 1.0
    assert all(r[k]["wall_s"] > 0 for k in ("single", "batched_1_thread", "batched_threads"))
    # worker processes with random actions only (a team's decisions need the robots' views)
    assert "batched_processes" not in r
    rnd = json.loads(out_json.read_text())["side by side, random"]
    procs = rnd["batched_processes"]
    assert procs["robot_steps"] == 8 and procs["process_s"] > procs["thread_s"] > 0
    assert f"random, batched, 2 worlds, {rnd['workers']} processes" in out


@pytest.mark.parametrize(
    ("extra", "names"),
    [
        (["--side-by-side", "0"], "side-by-side"),
        (["--side-by-side", "2", "--rounds", "0"], "rounds"),
        (["--side-by-side", "2", "--team", "no-such-team"], "team"),
    ],
)
def test_side_by_side_bad_options_name_themselves(extra: list[str], names: str) -> None:
    from mrexplore.studies.env_bench import main as env_main

    with pytest.raises(ConfigError, match=names):
        env_main(["--batched-only", *extra])
