"""The one merging path: local maps in, fused maps and merge facts out, every step.

Both the built-in merging of :class:`mrexplore.environment.MultiRobotExplorationEnv` and the generic
:class:`mrexplore.wrappers.MapMergeWrapper` run their maps through a :class:`FusionStage`, so
merging behaves identically whether you use our env or wrap your own.

A stage knows nothing of the ground truth: it sees each agent's own-frame int8 map, whether the
agents can talk (``links``), and the step counter.
"""

from __future__ import annotations

import dataclasses
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor
from typing import TYPE_CHECKING, Any, TypeVar

import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import ConfigError
from mrexplore.grid import MapChange, Transform, check_int8_map
from mrexplore.options import MERGE_EVERY_DEFAULT, RECHECK_EVERY_DEFAULT, Options
from mrexplore.types import Box, Merger

if TYPE_CHECKING:
    from mrexplore.merge.semantic import SemanticOptions
    from mrexplore.merge.tracker import TrackerOptions

#: ``rival_perfect_cells`` of the semantic merger in the loop: off. The perfect-rival test guards
#: a one-shot merge against b's rest lying in a's unseen part; in the loop that part gets seen
#: and the re-check drops a pose the grown maps contradict. There it only delayed merges
#: (docs/merging_history.md, "A far pose that nothing contradicts is a rival": one depot
#: episode of 20 never merged).
IN_LOOP_RIVAL_PERFECT_CELLS = 0
#: The semantic merger's options in the loop (the env's tracker and the loop study's seeded
#: diagnostic); options the caller gives win. The look-alike guard is the place test
#: (:mod:`~mrexplore.merge.places`): a match waits until agreement beyond the places holding
#: most of it pins the pose, whatever the rooms' size. It replaces the floors a single call
#: keeps, each a size chosen on our worlds: the shared space and the room match
#: (``min_common_m2``, ``room_match_m2``: rooms), the agreeing walls' area and the one-object
#: rule (``min_wall_area_m2``, ``min_object_m2``: a rack, a pillar). Agreement on one room or
#: one object lies in the places the test leaves out, so with it on they decided nothing more
#: (docs/merging.md).
IN_LOOP_SEMANTIC_OPTIONS: dict[str, Any] = {
    "place_test": True,
    "min_common_m2": 0.0,
    "room_match_m2": 0.0,
    "min_wall_area_m2": 0.0,
    "min_object_m2": 0.0,
    "rival_perfect_cells": IN_LOOP_RIVAL_PERFECT_CELLS,
}


_O = TypeVar("_O", bound=Options)


def semantic_named(merger: Any) -> bool:
    """Is ``merger`` the named semantic method (whose in-loop settings apply)?"""
    return isinstance(merger, str) and merger.lower() == "semantic"


def in_loop_semantic_options(**changes: Any) -> SemanticOptions:
    """The semantic merger's options in the loop (:data:`IN_LOOP_SEMANTIC_OPTIONS` over its
    defaults) with ``changes``: what to give the env's ``semantic_options`` to change one
    setting and keep the loop's others. A bad name or value is a ``ConfigError`` naming it.

    >>> o = in_loop_semantic_options(min_margin=0.05)
    >>> o.place_test, o.min_common_m2, o.min_margin
    (True, 0.0, 0.05)
    """
    from mrexplore.merge.semantic import SemanticOptions

    return SemanticOptions.from_kwargs(**{**IN_LOOP_SEMANTIC_OPTIONS, **changes})


def in_loop_tracker_options(**changes: Any) -> TrackerOptions:
    """The tracker's options in the loop with ``changes``: what to give the env's
    ``tracker_options``. They are the tracker's defaults for every merger: the semantic
    merger's former floor on the accepted pose's wall cells (``min_accept_cells`` 250, a length
    of wall chosen on our worlds) decided nothing more once the place test was on
    (docs/merging.md). The schedule (``merge_every``, ``recheck_every``,
    ``merge_latency_steps``) is the env's own options; set it there.

    >>> o = in_loop_tracker_options(drop_below=0.9)
    >>> o.drop_below, o.min_accept_cells
    (0.9, 0)
    """
    from mrexplore.merge.tracker import TrackerOptions

    return TrackerOptions.from_kwargs(**changes)


def _tracker_settings(
    merger: Any,
    schedule: Mapping[str, Any],
    merge_options: Mapping[str, Any] | None,
    semantic_options: SemanticOptions | None,
    tracker_options: TrackerOptions | None,
    resolution_m: float | None,
) -> tuple[TrackerOptions, dict[str, Any]]:
    """The tracker's options and the merger's keyword options of a stage, from the untyped
    ``merge_options`` (the merger's options with the tracker's knobs among them) or the typed
    ones; both forms for one part is a ``ConfigError``."""
    from mrexplore.merge.semantic import SemanticOptions
    from mrexplore.merge.tracker import TRACKER_KEYS, TrackerOptions

    options = dict(merge_options or {})
    knobs = {k: options.pop(k) for k in sorted(TRACKER_KEYS & set(options))}
    semantic = semantic_named(merger)
    if tracker_options is None:
        tuning = in_loop_tracker_options(**{**schedule, **knobs})
    elif not isinstance(tracker_options, TrackerOptions):
        raise ConfigError(f"tracker_options must be a TrackerOptions, got {tracker_options!r}")
    elif knobs:
        raise ConfigError(
            f"the tracker's {sorted(knobs)} given in merge_options and tracker_options: give "
            "them in tracker_options only"
        )
    else:
        tuning = _owned_by_stage(tracker_options, schedule, "tracker_options")
    if semantic_options is None:
        if semantic:
            # in the loop the maps grow, so asking for a room's worth of shared knowledge costs
            # seconds, while a one-shot merge has no "later"
            options = {**IN_LOOP_SEMANTIC_OPTIONS, **options}
            if resolution_m is not None:
                options.setdefault("resolution_m", float(resolution_m))
        return tuning, options
    if not isinstance(semantic_options, SemanticOptions):
        raise ConfigError(f"semantic_options must be a SemanticOptions, got {semantic_options!r}")
    if not semantic:
        raise ConfigError(f"semantic_options are the semantic merger's; the merger is {merger!r}")
    if options:
        raise ConfigError(
            f"the merger's {sorted(options)} given in merge_options and semantic_options: give "
            "them in semantic_options only"
        )
    resolution = {} if resolution_m is None else {"resolution_m": float(resolution_m)}
    return tuning, _owned_by_stage(semantic_options, resolution, "semantic_options").to_dict()


def _owned_by_stage(options: _O, stage: Mapping[str, Any], where: str) -> _O:
    """``options`` with the fields ``stage`` sets replaced by the stage's values; a field the
    caller set to a third value (neither its default nor the stage's) is a ``ConfigError``: it
    would be lost silently."""
    defaults = {f.name: f.default for f in dataclasses.fields(options)}  # type: ignore[arg-type]
    for name, value in stage.items():
        given = getattr(options, name)
        if given != defaults[name] and given != value:
            raise ConfigError(
                f"{where}.{name} is {given!r} but the env's {name} is {value!r}: set {name} "
                "on the env (it is the env's, not the options')"
            )
    return dataclasses.replace(options, **stage)  # type: ignore[type-var]


def _known_of(changes: Mapping[str, MapChange] | None, agent: str) -> Box | None:
    """The known box ``changes`` tells of ``agent``'s map (``(0, 0, 0, 0)`` when all is
    unknown), None when it tells nothing."""
    change = None if changes is None else changes.get(agent)
    if change is None:
        return None
    return (0, 0, 0, 0) if change.known_box is None else change.known_box


class FusionStage:
    """Runs a :class:`~mrexplore.merge.MapMergeTracker` over named agents.

    Args:
        agents: agent names, in a fixed order (index i = tracker robot i).
        merger: a method name for :func:`mrexplore.merge.merge_maps`, an object with
            ``merge(a, b)``, or ``None`` to never merge (each agent keeps its own map).
        merge_every: steps between merge attempts of a pair before its first success.
        recheck_every: steps between re-checks of an accepted transform.
        merge_latency_steps: steps between the start of a merge attempt and its effect (0: the
            same step; > 0: computed in a worker thread meanwhile).
        merge_options: extra keyword options for the merge method, and the tracker's knobs
            (:class:`~mrexplore.merge.TrackerOptions`' names) among them: the untyped form;
            ``semantic_options`` and ``tracker_options`` are the typed one.
        resolution_m: metres per cell of the maps; passed to the ``"semantic"`` merger (its
            minimum common area is in m^2) unless ``merge_options`` sets it.
        executor: the worker thread for delayed attempts, shared with other stages (see
            :class:`~mrexplore.merge.MapMergeTracker`); None: the tracker's own.
        semantic_options: the semantic merger's options, used as given (start from
            :func:`in_loop_semantic_options`); None: the loop's. Only with ``merger="semantic"``.
        tracker_options: the tracker's options, used as given but for the schedule above
            (start from :func:`in_loop_tracker_options`); None: the loop's.
        sightings: whether the owner hands the tracker sightings (``update``'s ``sightings``);
            the tracker's ``rendezvous_only`` left at None follows it (with sightings, a pair
            merges only once its robots have met); without them a tracker that merges only
            robots that met would never merge, which is refused here.
    """

    def __init__(
        self,
        agents: Sequence[str],
        merger: str | Merger | None = "semantic",
        merge_every: int = MERGE_EVERY_DEFAULT,
        recheck_every: int = RECHECK_EVERY_DEFAULT,
        merge_latency_steps: int = 0,
        merge_options: Mapping[str, Any] | None = None,
        resolution_m: float | None = None,
        executor: Executor | None = None,
        semantic_options: SemanticOptions | None = None,
        tracker_options: TrackerOptions | None = None,
        sightings: bool = False,
    ) -> None:
        self.agents = list(agents)
        self.index = {a: i for i, a in enumerate(self.agents)}
        self.enabled = merger is not None and len(self.agents) > 1
        self._maps: list[NDArray[np.int8]] = []
        # per agent: a box holding the own map's known cells, from its owner (None: not told)
        self._known: list[Box | None] = []
        self._memo: dict[tuple[str, str], Any] = {}  # answers of this update (see _memoised)
        self._first_merge_step: dict[str, int | None] = dict.fromkeys(self.agents)
        # fused_version: a counter that only grows (never reset, so a version never repeats),
        # the version of the last update without a merger, and per agent (what the fused map
        # was last seen as, its version)
        self._counter = 0
        self._update_version = 0
        self._seen: dict[str, tuple[tuple[str, Any], int]] = {}
        self.tracker: Any = None
        if self.enabled:
            from mrexplore.merge.tracker import MapMergeTracker

            tuning, options = _tracker_settings(
                merger,
                {
                    "merge_every": merge_every,
                    "recheck_every": recheck_every,
                    "merge_latency_steps": merge_latency_steps,
                },
                merge_options,
                semantic_options,
                tracker_options,
                resolution_m,
            )
            if tuning.rendezvous_only is None:
                # robots that can see each other merge only once they have: the maps alone lay
                # look-alike rooms on each other before the robots meet (docs/guide/merger.md)
                tuning = dataclasses.replace(tuning, rendezvous_only=bool(sightings))
            if tuning.rendezvous_only and not sightings:
                raise ConfigError(
                    "the tracker's rendezvous_only merges only robots that saw each other, and "
                    "no sightings reach it: turn sightings on (the env's sighting_range_m)"
                )
            self.tracker = MapMergeTracker(
                len(self.agents), merger=merger, options=tuning, executor=executor, **options
            )

    def reset(self) -> None:
        """Forget every transform (a new episode)."""
        self._maps = []
        self._known = []
        self._memo = {}
        self._first_merge_step = dict.fromkeys(self.agents)
        self._seen = {}
        if self.tracker is not None:
            self.tracker.reset()

    def update(
        self,
        local_maps: Mapping[str, NDArray[np.int8]],
        step: int,
        links: NDArray[np.bool_] | None = None,
        attempt: bool = True,
        changes: Mapping[str, MapChange] | None = None,
        sightings: Mapping[tuple[int, int], Transform] | None = None,
    ) -> None:
        """Feed this step's own-frame maps (one per agent, int8 -1/0/100).

        ``links[i, j]`` False means agents i and j cannot exchange maps this step; ``attempt``
        False records the maps without a merge attempt (at ``reset``: single-scan maps).
        ``changes``: optionally, per agent, what the map's owner knows of its changes (known
        and changed boxes, :class:`mrexplore.grid.MapChange`), which spares the tracker a scan
        of every canvas. ``sightings``: ``{(i, j): T_ij}`` guesses from robots that saw each
        other (agent indices, i < j; see :meth:`~mrexplore.merge.MapMergeTracker.update`).
        """
        missing = [a for a in self.agents if a not in local_maps]
        if missing:
            raise KeyError(f"no local map for agent(s) {missing}")
        self._maps = [check_int8_map(local_maps[a], f"local map of {a}") for a in self.agents]
        self._known = [_known_of(changes, a) for a in self.agents]
        self._memo = {}
        self._counter += 1
        self._update_version = self._counter
        if self.tracker is None:
            return
        hints = None if changes is None else [changes.get(a) for a in self.agents]
        self.tracker.update(
            self._maps, step, links, attempt=attempt, changes=hints, sightings=sightings
        )
        for a in self.agents:
            if self._first_merge_step[a] is None and self.tracker.merged(self.index[a]):
                self._first_merge_step[a] = step

    def _memoised(self, what: str, agent: str, compute: Callable[[], Any]) -> Any:
        """``compute()``, once per :meth:`update` for each (what, agent): the answers change
        only when the tracker takes new maps, and the env asks each several times a step."""
        key = (what, agent)
        if key not in self._memo:
            self._memo[key] = compute()
        return self._memo[key]

    def merged(self, agent: str) -> bool:
        """True once ``agent``'s map is fused with at least one teammate's."""
        if self.tracker is None:
            return False
        tracker = self.tracker
        return bool(self._memoised("merged", agent, lambda: tracker.merged(self.index[agent])))

    def unmerged_pairs(self) -> list[tuple[int, int]]:
        """Agent index pairs (i < j) whose maps are not merged (directly or through others)."""
        if self.tracker is None:
            return []
        n = len(self.agents)
        return [
            (i, j)
            for i in range(n)
            for j in range(i + 1, n)
            if self.tracker.transform(i, j) is None
        ]

    def sighting_pairs(self) -> list[tuple[int, int]]:
        """Agent index pairs (i < j) whose sightings the tracker takes: every pair, merged or
        not (a sighting guides an unmerged pair's attempts and checks a merged pair's pose);
        none without a tracker."""
        if self.tracker is None:
            return []
        n = len(self.agents)
        return [(i, j) for i in range(n) for j in range(i + 1, n)]

    def first_merge_step(self, agent: str) -> int | None:
        """The step at which ``agent`` was first merged, or None."""
        return self._first_merge_step[agent]

    def fused(self, agent: str) -> NDArray[np.int8]:
        """The fused map in ``agent``'s frame (its own map when not merged), same shape."""
        i = self.index[agent]
        tracker = self.tracker
        if tracker is not None and self.merged(agent):
            return self._memoised("fused", agent, lambda: np.asarray(tracker.fused(i)))
        return self._maps[i]

    def known_box(self, agent: str) -> Box | None:
        """A half-open box of :meth:`fused` of ``agent`` holding every cell that is not unknown
        (possibly larger than the tightest; ``(0, 0, 0, 0)`` when nothing is known), or None when
        the maps' owner did not tell their known boxes (``update``'s ``changes``)."""
        i = self.index[agent]
        tracker = self.tracker
        if tracker is not None and self.merged(agent):
            self.fused(agent)  # the box of this update's composition
            return tracker.fused_known_box(i)
        return self._known[i] if i < len(self._known) else None

    def fused_version(self, agent: str) -> int:
        """A number that changes whenever :meth:`fused` of ``agent`` may have changed.

        For caching per-map evaluations (the env's map-accuracy metrics). With a merger it
        changes only when the fused map (or, unmerged, the own map) really changed: the tracker
        returns the same fused array until a map or transform changes, and counts own-map
        changes. Without a merger (``merger=None`` or one agent) there is no change detection:
        it changes at every :meth:`update`. It never repeats across :meth:`reset`.
        """
        if self.tracker is None:
            return self._update_version
        i = self.index[agent]
        key: tuple[str, Any]
        if self.tracker.merged(i):
            key = ("fused", self.fused(agent))  # the same object until something changed
        else:
            key = ("own", self.tracker.map_version(i))
        seen = self._seen.get(agent)
        if seen is not None:
            (kind, ref), version = seen
            if kind == key[0] and (ref is key[1] if kind == "fused" else ref == key[1]):
                return version
        self._counter += 1
        self._seen[agent] = (key, self._counter)
        return self._counter

    def fused_change(self, agent: str) -> tuple[int, Box | None] | None:
        """For a merged ``agent``: ``(composition count, changed box)`` of its fused map (see
        :meth:`mrexplore.merge.MapMergeTracker.fused_change`; call :meth:`fused` first); None
        when it is not merged (its fused map is then its own map, which says what changed)."""
        if self.tracker is None or not self.tracker.merged(self.index[agent]):
            return None
        count, box = self.tracker.fused_change(self.index[agent])
        return int(count), box

    def fused_changed_cells(self, agent: str) -> NDArray[np.int64] | None:
        """For a merged ``agent``: the flat cells of its fused map the composition counted by
        :meth:`fused_change` changed (None: rebuilt whole, or not merged)."""
        if self.tracker is None or not self.tracker.merged(self.index[agent]):
            return None
        return self.tracker.fused_changed_cells(self.index[agent])

    def transforms(self, agent: str) -> dict[str, NDArray[np.float64]]:
        """Estimated transforms from each merged teammate's cells into ``agent``'s cells."""
        if self.tracker is None:
            return {}
        i = self.index[agent]
        out: dict[str, NDArray[np.float64]] = {}
        for other in self.agents:
            j = self.index[other]
            if j == i:
                continue
            T = self.tracker.transform(i, j)
            if T is not None:
                out[other] = np.asarray(T, dtype=np.float64)
        return out

    def hypotheses(self, agent: str) -> dict[str, tuple[list[Transform], NDArray[np.int8]]]:
        """For each teammate not merged with ``agent``: the tracker's candidate transforms
        (:meth:`~mrexplore.merge.MapMergeTracker.hypotheses`, the teammate's cells into
        ``agent``'s, most likely first) and the teammate's map as last fed (read-only view);
        teammates without candidates are left out."""
        if self.tracker is None or not self._maps:
            return {}
        i = self.index[agent]
        out: dict[str, tuple[list[Transform], NDArray[np.int8]]] = {}
        for other in self.agents:
            j = self.index[other]
            if j == i:
                continue
            cands = self.tracker.hypotheses(i, j)
            if cands:
                m = self._maps[j].view()
                m.flags.writeable = False
                out[other] = (cands, m)
        return out

    def score(self, agent: str) -> float | None:
        """Agreement score of the best accepted merge involving ``agent`` (None if none)."""
        if self.tracker is None:
            return None
        i = self.index[agent]
        best: float | None = None
        for other in self.agents:
            j = self.index[other]
            if j == i:
                continue
            res = self.tracker.last_result(i, j)
            if res is not None and getattr(res, "matched", False):
                s = float(res.score)
                best = s if best is None else max(best, s)
        return best
