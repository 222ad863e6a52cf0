"""``studies/merge_timeline.py``: every in-loop merge attempt beside the truth; options checked at
the door, an existing output kept without ``--force``."""

from __future__ import annotations

import json
from pathlib import Path
from types import ModuleType

import pytest

from tests.helpers import load_study


def _script() -> ModuleType:
    return load_study("merge_timeline")


@pytest.mark.parametrize(
    "argv",
    [
        ["--worlds", "no_such_world"],
        ["--seeds", "0"],
        ["--merge-options", "min_comon_m2=10"],
        ["--env-options", "map_l_occ=0"],
        ["--truth-cells", "0"],
        ["--noise", "loud"],
        ["--replay", "min_common_m2=10"],
        ["--replay", "confirmations=0"],
        ["--replay", "confirmations=1", "--merge-options", "keep_run_on_refusal=true"],
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
    argv += ["--replay", "confirmations=1", "--replay", "confirm_tol_cells=4"]
    assert timeline.main([*argv, "--json", str(out)]) == 2
    assert out.read_text() == "keep me"
    assert timeline.main([*argv, "--json", str(out), "--force"]) == 0
    printed = capsys.readouterr().out
    assert "symmetric_office (1 episodes, 0 wrong): medians shared > 0" in printed
    assert "  evidence: the maps shared >= 10 m^2 under the truth in " in printed
    assert "replay of the run's own rule" in printed and "reproduces every first merge" in printed
    assert "symmetric_office, replayed {'confirmations': 1," in printed
    assert "'confirm_tol_cells': 4" in printed
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


def _attempt(t: float, T: object, **kw: object) -> dict[str, object]:
    rec: dict[str, object] = {"t_s": t, "T": T, "standing": 0, "thin": False}
    rec.update({"overlap_cells": 300, "box": [0, 100, 0, 100], "best_error_cells": 1.0, **kw})
    return rec


def test_replay_follows_the_trackers_confirmation_rule() -> None:
    """Two agreeing attempts merge; a refusal, a standing rival or too little wall breaks the
    run; an agreeing attempt on less evidence keeps the run without extending it; poses farther
    apart than the tolerance start a new run."""
    import numpy as np

    from mrexplore.merge.common import translation

    replay = _script().replay
    T0, T1, far = np.eye(3).tolist(), translation(1.0, 0.0).tolist(), translation(3.0, 0.0).tolist()

    def ep(*attempts: dict[str, object]) -> dict[str, object]:
        return {"attempts": list(attempts)}

    assert replay(ep(_attempt(1, T0), _attempt(2, T1))) == (2.0, 1.0)
    assert replay(ep(_attempt(1, T0), _attempt(2, T1)), confirmations=1) == (1.0, 1.0)
    assert replay(ep(_attempt(1, T0), _attempt(2, None), _attempt(3, T1))) == (None, None)
    assert replay(ep(_attempt(1, T0), _attempt(2, T1, standing=1))) == (None, None)
    assert replay(ep(_attempt(1, T0), _attempt(2, T1, thin=True))) == (None, None)
    thinner = _attempt(2, T1, overlap_cells=299)
    assert replay(ep(_attempt(1, T0), thinner, _attempt(3, T1))) == (3.0, 1.0)
    assert replay(ep(_attempt(1, T0), _attempt(2, far), _attempt(3, far))) == (3.0, 1.0)
    assert replay(ep(_attempt(1, T0), _attempt(2, far)), confirm_tol_cells=3.0) == (2.0, 1.0)
