"""Where a world-step's CPU goes: the compiled kernels against the Python around them, for N
single envs stepped each alone or in turn.

The issue's batch-first step aims at the Python of a world-step; the worlds of a batch are
stepped in turn, which costs cache. This study steps ``--worlds`` envs (``symmetric_office``, 2
robots, random actions, merging off: the env's own step only) in alternating rounds, each
round ``--steps`` steps of every env, in two orders:

- alone: each env its ``--steps`` steps, then the next env (a single env's cache);
- in turn: one step of every env, ``--steps`` times (the batched env's order).

Per world-step it prints the thread CPU of the whole step and of each compiled kernel called in
it (the simulator's sensing call, the observation's view kernel, the map-accuracy scorers),
timed by wrapping the kernels (each wrapper adds ~1 us); the rest is Python and numpy.

``--processes 2`` runs the same measurement in two processes at once (their own worlds, seeds
apart; timed after both have warmed up), as the batched env's worker processes step their
blocks of worlds, and prints the mean over the processes: what stepping on every core costs
each world-step, part by part, against ``--processes 1``.

    python studies/step_split.py --worlds 32 --rounds 6 --steps 25 [--processes 2]
"""

from __future__ import annotations

import argparse
import multiprocessing
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from typing import Any

import numpy as np

import mrexplore
import mrexplore.kernels.scoring as scoring
import mrexplore.kernels.views as views
import mrexplore.sim as sim_module

#: The kernels timed: label -> (module holding the reference the env calls, attribute).
KERNELS: dict[str, tuple[Any, str]] = {
    "sensing": (sim_module._sensing, "sense_world"),
    "views": (views, "view_shares"),
    "score boxes": (scoring, "score_region"),
    "score cells": (scoring, "score_cells"),
}


@contextmanager
def timed_kernels(acc: dict[str, int]) -> Iterator[None]:
    """Wrap the :data:`KERNELS` so that each call adds its thread CPU (ns) to ``acc[label]``;
    restored on exit."""
    saved = {}
    for label, (module, name) in KERNELS.items():
        fn = getattr(module, name)
        saved[label] = fn

        def wrapper(*args: Any, _fn: Callable[..., Any] = fn, _label: str = label) -> Any:
            t = time.thread_time_ns()
            out = _fn(*args)
            acc[_label] += time.thread_time_ns() - t
            return out

        setattr(module, name, wrapper)
    try:
        yield
    finally:
        for label, (module, name) in KERNELS.items():
            setattr(module, name, saved[label])


def measure(
    n_worlds: int,
    rounds: int = 6,
    steps: int = 25,
    seed: int = 0,
    ready: Callable[[], Any] | None = None,
) -> dict[str, Any]:
    """Per order, the thread CPU per world-step (us) of the whole step and of each kernel,
    summed over ``rounds`` alternating rounds (the order that goes first alternates);
    ``ready`` is called once the envs are warm, before the timed rounds."""
    envs = [
        mrexplore.parallel_env(
            world="symmetric_office", n_robots=2, merger=None, max_cycles=1_000_000
        )
        for _ in range(n_worlds)
    ]
    for k, env in enumerate(envs):
        env.reset(seed=seed + k)
    rng = np.random.default_rng(seed)

    def step(env: Any) -> None:
        if not env.agents:
            env.reset()
        a = rng.integers(0, 3, size=len(env.possible_agents))
        env.step({agent: int(a[j]) for j, agent in enumerate(env.possible_agents)})

    def alone() -> None:
        for env in envs:
            for _ in range(steps):
                step(env)

    def in_turn() -> None:
        for _ in range(steps):
            for env in envs:
                step(env)

    for env in envs:  # compile and warm every env first
        for _ in range(5):
            step(env)
    if ready is not None:
        ready()
    orders = {"alone": alone, "in turn": in_turn}
    totals = {name: dict.fromkeys(["step", *KERNELS], 0) for name in orders}
    for r in range(rounds):
        for name in list(orders) if r % 2 == 0 else list(orders)[::-1]:
            acc = dict.fromkeys(KERNELS, 0)
            with timed_kernels(acc):
                t = time.thread_time_ns()
                orders[name]()
                totals[name]["step"] += time.thread_time_ns() - t
            for label, ns in acc.items():
                totals[name][label] += ns
    world_steps = rounds * steps * n_worlds
    return {
        "worlds": n_worlds,
        "rounds": rounds,
        "steps": steps,
        "us_per_world_step": {
            name: {k: v / world_steps / 1e3 for k, v in parts.items()}
            for name, parts in totals.items()
        },
    }


_barrier: Any = None


def _init(barrier: Any) -> None:
    global _barrier
    _barrier = barrier


def _measure_in_worker(n_worlds: int, rounds: int, steps: int, seed: int) -> dict[str, Any]:
    return measure(n_worlds, rounds, steps, seed, ready=_barrier.wait)


def measure_at_once(
    n_processes: int, n_worlds: int, rounds: int = 6, steps: int = 25
) -> dict[str, Any]:
    """:func:`measure` in ``n_processes`` processes at once (process k seeded ``1000 k``; all
    timed from the moment every one is warm), the parts' mean over the processes."""
    if n_processes == 1:
        return measure(n_worlds, rounds, steps)
    ctx = multiprocessing.get_context("spawn")
    barrier = ctx.Barrier(n_processes)
    with ctx.Pool(n_processes, initializer=_init, initargs=(barrier,)) as pool:
        runs = pool.starmap(
            _measure_in_worker, [(n_worlds, rounds, steps, 1000 * k) for k in range(n_processes)]
        )
    return mean_of(runs)


def mean_of(runs: list[dict[str, Any]]) -> dict[str, Any]:
    """One result of several :func:`measure` results: each order's parts averaged over them,
    ``processes`` their number."""
    out = dict(runs[0])
    out["us_per_world_step"] = {
        order: {
            part: sum(r["us_per_world_step"][order][part] for r in runs) / len(runs)
            for part in parts
        }
        for order, parts in runs[0]["us_per_world_step"].items()
    }
    out["processes"] = len(runs)
    return out


def main() -> None:
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawTextHelpFormatter)
    p.add_argument("--worlds", type=int, default=32)
    p.add_argument("--rounds", type=int, default=6)
    p.add_argument("--steps", type=int, default=25)
    p.add_argument("--processes", type=int, default=1)
    a = p.parse_args()
    if a.worlds < 1 or a.rounds < 1 or a.steps < 1 or a.processes < 1:
        p.error("--worlds, --rounds, --steps and --processes must be positive")
    res = measure_at_once(a.processes, a.worlds, a.rounds, a.steps)
    at_once = f"; {a.processes} processes at once, their mean" if a.processes > 1 else ""
    print(
        f"{a.worlds} envs of symmetric_office, 2 robots, random actions, merging off; "
        f"{a.rounds} alternating rounds of {a.steps} steps each{at_once}; "
        "thread CPU per world-step, us"
    )
    labels = ["step", *KERNELS]
    print(f"{'order':10s}" + "".join(f"{k:>13s}" for k in labels) + f"{'rest':>13s}")
    for name, parts in res["us_per_world_step"].items():
        rest = parts["step"] - sum(parts[k] for k in KERNELS)
        print(f"{name:10s}" + "".join(f"{parts[k]:13.0f}" for k in labels) + f"{rest:13.0f}")


if __name__ == "__main__":
    main()
