"""``mrexplore bench policies``: planner speed and cost per ``act`` over whole episodes.

Run ``mrexplore bench policies --worlds small_office symmetric_office --seeds 0``.
Prints figures (never asserts on time). Episodes run the simulator directly with views built
from each robot's own map and pose (no merging), until the policy reports ``done`` or a step
budget is spent.
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Sequence

import numpy as np

from mrexplore.policies.explorers import (
    CoordinatedFrontierPolicy,
    CostFrontierPolicy,
    FrontierExplorer,
    NearestFrontierPolicy,
)
from mrexplore.policies.planning import PlanningGrid, distance_field, distance_field_scan
from mrexplore.sim import Simulation
from mrexplore.types import RobotView
from mrexplore.world.registry import load_world


def _view(sim: Simulation, i: int) -> RobotView:
    """Robot ``i``'s view from its own map and pose (no merging, no teammates)."""
    return RobotView(
        agent=f"robot_{i}",
        map=sim.maps[i].to_int8(),
        resolution_m=sim.resolution_m,
        pose_cell=sim.pose_cell(i),
        robot_radius_m=sim.config.robot.radius_m,
        time_s=sim.time_s,
    )


def _episode(
    world_name: str, n_robots: int, policy: str, seed: int, max_steps: int
) -> dict[str, float]:
    sim = Simulation(load_world(world_name), n_robots)
    rng = np.random.default_rng(seed)
    sim.reset(rng)
    agents = [f"robot_{i}" for i in range(n_robots)]
    team = CoordinatedFrontierPolicy(agents)
    single: FrontierExplorer | None = None
    if policy == "nearest-frontier":
        single = NearestFrontierPolicy()
    elif policy == "cost-frontier":
        single = CostFrontierPolicy()
    if single is not None:
        single.reset(np.random.default_rng(seed))
    else:
        team.reset(np.random.default_rng(seed))
    cpu = 0.0
    steps = 0
    t90 = float("nan")
    for steps in range(1, max_steps + 1):  # noqa: B007 - steps is reported after the loop
        views = {a: _view(sim, i) for i, a in enumerate(agents)}
        t0 = time.process_time()
        if single is not None:
            actions = [single.act(views[agents[0]])]
            done = single.done
        else:
            acts = team.act(views)
            actions = [acts[a] for a in agents]
            done = team.done
        cpu += time.process_time() - t0
        if done:
            break
        sim.step(np.array(actions), rng)
        if np.isnan(t90) and sim.coverage() >= 0.9:
            t90 = sim.time_s
    robots = [single] if single is not None else list(team.robots.values())
    plans = sum(r.n_plans for r in robots)
    plan_s = sum(r.plan_time_s for r in robots)
    return {
        "steps": steps,
        "time_s": sim.time_s,
        "t90_s": t90,
        "coverage": sim.coverage(),
        "act_ms": 1e3 * cpu / steps,
        "plans": plans,
        "plan_ms": 1e3 * plan_s / max(plans, 1),
    }


def _field_timing(world_name: str, seed: int, steps: int) -> str:
    """Distance-field timings on a real map after ``steps`` steps of nearest-frontier runs."""
    sim = Simulation(load_world(world_name), 1)
    rng = np.random.default_rng(seed)
    sim.reset(rng)
    pol = NearestFrontierPolicy()
    pol.reset(rng)
    for _ in range(steps):
        sim.step(np.array([pol.act(_view(sim, 0))]), rng)
    v = _view(sim, 0)
    grid = PlanningGrid.build(v.map, v.resolution_m, v.robot_radius_m, v.pose_cell[:2])
    src = np.array([grid.start])
    out = []
    for name, fn in (
        ("dijkstra (numba)", lambda: distance_field(grid.free, src, method="dijkstra")),
        ("scan (numpy)", lambda: distance_field_scan(grid.free, src)),
    ):
        fn()
        t0 = time.process_time()
        for _ in range(10):
            fn()
        out.append(f"{name} {1e3 * (time.process_time() - t0) / 10:.2f} ms")
    t0 = time.process_time()
    for _ in range(10):
        pol.replan(v)
    plan_ms = 1e3 * (time.process_time() - t0) / 10
    h, w = grid.shape
    return (
        f"{world_name}: canvas {v.map.shape[0]}x{v.map.shape[1]}, planning grid {h}x{w} "
        f"(coverage {sim.coverage():.0%}): field "
        + ", ".join(out)
        + f"; full plan {plan_ms:.2f} ms"
    )


def main(argv: Sequence[str] | None = None) -> None:
    """Print the benchmark table."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", nargs="+", default=["small_office", "symmetric_office"])
    ap.add_argument("--seeds", nargs="+", type=int, default=[0])
    ap.add_argument("--max-steps", type=int, default=4000)
    args = ap.parse_args(argv)
    t0 = time.perf_counter()
    distance_field(np.ones((2, 2), dtype=bool), np.array([[0, 0]]))  # numba load / compile
    print(f"numba kernel ready in {time.perf_counter() - t0:.2f} s (first process only compiles)")
    for w in args.worlds:
        print(_field_timing(w, args.seeds[0], steps=600))
    print()
    header = (
        f"{'world':<18}{'policy':<22}{'robots':>6}{'seed':>5}{'steps':>7}{'t90 s':>8}"
        f"{'end s':>8}{'cov':>7}{'plans':>7}{'plan ms':>9}{'act ms':>8}"
    )
    print(header)
    print("-" * len(header))
    acts = []
    for w in args.worlds:
        for policy, n in (
            ("nearest-frontier", 1),
            ("cost-frontier", 1),
            ("coordinated-frontier", 2),
        ):
            for seed in args.seeds:
                r = _episode(w, n, policy, seed, args.max_steps)
                acts.append(r["act_ms"])
                print(
                    f"{w:<18}{policy:<22}{n:>6}{seed:>5}{r['steps']:>7.0f}{r['t90_s']:>8.1f}"
                    f"{r['time_s']:>8.1f}{r['coverage']:>7.1%}{r['plans']:>7.0f}"
                    f"{r['plan_ms']:>9.2f}{r['act_ms']:>8.2f}"
                )
    print("-" * len(header))
    print(
        "act ms = policy CPU time per step (whole team for coordinated, i.e. 2 robots), "
        f"mean over episodes {np.mean(acts):.2f} ms; coordinated runs are unmerged (plain sim)."
    )


if __name__ == "__main__":
    main()
