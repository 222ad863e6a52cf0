"""Typed, validated options of the multi-robot exploration environment.

Every keyword argument of :func:`mrexplore.parallel_env` lands in :class:`EnvConfig`; a keyword
that is not a field is an error (a typo must never be silently ignored), and every value is
checked when the env is built, not deep inside a step.
"""

from __future__ import annotations

import dataclasses
import math
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np

from mrexplore.errors import ConfigError
from mrexplore.types import Merger

RewardMode = Literal["time", "coverage"]
Task = Literal["explore", "navigate"]
CoverageMode = Literal["observed", "held"]
ObsLayout = Literal["chw", "hwc"]
ObsDtype = Literal["uint8", "float32"]
#: Observation layouts and dtypes (``obs_layout``, ``obs_dtype``) and the clients they suit.
OBS_LAYOUTS = ("chw", "hwc")
OBS_DTYPES = ("uint8", "float32")
NavGoal = Literal["far", "teammate"]


#: Options that take only ``True``/``False`` (or numpy bools).
BOOL_OPTIONS = ("aligned_headings", "nav_return_to_start", "obs_heading_up", "info_extra")
#: Upper limits of the noise options (name, limit, unit): beyond them the simulated robot is
#: not a robot any more (a 100 % odometry error per step throws poses off the map).
NOISE_LIMITS = (
    ("odom_noise_trans", 0.5, "std of the translation error as a fraction of the distance moved"),
    ("odom_noise_rot", 1.0, "std of the heading error, radians per radian turned"),
    ("odom_noise_rot_per_m", 1.0, "std of the heading error, radians per metre driven"),
)


@dataclass(frozen=True)
class EnvConfig:
    """Options of :class:`mrexplore.environment.MultiRobotExplorationEnv` (units in the names).

    World and team:
        world: a shipped world name (``"symmetric_office"``), a path to a map_server YAML, a
            :class:`~mrexplore.world.World`, or ``"random:<generator>"`` for a new world drawn from
            the episode's seed at every reset (training on many maps).
        n_robots: team size; ``1`` is the single-robot baseline (same world, same start of
            ``robot_0`` as the team runs for the same seed).
        task: ``"explore"`` (cover ``target_coverage`` of the reachable free space) or
            ``"navigate"`` (``robot_0`` must reach a goal given in its own frame).
    Robots and sensing:
        radius_m, speed_mps, turn_rate_rps, dt_s: robot body and motion (defaults: 0.15 m,
            0.5 m/s, pi/2 rad/s, 0.25 s per step: 0.125 m forward or 22.5 deg per step).
        n_beams, fov_deg, max_range_m, range_noise_m: the lidar.
        aligned_headings: all robots start with heading 0 in the world (the paper's setting);
            ``False`` draws start headings uniformly, so the maps are rotated w.r.t. each other.
        odom_noise_trans, odom_noise_rot, odom_noise_rot_per_m: odometry drift, standard
            deviations: translation as a fraction of the distance moved (at most 0.5); heading
            in radians per radian turned and per metre driven (each at most 1.0).
        min_start_separation_m: minimum distance between start positions.
    Merging:
        merger: merge method name for :func:`mrexplore.merge.merge_maps` (``"semantic"``,
            ``"paper"``, ``"orb"``), an object with ``merge(a, b)``, or ``None`` (never merge).
        merge_every: steps between merge attempts before the first success.
        recheck_every: steps between re-checks of an accepted transform.
        merge_latency_steps: a merge attempt started at step t takes effect at step t + this,
            computed meanwhile in a worker thread, so no step waits for the merger (default 8
            steps, 2 s at the default ``dt_s``: a radio exchange of maps and a merge take about
            that on real robots; 0 = in the step that starts it, no thread). A fixed delay, not
            "when ready": the same seed gives the same run on any machine.
        comm_range_m: maps are exchanged only while robots are within this distance (None = always).
    Episode and reward:
        target_coverage: exploration ends when the coverage (``coverage_mode``) reaches this
            share of the reachable free cells.
        coverage_mode: what counts as covered (evaluation; the robots never see it):
            ``"observed"`` (default): the team's union of the cells its sensors observed;
            ``"held"``: the largest, over robots, share of reachable free cells that the
            robot's own-or-fused map marks free at the true place (the map warped into the
            world with the true transform). Knowledge placed by a wrong merge then does not
            count, so a wrong merge costs task time, and a team finishes only when some robot
            holds a correct map. (Misplaced free cells that land on true free space still
            count: a wrong merge costs less than the share it misplaces.) Costs one world-sized
            warp per changed map per step.
        max_time_s: truncation time; ``max_cycles`` (steps) truncates too when given.
        reward_mode: ``"time"`` (``-dt_s`` per step: return = -task time) or ``"coverage"``
            (``coverage_reward_per_m2`` per newly observed m^2 minus ``time_penalty_per_s * dt_s``).
        goal_min_distance_m, goal_radius_m: navigation goal placement and arrival radius.
        nav_goal: where ``robot_0``'s goal is drawn: ``"far"`` (default): any reachable cell at
            least ``goal_min_distance_m`` from its start; ``"teammate"``: such a cell within
            ``nav_teammate_radius_m`` of ``robot_1``'s start, a place the teammate maps during
            the warm-up (the seed paper's protocol: a robot goes where its teammate has mapped).
            The goal is the same for every team size (a 1-robot run draws where ``robot_1``
            would have started from the same seed).
        nav_teammate_radius_m: the ``"teammate"`` goal's distance from ``robot_1``'s start.
        nav_warmup_s: navigation: the team explores this long before ``robot_0`` is given its
            goal (0 = at once); the task time counts from the goal. With a warm-up, the
            single-robot and the team runs both start navigating with a partial map, the team's
            merged: the setting in which the seed paper compares navigation times.
        nav_return_to_start: navigation with a warm-up: put ``robot_0`` back at its start pose
            when the goal is given, so single and team runs navigate from the same point with
            the maps they built (alone or merged); otherwise it navigates from where it is.
    Observation:
        global_view_m: side of the coarse, robot-centred view of the known map, metres.
        local_view_m: side of the fine, robot-centred view, metres.
        obs_size_px: each view is ``obs_size_px`` x ``obs_size_px`` pixels.
        obs_heading_up: turn both views so the robot's heading points along +row (egocentric);
            default False keeps the axes of the robot's own map frame.
        obs_layout: ``"chw"`` (default: channels first, ``(8, S, S)``, as SB3 and TorchRL's
            ``ConvNet`` read images) or ``"hwc"`` (channels last, ``(S, S, 8)``, as RLlib's
            default CNN reads them).
        obs_dtype: ``"uint8"`` (default: 0..255, what SB3's ``CnnPolicy`` expects and
            normalises itself) or ``"float32"`` (the same values / 255, in [0, 1], for clients
            whose models take floats as they come: RLlib, TorchRL).
    Infos:
        info_extra: add ``infos[agent]["extra"]``, a dict of richer, nested evaluation data (the
            merge error per teammate); off by default because clients that turn infos into
            tensors (TorchRL) need flat numbers. See ``docs/clients.md`` for the info keys.
    """

    world: Any = "symmetric_office"
    n_robots: int = 2
    task: Task = "explore"
    radius_m: float = 0.15
    speed_mps: float = 0.5
    turn_rate_rps: float = math.pi / 2
    dt_s: float = 0.25
    n_beams: int = 360
    fov_deg: float = 360.0
    max_range_m: float = 4.0
    range_noise_m: float = 0.01
    aligned_headings: bool = True
    odom_noise_trans: float = 0.0
    odom_noise_rot: float = 0.0
    odom_noise_rot_per_m: float = 0.0
    min_start_separation_m: float = 0.0
    merger: str | Merger | None = "semantic"
    merge_every: int = 10
    recheck_every: int = 100
    merge_latency_steps: int = 8
    comm_range_m: float | None = None
    target_coverage: float = 0.95
    coverage_mode: CoverageMode = "observed"
    max_time_s: float = 600.0
    max_cycles: int | None = None
    reward_mode: RewardMode = "time"
    coverage_reward_per_m2: float = 0.1
    time_penalty_per_s: float = 0.04
    goal_min_distance_m: float = 10.0
    goal_radius_m: float = 0.4
    nav_goal: NavGoal = "far"
    nav_teammate_radius_m: float = 3.0
    nav_warmup_s: float = 0.0
    nav_return_to_start: bool = True
    global_view_m: float = 25.6
    local_view_m: float = 6.4
    obs_size_px: int = 64
    obs_heading_up: bool = False
    obs_layout: ObsLayout = "chw"
    obs_dtype: ObsDtype = "uint8"
    info_extra: bool = False
    merge_options: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        self._normalise_types()

        def positive(name: str) -> None:
            v = getattr(self, name)
            if (
                not isinstance(v, (int, float))
                or isinstance(v, bool)
                or not v > 0
                or not math.isfinite(v)
            ):
                raise ConfigError(f"option {name} must be a positive number, got {v!r}")

        def non_negative(name: str) -> None:
            v = getattr(self, name)
            if (
                not isinstance(v, (int, float))
                or isinstance(v, bool)
                or not v >= 0
                or not math.isfinite(v)
            ):
                raise ConfigError(f"option {name} must be a non-negative number, got {v!r}")

        if (
            not isinstance(self.n_robots, int)
            or isinstance(self.n_robots, bool)
            or self.n_robots < 1
        ):
            raise ConfigError(f"option n_robots must be an integer >= 1, got {self.n_robots!r}")
        if self.task not in ("explore", "navigate"):
            raise ConfigError(f"option task must be 'explore' or 'navigate', got {self.task!r}")
        if self.reward_mode not in ("time", "coverage"):
            raise ConfigError(
                f"option reward_mode must be 'time' or 'coverage', got {self.reward_mode!r}"
            )
        if self.obs_layout not in OBS_LAYOUTS:
            raise ConfigError(
                f"option obs_layout must be 'chw' (channels first: SB3, TorchRL) or 'hwc' "
                f"(channels last: RLlib), got {self.obs_layout!r}"
            )
        if self.obs_dtype not in OBS_DTYPES:
            raise ConfigError(
                f"option obs_dtype must be 'uint8' (0..255: SB3) or 'float32' ([0, 1]: RLlib, "
                f"TorchRL), got {self.obs_dtype!r}"
            )
        if self.nav_goal not in ("far", "teammate"):
            raise ConfigError(f"option nav_goal must be 'far' or 'teammate', got {self.nav_goal!r}")
        if self.coverage_mode not in ("observed", "held"):
            raise ConfigError(
                f"option coverage_mode must be 'observed' or 'held', got {self.coverage_mode!r}"
            )
        for name in (
            "radius_m",
            "speed_mps",
            "turn_rate_rps",
            "dt_s",
            "fov_deg",
            "max_range_m",
            "max_time_s",
            "goal_radius_m",
            "nav_teammate_radius_m",
            "global_view_m",
            "local_view_m",
        ):
            positive(name)
        for name in (
            "range_noise_m",
            "odom_noise_trans",
            "odom_noise_rot",
            "odom_noise_rot_per_m",
            "min_start_separation_m",
            "coverage_reward_per_m2",
            "time_penalty_per_s",
            "goal_min_distance_m",
            "nav_warmup_s",
        ):
            non_negative(name)
        if self.fov_deg > 360.0:
            raise ConfigError(f"option fov_deg must be at most 360, got {self.fov_deg}")
        for name in ("n_beams", "merge_every", "recheck_every", "obs_size_px"):
            v = getattr(self, name)
            if not isinstance(v, int) or isinstance(v, bool) or v < 1:
                raise ConfigError(f"option {name} must be an integer >= 1, got {v!r}")
        v = self.merge_latency_steps
        if not isinstance(v, int) or isinstance(v, bool) or not 0 <= v <= 10_000:
            raise ConfigError(
                f"option merge_latency_steps must be an integer in [0, 10000], got {v!r}"
            )
        if self.obs_size_px < 36:
            # SB3's NatureCNN (CnnPolicy) needs at least 36x36 inputs.
            raise ConfigError(
                f"option obs_size_px must be at least 36 (CnnPolicy), got {self.obs_size_px}"
            )
        if not 0.0 < self.target_coverage <= 1.0:
            raise ConfigError(
                f"option target_coverage must be in (0, 1], got {self.target_coverage!r}"
            )
        if self.max_cycles is not None and (
            not isinstance(self.max_cycles, int) or self.max_cycles < 1
        ):
            raise ConfigError(
                f"option max_cycles must be an integer >= 1 or None, got {self.max_cycles!r}"
            )
        if self.task == "navigate" and self.nav_warmup_s >= self.max_time_s:
            raise ConfigError(
                f"option nav_warmup_s ({self.nav_warmup_s}) must be shorter than max_time_s "
                f"({self.max_time_s}): the goal would never be given"
            )
        for name, hi, unit in NOISE_LIMITS:
            v = getattr(self, name)
            if v > hi:
                raise ConfigError(
                    f"option {name}={v!r} is out of range: it must be in [0, {hi}] ({unit})"
                )
        if self.range_noise_m >= self.max_range_m:
            raise ConfigError(
                f"option range_noise_m={self.range_noise_m!r} must be below max_range_m "
                f"({self.max_range_m} m)"
            )
        if self.comm_range_m is not None:
            positive("comm_range_m")
        if not isinstance(self.merge_options, dict):
            raise ConfigError(
                f"option merge_options must be a dict, got {type(self.merge_options).__name__}"
            )

    def _normalise_types(self) -> None:
        """Accept numpy scalars for numbers (``np.int64(2)``) and bools, refuse anything else for
        a bool option (``"no"`` must not pass as True); store plain Python types."""
        for name in BOOL_OPTIONS:
            v = getattr(self, name)
            if not isinstance(v, (bool, np.bool_)):
                raise ConfigError(f"option {name} must be True or False, got {v!r}")
            object.__setattr__(self, name, bool(v))
        for f in dataclasses.fields(self):
            v = getattr(self, f.name)
            if isinstance(v, np.integer):
                object.__setattr__(self, f.name, int(v))
            elif isinstance(v, np.floating):
                object.__setattr__(self, f.name, float(v))

    @classmethod
    def from_kwargs(cls, **kwargs: Any) -> EnvConfig:
        """Build a config from keyword arguments; an unknown keyword is a :class:`ConfigError`."""
        names = {f.name for f in dataclasses.fields(cls)}
        unknown = sorted(set(kwargs) - names)
        if unknown:
            raise ConfigError(
                f"unknown option(s) {', '.join(unknown)}; known options: {', '.join(sorted(names))}"
            )
        return cls(**kwargs)

    def to_dict(self) -> dict[str, Any]:
        """Plain dict of the options (the world as given, e.g. its name)."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}
