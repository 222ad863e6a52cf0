"""Does a batch-first step pay for its order? N worlds sensed world by world or stage by stage.

A batch-first step runs each stage (the lidar cast, the own-map update, ...) over every world
before the next stage; the batched env today runs each world's whole step before the next
world's. On a CPU the first order could cost cache: a world's data is touched once per stage
instead of once per step. This study times the sensing (one lidar cast of both robots, then
their two map updates) of ``--worlds`` worlds that have each been stepped 40 times, three ways,
in alternating rounds, thread CPU time per world-step:

- world-major: each world cast, then mapped, then the next world (the batched env's order);
- stage-major: every world cast, then every world mapped (a batch-first order);
- one world N times: the same world sensed N times in a row, its data hot in the cache (what a
  single env stepped alone would see).

The casts repeat the same poses (the maps absorb the same scans again); only the timing is
read. It calls the simulator's two sensing parts (``Simulation.cast``, ``Simulation.integrate``).

    python studies/stage_order.py --worlds 32 --rounds 30
"""

from __future__ import annotations

import argparse
import time
from collections.abc import Callable

import numpy as np

from mrexplore import parallel_env
from mrexplore.sensors import Scan
from mrexplore.sim import Simulation


def stepped_sims(n_worlds: int, steps: int = 40) -> list[Simulation]:
    """``n_worlds`` simulators of ``symmetric_office`` (2 robots, merging off), world k reset
    with seed k and stepped ``steps`` times with random actions from a stream seeded k."""
    sims = []
    for k in range(n_worlds):
        env = parallel_env(world="symmetric_office", n_robots=2, merger=None)
        env.reset(seed=k)
        rng = np.random.default_rng(k)
        for _ in range(steps):
            env.step({a: int(rng.integers(0, 4)) for a in env.agents})
        ep = env.unwrapped.episode
        assert ep is not None
        sims.append(ep.sim)
    return sims


def orders(sims: list[Simulation], rng: np.random.Generator) -> dict[str, Callable[[], None]]:
    """The three orders, each sensing ``len(sims)`` world-steps."""

    def sense(sim: Simulation) -> None:
        integrate(sim, sim.cast(rng)[0])

    def integrate(sim: Simulation, scan: Scan) -> None:
        for i in range(sim.n_robots):
            sim.integrate(i, scan)

    def world_major() -> None:
        for s in sims:
            sense(s)

    def stage_major() -> None:
        scans = [s.cast(rng)[0] for s in sims]
        for s, scan in zip(sims, scans, strict=True):
            integrate(s, scan)

    def one_world() -> None:
        for _ in sims:
            sense(sims[0])

    return {
        "world-major": world_major,
        "stage-major": stage_major,
        "one world N times": one_world,
    }


def measure(n_worlds: int, rounds: int) -> dict[str, list[float]]:
    """Thread CPU time per world-step (us) of each order, one figure per round."""
    sims = stepped_sims(n_worlds)
    rng = np.random.default_rng(0)
    runs = orders(sims, rng)
    out: dict[str, list[float]] = {name: [] for name in runs}
    for _ in range(rounds):
        for name, fn in runs.items():
            t0 = time.thread_time()
            fn()
            out[name].append((time.thread_time() - t0) / n_worlds * 1e6)
    return out


def main() -> None:
    """Parse the arguments, time the orders, print one line per order and the ratio."""
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--worlds", type=int, default=32)
    ap.add_argument("--rounds", type=int, default=30)
    args = ap.parse_args()
    res = measure(args.worlds, args.rounds)
    print(
        f"sensing (a cast of 2 robots, 2 map updates) of {args.worlds} worlds of "
        f"symmetric_office, {args.rounds} rounds, thread CPU per world-step:"
    )
    for name, v in res.items():
        print(f"  {name:20s} median {np.median(v):7.1f} us")
    ratio = np.array(res["stage-major"]) / np.array(res["world-major"])
    print(f"  stage-major / world-major, median of the rounds' ratios: {np.median(ratio):.3f}")


if __name__ == "__main__":
    main()
