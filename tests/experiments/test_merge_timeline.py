"""``scripts/merge_timeline.py``: every in-loop merge attempt beside the truth; options checked at
the door, an existing output kept without ``--force``."""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType

import pytest

from tests.helpers import load_script


def _script() -> ModuleType:
    return load_script("merge_timeline")


@pytest.mark.parametrize(
    "argv",
    [
        ["--worlds", "no_such_world"],
        ["--seeds", "0"],
        ["--merge-options", "min_comon_m2=10"],
        ["--env-options", "map_l_occ=0"],
        ["--truth-cells", "0"],
    ],
)
def test_bad_options_fail_at_the_door(argv: list[str], capsys: pytest.CaptureFixture[str]) -> None:
    assert _script().main(argv) == 2
    assert "error" in capsys.readouterr().err


def test_logs_attempts_with_the_truth_and_keeps_an_existing_output(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    out = tmp_path / "t.json"
    out.write_text("keep me")
    timeline = _script()
    argv = ["--worlds", "symmetric_office", "--seeds", "1", "--max-time-s", "40"]
    assert timeline.main([*argv, "--json", str(out)]) == 2
    assert out.read_text() == "keep me"
    assert timeline.main([*argv, "--json", str(out), "--force"]) == 0
    printed = capsys.readouterr().out
    assert "symmetric_office (1 episodes, 0 wrong): medians shared > 0" in printed
    ep = json.loads(out.read_text())["episodes"][0]
    assert ep["attempts"], "a 40 s episode makes merge attempts"
    times = [a["t_s"] for a in ep["attempts"]]
    assert times == sorted(times) and all(a["pair"] == [0, 1] for a in ep["attempts"])
    assert all(a["shared_m2"] >= 0 and a["reason"] is not None for a in ep["attempts"])


def test_corner_error_is_the_largest_corner_displacement() -> None:
    import numpy as np

    from mrexplore.merge.common import translation

    err = _script().corner_error(np.eye(3), translation(3.0, 4.0), (0, 10, 0, 10))
    assert err == pytest.approx(5.0)
