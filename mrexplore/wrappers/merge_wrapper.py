"""``MapMergeWrapper``: the mrexplore map merger on any PettingZoo ``ParallelEnv``.

The map protocol
================
A wrapped env's ``unwrapped`` object must expose, for every agent in ``possible_agents`` and at
any time after ``reset``:

* ``local_map(agent) -> numpy.ndarray``: the agent's occupancy grid in *its own frame*, int8
  ``(H, W)``, ``-1`` unknown / ``0`` free / ``100`` occupied (values between are occupancy
  percentages), indexed ``grid[row, col]`` (the ROS ``OccupancyGrid`` convention, see
  :mod:`mrexplore.grid`). The shape may change between steps (a growing map) and may differ
  between agents.
* ``map_resolution_m: float``: metres per cell, the same for every agent (maps are merged cell
  to cell, so maps of different resolutions must be resampled by the env first).

and optionally

* ``own_pose_cell(agent) -> (col, row, theta)``: the agent's pose estimate in its own map cells
  (``theta`` in radians from +col towards +row). With it the fused-map image is centred on the
  agent and carries a fourth channel with the agent and its merged teammates (teammates placed
  through the *estimated* transforms); without it the image shows the whole fused map.

The protocol is checked when the wrapper is built: a missing method or attribute is a
:class:`~mrexplore.errors.ConfigError` that names it.
:class:`mrexplore.environment.MultiRobotExplorationEnv` implements the protocol.

A method on the env was chosen over maps in ``infos``: the maps are then only built when a
merger asks for them, ``reset`` and ``step`` keep their usual return values, and a missing map
is detected once, at wrap time, instead of at the first step.

One merging path
================
Every step the wrapper feeds the agents' maps to a :class:`mrexplore.merge.fusion.FusionStage`, the
very object our own env uses for its built-in merging, so merging behaves identically on our env
and on yours. An env whose ``merges_maps`` attribute is true (ours, unless built with
``merger=None``) already fuses its maps: wrapping it is refused with a ``ConfigError``, as it
would merge twice.

Observations
============
``mode="replace"``: each agent's observation becomes a uint8 image of the fused map in that
agent's frame, ``Box(0, 255, (C, S, S), uint8)`` with ``S = obs_size_px``, channel-first (SB3's
``CnnPolicy`` takes it as is):

====  =====================================================================================
 ch   meaning (each pixel averages the cells under it: the value is the share, 0..255)
====  =====================================================================================
 0    free cells
 1    occupied cells
 2    unknown cells
 3    only with ``own_pose_cell``: the agent (disk, 255) and its merged teammates (disks, 128)
====  =====================================================================================

The window is a square of ``view_m`` metres (default: the longer side of the map) centred on
the agent's pose when ``own_pose_cell`` exists, else on the map centre; cells outside the map
count as unknown. ``mode="augment"``: the observation is ``{"obs": original, "fused_map":
image}`` with space ``Dict({"obs": original space, "fused_map": Box(...)})``.

``infos[agent]`` gains ``merged`` (bool), ``transform`` (teammate -> 3x3 nested list, the
estimated transform from the teammate's cells into this agent's cells, or None while not
merged with that teammate) and ``score`` (agreement score of the best accepted merge, or None).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import TYPE_CHECKING, Any, Literal

import cv2
import gymnasium
import numpy as np
from numpy.typing import NDArray
from pettingzoo import ParallelEnv
from pettingzoo.utils.wrappers import BaseParallelWrapper

from mrexplore.errors import ConfigError
from mrexplore.grid import UNKNOWN, apply_transform, free_mask, occupied_mask, validate_grid
from mrexplore.merge.fusion import FusionStage
from mrexplore.options import (
    MERGE_EVERY_CHECK,
    MERGE_EVERY_DEFAULT,
    RECHECK_EVERY_CHECK,
    RECHECK_EVERY_DEFAULT,
    integer,
    optional,
    positive,
    validate,
)
from mrexplore.types import Merger

if TYPE_CHECKING:
    from mrexplore.merge import SemanticOptions, TrackerOptions

MergeMode = Literal["replace", "augment"]
LinksFn = Callable[[Any], "NDArray[np.bool_] | None"]


#: Value of the agent's own disk and of a merged teammate's disk in the robots channel.
_SELF_VALUE = 255
_MATE_VALUE = 128


def check_map_protocol(env: Any) -> bool:
    """Check that ``env.unwrapped`` implements the map protocol (see module docstring).

    Returns whether the optional ``own_pose_cell`` method is present.

    Raises:
        ConfigError: naming every missing or malformed part of the protocol.
    """
    target = getattr(env, "unwrapped", env)
    name = type(target).__name__
    missing: list[str] = []
    if not callable(getattr(target, "local_map", None)):
        missing.append("method local_map(agent) -> int8 (H, W) map in the agent's own frame")
    try:
        res = target.map_resolution_m
    except AttributeError:
        missing.append("attribute map_resolution_m (float, metres per cell)")
    else:
        ok = isinstance(res, (int, float, np.floating)) and not isinstance(res, bool)
        if not ok or not math.isfinite(float(res)) or float(res) <= 0:
            raise ConfigError(
                f"{name}.map_resolution_m must be a positive number of metres per cell, got {res!r}"
            )
    if missing:
        raise ConfigError(
            f"{name} does not implement the map protocol of MapMergeWrapper: missing "
            + "; ".join(missing)
            + " (see mrexplore.wrappers.merge_wrapper)"
        )
    return callable(getattr(target, "own_pose_cell", None))


def fused_map_image(
    grid: NDArray[np.int8],
    centre: tuple[float, float] | None,
    side_cells: int | None,
    size_px: int,
) -> NDArray[np.uint8]:
    """Free / occupied / unknown shares of a square window of ``grid``, resampled to ``size_px``.

    Args:
        grid: int8 (H, W) occupancy grid (-1/0/100).
        centre: (col, row) of the window centre in cells (the window's cell
            ``(side // 2, side // 2)`` is the cell nearest to it); None = the grid centred.
        side_cells: window side in cells; None = ``max(H, W)``.
        size_px: output side S in pixels.

    Returns:
        uint8 (3, S, S): channel 0 free, 1 occupied, 2 unknown; each pixel is the share of the
        cells under it (0..255). Window row 0 (lowest row) is image row 0. Outside the grid is
        unknown.
    """
    h, w = grid.shape
    side = int(side_cells) if side_cells is not None else max(h, w)
    side = max(side, 1)
    if centre is None:
        # The grid in the middle of the window (exact, no rounding of a half-cell centre).
        c0, r0 = (w - side) // 2, (h - side) // 2
    else:
        c0 = round(centre[0]) - side // 2
        r0 = round(centre[1]) - side // 2
    if c0 >= 0 and r0 >= 0 and c0 + side <= w and r0 + side <= h:
        win = grid[r0 : r0 + side, c0 : c0 + side]  # inside the grid: a view, no copy
    else:
        # Pad rather than clip so that the agent stays at the image centre at the map's border.
        win = np.full((side, side), UNKNOWN, dtype=np.int8)
        rs, cs = max(r0, 0), max(c0, 0)
        re, ce = min(r0 + side, h), min(c0 + side, w)
        if rs < re and cs < ce:
            win[rs - r0 : re - r0, cs - c0 : ce - c0] = grid[rs:re, cs:ce]
    free = free_mask(win)
    occ = occupied_mask(win)
    unknown = ~(free | occ)  # in-between probabilities count as unknown: neither class is sure
    cells = np.stack([free, occ, unknown], axis=-1).view(np.uint8) * np.uint8(255)
    # INTER_AREA averages the cells under each pixel (shares); upsampling keeps cells crisp.
    interp = cv2.INTER_AREA if side >= size_px else cv2.INTER_NEAREST
    out = cv2.resize(cells, (size_px, size_px), interpolation=interp)
    return np.ascontiguousarray(out.transpose(2, 0, 1))


class MapMergeWrapper(BaseParallelWrapper):
    """Runs the map merger on a ``ParallelEnv`` that implements the map protocol.

    Args:
        parallel_env: the env to wrap (its ``unwrapped`` must implement the map protocol).
        merger: merge method name for :func:`mrexplore.merge.merge_maps` (``"semantic"``,
            ``"paper"``, ``"orb"``), an object with ``merge(a, b)``, or None (never merge).
        mode: ``"replace"`` the observation by the fused-map image, or ``"augment"`` it
            (``{"obs": original, "fused_map": image}``).
        merge_every: steps between merge attempts of a pair before its first success.
        recheck_every: steps between re-checks of an accepted transform (0: never).
        comm_range_fn: called each reset/step with the unwrapped env; returns an (N, N) bool
            array, ``links[i, j]`` True when agents ``possible_agents[i]`` and ``[j]`` can
            exchange maps now, or None for "all can". None (default): always connected.
        obs_size_px: side S of the fused-map image, pixels (>= 36 for SB3's ``CnnPolicy``).
        view_m: side of the window shown, metres; None = the longer side of the map.
        semantic_options, tracker_options: the typed options of the semantic merger and of the
            tracker (:func:`mrexplore.merge.in_loop_semantic_options`,
            :func:`mrexplore.merge.in_loop_tracker_options`), as the env takes them; None: the
            loop's.
        **merge_options: extra keyword options of the merge method (the untyped form).

    Raises:
        ConfigError: the env lacks the map protocol, or an option has a bad value.
    """

    def __init__(
        self,
        parallel_env: ParallelEnv,
        merger: str | Merger | None = "semantic",
        mode: MergeMode = "replace",
        merge_every: int = MERGE_EVERY_DEFAULT,
        recheck_every: int = RECHECK_EVERY_DEFAULT,
        comm_range_fn: LinksFn | None = None,
        obs_size_px: int = 64,
        view_m: float | None = None,
        semantic_options: SemanticOptions | None = None,
        tracker_options: TrackerOptions | None = None,
        **merge_options: Any,
    ) -> None:
        if mode not in ("replace", "augment"):
            raise ConfigError(f"mode must be 'replace' or 'augment', got {mode!r}")
        for name, value, check in (
            ("merge_every", merge_every, MERGE_EVERY_CHECK),
            ("recheck_every", recheck_every, RECHECK_EVERY_CHECK),
            ("obs_size_px", obs_size_px, integer(1)),
            ("view_m", view_m, optional(positive)),
        ):
            validate("MapMergeWrapper", name, value, check)
        if comm_range_fn is not None and not callable(comm_range_fn):
            raise ConfigError(
                "comm_range_fn must be callable (unwrapped env -> (N, N) bool) or None"
            )
        self._has_pose = check_map_protocol(parallel_env)
        inner = getattr(parallel_env, "unwrapped", parallel_env)
        if getattr(inner, "merges_maps", False) is True:
            raise ConfigError(
                f"{type(inner).__name__} already merges its maps (merges_maps is True): build "
                "it with merger=None before wrapping it in MapMergeWrapper, or it would merge "
                "twice"
            )
        super().__init__(parallel_env)
        self.mode: MergeMode = mode
        self.obs_size_px = int(obs_size_px)
        self.view_m = view_m
        self.comm_range_fn = comm_range_fn
        self.fusion = FusionStage(
            list(parallel_env.possible_agents),
            merger=merger,
            merge_every=int(merge_every),
            recheck_every=int(recheck_every),
            merge_options=merge_options,
            resolution_m=float(parallel_env.unwrapped.map_resolution_m),
            semantic_options=semantic_options,
            tracker_options=tracker_options,
        )
        self._step = 0
        n_channels = 4 if self._has_pose else 3
        image_space = gymnasium.spaces.Box(
            0, 255, (n_channels, self.obs_size_px, self.obs_size_px), dtype=np.uint8
        )
        self._spaces: dict[Any, gymnasium.spaces.Space[Any]] = {}
        for agent in parallel_env.possible_agents:
            if mode == "replace":
                self._spaces[agent] = image_space
            else:
                self._spaces[agent] = gymnasium.spaces.Dict(
                    {"obs": parallel_env.observation_space(agent), "fused_map": image_space}
                )

    # ------------------------------------------------------------------ spaces
    def observation_space(self, agent: Any) -> gymnasium.spaces.Space[Any]:
        """The new observation space of ``agent`` (the same object for every call)."""
        try:
            return self._spaces[agent]
        except KeyError:
            raise KeyError(f"unknown agent {agent!r}; agents are {list(self._spaces)}") from None

    # ------------------------------------------------------------------ API
    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[Any, Any], dict[Any, dict[str, Any]]]:
        """Reset the env, forget every transform, merge the first maps."""
        obs, infos = self.env.reset(seed=seed, options=options)
        self.fusion.reset()
        self._step = 0
        self._merge()
        return self._transform(obs, infos)

    def step(
        self, actions: dict[Any, Any]
    ) -> tuple[
        dict[Any, Any],
        dict[Any, float],
        dict[Any, bool],
        dict[Any, bool],
        dict[Any, dict[str, Any]],
    ]:
        """Step the env, then merge this step's maps and rewrite observations and infos."""
        obs, rewards, terms, truncs, infos = self.env.step(actions)
        self._step += 1
        self._merge()
        new_obs, new_infos = self._transform(obs, infos)
        return new_obs, rewards, terms, truncs, new_infos

    def fused_map(self, agent: Any) -> NDArray[np.int8]:
        """The fused int8 map in ``agent``'s frame (its own map while not merged)."""
        return self.fusion.fused(agent)

    # ------------------------------------------------------------------ parts
    def _merge(self) -> None:
        u = self.env.unwrapped
        agents = self.fusion.agents
        maps = {a: validate_grid(np.asarray(u.local_map(a)), f"local_map({a!r})") for a in agents}
        links = None
        if self.comm_range_fn is not None:
            raw = self.comm_range_fn(u)
            if raw is not None:
                links = np.asarray(raw, dtype=bool)
                if links.shape != (len(agents), len(agents)):
                    raise ConfigError(
                        f"comm_range_fn returned shape {links.shape}, expected "
                        f"({len(agents)}, {len(agents)}) in possible_agents order"
                    )
        self.fusion.update(maps, self._step, links)

    def _image(self, agent: Any) -> NDArray[np.uint8]:
        """The fused-map image of ``agent`` (see the module docstring for the channels)."""
        u = self.env.unwrapped
        grid = self.fusion.fused(agent)
        side = None
        if self.view_m is not None:
            side = max(1, round(self.view_m / float(u.map_resolution_m)))
        if not self._has_pose:
            return fused_map_image(grid, None, side, self.obs_size_px)
        col, row, _ = u.own_pose_cell(agent)
        side = side if side is not None else max(grid.shape)
        base = fused_map_image(grid, (col, row), side, self.obs_size_px)
        robots = np.zeros((self.obs_size_px, self.obs_size_px), dtype=np.uint8)
        scale = self.obs_size_px / side
        radius = max(1, round(self.obs_size_px / 32))
        origin = np.array([round(col) - side // 2, round(row) - side // 2], dtype=np.float64)
        for other, T in self.fusion.transforms(agent).items():
            oc, orow, _ = u.own_pose_cell(other)
            p = (
                apply_transform(T, np.array([[oc, orow]], dtype=np.float64))[0] - origin + 0.5
            ) * scale
            x, y = math.floor(p[0]), math.floor(p[1])
            if 0 <= x < self.obs_size_px and 0 <= y < self.obs_size_px:
                cv2.circle(robots, (x, y), radius, _MATE_VALUE, -1)
        me = (np.array([col, row], dtype=np.float64) - origin + 0.5) * scale
        cv2.circle(robots, (math.floor(me[0]), math.floor(me[1])), radius, _SELF_VALUE, -1)
        return np.concatenate([base, robots[None]], axis=0)

    def _info(self, agent: Any) -> dict[str, Any]:
        transforms = self.fusion.transforms(agent)
        return {
            "merged": self.fusion.merged(agent),
            "transform": {
                other: (transforms[other].tolist() if other in transforms else None)
                for other in self.fusion.agents
                if other != agent
            },
            "score": self.fusion.score(agent),
        }

    def _transform(
        self, obs: dict[Any, Any], infos: dict[Any, dict[str, Any]]
    ) -> tuple[dict[Any, Any], dict[Any, dict[str, Any]]]:
        new_obs: dict[Any, Any] = {}
        new_infos: dict[Any, dict[str, Any]] = {}
        for agent, o in obs.items():
            image = self._image(agent)
            new_obs[agent] = image if self.mode == "replace" else {"obs": o, "fused_map": image}
        for agent in [*obs, *(a for a in infos if a not in obs)]:
            new_infos[agent] = {**infos.get(agent, {}), **self._info(agent)}
        return new_obs, new_infos
