"""Typed, validated options of the multi-robot exploration environment.

Every keyword argument of :func:`mrexplore.parallel_env` lands in :class:`EnvConfig`; a keyword
that is not a field is an error (a typo must never be silently ignored), and every value is
checked when the env is built, not deep inside a step.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

from mrexplore.errors import ConfigError
from mrexplore.mapping import L_FREE_DEFAULT, L_OCC_DEFAULT
from mrexplore.options import (
    MERGE_EVERY_CHECK,
    MERGE_EVERY_DEFAULT,
    MERGE_LATENCY_CHECK,
    RECHECK_EVERY_CHECK,
    RECHECK_EVERY_DEFAULT,
    Options,
    anything,
    boolean,
    integer,
    non_negative,
    number,
    one_of,
    option,
    optional,
    positive,
)
from mrexplore.types import Merger

RewardMode = Literal["time", "coverage"]
TaskName = Literal["explore", "navigate"]
CoverageMode = Literal["observed", "held"]
ObsLayout = Literal["chw", "hwc"]
ObsDtype = Literal["uint8", "float32"]
#: Observation layouts and dtypes (``obs_layout``, ``obs_dtype``) and the clients they suit.
OBS_LAYOUTS = ("chw", "hwc")
OBS_DTYPES = ("uint8", "float32")
NavGoal = Literal["far", "teammate"]


def _task_check(v: Any) -> None:
    """``"explore"``, ``"navigate"``, or a task object (:class:`mrexplore.environment.task.Task`:
    it has ``bind`` and ``terminated``)."""
    if isinstance(v, str):
        if v not in ("explore", "navigate"):
            raise ValueError("'explore' or 'navigate' (or a Task object)")
    elif not (callable(getattr(v, "bind", None)) and callable(getattr(v, "terminated", None))):
        raise ValueError("'explore' or 'navigate' (or a Task object)")


def _options_of(name: str) -> Callable[[Any], None]:
    """A check that a value is an instance of ``mrexplore.merge``'s options class ``name``
    (``SemanticOptions`` or ``TrackerOptions``; imported when checked, so the merger loads
    only when options for it are given)."""

    def check(v: Any) -> None:
        from mrexplore.merge import SemanticOptions, TrackerOptions

        classes = {"SemanticOptions": SemanticOptions, "TrackerOptions": TrackerOptions}
        if not isinstance(v, classes[name]):
            raise ValueError(f"a mrexplore.merge.{name}")

    return check


def _semantic_named(merger: Any) -> bool:
    """:func:`mrexplore.merge.fusion.semantic_named`, imported when asked (the merger loads only
    when options for it are given)."""
    from mrexplore.merge.fusion import semantic_named

    return semantic_named(merger)


def _is_dict(v: Any) -> None:
    if not isinstance(v, dict):
        raise ValueError("a dict of the merge method's options")


#: Upper limits of the odometry noise: beyond them the simulated robot is not a robot any more
#: (a 100 % odometry error per step throws poses off the map).
ODOM_TRANS_CHECK = number(0.0, 0.5, hint=" (std of the translation error / distance moved)")
ODOM_ROT_CHECK = number(0.0, 1.0, hint=" (std of the heading error, rad per rad turned)")
ODOM_ROT_PER_M_CHECK = number(0.0, 1.0, hint=" (std of the heading error, rad per m driven)")


@dataclass(frozen=True)
class EnvConfig(Options):
    """Options of :class:`mrexplore.environment.MultiRobotExplorationEnv` (units in the names).

    World and team:
        world: a shipped world name (``"symmetric_office"``), a path to a map_server YAML, a
            :class:`~mrexplore.world.World`, or ``"random:<generator>"`` for a new world drawn from
            the episode's seed at every reset (training on many maps).
        n_robots: team size; ``1`` is the single-robot baseline (same world, same start of
            ``robot_0`` as the team runs for the same seed).
        task: ``"explore"`` (cover ``target_coverage`` of the reachable free space) or
            ``"navigate"`` (``robot_0`` must reach a goal given in its own frame), or a
            :class:`~mrexplore.environment.task.Task` object: your own task (goal, reward,
            termination), bound to these options by the env.
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
        map_l_free, map_l_occ: the robots' own maps: log-odds added to a cell when a beam
            passes through it (free) and when a beam ends in it (occupied); one free
            observation must reach the free threshold (25 %, -1.10), one occupied the occupied
            threshold (65 %, +0.62). Defaults -1.2 and 3.6: a hit worth three passes keeps the
            walls that grazing beams erase with ``map_l_occ=1.4``, the former default
            (``docs/mapper.md``).
    Merging:
        merger: merge method name for :func:`mrexplore.merge.merge_maps` (``"semantic"``,
            ``"paper"``, ``"orb"``), an object with ``merge(a, b)``, or ``None`` (never merge).
        merge_every: steps between merge attempts before the first success.
        recheck_every: steps between re-checks of an accepted transform (0: never).
        merge_latency_steps: a merge attempt started at step t takes effect at step t + this,
            computed meanwhile in a worker thread, so no step waits for the merger (default 8
            steps, 2 s at the default ``dt_s``: a radio exchange of maps and a merge take about
            that on real robots; 0 = in the step that starts it, no thread). A fixed delay, not
            "when ready": the same seed gives the same run on any machine.
        comm_range_m: maps are exchanged only while robots are within this distance (None = always).
        sighting_range_m: robots that see each other within this distance (metres, no wall
            between them) measure each other's relative pose, and the merge tracker looks for
            the transform between their maps near the guess that follows (a rendezvous;
            :mod:`mrexplore.environment.sighting`). None (default): no sightings.
        sighting_noise_range_m, sighting_noise_bearing_rad, sighting_noise_heading_rad: standard
            deviations of that measurement (defaults 0.05 m, 0.02 rad, 0.05 rad).
        semantic_options: the semantic merger's options
            (:class:`~mrexplore.merge.semantic.SemanticOptions`), used as given: build them with
            :func:`~mrexplore.merge.fusion.in_loop_semantic_options` to change one and keep the
            loop's others (the loop's differ from a single call's: the place test on, no area
            floors). None (default): the loop's. Only with ``merger="semantic"``.
        tracker_options: the merge tracker's options
            (:class:`~mrexplore.merge.TrackerOptions`), used as given but for the schedule
            above (``merge_every``, ``recheck_every``, ``merge_latency_steps`` are the env's):
            build them with :func:`~mrexplore.merge.fusion.in_loop_tracker_options`. None
            (default): the loop's.
        merge_options: the untyped form: a dict of the merge method's keyword options with the
            tracker's among them (``{"min_margin": 0.05, "drop_below": 0.9}``); for a merger
            other than the semantic one, the only form. Not with the typed options for the same
            part.
    Episode and reward:
        target_coverage: exploration ends when the coverage (``coverage_mode``) reaches this
            share of the reachable free cells.
        coverage_mode: what counts as covered (evaluation; the robots never see it):
            ``"observed"`` (default): the team's union of the cells its sensors observed;
            ``"held"``: the largest, over robots, share of reachable free cells that the
            robot's own-or-fused map holds at the true place (the map warped into the world
            with the true transform): marked free, or marked occupied with a true wall within
            one cell (walls a cell thick on the floor beside them are no wrong knowledge).
            While a robot holds a wrong transform (the time ``merged_wrongly_s`` counts), it is
            credited with its own map's cells only: it cannot tell which of its teammates'
            knowledge is right, so misplaced free cells that land on true free space (a twin
            room on its twin) do not count either. A wrong merge thus costs task time, and a
            team finishes only when some robot holds a correct map. Costs one world-sized warp
            per changed map per step.
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
        evaluate: score every step against the truth for the evaluation-only infos
            (``merge_error_*``, ``fused_contradiction``, ``merged_wrongly_s``; they are -1.0
            with False). Nothing of it reaches a robot, so training may turn it off for speed
            (1.2-1.3x steps/s on ``symmetric_office``, docs/clients.md); ``coverage_mode="held"``
            needs it.
    """

    world: Any = option("symmetric_office", anything)  # checked by load_world
    n_robots: int = option(2, integer(1))
    task: TaskName | Any = option("explore", _task_check)
    radius_m: float = option(0.15, positive)
    speed_mps: float = option(0.5, positive)
    turn_rate_rps: float = option(math.pi / 2, positive)
    dt_s: float = option(0.25, positive)
    n_beams: int = option(360, integer(1))
    fov_deg: float = option(360.0, number(0.0, 360.0, low_open=True))
    max_range_m: float = option(4.0, positive)
    range_noise_m: float = option(0.01, non_negative)
    aligned_headings: bool = option(True, boolean)
    odom_noise_trans: float = option(0.0, ODOM_TRANS_CHECK)
    odom_noise_rot: float = option(0.0, ODOM_ROT_CHECK)
    odom_noise_rot_per_m: float = option(0.0, ODOM_ROT_PER_M_CHECK)
    min_start_separation_m: float = option(0.0, non_negative)
    map_l_free: float = option(L_FREE_DEFAULT, number(-5.0, -1.1, hint=" (log-odds per free look)"))
    map_l_occ: float = option(L_OCC_DEFAULT, number(0.62, 5.0, hint=" (log-odds per hit)"))
    merger: str | Merger | None = option("semantic", anything)  # checked by the tracker
    merge_every: int = option(MERGE_EVERY_DEFAULT, MERGE_EVERY_CHECK)
    recheck_every: int = option(RECHECK_EVERY_DEFAULT, RECHECK_EVERY_CHECK)
    merge_latency_steps: int = option(8, MERGE_LATENCY_CHECK)
    comm_range_m: float | None = option(None, optional(positive))
    sighting_range_m: float | None = option(None, optional(positive))
    sighting_noise_range_m: float = option(0.05, non_negative)
    sighting_noise_bearing_rad: float = option(0.02, non_negative)
    sighting_noise_heading_rad: float = option(0.05, non_negative)
    target_coverage: float = option(0.95, number(0.0, 1.0, low_open=True))
    coverage_mode: CoverageMode = option("observed", one_of("observed", "held"))
    max_time_s: float = option(600.0, positive)
    max_cycles: int | None = option(None, optional(integer(1)))
    reward_mode: RewardMode = option("time", one_of("time", "coverage"))
    coverage_reward_per_m2: float = option(0.1, non_negative)
    time_penalty_per_s: float = option(0.04, non_negative)
    goal_min_distance_m: float = option(10.0, non_negative)
    goal_radius_m: float = option(0.4, positive)
    nav_goal: NavGoal = option("far", one_of("far", "teammate"))
    nav_teammate_radius_m: float = option(3.0, positive)
    nav_warmup_s: float = option(0.0, non_negative)
    nav_return_to_start: bool = option(True, boolean)
    global_view_m: float = option(25.6, positive)
    local_view_m: float = option(6.4, positive)
    # SB3's NatureCNN (CnnPolicy) needs at least 36x36 inputs.
    obs_size_px: int = option(64, integer(36))
    obs_heading_up: bool = option(False, boolean)
    obs_layout: ObsLayout = option(
        "chw", one_of(*OBS_LAYOUTS, hint=" (channels first: SB3, TorchRL; last: RLlib)")
    )
    obs_dtype: ObsDtype = option(
        "uint8", one_of(*OBS_DTYPES, hint=" (0..255: SB3; [0, 1]: RLlib, TorchRL)")
    )
    info_extra: bool = option(False, boolean)
    evaluate: bool = option(True, boolean)
    merge_options: dict[str, Any] = option(None, _is_dict, factory=dict)
    semantic_options: Any = option(None, optional(_options_of("SemanticOptions")))
    tracker_options: Any = option(None, optional(_options_of("TrackerOptions")))

    def check_together(self) -> None:
        if self.semantic_options is not None and not _semantic_named(self.merger):
            raise ConfigError(
                f"option semantic_options are the semantic merger's; merger is {self.merger!r}"
            )
        if self.task == "navigate" and self.nav_warmup_s >= self.max_time_s:
            raise ConfigError(
                f"option nav_warmup_s ({self.nav_warmup_s}) must be shorter than max_time_s "
                f"({self.max_time_s}): the goal would never be given"
            )
        if self.coverage_mode == "held" and not self.evaluate:
            raise ConfigError(
                "option coverage_mode='held' scores the maps against the truth: it needs "
                "evaluate=True"
            )
        if self.range_noise_m >= self.max_range_m:
            raise ConfigError(
                f"option range_noise_m={self.range_noise_m!r} must be below max_range_m "
                f"({self.max_range_m} m)"
            )
