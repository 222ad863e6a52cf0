"""Goal-level actions: the exploration env where one step is one decision among candidate goals.

Build it with ``mrexplore.parallel_env(action_mode="goal", ...)`` (the other options are those
of :class:`~mrexplore.environment.config.EnvConfig` and go to the low-level env it wraps) or
wrap an env yourself: ``GoalActionEnv(mrexplore.parallel_env(...))``.

At each decision every robot chooses one of ``goal_candidates`` (K) candidate goals drawn from
what it knows: the reachable frontiers of its own map, or of the fused map once merged (the
frontier policies' candidate machinery, :class:`~mrexplore.policies.candidates.GoalExecutor`).
Our planner and path follower then drive every robot to its goal over several simulator steps;
the decision ends, for the whole team, when some robot needs a new one (it reached its goal,
the goal stopped being a frontier, it is stuck or collided, or ``goal_max_steps`` simulator
steps passed) or the episode ends. So a robot still on its way decides again too: its current
target is among its candidates (feature ``is_current``) and choosing it keeps going.
With ``goal_turns=1`` the robots choose in turn (Burgard's coordinated exploration): one env
step per robot, each robot's claim features holding the targets chosen just before it.

===================  ==========================================================================
Agents               as the low-level env: ``robot_0`` ... ``robot_{n-1}``
Action space         ``Discrete(K)``: row ``i`` of the observation (K = ``goal_candidates``, 8)
Observation space    ``Dict(observation=Box(0, 10, (K, F), float32), action_mask=Box(0, 1, (K,),
                     int8))``, F = ``len(FEATURE_NAMES)`` (16): one row per candidate, nearest
                     first, features in :data:`~mrexplore.policies.candidates.FEATURE_NAMES`
                     (path length, straight distance, frontier size, rank, heading error,
                     current target, Burgard claim discount, distances to teammates' targets
                     and positions, merged, time, number and total size of frontiers). Mask 1 =
                     a valid choice; with no reachable frontier only row 0 is valid and means
                     *wait*. A masked choice falls back to row 0. :meth:`GoalActionEnv.
                     action_masks` gives the masks too (sb3-contrib's ``MaskablePPO``, through
                     :class:`mrexplore.wrappers.action_masks.VecActionMasks`).
Reward               the sum of the low-level team rewards over the decision's simulator steps,
                     so returns are in the low-level units (``reward_mode="time"``: minus the
                     simulated seconds; task times compare with the frontier policies').
Termination          as the low-level env, at the simulator step it happens.
Infos                the low-level infos of the decision's last step (``task_time_s`` in
                     simulated seconds), plus ``decision_steps`` (simulator steps of this
                     decision, int), ``n_candidates`` (reachable frontiers, int) and, with
                     ``goal_turns=1``, ``on_turn`` (bool: this robot chooses at the next step).
===================  ==========================================================================

No ground truth reaches the candidates or features: they come from
:meth:`~mrexplore.environment.parallel_env.MultiRobotExplorationEnv.robot_view` and teammates'
announced targets (only once merged, only in radio range, moved with estimated transforms).
:attr:`GoalActionEnv.step_trace` holds the ``(task_time_s, coverage)`` of every simulator step
of the last decision, for experiments that measure times to a coverage level.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Any, ClassVar

import gymnasium
import numpy as np
from numpy.typing import NDArray
from pettingzoo import ParallelEnv

from mrexplore.errors import ConfigError, WorldError
from mrexplore.policies.candidates import (
    FEATURE_MAX,
    FEATURE_NAMES,
    GAIN_FEATURE_NAMES,
    GoalExecutor,
    candidate_features,
    gain_features,
    teammate_claims,
)
from mrexplore.types import RobotView

AgentID = str
ACTION_MODES = ("low", "goal")
#: Draws of a random world tried at ``reset`` before a generator's error is passed on.
WORLD_RETRIES = 3
#: What ``step`` returns: observations, rewards, terminations, truncations, infos per agent.
StepResult = tuple[
    dict[AgentID, dict[str, NDArray[Any]]],
    dict[AgentID, float],
    dict[AgentID, bool],
    dict[AgentID, bool],
    dict[AgentID, dict[str, Any]],
]
#: The ``parallel_env`` options that belong to the goal level (the rest go to the low level).
GOAL_OPTIONS = ("goal_candidates", "goal_max_steps", "goal_memory", "goal_gain", "goal_turns")


@dataclass(frozen=True)
class GoalConfig:
    """Options of the goal level.

    Attributes:
        goal_candidates: K, candidate goals per decision (rows of the observation), >= 1.
        goal_max_steps: simulator steps per decision at most (10 = 2.5 s, the frontier
            policies' ``replan_every``), >= 1. Above 10 it also raises the executors'
            ``replan_every`` (the age at which a plan is renewed) to match, unless
            ``executor_options`` sets it.
        goal_memory: 0 (default) or 1: frame stacking aligned to candidates. With 1, every row
            also holds the features the same frontier (its target within 1 m) had at the
            previous decision (zeros when it is new), so the observation is ``(K, 2F)``: the
            policy sees frontiers shrink (a teammate is exploring there) or paths shorten.
        goal_gain: 0 (default) or 1: append to every row the information-gain features
            :data:`~mrexplore.policies.candidates.GAIN_FEATURE_NAMES` (share of unknown cells
            around the target within 1 m and within the sensor range), before the memory
            columns: ``F`` becomes 18.
        goal_turns: 0 (default) or 1: the robots choose in turn, as in Burgard's coordinated
            exploration. A decision then takes one env step per live robot (sorted order): at
            each, only the robot on turn has a choice (its ``info["on_turn"]`` is True), and its
            ``claim`` and ``mate_target_m`` features already hold the targets the robots before
            it chose in this decision; the others' masks allow row 0 only and their actions
            are ignored. The simulator runs after the last robot's turn; the turns before it
            return reward 0 and no simulator step (``decision_steps`` 0).
    """

    goal_candidates: int = 8
    goal_max_steps: int = 10
    goal_memory: int = 0
    goal_gain: int = 0
    goal_turns: int = 0

    def __post_init__(self) -> None:
        for name in GOAL_OPTIONS:
            v = getattr(self, name)
            lo, hi = (0, 1) if name in ("goal_memory", "goal_gain", "goal_turns") else (1, 10**6)
            if isinstance(v, bool) or not isinstance(v, (int, np.integer)) or not lo <= v <= hi:
                raise ConfigError(f"{name} must be an integer in [{lo}, {hi}], got {v!r}")


def split_options(options: dict[str, Any]) -> tuple[str, GoalConfig | None, dict[str, Any]]:
    """``(action_mode, goal config or None, low-level options)`` of ``parallel_env`` options.

    Raises:
        ConfigError: an unknown ``action_mode``, or goal options with ``action_mode="low"``.
    """
    opts = dict(options)
    mode = opts.pop("action_mode", "low")
    if mode not in ACTION_MODES:
        raise ConfigError(f"action_mode must be one of {ACTION_MODES}, got {mode!r}")
    goal = {k: opts.pop(k) for k in GOAL_OPTIONS if k in opts}
    if mode == "low":
        if goal:
            raise ConfigError(f"{', '.join(goal)} need action_mode='goal'")
        return mode, None, opts
    return mode, GoalConfig(**goal), opts


class GoalActionEnv(ParallelEnv[AgentID, dict[str, NDArray[Any]], int]):
    """A low-level :class:`~mrexplore.environment.parallel_env.MultiRobotExplorationEnv` driven
    by goal-level decisions (see the module docstring).

    Args:
        low: the low-level env (not reset yet, or reset: ``reset`` starts over).
        config: the goal-level options.
        executor_options: options of every robot's
            :class:`~mrexplore.policies.candidates.GoalExecutor` (frontier machinery).
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "mrexplore_goal_v0",
        "render_modes": ["human", "rgb_array"],
        "is_parallelizable": True,
        "render_fps": 4,
    }

    def __init__(
        self,
        low: Any,
        config: GoalConfig | None = None,
        executor_options: dict[str, Any] | None = None,
    ) -> None:
        self.low = low
        self.config = config or GoalConfig()
        self.render_mode = low.render_mode
        self.possible_agents: list[AgentID] = list(low.possible_agents)
        self.agents: list[AgentID] = []
        f_row = len(FEATURE_NAMES) + len(GAIN_FEATURE_NAMES) * self.config.goal_gain
        k, f = self.config.goal_candidates, f_row * (1 + self.config.goal_memory)
        self._obs_space = gymnasium.spaces.Dict(
            {
                "observation": gymnasium.spaces.Box(0.0, FEATURE_MAX, (k, f), np.float32),
                "action_mask": gymnasium.spaces.Box(0, 1, (k,), np.int8),
            }
        )
        self._act_space: gymnasium.spaces.Discrete = gymnasium.spaces.Discrete(k)
        # A decision also ends at the executor's age re-plan (``replan_every``, 10 by default):
        # unless given, it grows with goal_max_steps, else a longer decision would be cut at 10.
        self._executor_options = {
            "replan_every": max(10, self.config.goal_max_steps),
            **(executor_options or {}),
        }
        # the square of the far gain feature: what one scan from the target could reveal
        self._sensor_range_m = float(getattr(getattr(low, "config", None), "max_range_m", 4.0))
        self.executors: dict[AgentID, GoalExecutor] = {}
        self._obs: dict[AgentID, dict[str, NDArray[Any]]] = {}
        self._index: dict[AgentID, NDArray[np.int64]] = {}
        self._n_cands: dict[AgentID, int] = {}
        # goal_turns: what each robot's features are built from at this decision (candidates,
        # view, target before it, gain and memory columns), so a turn can rebuild them
        self._parts: dict[AgentID, tuple[Any, RobotView, Any, Any, Any]] = {}
        # goal_turns: the targets before this decision, the order of turns, whose turn it is,
        # and the low-level infos of the last simulator step (returned again by the turns)
        self._start_targets: dict[AgentID, tuple[int, int] | None] = {}
        self._order: list[AgentID] = []
        self._turn = 0
        self._low_infos: dict[AgentID, dict[str, Any]] = {}
        # goal_memory: per agent, the (rows, 2) targets and (rows, F) features of the last
        # proposal's valid rows
        self._prev: dict[AgentID, tuple[NDArray[np.float64], NDArray[np.float32]]] = {}
        #: ``(task_time_s, coverage)`` after every simulator step of the last decision.
        self.step_trace: list[tuple[float, float]] = []

    # ------------------------------------------------------------------ spaces
    def observation_space(self, agent: AgentID) -> gymnasium.spaces.Dict:
        """``Dict(observation=Box(0, 10, (K, F), float32), action_mask=Box(0, 1, (K,), int8))``."""
        self._check_agent(agent)
        return self._obs_space

    def action_space(self, agent: AgentID) -> gymnasium.spaces.Discrete:
        """``Discrete(K)``: the row of the chosen candidate."""
        self._check_agent(agent)
        return self._act_space

    # ------------------------------------------------------------------ API
    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[AgentID, dict[str, NDArray[Any]]], dict[AgentID, dict[str, Any]]]:
        """Reset the low-level env (same seed, same world and starts) and propose goals.

        A world generator that finds no valid floor for this seed's stream (it happens about
        once in a thousand draws at the smallest sizes, e.g. ``twin_wings`` 12 x 12 m) is asked
        again with the env's next stream (``reset(seed=None)`` continues the same Generator),
        up to :data:`WORLD_RETRIES` times, so one bad draw does not end a training run; the
        result is still a function of the seed.
        """
        for attempt in range(WORLD_RETRIES + 1):
            try:
                _, infos = self.low.reset(seed=seed if attempt == 0 else None, options=options)
                break
            except WorldError:
                if attempt == WORLD_RETRIES:
                    raise
        self.executors = {a: GoalExecutor(**self._executor_options) for a in self.possible_agents}
        for ex in self.executors.values():
            ex.reset(np.random.default_rng(0))  # deterministic: the rng is unused
        self.agents = list(self.low.agents)
        self.step_trace = []
        self._prev = {}
        self._propose_all()
        self._low_infos = {a: infos[a] for a in self.agents}
        out = {a: self._info(a, infos[a], 0) for a in self.agents}
        return {a: self._obs[a] for a in self.agents}, out

    def step(self, actions: dict[AgentID, int]) -> StepResult:
        """One decision: commit every robot's choice, then run the simulator until some robot
        needs a new decision, ``goal_max_steps`` steps passed, or the episode ended. With
        ``goal_turns``, one robot's turn (see :class:`GoalConfig`)."""
        if not self.agents:
            raise RuntimeError("step() called on an env that is not running: call reset() first")
        low = self.low
        if self.config.goal_turns:
            on_turn = self._order[self._turn]
            self._commit(on_turn, actions.get(on_turn, 0))
            self._turn += 1
            if self._turn < len(self._order):
                return self._next_turn(on_turn)
        else:
            for a in self.agents:
                self._commit(a, actions.get(a, 0))
        total = 0.0
        n = 0
        self.step_trace = []
        a0 = self.agents[0]
        while True:
            acts = {a: self.executors[a].next_action(low.robot_view(a)) for a in low.agents}
            _, rewards, terms, truncs, infos = low.step(acts)
            n += 1
            total += float(rewards[a0])
            self.step_trace.append((float(infos[a0]["task_time_s"]), float(infos[a0]["coverage"])))
            if bool(terms[a0]) or bool(truncs[a0]):
                break
            # Every robot observes (its progress counters advance once per step).
            need = [self.executors[a].observe(low.robot_view(a)) for a in low.agents]
            if any(need) or n >= self.config.goal_max_steps:
                break
        agents = list(self.agents)
        done = not low.agents
        if not done:
            self._propose_all()
        self._low_infos = {a: infos[a] for a in agents}
        obs = {a: self._obs[a] for a in agents}
        rewards_out = dict.fromkeys(agents, total)
        terms_out = {a: bool(terms[a]) for a in agents}
        truncs_out = {a: bool(truncs[a]) for a in agents}
        infos_out = {a: self._info(a, infos[a], n) for a in agents}
        self.agents = list(low.agents)
        if self.render_mode == "human":
            self.render()
        return obs, rewards_out, terms_out, truncs_out, infos_out

    def action_masks(self, agent: AgentID | None = None) -> NDArray[np.int8]:
        """The valid rows: ``(K,)`` int8 for ``agent``, else ``(n_agents, K)`` for
        ``possible_agents`` (zeros but row 0 for agents that are done)."""
        if agent is not None:
            self._check_agent(agent)
            return self._obs[agent]["action_mask"].copy()
        k = self.config.goal_candidates
        out = np.zeros((len(self.possible_agents), k), dtype=np.int8)
        for i, a in enumerate(self.possible_agents):
            out[i] = self._obs[a]["action_mask"] if a in self._obs else 0
            if not out[i].any():
                out[i, 0] = 1
        return out

    def state(self) -> NDArray[Any]:
        """The low-level state (all robots' map observations stacked; no ground truth)."""
        return np.asarray(self.low.state())

    def robot_view(self, agent: AgentID) -> RobotView:
        """The low-level :meth:`robot_view` (what ``agent`` knows; no ground truth)."""
        return self.low.robot_view(agent)

    @property
    def map_resolution_m(self) -> float:
        """Metres per map cell (map protocol of :class:`~mrexplore.wrappers.MapMergeWrapper`)."""
        return float(self.low.map_resolution_m)

    def local_map(self, agent: AgentID) -> NDArray[np.int8]:
        """The agent's own map (map protocol)."""
        return self.low.local_map(agent)

    def own_pose_cell(self, agent: AgentID) -> tuple[float, float, float]:
        """The agent's own pose in its own cells (map protocol)."""
        return self.low.own_pose_cell(agent)

    @property
    def coverage(self) -> float:
        """The low-level team coverage."""
        return float(self.low.coverage)

    def render(self) -> NDArray[np.uint8] | None:
        """The low-level frame."""
        return self.low.render()

    def close(self) -> None:
        """Close the low-level env."""
        self.low.close()

    # ------------------------------------------------------------------ internals
    def _commit(self, agent: AgentID, action: Any) -> None:
        """Commit ``agent``'s chosen row (a masked or missing choice falls back to row 0)."""
        row = int(action if action is not None else 0)
        mask = self._obs[agent]["action_mask"]
        if not 0 <= row < mask.size or not mask[row]:
            row = 0
        self.executors[agent].commit(int(self._index[agent][row]), self.low.robot_view(agent))

    def _propose_all(self) -> None:
        """New candidates, features and masks for every live robot (in sorted order); with
        ``goal_turns``, the first robot's turn."""
        low = self.low
        k = self.config.goal_candidates
        targets = {a: ex.target for a, ex in self.executors.items()}
        self._start_targets = targets
        for a in sorted(low.agents):
            view = low.robot_view(a)
            ex = self.executors[a]
            current = ex.target
            cands = ex.propose(view)
            claims = teammate_claims(view, targets)
            feats, mask, index = candidate_features(cands, view, k, current, claims)
            gain = None
            if self.config.goal_gain:
                gain = gain_features(view, cands, index, self._sensor_range_m)
                feats = np.concatenate([feats, gain], axis=1)
            if self.config.goal_memory:
                feats = self._with_memory(a, feats, index, cands, float(view.resolution_m))
            if self.config.goal_turns:  # a later turn rebuilds the features with new claims
                prev = feats[:, feats.shape[1] // 2 :] if self.config.goal_memory else None
                self._parts[a] = (cands, view, current, gain, prev)
            self._obs[a] = {"observation": feats, "action_mask": mask}
            self._index[a] = index
            self._n_cands[a] = 0 if cands is None else len(cands)
        if self.config.goal_turns:
            self._order = sorted(low.agents)
            self._turn = 0
            for a in self._order[1:]:
                self._obs[a] = self._waiting(a)

    def _waiting(self, agent: AgentID) -> dict[str, NDArray[Any]]:
        """``agent``'s observation while another robot is on turn: row 0 is its only choice."""
        mask = np.zeros(self.config.goal_candidates, dtype=np.int8)
        mask[0] = 1
        return {"observation": self._obs[agent]["observation"], "action_mask": mask}

    def _next_turn(self, done: AgentID) -> StepResult:
        """The next robot's turn (``done`` has just chosen): its features rebuilt with the
        targets chosen so far in this decision; no simulator step, reward 0."""
        a = self._order[self._turn]
        chosen = set(self._order[: self._turn])
        targets = {
            b: (ex.target if b in chosen else self._start_targets.get(b))
            for b, ex in self.executors.items()
        }
        cands, view, current, gain, prev = self._parts[a]
        k = self.config.goal_candidates
        feats, mask, index = candidate_features(
            cands, view, k, current, teammate_claims(view, targets)
        )
        feats = np.concatenate([x for x in (feats, gain, prev) if x is not None], axis=1)
        self._obs[a] = {"observation": feats, "action_mask": mask}
        self._index[a] = index
        self._obs[done] = self._waiting(done)
        self.step_trace = []
        agents = list(self.agents)
        return (
            {b: self._obs[b] for b in agents},
            dict.fromkeys(agents, 0.0),
            dict.fromkeys(agents, False),
            dict.fromkeys(agents, False),
            {b: self._info(b, self._low_infos[b], 0) for b in agents},
        )

    def _with_memory(
        self,
        agent: AgentID,
        feats: NDArray[np.float32],
        index: NDArray[np.int64],
        cands: Any,
        res: float,
    ) -> NDArray[np.float32]:
        """``feats`` with each row's features at the previous decision appended (0 if new)."""
        valid = np.flatnonzero(index >= 0)
        targets = (
            cands.targets[index[valid]].astype(np.float64)
            if valid.size
            else np.zeros((0, 2), dtype=np.float64)
        )
        prev = np.zeros_like(feats)
        old = self._prev.get(agent)
        if old is not None and valid.size and old[0].shape[0]:
            d = np.hypot(
                targets[:, None, 0] - old[0][None, :, 0], targets[:, None, 1] - old[0][None, :, 1]
            )
            j = np.argmin(d, axis=1)
            hit = d[np.arange(valid.size), j] * res <= 1.0
            prev[valid[hit]] = old[1][j[hit]]
        self._prev[agent] = (targets, feats[valid].copy())
        return np.concatenate([feats, prev], axis=1)

    def _info(self, agent: AgentID, info: dict[str, Any], steps: int) -> dict[str, Any]:
        out = dict(info)
        out["decision_steps"] = int(steps)
        out["n_candidates"] = int(self._n_cands.get(agent, 0))
        if self.config.goal_turns:
            out["on_turn"] = bool(
                self._order and agent == self._order[self._turn % len(self._order)]
            )
        return out

    def _check_agent(self, agent: AgentID) -> None:
        if agent not in self.possible_agents:
            raise KeyError(f"unknown agent {agent!r}; agents are {self.possible_agents}")
