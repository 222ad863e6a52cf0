"""``mrexplore bench policies`` and ``mrexplore bench wrappers`` run end to end on tiny settings
and print their tables (figures, never asserted)."""

from __future__ import annotations

import pytest

from mrexplore.cli import main


def test_bench_policies_prints_a_row_per_policy(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "policies", "--worlds", "small_office", "--max-steps", "5"]) == 0
    out = capsys.readouterr().out
    for policy in ("nearest-frontier", "cost-frontier", "coordinated-frontier"):
        assert f"small_office      {policy}" in out


def test_bench_wrappers_prints_a_line_per_face(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["bench", "wrappers", "--world", "small_office", "--steps", "3"]) == 0
    out = capsys.readouterr().out
    assert "MapMergeWrapper" in out and "SingleRobotExploreEnv" in out
    assert out.count("ParallelEnvVecEnv") == 3
