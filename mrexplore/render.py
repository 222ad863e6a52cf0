"""Frames from state only (the viewer) and GIF/MP4 writing.

Rendering reads the env's state; it never computes or changes it.
"""

from __future__ import annotations

from collections.abc import Sequence
from pathlib import Path
from typing import TYPE_CHECKING

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore.grid import apply_transform, free_mask, known_mask, occupied_mask

if TYPE_CHECKING:  # pragma: no cover
    from mrexplore.environment.parallel_env import MultiRobotExplorationEnv

#: BGR-free RGB colours of robots 0, 1, 2, ... (cycled).
ROBOT_COLOURS: list[tuple[int, int, int]] = [
    (220, 50, 47),
    (38, 139, 210),
    (133, 153, 0),
    (211, 54, 130),
    (181, 137, 0),
    (42, 161, 152),
]
PANEL_PX = 360


def colour(i: int) -> tuple[int, int, int]:
    """RGB colour of robot ``i``."""
    return ROBOT_COLOURS[i % len(ROBOT_COLOURS)]


def grid_to_rgb(grid: NDArray[np.int8]) -> NDArray[np.uint8]:
    """An int8 occupancy grid as RGB (unknown grey, free white, occupied black), row 0 at the
    *bottom* of the picture as on a map."""
    img = np.full((*grid.shape, 3), 160, dtype=np.uint8)
    img[free_mask(grid)] = 255
    img[occupied_mask(grid)] = 0
    return np.ascontiguousarray(img[::-1])


def _fit(img: NDArray[np.uint8], size: int = PANEL_PX) -> tuple[NDArray[np.uint8], float]:
    """Scale ``img`` to fit a ``size`` x ``size`` square panel (nearest: keep cells crisp)."""
    h, w = img.shape[:2]
    s = size / max(h, w)
    out = cv2.resize(img, (max(1, int(w * s)), max(1, int(h * s))), interpolation=cv2.INTER_NEAREST)
    panel = np.full((size, size, 3), 235, dtype=np.uint8)
    panel[: out.shape[0], : out.shape[1]] = out
    return panel, s


def _title(panel: NDArray[np.uint8], text: str) -> NDArray[np.uint8]:
    bar = np.full((22, panel.shape[1], 3), 250, dtype=np.uint8)
    cv2.putText(bar, text, (4, 16), cv2.FONT_HERSHEY_SIMPLEX, 0.45, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([bar, panel])


def _crop_known(grid: NDArray[np.int8], margin: int = 10) -> tuple[NDArray[np.int8], int, int]:
    """Crop a map to its known bounding box plus a margin; returns (crop, col0, row0)."""
    km = known_mask(grid)
    rows = np.flatnonzero(km.any(axis=1))
    cols = np.flatnonzero(km.any(axis=0))
    if len(rows) == 0:
        return grid[:1, :1], 0, 0
    r0, r1 = max(rows[0] - margin, 0), min(rows[-1] + margin + 1, grid.shape[0])
    c0, c1 = max(cols[0] - margin, 0), min(cols[-1] + margin + 1, grid.shape[1])
    return grid[r0:r1, c0:c1], int(c0), int(r0)


def map_panel(
    grid: NDArray[np.int8],
    title: str,
    poses: Sequence[tuple[float, float, float, int]] = (),
    trails: Sequence[tuple[NDArray[np.float64], int]] = (),
) -> NDArray[np.uint8]:
    """One map as a titled panel, cropped to what is known, with robots (col, row, theta, idx)
    and trails ((T, 2) cells, idx) drawn in their colours."""
    crop, c0, r0 = _crop_known(grid)
    panel, s = _fit(grid_to_rgb(crop))
    h = crop.shape[0]

    def px(c: float, r: float) -> tuple[int, int]:
        return int((c - c0 + 0.5) * s), int((h - 1 - (r - r0) + 0.5) * s)

    for cells, idx in trails:
        if len(cells) > 1:
            pts = np.array([px(c, r) for c, r in cells[:: max(1, len(cells) // 400)]], np.int32)
            cv2.polylines(panel, [pts], False, colour(idx), 1, cv2.LINE_AA)
    for c, r, th, idx in poses:
        p = px(c, r)
        cv2.circle(panel, p, 4, colour(idx), -1, cv2.LINE_AA)
        q = (int(p[0] + 10 * np.cos(th)), int(p[1] - 10 * np.sin(th)))
        cv2.line(panel, p, q, colour(idx), 2, cv2.LINE_AA)
    return _title(panel, title)


def render_env_frame(env: MultiRobotExplorationEnv) -> NDArray[np.uint8]:
    """The env's frame: true world | each robot's own map | fused map of robot_0, plus status."""
    sim, world = env.sim, env.world
    assert sim is not None and world is not None
    n = len(env.possible_agents)
    # --- the true world, what the team has observed, beams, trails, robots
    seen = sim.observed.any(axis=0)
    img = np.full((*world.walls.shape, 3), 255, dtype=np.uint8)
    img[seen & ~world.walls] = (200, 230, 200)
    img[world.walls] = (40, 40, 40)
    img = np.ascontiguousarray(img[::-1])
    panel, s = _fit(img)
    h = world.walls.shape[0]

    def wpx(cr: NDArray[np.float64]) -> NDArray[np.int32]:
        return np.stack([(cr[:, 0] + 0.5) * s, (h - 1 - cr[:, 1] + 0.5) * s], axis=1).astype(
            np.int32
        )

    scan = sim.last_scan
    for i in range(n):
        pose = sim.true_poses[i]
        p = wpx(world.cell_of(pose[None, :2]))[0]
        if scan is not None:
            ang = pose[2] + scan.angles[::8]
            rng_m = scan.ranges_m[i, ::8]
            ends = pose[None, :2] + np.stack([np.cos(ang), np.sin(ang)], 1) * rng_m[:, None]
            for q in wpx(world.cell_of(ends)):
                cv2.line(panel, tuple(p), tuple(q), (255, 200, 120), 1)
        trail = sim.trail_cells(i)
        if len(trail) > 1:
            tw = apply_transform(sim.world_from_map(i), trail[:: max(1, len(trail) // 400)])
            cv2.polylines(panel, [wpx(tw)], False, colour(i), 1, cv2.LINE_AA)
    for i in range(n):
        pose = sim.true_poses[i]
        p = wpx(world.cell_of(pose[None, :2]))[0]
        cv2.circle(panel, tuple(p), 5, colour(i), -1, cv2.LINE_AA)
        q = (int(p[0] + 12 * np.cos(pose[2])), int(p[1] - 12 * np.sin(pose[2])))
        cv2.line(panel, tuple(p), q, colour(i), 2, cv2.LINE_AA)
    panels = [_title(panel, f"world (truth)  t={sim.time_s:.1f}s  cov={sim.coverage():.0%}")]
    # --- each robot's own map, in its own frame
    for i, a in enumerate(env.possible_agents):
        c, r, th = sim.pose_cell(i)
        panels.append(
            map_panel(
                sim.maps[i].to_int8(), f"{a} own map", [(c, r, th, i)], [(sim.trail_cells(i), i)]
            )
        )
    # --- the fused map in robot_0's frame
    if n > 1:
        a0 = env.possible_agents[0]
        view = env.robot_view(a0)
        poses = [(*view.pose_cell, 0)] + [
            (c, r, 0.0, env.possible_agents.index(o)) for o, (c, r) in view.teammates.items()
        ]
        err = env._merge_error(a0) if view.merged else None
        status = "MERGED" if view.merged else "not merged"
        if err is not None:
            status += f" err {err['translation_cells']:.1f}c {err['rotation_deg']:.1f}deg"
        panels.append(map_panel(view.map, f"fused ({a0} frame): {status}", poses))
    frame = np.hstack(panels)
    return np.ascontiguousarray(frame)


def write_video(frames: Sequence[NDArray[np.uint8]], path: str | Path, fps: float = 8.0) -> Path:
    """Write RGB frames as an animated GIF (Pillow, if installed) or MP4 (OpenCV) by suffix."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not frames:
        raise ValueError("no frames to write")
    if path.suffix.lower() == ".gif":
        try:
            from PIL import Image
        except ImportError as exc:  # pragma: no cover
            raise ImportError(
                "writing GIFs needs Pillow: pip install pillow (or use .mp4)"
            ) from exc
        imgs = [Image.fromarray(f) for f in frames]
        imgs[0].save(path, save_all=True, append_images=imgs[1:], duration=int(1000 / fps), loop=0)
        return path
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"mp4v"), fps, (w, h))
    for f in frames:
        writer.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    writer.release()
    return path
