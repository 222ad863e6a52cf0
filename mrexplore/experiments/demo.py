"""``mrexplore demo``: one two-robot episode on the default symmetric world, as pictures.

Writes ``<out>/episode.gif`` (the episode), ``<out>/final.png`` (last frame: world, both own
maps, the fused map, one scale and a legend; above it a headline with the coverage the console
prints, below it the frame at the moment of the merge) and prints a summary.
"""

from __future__ import annotations

import time
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from mrexplore.errors import ConfigError
from mrexplore.experiments.episode import run_episode
from mrexplore.experiments.task_time import make_team
from mrexplore.io_safety import atomic_path, check_out_dir, check_outputs, write_bytes
from mrexplore.render import format_coverage, write_video


def _banner(text: str, width: int, scale: float, height: int) -> np.ndarray:
    bar = np.full((height, width, 3), 255, np.uint8)
    y = height // 2 + 6
    cv2.putText(bar, text, (6, y), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), 1, cv2.LINE_AA)
    return bar


def run_demo(
    out: str | Path = "demo",
    world: str = "symmetric_office",
    seed: int = 0,
    policy: str = "coordinated-frontier",
    n_robots: int = 2,
    record_every: int = 12,
    force: bool = False,
    **env_options: Any,
) -> dict[str, Any]:
    """Run the demo episode and write its pictures; returns the printed summary as a dict.

    Raises:
        OutputExistsError: ``out`` is a file, or holds an earlier demo's pictures and ``force``
            is False (checked before the episode runs).
    """
    out = check_out_dir(out, force=True, what="mrexplore demo")
    check_outputs([out / "episode.gif", out / "final.png"], force=force, what="mrexplore demo")
    if isinstance(seed, bool) or not isinstance(seed, (int, np.integer)) or seed < 0:
        raise ConfigError(f"demo: seed must be an integer >= 0, got {seed!r}")
    out.mkdir(parents=True, exist_ok=True)
    agents = [f"robot_{i}" for i in range(n_robots)]
    t0 = time.perf_counter()
    res = run_episode(
        {"world": world, "n_robots": n_robots, **env_options},
        make_team(policy, agents, "explore"),
        seed,
        record_every=record_every,
    )
    wall_s = time.perf_counter() - t0
    gif = out / "episode.gif"
    with atomic_path(gif) as tmp:
        write_video(res.frames, tmp, fps=8)
    final = res.frames[-1]
    if res.merge_frame is not None:
        label = _banner(
            f"below: the moment of the merge, t = {res.first_merge_time_s:.1f} s",
            final.shape[1],
            0.55,
            26,
        )
        final = np.vstack([final, label, res.merge_frame])
    headline = (
        f"{n_robots} robots on '{world}' (seed {seed}, policy {policy}): "
        f"task time {res.task_time_s:.1f} s, coverage {format_coverage(res.coverage)}"
    )
    final = np.vstack([_banner(headline, final.shape[1], 0.6, 30), final])
    ok, png = cv2.imencode(".png", cv2.cvtColor(final, cv2.COLOR_RGB2BGR))
    if ok:
        write_bytes(out / "final.png", png.tobytes())
    summary = {
        "world": world,
        "seed": seed,
        "n_robots": n_robots,
        "task_time_s": res.task_time_s,
        "coverage": res.coverage,
        "success": res.success,
        "first_merge_time_s": res.first_merge_time_s,
        "merge_error": res.merge_error,
        "wall_time_s": wall_s,
        "files": [str(gif), str(out / "final.png")],
        "figure_title": headline,
    }
    merge_txt = (
        f"merged at t = {res.first_merge_time_s:.1f} s"
        if res.first_merge_time_s is not None
        else "never merged"
    )
    err_txt = (
        f", error {res.merge_error['translation_cells']:.2f} cells / "
        f"{res.merge_error['rotation_deg']:.2f} deg"
        if res.merge_error
        else ""
    )
    print(
        f"demo: {n_robots} robots on '{world}' (seed {seed}, policy {policy})\n"
        f"  task time {res.task_time_s:.1f} s simulated "
        f"({'target reached' if res.success else 'truncated'}), "
        f"coverage {format_coverage(res.coverage)}\n"
        f"  {merge_txt}{err_txt}\n"
        f"  wrote {gif} and {out / 'final.png'} in {wall_s:.1f} s wall time"
    )
    return summary
