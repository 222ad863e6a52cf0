"""Demo figures: legend, one scale for all panels, fixed geometry, one coverage."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import numpy as np
import pytest

import mrexplore
from mrexplore import render
from mrexplore.experiments.episode import EpisodeResult
from mrexplore.grid import apply_transform, invert_transform

SMALL = {"world": "small_office", "max_time_s": 60.0}


def _env(**opts: Any) -> Any:
    penv = mrexplore.parallel_env(render_mode="rgb_array", **{**SMALL, **opts})
    penv.reset(seed=0)
    return penv


def _step(penv: Any, k: int) -> None:
    for _ in range(k):
        penv.step({a: 0 for a in penv.agents})


def test_legend_is_drawn_below_the_panels() -> None:
    penv = _env()
    frame = penv.render()
    layout = render.frame_layout(penv.snapshot())
    strip, swatches = render.legend(penv.possible_agents, layout, frame.shape[1])
    top = render.TITLE_PX + render.PANEL_PX
    assert frame.shape[0] == top + strip.shape[0]
    np.testing.assert_array_equal(frame[top:], strip)
    expected = {
        "robot_0": render.colour(0),
        "robot_1": render.colour(1),
        "lidar beams": render.BEAM,
        "wall": render.WORLD_WALL,
        "seen by the team": render.WORLD_SEEN,
        "not yet seen": render.WORLD_UNSEEN,
        "unknown": render.MAP_UNKNOWN,
        "free": render.MAP_FREE,
        "occupied": render.MAP_OCCUPIED,
    }
    for label, rgb in expected.items():
        x, y, w, h = swatches[label]
        if label.startswith("robot_"):  # the dot
            px = frame[top + y + h // 2, x + 6]
        elif label == "lidar beams":  # a line through the middle
            px = frame[top + y + h // 2, x + w // 2]
        else:  # inside the box's border
            px = frame[top + y + h // 2, x + w // 2]
        assert tuple(int(v) for v in px) == rgb, label
    assert "path driven (robot's colour)" in swatches
    assert any(k.endswith("same scale in all panels") for k in swatches)


def test_legend_fits_one_robot_frame() -> None:
    penv = _env(n_robots=1)
    layout = render.frame_layout(penv.snapshot())
    strip, swatches = render.legend(penv.possible_agents, layout, render.PANEL_PX * 2)
    assert all(x + w <= strip.shape[1] for x, _, w, _ in swatches.values())
    assert len(swatches) == 10  # one robot, trail, beams, scale, 3 world and 3 map classes


def test_frames_keep_their_geometry_as_maps_grow() -> None:
    penv = _env()
    layout0 = render.frame_layout(penv.snapshot())
    f0 = penv.render()
    _step(penv, 40)
    f1 = penv.render()
    assert f0.shape == f1.shape
    assert render.frame_layout(penv.snapshot()) == layout0  # same windows, same scale: a fixed zoom
    # the world's walls (never changing) are drawn at the same pixels in both frames
    panel = (slice(render.TITLE_PX, render.TITLE_PX + render.PANEL_PX), slice(render.PANEL_PX))
    walls0 = np.all(f0[panel] == render.WORLD_WALL, axis=2)
    walls1 = np.all(f1[panel] == render.WORLD_WALL, axis=2)
    assert walls0.sum() > 1000
    assert (walls0 & ~walls1).sum() < 0.05 * walls0.sum()  # robots/beams may hide a few


@pytest.mark.parametrize("aligned", [True, False])
def test_all_panels_share_one_scale(aligned: bool) -> None:
    """A wall segment of known length spans the same pixels in the world panel and, carried
    into each robot's frame with the true transform, in that robot's map panel."""
    penv = _env(aligned_headings=aligned)
    layout = render.frame_layout(penv.snapshot())
    h, w = penv.world.walls.shape
    seg_world = np.array([[0.0, 0.0], [w - 1.0, 0.0]])  # the bottom wall, (w - 1) cells long
    length_px = np.linalg.norm(np.diff(layout.world.px(seg_world).astype(float), axis=0))
    assert length_px == pytest.approx((w - 1) * layout.px_per_cell, abs=1.5)
    for i, view in enumerate(layout.robots):
        assert view.px_per_cell == layout.world.px_per_cell
        seg = apply_transform(invert_transform(penv.sim.world_from_map(i)), seg_world)
        seg_px = np.linalg.norm(np.diff(view.px(seg).astype(float), axis=0))
        assert seg_px == pytest.approx(length_px, abs=2.0)
        # the whole world, seen from the robot's frame, fits its panel
        corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], float)
        px = view.px(apply_transform(invert_transform(penv.sim.world_from_map(i)), corners))
        assert px.min() >= 0 and px.max() < render.PANEL_PX
    assert layout.m_per_px == pytest.approx(penv.world.resolution_m / layout.px_per_cell)


def test_world_panel_shows_the_coverage_infos_report() -> None:
    penv = _env(coverage_mode="held")
    _step(penv, 30)
    _, _, _, _, infos = penv.step({a: 0 for a in penv.agents})
    cov = infos["robot_0"]["coverage"]
    assert penv.coverage == cov
    assert render.format_coverage(cov) in render.world_title(penv.snapshot())


def test_demo_figure_title_matches_console(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    from mrexplore.experiments import demo

    frame = np.full((50, 1440, 3), 255, np.uint8)

    def fake_episode(*args: object, **kwargs: object) -> EpisodeResult:
        return EpisodeResult(
            task_time_s=12.0,
            success=False,
            coverage=0.83456,
            times_s=[0.0],
            coverages=[0.83456],
            first_merge_time_s=None,
            merge_error=None,
            collisions=0,
            frames=[frame, frame],
        )

    monkeypatch.setattr(demo, "run_episode", fake_episode)
    summary = demo.run_demo(out=tmp_path / "d", world="small_office")
    console = capsys.readouterr().out
    assert "coverage 83.5%" in console
    assert "coverage 83.5%" in summary["figure_title"]
