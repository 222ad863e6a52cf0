"""``mrexplore demo``: one two-robot episode on the default symmetric world, as pictures.

Writes ``<out>/episode.gif`` (the episode), ``<out>/final.png`` (last frame: world, both own
maps, the fused map, one scale and a legend; above it a headline with the coverage the console
prints, below it the frame at the moment of the merge) and prints a summary, with, per robot
pair, when it merged and whether and how long a wrong merge was held (:class:`PairLedger`:
read from the env's evaluation against the truth after each step; nothing of it reaches the
robots or the merger).
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from itertools import combinations
from pathlib import Path
from typing import Any

import cv2
import numpy as np

from mrexplore.environment.evaluation import is_wrong_merge
from mrexplore.errors import ConfigError
from mrexplore.experiments.episode import run_episode
from mrexplore.experiments.task_time import make_team
from mrexplore.io_safety import atomic_path, check_out_dir, check_outputs, write_bytes
from mrexplore.render import format_coverage, write_video


@dataclass
class PairRecord:
    """One robot pair's merges over an episode (simulated seconds; evaluation only).

    Attributes:
        first_merge_time_s: when either robot first held a transform to the other (None:
            never).
        merged_wrongly_s: seconds either held a transform to the other that is a wrong merge
            (:func:`~mrexplore.environment.evaluation.is_wrong_merge`: >= 5 cells off the truth
            beyond drift).
        first_wrong_time_s: when that first happened (None: never).
    """

    first_merge_time_s: float | None = None
    merged_wrongly_s: float = 0.0
    first_wrong_time_s: float | None = None

    @property
    def wrong_merge(self) -> bool:
        """The pair held a wrong merge at some step."""
        return self.first_wrong_time_s is not None

    def text(self) -> str:
        """One line of the demo's summary."""
        if self.first_merge_time_s is None:
            return "never merged"
        merged = f"merged at t = {self.first_merge_time_s:.1f} s"
        if self.first_wrong_time_s is None:
            return f"{merged}, no wrong merge"
        return (
            f"{merged}, held a WRONG merge for {self.merged_wrongly_s:.1f} s "
            f"(from t = {self.first_wrong_time_s:.1f} s)"
        )


class PairLedger:
    """Per robot pair: when it merged and how long it held a wrong merge, read from the env's
    truth monitor (:mod:`mrexplore.environment.evaluation`, the same errors and threshold as
    the ``merged_wrongly_s`` info) after every step. Evaluation only: it reads the env, nothing
    goes back to a robot or the merger.

    Use: ``run_episode(..., prepare=ledger.bind, on_step=ledger.step)``. A goal-level env is read
    once per decision (its low-level env's state after the decision's last simulator step).
    """

    def __init__(self) -> None:
        self.env: Any = None
        self.pairs: dict[tuple[str, str], PairRecord] = {}
        self._last_s = 0.0  # simulated s of the last record

    def bind(self, penv: Any) -> None:
        """Read ``penv`` (the low-level env of a goal-level one) from now on."""
        self.env = getattr(penv, "low", penv)
        agents = list(self.env.possible_agents)
        self.pairs = {pair: PairRecord() for pair in combinations(agents, 2)}
        self._last_s = 0.0

    def step(self, step: int) -> None:
        """Record the state after step ``step`` (the ``on_step`` hook of ``run_episode``)."""
        ep = self.env.episode
        if ep is None or ep.truth is None:
            return
        now = float(ep.sim.time_s)
        dt_s, self._last_s = now - self._last_s, now
        errors = {
            a: ep.truth.merge_errors(a, ep.transforms.get(a, {})) for a in self.env.possible_agents
        }
        for (a, b), rec in self.pairs.items():
            pair_errors = [e for e in (errors[a].get(b), errors[b].get(a)) if e is not None]
            if not pair_errors:
                continue
            if rec.first_merge_time_s is None:
                rec.first_merge_time_s = now
            if any(is_wrong_merge(e) for e in pair_errors):
                rec.merged_wrongly_s += dt_s
                if rec.first_wrong_time_s is None:
                    rec.first_wrong_time_s = now


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
    ledger = PairLedger()
    res = run_episode(
        {"world": world, "n_robots": n_robots, **env_options},
        make_team(policy, agents, "explore"),
        seed,
        record_every=record_every,
        on_step=ledger.step,
        prepare=ledger.bind,
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
        # per pair, against the truth (evaluation only)
        "pairs": [
            {
                "robots": [a, b],
                "first_merge_time_s": rec.first_merge_time_s,
                "wrong_merge": rec.wrong_merge,
                "merged_wrongly_s": rec.merged_wrongly_s,
                "first_wrong_time_s": rec.first_wrong_time_s,
            }
            for (a, b), rec in ledger.pairs.items()
        ],
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
    pairs_txt = format_pairs(ledger.pairs)
    print(
        f"demo: {n_robots} robots on '{world}' (seed {seed}, policy {policy})\n"
        f"  task time {res.task_time_s:.1f} s simulated "
        f"({'target reached' if res.success else 'truncated'}), "
        f"coverage {format_coverage(res.coverage)}\n"
        f"  {merge_txt}{err_txt}\n"
        f"{pairs_txt}"
        f"  wrote {gif} and {out / 'final.png'} in {wall_s:.1f} s wall time"
    )
    return summary


def format_pairs(pairs: dict[tuple[str, str], PairRecord]) -> str:
    """The summary's pair lines (each ending in a newline; empty for one robot)."""
    if not pairs:
        return ""
    lines = ["  robot pairs (checked against the truth; the robots never see it):"]
    lines += [f"    {a} - {b}: {rec.text()}" for (a, b), rec in pairs.items()]
    wrong = [rec for rec in pairs.values() if rec.wrong_merge]
    if wrong:
        lines.append(
            f"  WARNING: {len(wrong)} of {len(pairs)} pairs held a wrong merge; the task time "
            "and coverage include it"
        )
    return "\n".join(lines) + "\n"
