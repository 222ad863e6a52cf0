"""``mrexplore merge a.yaml b.yaml -o out.yaml``: files in, files out, exit codes."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
from conftest import two_rooms

from mrexplore.errors import MapFileError
from mrexplore.experiments.merge_files import main, merge_files
from mrexplore.world.map_io import read_map_yaml, write_map_yaml


@pytest.fixture()
def files(tmp_path: Path, office_pair) -> tuple[Path, Path, Path]:  # type: ignore[no-untyped-def]
    a, b, _ = office_pair
    pa = write_map_yaml(tmp_path / "a.yaml", a, 0.05, (-1.0, 2.0, 0.0))
    pb = write_map_yaml(tmp_path / "b.yaml", b, 0.05)
    pc = write_map_yaml(tmp_path / "c.yaml", b, 0.10)
    return pa, pb, pc


def test_merge_writes_map_and_figure(files, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    pa, pb, _ = files
    out = tmp_path / "out" / "merged.yaml"
    assert main([str(pa), str(pb), "-o", str(out)]) == 0
    text = capsys.readouterr().out
    assert "score" in text and "rotation" in text
    merged = read_map_yaml(out)
    a = read_map_yaml(pa)
    assert out.with_suffix(".png").exists()
    # a's cells keep their world coordinates: origin shifted by the canvas offset
    res = merge_files(pa, pb, tmp_path / "again.yaml")
    dc, dr = res.offset
    np.testing.assert_allclose(merged.origin_m[:2], (-1.0 - dc * 0.05, 2.0 - dr * 0.05))
    window = merged.grid[dr : dr + a.grid.shape[0], dc : dc + a.grid.shape[1]]
    known = a.grid != -1
    assert np.all(window[known] >= a.grid[known])


def test_refusal_exit_code_and_message(files, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    pa, pb, _ = files
    rc = main(
        [str(pa), str(pb), "-o", str(tmp_path / "m.yaml"), "--method", "orb", "--detector", "orb"]
    )
    out = capsys.readouterr().out
    assert rc in (0, 1)
    if rc == 1:
        assert "no reliable match found" in out and not (tmp_path / "m.yaml").exists()


@pytest.mark.parametrize(
    ("which", "extra"),
    [
        ("c", []),  # resolutions differ (0.05 vs 0.10)
        ("missing", []),  # no such file
        ("b", ["--method", "nope"]),  # unknown method
        ("b", ["--detector", "akaze"]),  # absent from this OpenCV
    ],
)
def test_bad_input_exit_code_2(files, tmp_path: Path, which: str, extra: list[str], capsys) -> None:  # type: ignore[no-untyped-def]
    pa, pb, pc = files
    other = {"b": pb, "c": pc, "missing": tmp_path / "none.yaml"}[which]
    assert main([str(pa), str(other), "-o", str(tmp_path / "m.yaml"), *extra]) == 2
    assert "error:" in capsys.readouterr().err


def test_different_resolutions_raise(files, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    pa, _, pc = files
    with pytest.raises(MapFileError, match="resolutions"):
        merge_files(pa, pc, tmp_path / "m.yaml")


# --- never destroy a user's files -----------------------------------------------------------------


def _snapshot(folder: Path) -> dict[str, bytes]:
    return {p.name: p.read_bytes() for p in folder.iterdir() if p.is_file()}


@pytest.mark.parametrize("target", ["a", "b"])
def test_output_naming_an_input_is_refused_and_nothing_is_written(
    files, tmp_path: Path, target: str, capsys
) -> None:  # type: ignore[no-untyped-def]
    pa, pb, _ = files
    before = _snapshot(tmp_path)
    out = {"a": pa, "b": pb}[target]
    assert main([str(pa), str(pb), "-o", str(out)]) == 2
    assert "would overwrite the input" in capsys.readouterr().err
    assert _snapshot(tmp_path) == before  # neither the YAML nor its image (or a .png) changed


def test_figure_png_colliding_with_an_input_image_is_refused(
    tmp_path: Path, office_pair, capsys
) -> None:  # type: ignore[no-untyped-def]
    a, b, _ = office_pair
    pa = write_map_yaml(tmp_path / "a.yaml", a, 0.05, image_format="png")  # image a.png
    pb = write_map_yaml(tmp_path / "b.yaml", b, 0.05)
    before = _snapshot(tmp_path)
    # out.yaml elsewhere, but its figure would be tmp/a.png = a's own image
    assert main([str(pa), str(pb), "-o", str(tmp_path / "a.yml")]) == 2
    assert "a.png" in capsys.readouterr().err
    assert _snapshot(tmp_path) == before


def test_existing_output_needs_force(files, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    pa, pb, _ = files
    out = tmp_path / "m.yaml"
    out.write_text("precious\n")
    assert main([str(pa), str(pb), "-o", str(out)]) == 2
    assert "already exists" in capsys.readouterr().err and out.read_text() == "precious\n"
    assert main([str(pa), str(pb), "-o", str(out), "--force"]) == 0
    assert read_map_yaml(out).grid.size > 0
    assert not [p for p in tmp_path.iterdir() if ".tmp-" in p.name]  # no temporary left over


def test_output_naming_a_folder_is_a_bad_input(files, tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    pa, pb, _ = files
    (tmp_path / "d.yaml").mkdir()
    assert main([str(pa), str(pb), "-o", str(tmp_path / "d.yaml")]) == 2
    assert "folder" in capsys.readouterr().err


def test_min_common_m2_is_measured_at_the_files_resolution(tmp_path: Path, office_pair) -> None:  # type: ignore[no-untyped-def]
    # At 0.1 m/cell the two crops share ~150 m^2; assuming 0.05 m/cell made it ~38 m^2.
    a, b, _ = office_pair
    pa = write_map_yaml(tmp_path / "a.yaml", a, 0.1)
    pb = write_map_yaml(tmp_path / "b.yaml", b, 0.1)
    res = merge_files(pa, pb, tmp_path / "m.yaml", min_common_m2=100.0)
    assert res.info["resolution_m"] == 0.1 and res.info["resolution_assumed"] is False
    assert res.matched, res.reason


def test_an_ambiguous_refusal_prints_the_poses_it_could_not_tell_apart(
    tmp_path: Path, capsys
) -> None:  # type: ignore[no-untyped-def]
    """Two identical rooms side by side: b (the left room) fits both. The merger refuses, and
    the CLI prints the best pose and the rival one room-width (130 cells, 6.5 m) away, so a user
    who knows where b was mapped can tell which is right."""
    a = two_rooms()
    pa = write_map_yaml(tmp_path / "a.yaml", a, 0.05)
    pb = write_map_yaml(tmp_path / "b.yaml", a[:, :131].copy(), 0.05)
    assert main([str(pa), str(pb), "-o", str(tmp_path / "m.yaml")]) == 1
    out = capsys.readouterr().out
    assert "ambiguous" in out and "its rivals" in out and "--prior" in out
    poses = [line for line in out.splitlines() if line.startswith(("  best", "  rival"))]
    assert len(poses) >= 2
    xs = sorted(float(line.split("translation (")[1].split(",")[0]) for line in poses[:2])
    assert xs[0] == pytest.approx(0.0, abs=1.0) and xs[1] == pytest.approx(130.0, abs=1.0)
    assert "6.50" in out or "6.49" in out or "6.51" in out
    assert not (tmp_path / "m.yaml").exists()


def test_a_prior_in_metres_picks_the_room(tmp_path: Path, capsys) -> None:  # type: ignore[no-untyped-def]
    """b is the right-hand room of a, both maps in one frame (b's origin is where its cells lie
    in a's frame). Alone the merger refuses (b fits both rooms); ``--prior 0,0,0`` (the frames
    agree) merges b onto the right room, 129 cells along; a guess near the left room merges it
    there: the merger trusts the guess. A bad guess string or a method without priors: exit 2."""
    a = two_rooms()
    pa = write_map_yaml(tmp_path / "a.yaml", a, 0.05, (1.0, -2.0, 0.0))
    pb = write_map_yaml(tmp_path / "b.yaml", a[:, 129:].copy(), 0.05, (1.0 + 129 * 0.05, -2.0, 0.0))
    assert main([str(pa), str(pb), "-o", str(tmp_path / "alone.yaml")]) == 1
    out = tmp_path / "m.yaml"
    assert main([str(pa), str(pb), "-o", str(out), "--prior", "0.3,-0.2,4"]) == 0
    res = merge_files(pa, pb, tmp_path / "m2.yaml", prior_m=(0.0, 0.0, 0.0))
    assert res.matched and res.transform is not None
    np.testing.assert_allclose(res.transform[:2, 2], (129.0, 0.0), atol=1.0)
    left = merge_files(pa, pb, tmp_path / "m3.yaml", prior_m=(-6.5, 0.0, 0.0))
    assert left.matched and left.transform is not None
    np.testing.assert_allclose(left.transform[:2, 2], (-1.0, 0.0), atol=1.0)
    capsys.readouterr()
    assert main([str(pa), str(pb), "-o", str(tmp_path / "x.yaml"), "--prior", "1,two,3"]) == 2
    assert "--prior" in capsys.readouterr().err
    bad = ["--prior", "0,0,0", "--method", "orb", "--detector", "orb"]
    assert main([str(pa), str(pb), "-o", str(tmp_path / "y.yaml"), *bad]) == 2
    zero = ["--prior", "0,0,0", "--prior-radius-m", "0"]
    assert main([str(pa), str(pb), "-o", str(tmp_path / "z.yaml"), *zero]) == 2
    assert "--prior-radius-m" in capsys.readouterr().err


def test_the_refusals_rivals_are_listed_strongest_first() -> None:
    """The merger appends a rival found by its last check (a map's repeat) after the others;
    the user reads the strongest first, the one most likely to be the truth."""
    from mrexplore.experiments.merge_files import candidate_lines
    from mrexplore.merge.common import Agreement, MergeResult, translation

    weak, strong = translation(50.0, 0.0), translation(-90.0, 0.0)
    res = MergeResult(
        matched=False,
        transform=None,
        score=0.99,
        method="semantic",
        reason="ambiguous: the maps repeat: ...",
        info={
            "best_transform": np.eye(3),
            "best_agreement": Agreement(900, 9),
            "rivals": [weak, strong],
            "rival_agreements": [Agreement(500, 50), Agreement(880, 0)],
        },
    )
    lines = candidate_lines(res, 0.05)
    assert "(-90.0, 0.0) cells" in lines[2] and "(50.0, 0.0) cells" in lines[3]


def test_the_figure_is_written_and_says_what_each_panel_is(files, tmp_path: Path) -> None:  # type: ignore[no-untyped-def]
    import cv2

    from mrexplore.experiments.merge_files import figure_labels

    pa, pb, _ = files
    out = tmp_path / "merged.yaml"
    res = merge_files(pa, pb, out)
    assert res.matched
    img = cv2.imread(str(out.with_suffix(".png")))
    assert img is not None and img.ndim == 3 and img.shape[1] >= 480
    labels = figure_labels(res, "a.yaml", "b.yaml")
    assert labels["a"].startswith("a: a.yaml") and "reference" in labels["a"]
    assert labels["b"].startswith("b: b.yaml")
    assert "MERGED" in labels["result"] and f"score {res.score:.3f}" in labels["result"]
    assert "rotation" in labels["result"] and " m" in labels["result"]  # metres, from res.info
    assert f"of {len(res.matches)} matched point pairs" in labels["matches"]


def test_a_refused_figure_gives_the_reason() -> None:
    from mrexplore.experiments.merge_files import figure, figure_labels
    from mrexplore.merge.common import MergeResult

    res = MergeResult(
        matched=False, transform=None, score=0.25, method="semantic", reason="too little overlap"
    )
    labels = figure_labels(res, "x.yaml", "y.yaml")
    assert "REFUSED" in labels["result"] and "too little overlap" in labels["result"]
    assert "MERGED" not in labels["result"] and labels["matches"] == "no matched points to draw"
    a = np.zeros((40, 30), np.int8)
    img = figure(a, a, res, a_name="x.yaml", b_name="y.yaml")
    assert img.dtype == np.uint8 and img.shape[2] == 3 and img.shape[0] > 40
