"""``studies/step_split.py``: a figure per order and part, the kernels inside the step, and the
kernels put back afterwards."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import mrexplore.kernels.scoring as scoring
from tests.helpers import load_study


def test_a_figure_per_order_and_part_and_the_kernels_restored() -> None:
    script = load_study("step_split")
    before = scoring.score_region
    res = script.measure(2, rounds=2, steps=3)
    assert scoring.score_region is before
    assert set(res["us_per_world_step"]) == {"alone", "in turn"}
    for parts in res["us_per_world_step"].values():
        assert set(parts) == {"step", *script.KERNELS}
        assert parts["sensing"] > 0 and parts["views"] > 0
        assert sum(parts[k] for k in script.KERNELS) < parts["step"]


def test_the_mean_of_several_processes_figures() -> None:
    script = load_study("step_split")
    runs = [
        {"worlds": 1, "us_per_world_step": {"alone": {"step": a, "sensing": b}}}
        for a, b in ((10.0, 4.0), (20.0, 8.0))
    ]
    res = script.mean_of(runs)
    assert res["us_per_world_step"] == {"alone": {"step": 15.0, "sensing": 6.0}}
    assert res["processes"] == 2 and res["worlds"] == 1


def test_processes_at_once_print_the_mean_of_their_figures() -> None:
    script = Path(__file__).resolve().parents[2] / "studies" / "step_split.py"
    args = ["--worlds", "1", "--rounds", "1", "--steps", "2", "--processes", "2"]
    out = subprocess.run(
        [sys.executable, str(script), *args],
        check=True,
        capture_output=True,
        text=True,
    ).stdout.splitlines()
    assert "2 processes at once, their mean" in out[0]
    rows = {line.split()[0] + (" turn" if "turn" in line else ""): line for line in out[2:]}
    assert set(rows) == {"alone", "in turn"}
    for line in rows.values():
        step, sensing = (float(v) for v in line.split()[-6:-4])
        assert 0 < sensing < step
