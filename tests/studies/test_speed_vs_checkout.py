"""``studies/speed_vs_checkout.py``: its settings, with and without ``--env-options``."""

from __future__ import annotations

from pathlib import Path

import pytest

from mrexplore.errors import ConfigError
from tests.helpers import load_study


def test_env_options_replace_the_table_per_team_size() -> None:
    script = load_study("speed_vs_checkout")
    plain = script.rows([2], "semantic", None)
    assert [opts["n_robots"] for _, opts in plain if "n_robots" in opts] == [2]
    text = "world=random:symmetric_office?width_m=10&height_m=8,obs_heading_up=true"
    table = script.rows([1, 2], None, text)
    assert [label for label, _ in table] == [f"1 robots, {text}", f"2 robots, {text}"]
    for n, (_, opts) in zip((1, 2), table, strict=True):
        assert opts == {
            "world": "random:symmetric_office?width_m=10&height_m=8",
            "obs_heading_up": True,
            "n_robots": n,
            "merger": None,
        }


def test_a_bad_env_option_is_named() -> None:
    script = load_study("speed_vs_checkout")
    with pytest.raises(ConfigError, match="--env-options"):
        script.rows([2], None, "obs_heading_up")


def test_the_rollout_takes_env_options() -> None:
    script = load_study("speed_vs_checkout")
    label, opts = script.rollout_setting("coordinated-frontier", "semantic", None)
    assert label == "coordinated-frontier, symmetric_office, 2 robots"
    assert opts["team"] == "coordinated-frontier" and opts["merger"] == "semantic"
    assert "n_robots" not in opts  # the env's default team
    label, opts = script.rollout_setting("coordinated-frontier", None, "n_robots=8")
    assert label == "coordinated-frontier, symmetric_office, 8 robots, n_robots=8"
    assert opts["n_robots"] == 8 and opts["merger"] is None
    with pytest.raises(ConfigError, match="--env-options"):
        script.rollout_setting("coordinated-frontier", None, "n_robots")


def test_the_rollout_summary_prints_the_merge_workers_ratio(
    capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    script = load_study("speed_vs_checkout")
    keys = ("process_ms", "thread_ms", "policy_ms", "env_ms", "policy_share", "p50_ms")
    keys += ("p99_ms", "max_ms", "max_over_p50", "max_policy_ms", "max_env_ms", "wall_ms")

    def row(process: float, merge: float) -> dict[str, dict[str, float]]:
        fields = {k: 1.0 for k in keys}
        fields.update(process_ms=process, merge_ms=merge, merge_attempts=3, merge_rechecks=1)
        return {"r": fields}

    runs = {"base": [row(4.0, 2.0), row(4.4, 2.2)], "this": [row(3.0, 1.0), row(3.3, 1.1)]}
    script._print_rollouts(runs, "r", 2, tmp_path, tmp_path)
    last = capsys.readouterr().out.strip().splitlines()[-1]
    assert last.endswith("process CPU 0.75x, policy 1.00x, merge worker 0.50x")
    for run in runs["base"]:  # a tree that does not report the merge worker
        del run["r"]["merge_ms"]
    script._print_rollouts(runs, "r", 2, tmp_path, tmp_path)
    assert capsys.readouterr().out.strip().endswith("process CPU 0.75x, policy 1.00x")
