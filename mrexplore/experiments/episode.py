"""Run one episode of the env with a team policy and record what an experiment needs."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

import mrexplore
from mrexplore.environment.evaluation import is_wrong_merge
from mrexplore.environment.infos import merge_error_of
from mrexplore.render import render_frame


@dataclass
class EpisodeResult:
    """What one episode measured (simulated seconds, shares in [0, 1]).

    Attributes:
        task_time_s: simulated time at the end of the episode.
        success: the task was completed (coverage target or goal reached), not truncated.
        coverage: final team coverage.
        times_s, coverages: the coverage curve, one entry per simulator step (step 0 = after
            reset; a goal-level env contributes every simulator step of its decisions).
        first_merge_time_s: when robot_0 was first merged (None if never, or single robot).
        merge_error: robot_0's merge error against the truth at the end (None if not merged).
        collisions: total collisions of the team.
        max_fused_contradiction: the largest ``fused_contradiction`` of any robot at any step
            (share of its own-or-fused map's claims that contradict the truth; NaN if never
            defined). Evaluation only, see :mod:`mrexplore.environment.parallel_env`.
        merged_wrongly_s: the largest, over robots, ``merged_wrongly_s`` at the end: simulated
            seconds a robot held a transform >= 5 cells off the truth.
        wrong_merge: some robot held a transform >= 5 cells off the truth at some step.
        merges_lost: the most times any robot went from merged to not merged (a re-check
            dropped its transform); 0 if it never merged or kept its merge.
        frames: rendered frames when recording, else empty.
        merge_frame: the frame rendered at the first merge, when recording.
    """

    task_time_s: float
    success: bool
    coverage: float
    times_s: list[float]
    coverages: list[float]
    first_merge_time_s: float | None
    merge_error: dict[str, float] | None
    collisions: int
    frames: list[NDArray[np.uint8]] = field(default_factory=list)
    merge_frame: NDArray[np.uint8] | None = None
    max_fused_contradiction: float = math.nan
    merged_wrongly_s: float = 0.0
    wrong_merge: bool = False
    merges_lost: int = 0

    def summary(self) -> dict[str, Any]:
        """JSON-friendly fields (no frames; NaN becomes None)."""
        c = self.max_fused_contradiction
        return {
            "task_time_s": self.task_time_s,
            "success": self.success,
            "coverage": self.coverage,
            "first_merge_time_s": self.first_merge_time_s,
            "merge_error": self.merge_error,
            "collisions": self.collisions,
            "max_fused_contradiction": None if math.isnan(c) else c,
            "merged_wrongly_s": self.merged_wrongly_s,
            "wrong_merge": self.wrong_merge,
            "merges_lost": self.merges_lost,
        }


class _MapQuality:
    """Running maxima of the env's map-accuracy infos over the robots and the steps."""

    def __init__(self) -> None:
        self.max_contradiction = math.nan
        self.wrong = False
        self.wrong_s = 0.0
        self._merged: dict[str, bool] = {}
        self._lost: dict[str, int] = {}

    @property
    def merges_lost(self) -> int:
        """The most merged -> not merged changes of any robot so far."""
        return max(self._lost.values(), default=0)

    def add(self, infos: Mapping[str, Mapping[str, Any]]) -> None:
        for agent, info in infos.items():
            merged = bool(info.get("merged", False))
            if self._merged.get(agent, False) and not merged:
                self._lost[agent] = self._lost.get(agent, 0) + 1
            self._merged[agent] = merged
            c = float(info.get("fused_contradiction", -1.0))  # -1: no claim yet
            if c >= 0 and not c <= self.max_contradiction:
                self.max_contradiction = c
            err = merge_error_of(info)
            if err is not None and is_wrong_merge(err):
                self.wrong = True
            self.wrong_s = max(self.wrong_s, float(info.get("merged_wrongly_s", 0.0)))


def run_episode(
    env_options: dict[str, Any],
    team_policy: Any,
    seed: int,
    record_every: int = 0,
    on_step: Callable[[int], None] | None = None,
    prepare: Callable[[Any], None] | None = None,
) -> EpisodeResult:
    """Run one episode to its end.

    Args:
        env_options: options of :func:`mrexplore.parallel_env`.
        team_policy: an object with ``reset(rng)`` and ``act(views) -> {agent: action}``
            (:class:`mrexplore.policies.TeamPolicy`); it sees only ``env.robot_view(agent)``.
        seed: the episode seed (env reset seed; the policy gets its own Generator from it).
        record_every: render a frame every this many steps (0 = no frames).
        on_step: called with the step number after each step (progress bars).
        prepare: called with the env once it is built, before ``reset`` (e.g. to bind a
            benchmark's oracle merger to the env's simulator).
    """
    penv = mrexplore.parallel_env(**env_options)  # frames: drawn from snapshots
    if prepare is not None:
        prepare(penv)
    obs, infos = penv.reset(seed=seed)
    quality = _MapQuality()
    quality.add(infos)
    # Trained policies act on the env's observations; planners act on robot views.
    uses_obs = bool(getattr(team_policy, "uses_observations", False))
    team_policy.reset(np.random.default_rng([seed, 1]))
    a0 = penv.possible_agents[0]
    times, covs = [0.0], [float(infos[a0]["coverage"])]
    frames: list[NDArray[np.uint8]] = []
    merge_frame = None
    step = 0
    if record_every:
        frames.append(render_frame(penv.snapshot()))
    done = False
    terminated = False
    info0 = infos[a0]
    while not done:
        if uses_obs:
            actions = team_policy.act_obs(obs)
        else:
            actions = team_policy.act({a: penv.robot_view(a) for a in penv.agents})
        obs, _, terms, truncs, infos = penv.step(actions)
        step += 1
        info0 = infos[a0]
        quality.add(infos)
        # A goal-level env runs several simulator steps per step: take the curve of them all.
        trace = getattr(penv, "step_trace", None)
        if trace:
            times.extend(t for t, _ in trace)
            covs.extend(c for _, c in trace)
        else:
            times.append(float(info0["task_time_s"]))
            covs.append(float(info0["coverage"]))
        terminated = bool(terms[a0])
        done = terminated or bool(truncs[a0])
        if record_every:
            if merge_frame is None and info0["merged"]:
                merge_frame = render_frame(penv.snapshot())
            if step % record_every == 0 or done:
                frames.append(render_frame(penv.snapshot()))
        if on_step is not None:
            on_step(step)
    collisions = sum(int(i["collisions"]) for i in infos.values())
    first = float(info0["first_merge_time_s"])  # -1: never merged
    penv.close()
    return EpisodeResult(
        task_time_s=float(info0["task_time_s"]),
        success=terminated,
        coverage=float(info0["coverage"]),
        times_s=times,
        coverages=covs,
        first_merge_time_s=None if first < 0 else first,
        merge_error=merge_error_of(info0),
        collisions=collisions,
        frames=frames,
        merge_frame=merge_frame,
        max_fused_contradiction=quality.max_contradiction,
        merged_wrongly_s=quality.wrong_s,
        wrong_merge=quality.wrong,
        merges_lost=quality.merges_lost,
    )
