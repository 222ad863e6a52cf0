"""The multi-robot exploration environment (PettingZoo ``ParallelEnv``).

Robots with 2-D lidars map a world with symmetric parts, each on its own occupancy grid in its
own frame; a map merger fuses their maps every step into the shared observation; the reward
measures coverage time.

===================  ==========================================================================
Agents               ``robot_0`` ... ``robot_{n-1}`` (``n_robots=1`` is the single-robot baseline)
Action space         ``Discrete(4)``: 0 forward (0.125 m), 1 turn left (22.5 deg), 2 turn right,
                     3 stay (:class:`mrexplore.robot.Action`; defaults 0.5 m/s, pi/2 rad/s, 0.25 s)
Observation space    ``Box(0, 255, (8, 64, 64), uint8)``, robot-centred, own frame; see
                     :mod:`mrexplore.environment.observations`. Built from the fused map once
                     the robot's map is merged, else from its own map. Never from the truth.
                     ``obs_layout="hwc"``: ``(64, 64, 8)``; ``obs_dtype="float32"``: [0, 1].
State space          ``(8 * n, 64, 64)`` (``hwc``: ``(64, 64, 8 * n)``): all observations
                     stacked on the channel axis.
Reward               team reward (same for all): ``"time"``: ``-dt_s`` per step, so the return
                     is minus the task time; ``"coverage"``: ``coverage_reward_per_m2`` x newly
                     observed m^2 minus ``time_penalty_per_s * dt_s``.
Termination          explore: coverage >= ``target_coverage`` (0.95), see ``coverage_mode``;
                     navigate: ``robot_0`` within ``goal_radius_m`` of its goal.
Truncation           simulated time >= ``max_time_s`` (600 s) or steps >= ``max_cycles``; infos
                     then carry ``TimeLimit.truncated = True`` (False on every other step).
===================  ==========================================================================

``infos[agent]``: the same flat keys on every reset and step (:data:`INFO_KEYS`; table with
units in ``docs/clients.md``), each a bool, an int or a float, ``-1.0`` where unknown (every such
value is >= 0 when known; not NaN, which Gymnasium's and PettingZoo's checkers take for
non-determinism as NaN != NaN; never None, never a nested dict, so TorchRL and Gymnasium's vector
envs turn them into one array per key):
``coverage`` (the share of reachable free cells that termination and the ``"coverage"`` reward
use: with ``coverage_mode="observed"`` (default) the team's union of observed cells; with
``"held"`` the largest, over robots, share that the robot's own-or-fused map marks free at the
true place, so knowledge placed by a wrong merge does not count), ``task_time_s``, ``step``,
``merged``, ``score`` (-1 until merged), ``first_merge_time_s`` (-1 until merged),
``merge_error_cells``, ``merge_error_deg``, ``merge_error_drift_cells`` (the worst merged
teammate's mean displacement and rotation error against the truth and the drift allowance; -1
until merged; evaluation only, policies must not read them), ``collisions`` (this robot's count),
``collided`` (this step), ``goal_given``, ``goal_reached`` (navigation; False when exploring, where
``task_time_s`` counts from the moment the goal is given, after ``nav_warmup_s`` of exploring),
``TimeLimit.truncated`` (True on a time-limit end). With ``info_extra=True`` also ``extra``: a
nested dict (``merge_error`` as a dict or None, ``merge_errors`` per teammate) that clients which
need flat infos must drop.

Map accuracy, evaluation only (scored against the truth; nothing of it reaches a robot, a policy
or the merger), two float keys present on every step:

- ``fused_contradiction``: the share of the claims of the agent's current own-or-fused map (its
  known-free and known-occupied cells, warped into the world with the true transform) that
  contradict the truth: a free cell on a true wall, or an occupied cell with no true wall within
  1 cell (:class:`mrexplore.truth.MapScorer`). About 0.005 for a correct map without odometry
  noise; a wrong merge raises it. -1.0 when the map makes no claim inside the world. Recomputed
  only when the fused map changed (:meth:`mrexplore.merge.fusion.FusionStage.fused_version`).
- ``merged_wrongly_s``: simulated seconds since reset during which this agent held a transform
  to some teammate whose merge error (``translation_cells``, the mean displacement of the
  teammate's known cells) was >= ``WRONG_MERGE_CELLS`` (5) cells more than odometry drift
  explains (``merge_error_drift_cells``, 0 with exact odometry; :func:`is_wrong_merge`);
  0.0 when never.

Policies read what a robot knows through :meth:`MultiRobotExplorationEnv.robot_view`.

Version history: v0 (this): first release; infos flat and fixed (``merge_error`` became
``merge_error_cells``/``_deg``/``_drift_cells``, None became NaN); ``obs_layout``/``obs_dtype``.
"""

from __future__ import annotations

import copy
import math
import warnings
from collections.abc import Mapping
from typing import Any, ClassVar

import gymnasium
import numpy as np
from numpy.typing import NDArray
from pettingzoo import ParallelEnv

from mrexplore.environment.config import EnvConfig
from mrexplore.environment.observations import ObservationBuilder, ObservationFormat
from mrexplore.environment.view import RobotView
from mrexplore.errors import ConfigError
from mrexplore.grid import UNKNOWN, apply_transform, invert_transform, transform_angle
from mrexplore.merge.fusion import FusionStage
from mrexplore.robot import Action, RobotConfig
from mrexplore.sensors import LidarConfig
from mrexplore.sim import SimConfig, Simulation
from mrexplore.truth import IncrementalScore, MapScorer, nearest_sampling
from mrexplore.world import World, load_world

AgentID = str

#: The keys of ``infos[agent]``, on every reset and step, in this order (plus ``"extra"`` with
#: ``info_extra=True``). Values: bool, int or float (``UNKNOWN_INFO`` where unknown).
INFO_KEYS = (
    "coverage",
    "task_time_s",
    "step",
    "merged",
    "score",
    "first_merge_time_s",
    "merge_error_cells",
    "merge_error_deg",
    "merge_error_drift_cells",
    "collisions",
    "collided",
    "fused_contradiction",
    "merged_wrongly_s",
    "goal_given",
    "goal_reached",
    "TimeLimit.truncated",
)

#: The value of a float info that is not known (yet): never merged, no map claim. Every such
#: value is >= 0 when known. Not NaN: Gymnasium's ``check_env`` and PettingZoo's seed test
#: compare infos with ``==``, and NaN != NaN.
UNKNOWN_INFO = -1.0

#: A merge error (mean displacement of the teammate's known cells) at least this large is a
#: wrong merge (cells; the merge benchmark's threshold too).
WRONG_MERGE_CELLS = 5.0


def is_wrong_merge(err: Mapping[str, float]) -> bool:
    """A merge error (``_merge_error``'s dict) that drift cannot explain: the mean displacement
    of the teammate's cells exceeds ``WRONG_MERGE_CELLS`` plus the odometry-drift allowance.

    >>> is_wrong_merge({"translation_cells": 6.0, "rotation_deg": 2.0, "drift_cells": 3.0})
    False
    >>> is_wrong_merge({"translation_cells": 310.0, "rotation_deg": 0.0, "drift_cells": 0.0})
    True
    """
    return err["translation_cells"] >= WRONG_MERGE_CELLS + err.get("drift_cells", 0.0)


def merge_error_of(info: Mapping[str, Any]) -> dict[str, float] | None:
    """The merge error dict (``translation_cells``, ``rotation_deg``, ``drift_cells``) of one
    agent's flat infos, or None when it holds no transform (the flat keys are -1).

    >>> merge_error_of({"merge_error_cells": 0.5, "merge_error_deg": 0.2,
    ...                 "merge_error_drift_cells": 0.0})
    {'translation_cells': 0.5, 'rotation_deg': 0.2, 'drift_cells': 0.0}
    >>> merge_error_of({"merge_error_cells": -1.0, "merge_error_deg": -1.0,
    ...                 "merge_error_drift_cells": -1.0}) is None
    True
    """
    cells = float(info["merge_error_cells"])
    if cells < 0:
        return None
    return {
        "translation_cells": cells,
        "rotation_deg": float(info["merge_error_deg"]),
        "drift_cells": float(info["merge_error_drift_cells"]),
    }


class MultiRobotExplorationEnv(ParallelEnv[AgentID, NDArray[Any], int]):
    """PettingZoo parallel env; build it with :func:`mrexplore.parallel_env`.

    Options: :class:`~mrexplore.environment.config.EnvConfig`.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "mrexplore_v0",
        "render_modes": ["human", "rgb_array"],
        "is_parallelizable": True,
        "render_fps": 8,
    }

    def __init__(self, render_mode: str | None = None, **options: Any) -> None:
        self.config = EnvConfig.from_kwargs(**options)
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, "
                f"got {render_mode!r}"
            )
        self.render_mode = render_mode
        cfg = self.config
        self.possible_agents: list[AgentID] = [f"robot_{i}" for i in range(cfg.n_robots)]
        self.agents: list[AgentID] = []
        self._random_world = isinstance(cfg.world, str) and cfg.world.startswith("random:")
        # A fixed world is loaded once, here, so a bad name or file fails at construction.
        self._fixed_world: World | None = None if self._random_world else load_world(cfg.world)
        probe = self._fixed_world or load_world(cfg.world, rng=np.random.default_rng(0))
        self._resolution_m = probe.resolution_m
        self._obs_builder = ObservationBuilder(
            self._resolution_m,
            cfg.global_view_m,
            cfg.local_view_m,
            cfg.obs_size_px,
            heading_up=cfg.obs_heading_up,
        )
        # What the client reads: channels first or last, uint8 or float in [0, 1].
        self._obs_format = ObservationFormat(cfg.obs_layout, cfg.obs_dtype)
        self._obs_space = self._obs_format.space(self._obs_builder.shape)
        self._act_space: gymnasium.spaces.Discrete = gymnasium.spaces.Discrete(len(Action))
        n, s = cfg.n_robots, cfg.obs_size_px
        self.state_space = self._obs_format.space((self._obs_builder.shape[0] * n, s, s))
        self._sim_config = SimConfig(
            robot=RobotConfig(
                radius_m=cfg.radius_m,
                speed_mps=cfg.speed_mps,
                turn_rate_rps=cfg.turn_rate_rps,
                dt_s=cfg.dt_s,
            ),
            lidar=LidarConfig(
                n_beams=cfg.n_beams,
                fov_rad=math.radians(cfg.fov_deg),
                max_range_m=cfg.max_range_m,
                noise_std_m=cfg.range_noise_m,
            ),
            aligned_headings=cfg.aligned_headings,
            odom_noise_trans=cfg.odom_noise_trans,
            odom_noise_rot=cfg.odom_noise_rot,
            odom_noise_rot_per_m=cfg.odom_noise_rot_per_m,
            min_start_separation_m=cfg.min_start_separation_m,
        )
        self.fusion = FusionStage(
            self.possible_agents,
            merger=cfg.merger,
            merge_every=cfg.merge_every,
            recheck_every=cfg.recheck_every,
            merge_latency_steps=cfg.merge_latency_steps,
            merge_options=cfg.merge_options,
            resolution_m=self._resolution_m,
        )
        self._rng: np.random.Generator | None = None
        self._run_rng = np.random.default_rng(0)
        self.sim: Simulation | None = None
        self.world: World | None = None
        self._obs: dict[AgentID, NDArray[Any]] = {}
        self._collisions = np.zeros(cfg.n_robots, dtype=np.int64)
        self._collided = np.zeros(cfg.n_robots, dtype=bool)  # this step's bumps (infos)
        self._goal_world: NDArray[np.float64] | None = None
        self._goal_cell: tuple[float, float] | None = None
        self._done = True
        self._renderer: Any = None
        self._heard: dict[tuple[AgentID, AgentID], tuple[float, float]] = {}
        self._current_links: NDArray[np.bool_] | None = None
        self._transforms: dict[AgentID, dict[AgentID, NDArray[np.float64]]] = {}
        self._error_cache: dict[
            tuple[int, int], tuple[int, NDArray[np.float64], dict[str, float]]
        ] = {}
        self._last_coverage = 0.0
        # evaluation only: the truth scorer of this episode's maps, per robot the cached
        # (fused-map version, contradiction share, held free cells or None), and the seconds
        # each robot held a wrong transform
        self._scorer: MapScorer | None = None
        self._accuracy: dict[int, tuple[int, float, int | None]] = {}
        self._wrong_s = np.zeros(cfg.n_robots, dtype=np.float64)
        # per robot, the incremental scorer of its map (None: sampling not exact, warp whole)
        # and the (source, version) it last scored
        self._inc: dict[int, IncrementalScore | None] = {}
        self._inc_seen: dict[int, tuple[str, int]] = {}

    # ------------------------------------------------------------------ spaces
    def observation_space(self, agent: AgentID) -> gymnasium.spaces.Box:
        """``Box(0, 255, (8, S, S), uint8)`` by default; ``(S, S, 8)`` with ``obs_layout="hwc"``,
        ``Box(0.0, 1.0, ..., float32)`` with ``obs_dtype="float32"``. The same object for every
        call."""
        self._check_agent(agent)
        return self._obs_space

    def action_space(self, agent: AgentID) -> gymnasium.spaces.Discrete:
        """``Discrete(4)`` (see :class:`mrexplore.robot.Action`); the same object for every call."""
        self._check_agent(agent)
        return self._act_space

    # ------------------------------------------------------------------ API
    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[AgentID, NDArray[Any]], dict[AgentID, dict[str, Any]]]:
        """Start an episode.

        ``seed`` (an integer >= 0) re-seeds the env's one Generator (``None`` continues it). From
        it, independent child streams are spawned for the world, the starts, the goal and the run
        (noise), so that robot_0's start and the navigation goal are the same for every team size.
        ``options``: ``{"starts": (n, 3) array}`` fixes the start poses (world metres, radians);
        other keys are ignored (PettingZoo's API test passes arbitrary options).
        """
        if seed is not None and (
            isinstance(seed, (bool, np.bool_))
            or not isinstance(seed, (int, np.integer))
            or seed < 0
        ):
            raise ConfigError(f"reset: seed must be an integer >= 0 or None, got {seed!r}")
        if seed is not None or self._rng is None:
            self._rng = np.random.default_rng(seed)
        world_rng, start_rng, goal_rng, self._run_rng = self._rng.spawn(4)
        self.world = (
            self._fixed_world
            if self._fixed_world is not None
            else load_world(self.config.world, rng=world_rng)
        )
        starts = None
        if options and options.get("starts") is not None:
            starts = np.asarray(options["starts"], dtype=np.float64)
            if starts.shape != (self.config.n_robots, 3):
                raise ConfigError(
                    f"reset option starts must have shape ({self.config.n_robots}, 3), "
                    f"got {starts.shape}"
                )
        self.sim = Simulation(self.world, self.config.n_robots, self._sim_config)
        mate_start = self._teammate_start(start_rng, starts)
        self.sim.reset(start_rng, starts=starts)
        self.agents = list(self.possible_agents)
        self._collisions[:] = 0
        self._collided[:] = False
        self._error_cache = {}
        self._heard = {}
        self._done = False
        self.fusion.reset()
        self._goal_world = None
        self._goal_cell = None
        if self.config.task == "navigate":
            self._place_goal(goal_rng, mate_start)
        self._scorer = MapScorer(self.world.walls, self.sim.reachable)
        self._accuracy = {}
        self._inc, self._inc_seen = {}, {}
        self._wrong_s[:] = 0.0
        self._merge()
        self._last_coverage = self._coverage_now()
        self._obs = self._observe()
        infos = {a: self._info(a, truncated=False) for a in self.agents}
        return dict(self._obs), infos

    def step(
        self, actions: dict[AgentID, int]
    ) -> tuple[
        dict[AgentID, NDArray[Any]],
        dict[AgentID, float],
        dict[AgentID, bool],
        dict[AgentID, bool],
        dict[AgentID, dict[str, Any]],
    ]:
        """Advance all robots one step. Live agents missing from ``actions`` stay in place."""
        if self.sim is None or self._done:
            raise RuntimeError("step() called on an env that is not running: call reset() first")
        act = self._parse_actions(actions)
        sim = self.sim
        given_before = self._goal_given()
        self._act(act)
        if (
            self.config.task == "navigate"
            and self.config.nav_return_to_start
            and self.config.nav_warmup_s > 0
            and not given_before
            and self._goal_given()
        ):
            # The warm-up is over: robot_0 navigates from its start with the map it has.
            sim.place(0, sim.start_poses[0])
        self._merge()
        self._count_wrong_merges()
        self._obs = self._observe()
        reward = self._reward()
        terminated = self._terminated()
        truncated = not terminated and self._truncated()
        self._done = terminated or truncated
        agents = list(self.agents)
        obs = {a: self._obs[a] for a in agents}
        rewards = dict.fromkeys(agents, reward)
        terms = dict.fromkeys(agents, terminated)
        truncs = dict.fromkeys(agents, truncated)
        infos = {a: self._info(a, truncated=truncated) for a in agents}
        if self._done:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return obs, rewards, terms, truncs, infos

    def state(self) -> NDArray[Any]:
        """All robots' observations stacked on the channel axis (first or last, as
        ``obs_layout``), in ``state_space`` (no ground truth)."""
        if self.sim is None:
            raise RuntimeError("state() called before reset()")
        axis = self._obs_format.channel_axis
        return np.concatenate([self._obs[a] for a in self.possible_agents], axis=axis)

    def robot_view(self, agent: AgentID) -> RobotView:
        """What ``agent`` knows now: the documented accessor for policies (no ground truth)."""
        self._check_agent(agent)
        if self.sim is None:
            raise RuntimeError("robot_view() called before reset()")
        sim = self.sim
        i = self.possible_agents.index(agent)
        merged = self.fusion.merged(agent)
        teammates: dict[str, tuple[float, float]] = {}
        transforms: dict[str, NDArray[np.float64]] = {}
        if merged:
            transforms = self._transforms[agent]
            for other in transforms:
                # Teammates' positions travel over the radio with their maps: out of range, a
                # robot knows only where a teammate was when it was last heard.
                heard = self._heard.get((agent, other))
                if heard is not None:
                    teammates[other] = heard
        goal = self._goal_cell if (i == 0 and self._goal_given()) else None
        links = self._current_links
        in_range = frozenset(
            o
            for j, o in enumerate(self.possible_agents)
            if j != i and (links is None or bool(links[i, j] and links[j, i]))
        )
        return RobotView(
            agent=agent,
            map=self.fusion.fused(agent),
            resolution_m=self._resolution_m,
            pose_cell=sim.pose_cell(i),
            robot_radius_m=self.config.radius_m,
            merged=merged,
            teammates=teammates,
            transforms=transforms,
            in_range=in_range,
            goal_cell=goal,
            time_s=float(sim.time_s),
        )

    @property
    def coverage(self) -> float:
        """The team coverage that ``infos[agent]["coverage"]`` reports (``coverage_mode``), as of
        the last ``reset``/``step``; the rendered frame shows this same value."""
        return float(self._last_coverage)

    # ------------------------------------------------------------------ map protocol
    @property
    def merges_maps(self) -> bool:
        """True when this env fuses its robots' maps itself (a merger and >= 2 robots):
        :class:`~mrexplore.wrappers.MapMergeWrapper` then refuses to wrap it."""
        return bool(self.fusion.enabled)

    @property
    def map_resolution_m(self) -> float:
        """Metres per cell of every robot's map (the :mod:`mrexplore.wrappers` map protocol)."""
        return self._resolution_m

    def local_map(self, agent: AgentID) -> NDArray[np.int8]:
        """``agent``'s own-frame int8 map (-1/0/100) (the map protocol of ``MapMergeWrapper``)."""
        self._check_agent(agent)
        if self.sim is None:
            raise RuntimeError("local_map() called before reset()")
        return self.sim.maps[self.possible_agents.index(agent)].to_int8()

    def own_pose_cell(self, agent: AgentID) -> tuple[float, float, float]:
        """``agent``'s pose estimate (col, row, theta) in its own map cells (map protocol)."""
        self._check_agent(agent)
        if self.sim is None:
            raise RuntimeError("own_pose_cell() called before reset()")
        return self.sim.pose_cell(self.possible_agents.index(agent))

    def render(self, mode: str | None = None) -> NDArray[np.uint8] | None:
        """``"rgb_array"``: an HxWx3 uint8 frame (true world with robots, beams and trails beside
        each robot's map and the fused map, merge status written on it). ``"human"``: shows the
        frame in a matplotlib window when matplotlib and a display are available; on a headless
        machine it draws nothing and returns None (a warning is issued once).

        ``mode`` is accepted only because RLlib's ``ParallelPettingZooEnv.render()`` passes its
        own ``render_mode`` (None, or ours) positionally; the mode is fixed at construction, so
        any other value is an error."""
        if mode is not None and mode != self.render_mode:
            raise ConfigError(
                f"render(mode={mode!r}): the render mode is set when the env is built "
                f"(render_mode={self.render_mode!r})"
            )
        if self.render_mode is None:
            gymnasium.logger.warn(
                "render() called without a render_mode; pass render_mode='rgb_array'"
            )
            return None
        if self.sim is None:
            raise RuntimeError("render() called before reset()")
        from mrexplore.render import render_env_frame

        frame = render_env_frame(self)
        if self.render_mode == "rgb_array":
            return frame
        self._show_human(frame)
        return None

    def close(self) -> None:
        """Release the human-mode window, if any."""
        if self._renderer is not None:
            try:
                import matplotlib.pyplot as plt

                plt.close(self._renderer[0])
            except Exception:  # pragma: no cover - closing a window must never raise
                pass
            self._renderer = None

    def __getstate__(self) -> dict[str, Any]:
        """Plain ``pickle`` support: everything but a human-mode window (re-opened on demand)."""
        state = dict(self.__dict__)
        state["_renderer"] = None
        return state

    # ------------------------------------------------------------------ step parts
    def _parse_actions(self, actions: dict[AgentID, int]) -> NDArray[np.int64]:
        if not isinstance(actions, dict):
            raise TypeError(f"actions must be a dict agent -> action, got {type(actions).__name__}")
        act = np.full(self.config.n_robots, int(Action.STAY), dtype=np.int64)
        for agent, a in actions.items():
            if agent not in self.possible_agents:
                raise KeyError(f"unknown agent {agent!r}; agents are {self.possible_agents}")
            if agent not in self.agents:
                raise ValueError(f"agent {agent!r} is done and cannot act")
            if a is None:
                continue
            if isinstance(a, (bool, np.bool_)):
                raise ValueError(f"action {a!r} of {agent} is a bool, not an action index")
            # plain ints in range skip gymnasium's contains (~30 us a step for two robots)
            fast = type(a) is int and 0 <= a < self._act_space.n
            if not fast and not self._act_space.contains(a):
                raise ValueError(
                    f"action {a!r} of {agent} is outside the action space {self._act_space}"
                )
            act[self.possible_agents.index(agent)] = int(a)
        return act

    def _act(self, act: NDArray[np.int64]) -> NDArray[np.bool_]:
        """Move, sense and update each robot's own map (all in the simulator)."""
        assert self.sim is not None
        info = self.sim.step(act, self._run_rng)
        collided = np.asarray(info.collided, dtype=bool)
        self._collisions += collided
        self._collided[:] = collided
        return collided

    def _links(self) -> NDArray[np.bool_] | None:
        """Who can exchange maps now: everyone, or robots within ``comm_range_m`` (true distance:
        the radio's physics, not knowledge given to the robots)."""
        if self.config.comm_range_m is None or self.sim is None:
            return None
        xy = self.sim.true_poses[:, :2]
        d = np.linalg.norm(xy[:, None, :] - xy[None, :, :], axis=-1)
        return np.asarray(d <= self.config.comm_range_m)

    def _merge(self) -> None:
        assert self.sim is not None
        maps = {a: self.local_map(a) for a in self.possible_agents}
        # The maps track their known and changed boxes: the tracker need not scan canvases.
        changes = {a: m.change() for a, m in zip(self.possible_agents, self.sim.maps, strict=True)}
        links = self._links()
        self._current_links = links
        # No attempt at reset: single-scan maps cannot be merged, and each attempt costs ~50 ms.
        steps = int(self.sim.steps)
        self.fusion.update(maps, steps, links, attempt=steps > 0, changes=changes)
        # Each agent's estimated transforms, once per step (views, heard positions, infos).
        self._transforms = {a: self.fusion.transforms(a) for a in self.possible_agents}
        self._update_heard(links)

    def _update_heard(self, links: NDArray[np.bool_] | None) -> None:
        """Refresh, for every merged and linked pair, where each robot last heard the other
        (the teammate's own pose estimate mapped through the *estimated* transform)."""
        assert self.sim is not None
        for a in self.possible_agents:
            i = self.possible_agents.index(a)
            for other, T in self._transforms[a].items():
                j = self.possible_agents.index(other)
                if links is not None and not (links[i, j] and links[j, i]):
                    continue
                c, r, _ = self.sim.pose_cell(j)
                p = apply_transform(T, np.array([[c, r]]))[0]
                self._heard[(a, other)] = (float(p[0]), float(p[1]))

    def _observe(self) -> dict[AgentID, NDArray[Any]]:
        assert self.sim is not None
        out = {}
        for i, a in enumerate(self.possible_agents):
            obs = self._obs_builder.build(self.robot_view(a), self.sim.trail_cells(i))
            out[a] = self._obs_format.apply(obs)
        return out

    def _reward(self) -> float:
        assert self.sim is not None and self.world is not None
        cfg = self.config
        cov = self._coverage_now()
        gain = cov - self._last_coverage
        self._last_coverage = cov
        if cfg.reward_mode == "time":
            return -cfg.dt_s
        area_m2 = gain * self.sim.reachable_cells * self.world.resolution_m**2
        return float(cfg.coverage_reward_per_m2 * area_m2 - cfg.time_penalty_per_s * cfg.dt_s)

    def _coverage_now(self) -> float:
        """The coverage of ``coverage_mode`` (see the module doc), in [0, 1]."""
        assert self.sim is not None
        if self.config.coverage_mode == "observed" or self.sim.reachable_cells == 0:
            return self.sim.coverage()
        held = max(self._map_accuracy(i)[1] or 0 for i in range(self.config.n_robots))
        return held / self.sim.reachable_cells

    def _map_accuracy(self, i: int) -> tuple[float, int | None]:
        """Robot i's own-or-fused map against the truth: (contradiction share or NaN, reachable
        free cells it marks free at the true place, counted only with ``coverage_mode="held"``).
        Cached on the fusion stage's fused-map version: an unchanged map costs nothing."""
        assert self.sim is not None and self._scorer is not None
        agent = self.possible_agents[i]
        version = self.fusion.fused_version(agent)
        cached = self._accuracy.get(i)
        if cached is not None and cached[0] == version:
            return cached[1], cached[2]
        fused = self.fusion.fused(agent)
        want_held = self.config.coverage_mode == "held"
        if i not in self._inc:
            T = self.sim.world_from_map(i)
            sample = nearest_sampling(T, self.sim.canvas_shape, self._scorer.shape)
            self._inc[i] = None if sample is None else IncrementalScore(self._scorer, T, sample)
        inc = self._inc[i]
        if inc is None:
            warped = self._scorer.warp(fused, self.sim.world_from_map(i))
            share, held = self._scorer.scores(warped, held=want_held)
        else:
            # Re-score only the world cells that sample the part of the map that changed since
            # the version last scored (the same figures as warping the whole map).
            fc = self.fusion.fused_change(agent)
            if fc is None:
                ch = self.sim.maps[i].change()
                source, ver, box = "own", ch.version, ch.changed_box
            else:
                source, (ver, box) = "fused", fc
            seen = self._inc_seen.get(i)
            if seen is None or seen[0] != source or ver > seen[1] + 1 or ver < seen[1]:
                box = None  # a new source or a skipped version: score it whole
            elif ver == seen[1]:
                box = (0, 0, 0, 0)
            share, n_held = inc.update(fused, box)
            held = n_held if want_held else None
            self._inc_seen[i] = (source, ver)
        self._accuracy[i] = (version, share, held)
        return share, held

    def _count_wrong_merges(self) -> None:
        """Add this step's ``dt_s`` to each robot holding a transform >= 5 cells off."""
        for i, agent in enumerate(self.possible_agents):
            err = self._merge_error(agent)
            if err is not None and is_wrong_merge(err):
                self._wrong_s[i] += self.config.dt_s

    def _terminated(self) -> bool:
        assert self.sim is not None
        if self.config.task == "navigate":
            return self._goal_given() and self._goal_reached()
        return self._last_coverage >= self.config.target_coverage

    def _truncated(self) -> bool:
        assert self.sim is not None
        if self.config.max_cycles is not None and self.sim.steps >= self.config.max_cycles:
            return True
        # A small epsilon so 600 s / 0.25 s = 2400 steps truncates at step 2400, not 2401.
        return bool(self.sim.time_s >= self.config.max_time_s - 1e-9)

    # ------------------------------------------------------------------ navigation
    def _teammate_start(
        self, start_rng: np.random.Generator, starts: NDArray[np.float64] | None
    ) -> NDArray[np.float64] | None:
        """``robot_1``'s start (world x, y metres) for a ``nav_goal="teammate"`` goal, also for a
        1-robot team: where robot_1 would start from this seed (drawn from a copy of the start
        stream, which the real draw then repeats). None when there is no such goal."""
        if self.config.task != "navigate" or self.config.nav_goal != "teammate":
            return None
        assert self.sim is not None
        if starts is not None:
            return starts[1, :2].copy() if starts.shape[0] > 1 else None
        return self.sim.sample_starts(copy.deepcopy(start_rng), 2)[1, :2]

    def _place_goal(
        self, rng: np.random.Generator, mate_start: NDArray[np.float64] | None = None
    ) -> None:
        """A goal for robot_0: a reachable free cell at least ``goal_min_distance_m`` away (and,
        given ``mate_start``, within ``nav_teammate_radius_m`` of it, else the far cells
        nearest to it), given to the robot in its own map frame (the task definition, not a
        leak)."""
        assert self.sim is not None and self.world is not None
        world = self.world
        rows, cols = np.nonzero(self.sim.reachable_cspace)
        start = self.world.cell_of(self.sim.true_poses[0, :2])[0]
        d_m = np.hypot(cols - start[0], rows - start[1]) * world.resolution_m
        far = np.nonzero(d_m >= self.config.goal_min_distance_m)[0]
        pool = far if len(far) else np.arange(len(rows))
        if mate_start is not None:
            mate = self.world.cell_of(mate_start[None])[0]
            d_mate = np.hypot(cols[pool] - mate[0], rows[pool] - mate[1]) * world.resolution_m
            near = d_mate <= self.config.nav_teammate_radius_m
            # none that near: the far cells nearest to the teammate's start (within a cell)
            pool = pool[near] if near.any() else pool[d_mate <= d_mate.min() + world.resolution_m]
        k = int(pool[int(rng.integers(len(pool)))])
        goal_cell_world = np.array([cols[k], rows[k]], dtype=np.float64)
        self._goal_world = world.xy_of(goal_cell_world[None])[0]
        T_world_from_map0 = self.sim.world_from_map(0)
        T_map0_from_world = invert_transform(T_world_from_map0)
        g = apply_transform(T_map0_from_world, goal_cell_world[None])[0]
        self._goal_cell = (float(g[0]), float(g[1]))

    def _goal_given(self) -> bool:
        """Navigation: robot_0 has its goal (the team first explores ``nav_warmup_s``)."""
        assert self.sim is not None
        return self.config.task == "navigate" and self.sim.time_s >= self.config.nav_warmup_s - 1e-9

    def _task_time(self) -> float:
        """Seconds of the task: since reset (explore) or since the goal was given (navigate)."""
        assert self.sim is not None
        if self.config.task == "navigate":
            return max(0.0, float(self.sim.time_s) - self.config.nav_warmup_s)
        return float(self.sim.time_s)

    def _goal_reached(self) -> bool:
        assert self.sim is not None and self._goal_world is not None
        d = float(np.hypot(*(self.sim.true_poses[0, :2] - self._goal_world)))
        return d <= self.config.goal_radius_m

    # ------------------------------------------------------------------ info
    def _merge_error(self, agent: AgentID) -> dict[str, float] | None:
        """Worst error of ``agent``'s estimated transforms against the truth (evaluation only):
        mean displacement (cells) of the teammate's known cells (an even sample of at most 4096),
        and the rotation error (degrees). The merge bench uses the same measure."""
        worst: dict[str, float] | None = None
        for err in self._merge_errors(agent).values():
            if worst is None or err["translation_cells"] > worst["translation_cells"]:
                worst = err
        return worst

    def _merge_errors(self, agent: AgentID) -> dict[AgentID, dict[str, float]]:
        """The error of each of ``agent``'s estimated transforms (teammate -> error dict)."""
        assert self.sim is not None
        i = self.possible_agents.index(agent)
        out: dict[AgentID, dict[str, float]] = {}
        for other, T in self._transforms[agent].items():
            err = self._pair_error(i, self.possible_agents.index(other), T)
            if err is not None:
                out[other] = err
        return out

    def _pair_error(self, i: int, j: int, T: NDArray[np.float64]) -> dict[str, float] | None:
        """Error of the estimated ``T`` (j's cells -> i's) against the truth. Cached: recomputed
        when ``T`` changes or every 10 steps (the known cells grow slowly; this runs each step)."""
        assert self.sim is not None
        key = (i, j)
        cached = self._error_cache.get(key)
        if cached is not None and cached[0] + 10 > self.sim.steps and np.array_equal(cached[1], T):
            return cached[2]
        box = self.sim.maps[j].known_bbox()
        if box is None:
            return None
        r0, r1, c0, c1 = box
        rows, cols = np.nonzero(self.sim.maps[j].to_int8()[r0 : r1 + 1, c0 : c1 + 1] != UNKNOWN)
        step = max(1, len(rows) // 4096)
        pts = np.stack([cols[::step] + c0, rows[::step] + r0], axis=1).astype(np.float64)
        T_true = self.sim.true_transform(i, j)
        disp = np.linalg.norm(apply_transform(T, pts) - apply_transform(T_true, pts), axis=1)
        rot = abs(math.degrees(transform_angle(T @ np.linalg.inv(T_true))))
        err = {
            "translation_cells": float(disp.mean()),
            "rotation_deg": float(rot),
            "drift_cells": self.sim.drift_allowance(i, j, pts),
        }
        self._error_cache[key] = (int(self.sim.steps), np.array(T, copy=True), err)
        return err

    def _info(self, agent: AgentID, truncated: bool) -> dict[str, Any]:
        """The fixed, flat info dict of ``agent`` (:data:`INFO_KEYS`, in that order): the same
        keys on every reset and step, every value a bool, an int or a float (NaN where unknown),
        so that clients which turn infos into arrays or tensors (TorchRL, Gymnasium's vector
        envs) get one dtype per key; ``UNKNOWN_INFO`` (-1.0) where unknown. Richer data only
        under ``"extra"`` (``info_extra=True``)."""
        assert self.sim is not None
        i = self.possible_agents.index(agent)
        first = self.fusion.first_merge_step(agent)
        score = self.fusion.score(agent)
        err = self._merge_error(agent)
        contradiction = float(self._map_accuracy(i)[0])  # NaN: no claim (NaN >= 0 is False)
        unknown = UNKNOWN_INFO
        goal_given = self._goal_given()
        info: dict[str, Any] = {
            "coverage": self.coverage,
            "task_time_s": self._task_time(),
            "step": int(self.sim.steps),
            "merged": bool(self.fusion.merged(agent)),
            "score": unknown if score is None else float(score),
            "first_merge_time_s": unknown if first is None else float(first * self.config.dt_s),
            "merge_error_cells": unknown if err is None else err["translation_cells"],
            "merge_error_deg": unknown if err is None else err["rotation_deg"],
            "merge_error_drift_cells": unknown if err is None else err["drift_cells"],
            "collisions": int(self._collisions[i]),
            "collided": bool(self._collided[i]),
            "fused_contradiction": contradiction if contradiction >= 0 else unknown,
            "merged_wrongly_s": float(self._wrong_s[i]),
            "goal_given": goal_given,
            "goal_reached": goal_given and self._goal_reached(),
            "TimeLimit.truncated": bool(truncated),
        }
        if self.config.info_extra:
            info["extra"] = {"merge_error": err, "merge_errors": self._merge_errors(agent)}
        return info

    def _check_agent(self, agent: AgentID) -> None:
        if agent not in self.possible_agents:
            raise KeyError(f"unknown agent {agent!r}; agents are {self.possible_agents}")

    def _show_human(self, frame: NDArray[np.uint8]) -> None:
        try:
            import matplotlib

            if matplotlib.get_backend().lower() in ("agg", "pdf", "svg", "ps", "cairo", "template"):
                raise RuntimeError("no interactive matplotlib backend (headless machine)")
            import matplotlib.pyplot as plt
        except Exception as exc:
            if not getattr(self, "_warned_human", False):
                warnings.warn(
                    f"render_mode='human' shows nothing here ({exc}); use render_mode='rgb_array' "
                    "and write frames with mrexplore.render.write_video",
                    stacklevel=2,
                )
                self._warned_human = True
            return
        if self._renderer is None:
            fig, ax = plt.subplots()
            ax.axis("off")
            self._renderer = (fig, ax.imshow(frame))
        else:
            self._renderer[1].set_data(frame)
        plt.pause(1.0 / self.metadata["render_fps"])
