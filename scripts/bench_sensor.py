"""Benchmark: lidar cast + own-map update, in robot updates per second (one core).

A "robot update" is one robot's scan (all its beams) plus the update of its own occupancy map
with that scan: what the simulator does per robot per step, without motion and coverage. The
cast of all robots runs as one vectorised call, as in the simulator.

Usage: python scripts/bench_sensor.py [--steps 300] [--robots 2]
"""

from __future__ import annotations

import argparse
import math
import time

import numpy as np

from mrexplore.mapping import OccupancyMap
from mrexplore.robot import Motion, RobotConfig, largest_component
from mrexplore.sensors import Lidar, LidarConfig
from mrexplore.sim import canvas_for
from mrexplore.world import load_world
from mrexplore.world.world import World


def bench(world: World, max_range_m: float, n_robots: int, steps: int, seed: int = 0) -> None:
    rng = np.random.default_rng(seed)
    lidar = Lidar(LidarConfig(n_beams=360, max_range_m=max_range_m, noise_std_m=0.01))
    grid = lidar.prepare(world.walls)
    free = largest_component(~Motion(world, RobotConfig()).cspace)
    rows, cols = np.nonzero(free)
    picks = rng.integers(len(rows), size=(steps, n_robots))
    origins = np.stack([cols[picks], rows[picks]], axis=-1).astype(np.float64)
    origins += rng.uniform(-0.5, 0.5, size=origins.shape)
    headings = rng.uniform(-math.pi, math.pi, size=(steps, n_robots))
    shape, origin_cell = canvas_for(world, world.resolution_m)
    maps = [OccupancyMap(shape, world.resolution_m, origin_cell) for _ in range(n_robots)]
    res = world.resolution_m

    # warm-up (first-touch of the canvases, numpy caches)
    for k in range(min(10, steps)):
        lidar.cast(grid, origins[k], headings[k], res, rng=rng)

    scans = []
    t0 = time.perf_counter()
    for k in range(steps):
        scans.append(lidar.cast(grid, origins[k], headings[k], res, rng=rng))
    t_cast = time.perf_counter() - t0

    t0 = time.perf_counter()
    for k in range(steps):
        lidar.cast(grid, origins[k], headings[k], res, rng=rng, want_visible=True)
    t_cast_vis = time.perf_counter() - t0

    t0 = time.perf_counter()
    for k, scan in enumerate(scans):
        for i in range(n_robots):
            # the robot's own frame: its pose relative to a start at the world origin cell
            x = (origins[k, i, 0] - origins[0, i, 0]) * res
            y = (origins[k, i, 1] - origins[0, i, 1]) * res
            maps[i].update((x, y, headings[k, i]), scan.angles, scan.ranges_m[i], scan.hit[i])
    t_map = time.perf_counter() - t0

    n_upd = steps * n_robots
    hit_share = float(np.mean([s.hit.mean() for s in scans]))
    mean_range = float(np.mean([s.ranges_m.mean() for s in scans]))
    print(
        f"world {world.name!r} {world.shape[0]}x{world.shape[1]} @ {res} m, "
        f"{n_robots} robots x 360 beams, range {max_range_m} m "
        f"(mean range {mean_range:.2f} m, {hit_share:.0%} hits), canvas {shape[0]}x{shape[1]}"
    )
    total = t_cast + t_map
    total_v = t_cast_vis + t_map
    table = [
        ("cast only", t_cast, "robot scans/s"),
        ("cast + visible cells", t_cast_vis, "robot scans/s"),
        ("map update only", t_map, "robot updates/s"),
        ("cast + map update", total, "robot updates/s"),
        ("+ visible (simulator)", total_v, "robot updates/s"),
    ]
    for label, secs, unit in table:
        print(
            f"  {label:22s}: {n_upd / secs:8.0f} {unit:16s} ({1e3 * secs / steps:.3f} ms per step)"
        )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--robots", type=int, default=2)
    args = ap.parse_args()
    bench(load_world("symmetric_office"), 4.0, args.robots, args.steps)
    try:
        coarse = load_world("symmetric_office_coarse")
    except Exception as exc:  # the coarse world is optional
        print(f"(symmetric_office_coarse not available: {exc})")
        return
    bench(coarse, 3.0, args.robots, args.steps)


if __name__ == "__main__":
    main()
