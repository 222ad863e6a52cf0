"""``studies/speed_vs_checkout.py``: its settings, with and without ``--env-options``."""

from __future__ import annotations

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
