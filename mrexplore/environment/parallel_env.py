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

``infos[agent]``: the same flat keys on every reset and step, each a bool, an int or a float
(-1.0 where unknown): :mod:`mrexplore.environment.infos`; the table with units, including the
evaluation-only keys scored against the truth, is in ``docs/clients.md``.

``step()`` reads as its parts: the :class:`~mrexplore.environment.task.Task` (goal, warm-up,
reward, termination), the simulator (motion, lidar, own maps), the
:class:`~mrexplore.environment.radio.Radio` and the :class:`~mrexplore.merge.fusion.FusionStage`
(who exchanges maps, the fused maps), the observation builder, and the
:class:`~mrexplore.environment.evaluation.TruthMonitor` (infos only). What one episode owns is
one :class:`~mrexplore.environment.state.EpisodeState`. Policies read what a robot knows
through :meth:`MultiRobotExplorationEnv.robot_view`; the viewer reads
:meth:`MultiRobotExplorationEnv.snapshot`.

Version history: v0 (this): first release; infos flat and fixed (``merge_error`` became
``merge_error_cells``/``_deg``/``_drift_cells``, None became -1.0); ``obs_layout``/``obs_dtype``.

Size: the PettingZoo face (spaces, reset, step, state, render, the map protocol) with the
module's table of the env; each part it calls has its own module.
"""

from __future__ import annotations

import copy
import math
import time
from collections.abc import Callable
from concurrent.futures import Executor
from typing import Any, ClassVar, NamedTuple

import gymnasium
import numpy as np
from numpy.typing import NDArray
from pettingzoo import ParallelEnv

from mrexplore.environment.config import EnvConfig
from mrexplore.environment.evaluation import TruthMonitor
from mrexplore.environment.infos import UNKNOWN_INFO, known_or_unknown, merge_error_infos
from mrexplore.environment.observations import ObservationBuilder, ObservationFormat
from mrexplore.environment.radio import Radio
from mrexplore.environment.sighting import SightingSensor, sightings
from mrexplore.environment.state import EpisodeState
from mrexplore.environment.task import make_task
from mrexplore.errors import ConfigError
from mrexplore.merge.fusion import FusionStage
from mrexplore.render import FrameSnapshot, HumanWindow, render_frame
from mrexplore.robot import Action, RobotConfig
from mrexplore.sensors import LidarConfig
from mrexplore.sim import SimConfig, Simulation
from mrexplore.types import AgentID, Box, RobotView

__all__ = ["STEP_STAGES", "MultiRobotExplorationEnv", "StageTimer"]
from mrexplore.world import World, load_world

Observations = dict[AgentID, NDArray[Any]]
Infos = dict[AgentID, dict[str, Any]]
#: ``timer(stage, seconds)``: told, after each stage of a ``step()``, its name (one of
#: :data:`STEP_STAGES`) and the stepping thread's CPU seconds it took (``time.thread_time``).
StageTimer = Callable[[str, float], None]
#: The stages of ``step()`` a :data:`StageTimer` is told of, in order: ``act`` (move, lidar and
#: own maps: the simulator), ``merge`` (radio links and the fusion stage), ``observe`` (the
#: observation images). The rest of a step (task, reward, infos) is not a named stage.
STEP_STAGES = ("act", "merge", "observe")


def one_opencv_thread() -> None:
    """``cv2.setNumThreads(1)``, process-wide as OpenCV's setting is, once per process: the
    env's and the merger's calls are small (a window, a map), so OpenCV's pool only spins beside
    the stepping thread, the merge worker and, in a batched env, the other worlds' threads. The
    results do not depend on it (the pinned rollouts hash the same)."""
    global _OPENCV_SET
    if not _OPENCV_SET:
        import cv2

        cv2.setNumThreads(1)
        _OPENCV_SET = True


_OPENCV_SET = False


class _Drawn(NamedTuple):
    """The parts of a robot's view that its observation draws (``RobotView``'s fields)."""

    map: NDArray[np.int8]
    pose_cell: tuple[float, float, float]
    known_box: Box | None
    trail: NDArray[np.float64]
    teammates: dict[AgentID, tuple[float, float]]
    goal_cell: tuple[float, float] | None


class MultiRobotExplorationEnv(ParallelEnv[AgentID, NDArray[Any], int]):
    """PettingZoo parallel env; build it with :func:`mrexplore.parallel_env`.

    Options: :class:`~mrexplore.environment.config.EnvConfig` (the task among them: a name or
    a :class:`~mrexplore.environment.task.Task` object). Parts with defaults, as jumanji's envs
    take theirs: ``radio`` (a :class:`~mrexplore.environment.radio.Radio`; default: one with
    ``comm_range_m``), ``viewer`` (``FrameSnapshot -> RGB frame``; default
    :func:`mrexplore.render.render_frame`) and ``merge_executor`` (the worker thread of delayed
    merge attempts, which the caller owns and may share between env copies, as the batched env
    of :mod:`mrexplore.environment.batched` does; default: a private one made on first use).

    ``stage_timer`` (a :data:`StageTimer`, also settable later as the attribute; default None:
    nothing is timed) is told each stage of every ``step()`` with its thread CPU seconds, for
    profiling (``mrexplore bench env --breakdown``). It only reads the clock: the episode, its
    random draws and its results are the same with it or without.

    Making an env sets OpenCV to one thread, process-wide (:func:`one_opencv_thread`): the
    step's and the merger's OpenCV calls are small, and OpenCV's pool spent a fifth of a
    realistic rollout's process CPU for no faster step (``docs/speed.md``). Call
    ``cv2.setNumThreads(n)`` after it to give your own OpenCV work its threads back.
    """

    metadata: ClassVar[dict[str, Any]] = {
        "name": "mrexplore_v0",
        "render_modes": ["human", "rgb_array"],
        "is_parallelizable": True,
        "render_fps": 8,
    }

    def __init__(
        self,
        render_mode: str | None = None,
        *,
        radio: Radio | None = None,
        viewer: Callable[[FrameSnapshot], NDArray[np.uint8]] | None = None,
        merge_executor: Executor | None = None,
        stage_timer: StageTimer | None = None,
        **options: Any,
    ) -> None:
        self.config = cfg = EnvConfig.from_kwargs(**options)
        one_opencv_thread()
        if stage_timer is not None and not callable(stage_timer):
            raise ConfigError(
                f"stage_timer must be a callable (stage, seconds), got {stage_timer!r}"
            )
        #: told each step stage and its thread CPU seconds (None: no clock is read)
        self.stage_timer: StageTimer | None = stage_timer
        if render_mode is not None and render_mode not in self.metadata["render_modes"]:
            raise ConfigError(
                f"render_mode must be one of {self.metadata['render_modes']} or None, "
                f"got {render_mode!r}"
            )
        self.render_mode = render_mode
        self.possible_agents: list[AgentID] = [f"robot_{i}" for i in range(cfg.n_robots)]
        self.agents: list[AgentID] = []
        # A fixed world is loaded once, here, so a bad name or file fails at construction.
        random_world = isinstance(cfg.world, str) and cfg.world.startswith("random:")
        self._fixed_world: World | None = None if random_world else load_world(cfg.world)
        probe = self._fixed_world or load_world(cfg.world, rng=np.random.default_rng(0))
        self._resolution_m = probe.resolution_m
        # --- the parts, which live across episodes
        self.task = make_task(cfg)
        if radio is not None and list(radio.agents) != self.possible_agents:
            raise ConfigError(
                f"radio: its agents {radio.agents} must be the env's {self.possible_agents}"
            )
        self.radio = radio if radio is not None else Radio(self.possible_agents, cfg.comm_range_m)
        self._sighting = (
            None
            if cfg.sighting_range_m is None
            else SightingSensor(
                cfg.sighting_range_m,
                cfg.sighting_noise_range_m,
                cfg.sighting_noise_bearing_rad,
                cfg.sighting_noise_heading_rad,
            )
        )
        self.viewer = viewer if viewer is not None else render_frame
        self.fusion = FusionStage(
            self.possible_agents,
            merger=cfg.merger,
            merge_every=cfg.merge_every,
            recheck_every=cfg.recheck_every,
            merge_latency_steps=cfg.merge_latency_steps,
            merge_options=cfg.merge_options,
            resolution_m=self._resolution_m,
            executor=merge_executor,
            semantic_options=cfg.semantic_options,
            tracker_options=cfg.tracker_options,
            sightings=cfg.sighting_range_m is not None,
        )
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
            map_l_free=cfg.map_l_free,
            map_l_occ=cfg.map_l_occ,
        )
        self.window = HumanWindow(self.metadata["render_fps"]) if render_mode == "human" else None
        self._rng: np.random.Generator | None = None
        self._run_rng = np.random.default_rng(0)
        self._sight_rng = np.random.default_rng(1)
        #: the current episode, None before the first reset
        self.episode: EpisodeState | None = None

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
    ) -> tuple[Observations, Infos]:
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
        # sightings draw from a child of the run's generator: the run's own draws (lidar and
        # odometry noise) stay what they are with sightings off
        self._sight_rng = self._run_rng.spawn(1)[0]
        starts = self._fixed_starts(options)
        world = self._fixed_world or load_world(self.config.world, rng=world_rng)
        sim = Simulation(world, self.config.n_robots, self._sim_config)
        start_stream = copy.deepcopy(start_rng)  # a teammate goal repeats the start draw
        sim.reset(start_rng, starts=starts)
        self.task.reset(sim, goal_rng, start_stream, starts)
        self.radio.reset()
        self.fusion.reset()
        n = self.config.n_robots
        ep = self.episode = EpisodeState(
            world=world,
            sim=sim,
            truth=(
                TruthMonitor(
                    self.possible_agents, sim, self.fusion, self.config.coverage_mode == "held"
                )
                if self.config.evaluate
                else None
            ),
            collisions=np.zeros(n, dtype=np.int64),
            collided=np.zeros(n, dtype=bool),
        )
        self.agents = list(self.possible_agents)
        # No attempt at reset: single-scan maps cannot be merged, and each attempt costs ~50 ms.
        self._exchange_maps(ep, attempt=False)
        ep.coverage = self._coverage_now(ep)
        ep.obs = self._observe(ep)
        return dict(ep.obs), self._infos(ep, self.agents, truncated=False)

    def step(
        self, actions: dict[AgentID, int]
    ) -> tuple[Observations, dict[AgentID, float], dict[AgentID, bool], dict[AgentID, bool], Infos]:
        """Advance all robots one step. Live agents missing from ``actions`` stay in place."""
        ep = self.episode
        if ep is None or ep.done:
            raise RuntimeError("step() called on an env that is not running: call reset() first")
        act = self._parse_actions(actions)
        given_before = self.task.given(ep.sim)
        self._stage("act", self._move, ep, act)
        self.task.after_move(ep.sim, given_before)
        self._stage("merge", self._exchange_maps, ep, True)
        if ep.truth is not None:
            ep.truth.count_wrong(ep.transforms, self.config.dt_s)
        ep.obs = self._stage("observe", self._observe, ep)
        coverage = self._coverage_now(ep)
        reward = self.task.reward(coverage - ep.coverage, ep.sim, self._resolution_m)
        ep.coverage = coverage
        terminated = self.task.terminated(ep.sim, coverage)
        truncated = not terminated and self.task.truncated(ep.sim)
        ep.done = terminated or truncated
        agents = list(self.agents)
        obs = {a: ep.obs[a] for a in agents}
        infos = self._infos(ep, agents, truncated=truncated)
        if ep.done:
            self.agents = []
        if self.render_mode == "human":
            self.render()
        return (
            obs,
            dict.fromkeys(agents, reward),
            dict.fromkeys(agents, terminated),
            dict.fromkeys(agents, truncated),
            infos,
        )

    def state(self) -> NDArray[Any]:
        """All robots' observations stacked on the channel axis (first or last, as
        ``obs_layout``), in ``state_space`` (no ground truth)."""
        ep = self._started("state")
        axis = self._obs_format.channel_axis
        return np.concatenate([ep.obs[a] for a in self.possible_agents], axis=axis)

    def robot_view(self, agent: AgentID) -> RobotView:
        """What ``agent`` knows now: the documented accessor for policies (no ground truth)."""
        return self._robot_view(agent, with_hypotheses=True)

    def _robot_view(self, agent: AgentID, with_hypotheses: bool = False) -> RobotView:
        """:meth:`robot_view`; the observation builder reads no merge ``hypotheses`` (skipped)."""
        self._check_agent(agent)
        ep = self._started("robot_view")
        i = self.possible_agents.index(agent)
        merged = self.fusion.merged(agent)
        transforms = ep.transforms[agent] if merged else {}
        drawn = self._drawn(ep, i, agent, transforms)
        return RobotView(
            agent=agent,
            map=drawn.map,
            resolution_m=self._resolution_m,
            pose_cell=drawn.pose_cell,
            robot_radius_m=self.config.radius_m,
            merged=merged,
            teammates=drawn.teammates,
            transforms=transforms,
            in_range=self.radio.in_range(agent),
            goal_cell=drawn.goal_cell,
            time_s=float(ep.sim.time_s),
            trail=drawn.trail,
            hypotheses=self._hypotheses(agent) if with_hypotheses and not merged else {},
            known_box=drawn.known_box,
        )

    def _drawn(
        self,
        ep: EpisodeState,
        i: int,
        agent: AgentID,
        transforms: dict[AgentID, NDArray[np.float64]],
    ) -> _Drawn:
        """The parts of agent ``i``'s view that its observation draws; ``transforms``: its
        merged teammates' (empty while not merged)."""
        return _Drawn(
            self.fusion.fused(agent),
            ep.sim.pose_cell(i),
            self.fusion.known_box(agent),
            ep.sim.trail_cells(i),
            # positions travel over the radio with the maps: out of range, where last heard
            self.radio.heard(agent, list(transforms)),
            self.task.goal_cell(i, ep.sim),
        )

    def _hypotheses(
        self, agent: AgentID
    ) -> dict[str, tuple[list[NDArray[np.float64]], NDArray[np.int8]]]:
        """The merger's candidates for teammates in ``agent``'s radio range (maps travel
        only between robots that can talk)."""
        reach = self.radio.in_range(agent)
        return {b: h for b, h in self.fusion.hypotheses(agent).items() if b in reach}

    @property
    def coverage(self) -> float:
        """The team coverage that ``infos[agent]["coverage"]`` reports (``coverage_mode``), as of
        the last ``reset``/``step``; the rendered frame shows this same value."""
        return 0.0 if self.episode is None else float(self.episode.coverage)

    @property
    def sim(self) -> Simulation | None:
        """The current episode's simulator (the truth: evaluation and tests only), or None."""
        return None if self.episode is None else self.episode.sim

    @property
    def world(self) -> World | None:
        """The current episode's world (the truth), or None before the first reset."""
        return None if self.episode is None else self.episode.world

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
        return self._started("local_map").sim.maps[self.possible_agents.index(agent)].to_int8()

    def own_pose_cell(self, agent: AgentID) -> tuple[float, float, float]:
        """``agent``'s pose estimate (col, row, theta) in its own map cells (map protocol)."""
        self._check_agent(agent)
        return self._started("own_pose_cell").sim.pose_cell(self.possible_agents.index(agent))

    # ------------------------------------------------------------------ viewing
    def snapshot(self) -> FrameSnapshot:
        """What the viewer draws of the current step (:func:`mrexplore.render.render_frame`);
        it holds the truth, for pictures only."""
        ep = self._started("snapshot")
        sim, n = ep.sim, self.config.n_robots
        a0 = self.possible_agents[0]
        fused = self._robot_view(a0) if n > 1 else None
        merged = fused is not None and fused.merged
        return FrameSnapshot(
            agents=tuple(self.possible_agents),
            world=ep.world,
            seen=np.asarray(sim.observed.any(axis=0)),
            true_poses=sim.true_poses,
            scan=sim.last_scan,
            maps=tuple(m.to_int8() for m in sim.maps),
            pose_cells=tuple(sim.pose_cell(i) for i in range(n)),
            trails=tuple(sim.trail_cells(i) for i in range(n)),
            world_from_map=tuple(sim.world_from_map(i) for i in range(n)),
            fused=fused,
            fused_error=(
                ep.truth.merge_error(a0, ep.transforms[a0])
                if merged and ep.truth is not None
                else None
            ),
            time_s=float(sim.time_s),
            coverage=self.coverage,
        )

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
        frame = self.viewer(self.snapshot())
        if self.window is None:
            return frame
        self.window.show(frame)
        return None

    def close(self) -> None:
        """Release the human-mode window, if any."""
        if self.window is not None:
            self.window.close()

    # ------------------------------------------------------------------ step parts
    def _fixed_starts(self, options: dict[str, Any] | None) -> NDArray[np.float64] | None:
        """The ``starts`` reset option, checked: (n, 3) world metres and radians, or None."""
        if not options or options.get("starts") is None:
            return None
        starts = np.asarray(options["starts"], dtype=np.float64)
        if starts.shape != (self.config.n_robots, 3):
            raise ConfigError(
                f"reset option starts must have shape ({self.config.n_robots}, 3), "
                f"got {starts.shape}"
            )
        return starts

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

    def _stage(self, name: str, fn: Callable[..., Any], *args: Any) -> Any:
        """``fn(*args)``, its thread CPU time told to :attr:`stage_timer` when there is one."""
        timer = self.stage_timer
        if timer is None:
            return fn(*args)
        t0 = time.thread_time()
        try:
            return fn(*args)
        finally:
            timer(name, time.thread_time() - t0)

    def _move(self, ep: EpisodeState, act: NDArray[np.int64]) -> None:
        """Move, sense and update each robot's own map (all in the simulator)."""
        collided = np.asarray(ep.sim.step(act, self._run_rng).collided, dtype=bool)
        ep.collisions += collided
        ep.collided[:] = collided

    def _exchange_maps(self, ep: EpisodeState, attempt: bool) -> None:
        """The radio's links, the fusion stage's update (a merge attempt if ``attempt``), each
        agent's estimated transforms, and the positions heard over the links."""
        sim = ep.sim
        links = self.radio.update_links(sim.true_poses[:, :2])
        maps = {a: m.to_int8() for a, m in zip(self.possible_agents, sim.maps, strict=True)}
        # The maps track their known and changed boxes: the tracker need not scan canvases.
        changes = {a: m.change() for a, m in zip(self.possible_agents, sim.maps, strict=True)}
        seen = self._sightings(sim) if attempt and self._sighting is not None else None
        self.fusion.update(
            maps, int(sim.steps), links, attempt=attempt, changes=changes, sightings=seen
        )
        ep.transforms = {a: self.fusion.transforms(a) for a in self.possible_agents}
        self.radio.hear(ep.transforms, sim.pose_cell)

    def _sightings(self, sim: Any) -> dict[tuple[int, int], Any]:
        """This step's sightings, merged pairs too (noise drawn from the sightings' own child
        of the run's generator)."""
        assert self._sighting is not None
        pairs = self.fusion.sighting_pairs()
        if not pairs:
            return {}
        return sightings(
            self._sighting,
            sim.world.walls,
            sim.true_poses,
            sim.world.cell_of(sim.true_poses[:, :2]),
            [sim.pose_cell(k) for k in range(sim.n_robots)],
            sim.resolution_m,
            pairs,
            self._sight_rng,
        )

    def _observe(self, ep: EpisodeState) -> Observations:
        """Every agent's observation, from the parts of its :meth:`robot_view` that are drawn
        (the view itself is not made: its radio and merge fields are not drawn)."""
        out = {}
        build = self._obs_builder.build_from
        for i, a in enumerate(self.possible_agents):
            mates = ep.transforms[a] if self.fusion.merged(a) else {}
            d = self._drawn(ep, i, a, mates)
            obs = build(
                d.map,
                d.pose_cell,
                d.known_box,
                d.trail,
                d.teammates,
                d.goal_cell,
                self.config.radius_m,
                self._resolution_m,
            )
            out[a] = self._obs_format.apply(obs)
        return out

    def _coverage_now(self, ep: EpisodeState) -> float:
        """The coverage of ``coverage_mode`` (see :class:`EnvConfig`), in [0, 1]."""
        sim = ep.sim
        if self.config.coverage_mode == "observed" or sim.reachable_cells == 0:
            return sim.coverage()
        assert ep.truth is not None, "coverage_mode='held' needs evaluate=True (EnvConfig)"
        # a robot holding a wrong transform is credited with its own map only (held_free)
        truth = ep.truth
        held = max(truth.held_free(i, ep.transforms[a]) for i, a in enumerate(self.possible_agents))
        return held / sim.reachable_cells

    def _infos(
        self, ep: EpisodeState, agents: list[AgentID], truncated: bool
    ) -> dict[AgentID, dict[str, Any]]:
        """Each of ``agents``' flat infos (:data:`~mrexplore.environment.infos.INFO_KEYS`, in
        order); the team's figures are read once for all of them."""
        sim, fusion, truth = ep.sim, self.fusion, ep.truth
        coverage = self.coverage
        task_time_s = self.task.time_s(sim)
        step = int(sim.steps)
        given = self.task.given(sim)
        reached = given and self.task.reached(sim)
        collisions = ep.collisions.tolist()
        collided = ep.collided.tolist()
        out = {}
        for agent in agents:
            i = self.possible_agents.index(agent)
            first = fusion.first_merge_step(agent)
            err = None if truth is None else truth.merge_error(agent, ep.transforms[agent])
            accuracy = UNKNOWN_INFO if truth is None else truth.map_accuracy(i)[0]
            score = fusion.score(agent)
            info: dict[str, Any] = {
                "coverage": coverage,
                "task_time_s": task_time_s,
                "step": step,
                "merged": bool(fusion.merged(agent)),
                "score": UNKNOWN_INFO if score is None else float(score),
                "first_merge_time_s": known_or_unknown(
                    None if first is None else first * self.config.dt_s
                ),
                **merge_error_infos(err),
                "collisions": int(collisions[i]),
                "collided": bool(collided[i]),
                "fused_contradiction": known_or_unknown(accuracy),
                "merged_wrongly_s": UNKNOWN_INFO if truth is None else float(truth.wrong_s[i]),
                "goal_given": given,
                "goal_reached": reached,
                "TimeLimit.truncated": bool(truncated),
            }
            if self.config.info_extra:
                info["extra"] = {
                    "merge_error": err,
                    "merge_errors": {}
                    if truth is None
                    else truth.merge_errors(agent, ep.transforms[agent]),
                }
            out[agent] = info
        return out

    def _started(self, what: str) -> EpisodeState:
        if self.episode is None:
            raise RuntimeError(f"{what}() called before reset()")
        return self.episode

    def _check_agent(self, agent: AgentID) -> None:
        if agent not in self.possible_agents:
            raise KeyError(f"unknown agent {agent!r}; agents are {self.possible_agents}")
