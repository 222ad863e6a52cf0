"""``mrexplore bench sensor``: lidar cast, cast + own-map update, the whole simulator step.

A "robot update" is one robot's scan (all its beams) plus the update of its own occupancy map
with that scan: what the simulator does per robot per step, without motion and coverage. The
cast of all robots runs as one call, as in the simulator. The "Simulation.step" row is the whole
simulator step (motion, odometry, one cast + observed marking for all robots, one map update per
robot, trails) with random actions (70 % FORWARD).

Compile time is excluded: every path is warmed up first (the numba kernels are compiled, or
loaded from the on-disk cache, before any timing). Each figure is the best of ``--repeats``
runs of CPU time of the calling thread (``time.thread_time``), since the machine may be
shared.

Usage: ``mrexplore bench sensor [--steps 300] [--robots 2] [--repeats 3] [--numpy]``
"""

from __future__ import annotations

import argparse
import math
import time
from collections.abc import Callable, Sequence

import numpy as np

from mrexplore import kernels
from mrexplore.mapping import OccupancyMap
from mrexplore.robot import Action, Motion, RobotConfig, largest_component
from mrexplore.sensors import Lidar, LidarConfig, Scan
from mrexplore.sim import SimConfig, Simulation, canvas_for
from mrexplore.world import load_world
from mrexplore.world.world import World


def best_time(fn: Callable[[], None], repeats: int) -> float:
    """Smallest CPU time (s, this thread) of ``repeats`` calls of ``fn``."""
    best = math.inf
    for _ in range(repeats):
        t0 = time.thread_time()
        fn()
        best = min(best, time.thread_time() - t0)
    return best


def bench(
    world: World, max_range_m: float, n_robots: int, steps: int, repeats: int, seed: int = 0
) -> None:
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
    res = world.resolution_m
    h, w = world.shape

    def fresh_maps() -> list[OccupancyMap]:
        return [OccupancyMap(shape, res, origin_cell) for _ in range(n_robots)]

    maps = fresh_maps()
    scans: list[Scan] = []

    def run_cast() -> None:
        scans.clear()
        for k in range(steps):
            scans.append(lidar.cast(grid, origins[k], headings[k], res, rng=rng))

    def run_observe() -> None:
        obs = np.zeros((n_robots, h, w), dtype=bool)
        team = np.zeros((h, w), dtype=bool)
        for k in range(steps):
            lidar.cast_observe(grid, origins[k], headings[k], res, rng, obs, free, team)

    def run_map() -> None:
        for k, scan in enumerate(scans):
            for i in range(n_robots):
                # the robot's own frame: its pose relative to a start at its first position
                x = (origins[k, i, 0] - origins[0, i, 0]) * res
                y = (origins[k, i, 1] - origins[0, i, 1]) * res
                maps[i].update((x, y, headings[k, i]), scan.angles, scan.ranges_m[i], scan.hit[i])

    cfg = SimConfig(lidar=LidarConfig(n_beams=360, max_range_m=max_range_m, noise_std_m=0.01))
    sim = Simulation(world, n_robots, cfg)
    act_rng = np.random.default_rng(seed + 1)
    actions = np.where(
        act_rng.random((steps, n_robots)) < 0.7,
        int(Action.FORWARD),
        act_rng.integers(1, 4, size=(steps, n_robots)),
    )

    def run_sim() -> None:
        sim_rng = np.random.default_rng(seed)
        sim.reset(sim_rng)
        for k in range(steps):
            sim.step(actions[k], sim_rng)

    # Warm-up: compiles / loads the kernels, touches the canvases' pages.
    for fn in (run_cast, run_observe, run_map, run_sim):
        fn()
    maps = fresh_maps()
    t_cast = best_time(run_cast, repeats)
    t_obs = best_time(run_observe, repeats)
    t_map = best_time(run_map, repeats)
    t_sim = best_time(run_sim, repeats)

    n_upd = steps * n_robots
    hit_share = float(np.mean([s.hit.mean() for s in scans]))
    mean_range = float(np.mean([s.ranges_m.mean() for s in scans]))
    print(
        f"world {world.name!r} {h}x{w} @ {res} m, "
        f"{n_robots} robots x 360 beams, range {max_range_m} m "
        f"(mean range {mean_range:.2f} m, {hit_share:.0%} hits), canvas {shape[0]}x{shape[1]}"
    )
    table = [
        ("cast only", t_cast, "robot scans/s"),
        ("cast + observed marking", t_obs, "robot scans/s"),
        ("map update only", t_map, "robot updates/s"),
        ("cast + map update", t_cast + t_map, "robot updates/s"),
        ("Simulation.step", t_sim, "robot steps/s"),
    ]
    for label, secs, unit in table:
        print(
            f"  {label:24s}: {n_upd / secs:8.0f} {unit:16s} "
            f"({1e3 * secs / steps:.3f} ms per {n_robots}-robot step)"
        )


def main(argv: Sequence[str] | None = None) -> int:
    ap = argparse.ArgumentParser(prog="mrexplore bench sensor", description=__doc__.splitlines()[0])
    ap.add_argument("--steps", type=int, default=300)
    ap.add_argument("--robots", type=int, default=2)
    ap.add_argument("--repeats", type=int, default=3, help="best of this many runs")
    ap.add_argument("--numpy", action="store_true", help="the numpy fallback, not numba")
    args = ap.parse_args(argv)
    kernels.USE_NUMBA = kernels.HAVE_NUMBA and not args.numpy
    print(
        f"path: {'numba kernels' if kernels.enabled() else 'numpy'}; compile time excluded "
        f"(warmed up first); best of {args.repeats} runs of {args.steps} steps"
    )
    bench(load_world("symmetric_office"), 4.0, args.robots, args.steps, args.repeats)
    try:
        coarse = load_world("symmetric_office_coarse")
    except Exception as exc:  # the coarse world is optional
        print(f"(symmetric_office_coarse not available: {exc})")
        return 0
    bench(coarse, 3.0, args.robots, args.steps, args.repeats)
    return 0
