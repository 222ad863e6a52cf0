"""``MapMergeTracker``: map merging for N robots, every time step.

Each step the caller hands over the robots' own-frame maps. The tracker

- every ``merge_every`` steps tries to merge each pair of robots that are in communication range
  and not yet connected (directly or through a chain of merged pairs), calling the merger on the
  maps cropped to their known bounding boxes;
- accepts a pair's transform only once ``confirmations`` consecutive attempts found the same
  transform (within ``confirm_tol_cells``), each resting on ``confirm_growth`` more shared wall
  cells than the one before: evidence accumulated over time. A look-alike match stays confined
  to the look-alike part (its shared evidence cannot grow without a contradiction, which
  refuses and breaks the run), the true one spreads as the maps grow. A pose accepted by an
  attempt a sighting guided needs no later attempt when it puts the seen robot where it was
  seen (``SIGHTING_CONFIRMS``): the sighting is the other measurement;
- keeps an accepted transform; every ``recheck_every`` steps re-runs the merger on merged pairs
  and replaces the transform only when the new one scores clearly better (by
  ``REPLACE_MARGIN``) than the kept one does *on the same current maps*: no flip-flopping;
  and drops it when, on the current maps, it agrees less than ``drop_below`` (new evidence
  contradicts it: a wrong merge is worse than no merge). The agreement that decides a drop
  discounts the maps' noise as the default merger's acceptance does (walls within
  ``RECHECK_SLACK_CELLS`` of each other agree, lone contradictions under
  ``RECHECK_MIN_RUN_CELLS`` cells do not count), so a pose accepted as consistent is not
  dropped for the noise and drift it was accepted with; a contradicted transform is
  replaced instead of dropped when the merger, run on the same maps, accepts one within
  ``RELOCATE_TOL_CELLS`` of it, or ranks one there first and refuses it only for the maps'
  bending (the same place, refitted to maps that drift has bent); and it is kept when it is
  contradicted only by walls a drift's width apart (``DRIFT_SLACK_CELLS``). A re-check also
  judges the kept place as a rival of the merger's best pose (``OUTRANKED_DROP``): when the
  grown maps single out another place, consistent with them, that neither the kept place nor
  any other pose stands against, the pair moves there (the merger accepted it) or is un-merged;
- lets a sighting bind its pair (``SIGHTING_BINDS``): robots that see each other measure the
  transform, so a kept pose that puts the seen robot elsewhere than the sighting's region is
  dropped and the next attempt looks only in that region; re-checks of a sighted pair look only
  there too (a look-alike elsewhere cannot win a re-check against a rendezvous). A pair merged
  only through teammates is bound too: when the chain puts the seen robot elsewhere, every edge
  of the chain that no sighting of its own pair vouches for is dropped;
- chains transforms through merged pairs (0-1 and 1-2 merged => 0-2 known);
- hands the pixels to :class:`~mrexplore.merge.compositor.MapCompositor`: change detection,
  each teammate's map warped into i's frame, and robot i's fused map ("occupied beats free
  beats unknown"); maps travel only over links that are up.

The decision rules are :meth:`MapMergeTracker._decide_attempt` and
:meth:`MapMergeTracker._decide_recheck`; :meth:`MapMergeTracker._compute` is the only call of
the merger.

Size: the two decision rules, the transform graph and the fixed-latency job schedule that
makes the rules deterministic; the pixels (change detection, fused maps) are in
:mod:`~mrexplore.merge.compositor`.
"""

from __future__ import annotations

import time
from collections import deque
from collections.abc import Callable, Mapping, Sequence
from concurrent.futures import Executor, Future, ThreadPoolExecutor, wait
from dataclasses import dataclass, fields, replace
from typing import Any, ClassVar

import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import ConfigError, GridError
from mrexplore.grid import (
    Int8Grid,
    MapChange,
    Transform,
    chain,
    check_int8_map,
    invert_transform,
    map_points,
)
from mrexplore.merge import semantic as _semantic
from mrexplore.merge.api import METHODS, merge_maps
from mrexplore.merge.common import MapCodes, MergeResult, Verifier, translation
from mrexplore.merge.compositor import MapCompositor
from mrexplore.merge.semantic import (
    PosePrior,
    SemanticOptions,
    rival_structure,
    stands_as_rival,
    turn_between_deg,
)
from mrexplore.options import (
    MERGE_EVERY_CHECK,
    MERGE_EVERY_DEFAULT,
    MERGE_LATENCY_CHECK,
    RECHECK_EVERY_CHECK,
    RECHECK_EVERY_DEFAULT,
    Options,
    boolean,
    integer,
    number,
    option,
    optional,
    positive,
    validate,
)
from mrexplore.types import Box, Merger, Sighting

#: A merge function ``(a, b) -> MergeResult`` (a named method, or a Merger's ``merge``).
MergeFn = Callable[[Int8Grid, Int8Grid], MergeResult]

#: ``min_common_m2`` of the semantic merger in an attempt guided by a sighting (m^2).
GUIDED_MIN_COMMON_M2 = 5.0


# --- the in-loop rules' settings that are not options: one value each (what each does and its
# measured effect: docs/merging.md; how each was chosen: docs/merging_history.md). Read where
# used, so a test may set one for a run. ----------------------------------------------------
#: A re-check replaces the kept transform only when the new one's score beats the kept one's on the
#: same maps by this: no flip-flopping.
REPLACE_MARGIN: float = 0.05
#: In a re-check's noise-aware agreement, walls within this many cells beyond the one-cell tolerance
#: agree (the semantic merger's ``SLACK_CELLS``).
RECHECK_SLACK_CELLS: int = 2
#: In that agreement, contradicting cells count only in 8-connected groups this large (the semantic
#: merger's ``MIN_RUN_CELLS``).
RECHECK_MIN_RUN_CELLS: int = 5
#: A contradicted transform is kept, refitted, when the merger accepts one within this many cells of
#: it (0.5 m at 0.05 m: a long episode's drift; 0: always drop).
RELOCATE_TOL_CELLS: float = 10.0
#: A contradicted transform is also kept, refitted, when the merger refuses but ranks a consistent
#: pose within ``RELOCATE_TOL_CELLS`` first, beating every farther rival.
REFIT_REFUSED: bool = True
#: A contradicted transform is kept when, with walls this many cells apart taken as one (0.3 m:
#: drift), it agrees at least ``DRIFT_KEEP_ABOVE`` (0: off).
DRIFT_SLACK_CELLS: int = 6
#: The agreement with ``DRIFT_SLACK_CELLS`` that keeps a contradicted transform as drift.
DRIFT_KEEP_ABOVE: float = 0.9
#: A re-check hands the merger the kept place and judges it as a rival of the merger's best pose
#: on the current maps: the pair lets it go when the maps single out another place
#: (:meth:`MapMergeTracker._outranked`; False: off, the kept place judged by ``drop_below`` only).
OUTRANKED_DROP: bool = True
#: A sighting binds its pair: a kept pose outside the latest sighting's region is dropped (the
#: next attempt looks in the region; merged through teammates, the chain's edges no sighting of
#: their own vouches for), and a re-check moves or replaces the kept pose only inside it
#: (False: sightings guide the attempts of unmerged pairs only).
SIGHTING_BINDS: bool = True
#: A pose the merger accepts in an attempt guided by a sighting is merged at once when it puts
#: the seen robot where the sighting saw it (within ``confirm_tol_cells``): the sighting measured
#: the pose independently of the maps, so it is the second agreeing measurement that
#: ``confirmations`` otherwise waits for from a later attempt; a pose the maps slid elsewhere in
#: the sighting's region waits as any pose does (False: every pose waits).
SIGHTING_CONFIRMS: bool = True
#: A pose the maps propose for a sighted pair (an attempt's, or a re-check's that would move or
#: replace the kept one) must also keep the sighting's heading within ``PRIOR_TURN_DEG``, the
#: region a guided attempt searches; a kept pose is judged by position only (False: new poses
#: too).
SIGHTING_TURN_BINDS: bool = True
#: A sighting-guided attempt looks within this many cells of the guess (2 m at 0.05 m).
PRIOR_RADIUS_CELLS: float = 40.0
#: A sighting-guided attempt looks within this many degrees of the guess's heading.
PRIOR_TURN_DEG: float = 10.0
#: Rivals remembered per unmerged pair; a pose is accepted only once the maps rule out every one (0:
#: none).
RIVAL_MEMORY: int = 8
#: An unmerged pair is tried again only once its two maps know this share more cells (the same maps
#: give the same answer).
RETRY_GROWTH: float = 0.02
#: Each attempt round tries every robot with one partner, the offset between them rotating round
#: by round, so a team's attempts grow with its robots, not its pairs: every pair gets its turn
#: within n / 2 rounds, and teams of two or three try every pair every round either way (False:
#: every unmerged pair every round).
ROTATING_PARTNERS: bool = False

#: The tracker's former options that are now the constants above (name -> constant name).
DEMOTED_TRACKER_OPTIONS: dict[str, str] = {
    "replace_margin": "REPLACE_MARGIN",
    "recheck_slack_cells": "RECHECK_SLACK_CELLS",
    "recheck_min_run_cells": "RECHECK_MIN_RUN_CELLS",
    "relocate_tol_cells": "RELOCATE_TOL_CELLS",
    "refit_refused": "REFIT_REFUSED",
    "drift_slack_cells": "DRIFT_SLACK_CELLS",
    "drift_keep_above": "DRIFT_KEEP_ABOVE",
    "prior_radius_cells": "PRIOR_RADIUS_CELLS",
    "prior_turn_deg": "PRIOR_TURN_DEG",
    "rival_memory": "RIVAL_MEMORY",
    "retry_growth": "RETRY_GROWTH",
}


def rival_rule(merger: Any, merge_options: Mapping[str, Any]) -> SemanticOptions:
    """How the tracker judges a remembered rival against an accepted pose on the current maps:
    as the semantic merger of this run judges a rival (``FAR_CELLS`` from it, explaining at
    least ``RIVAL_SUPPORT`` of its agreeing wall cells, not beaten by ``min_margin`` in index
    and ``MIN_EVIDENCE_CELLS`` contradicting wall cells, nor ruled out by one object), with the
    run's own options when the merger is the named semantic one, its defaults otherwise (the
    upper-case settings are constants of :mod:`~mrexplore.merge.semantic`, the same for both)."""
    if isinstance(merger, str) and merger.lower() == "semantic":
        return SemanticOptions.from_kwargs(**merge_options)
    return SemanticOptions.from_kwargs()


Offsets = tuple[tuple[int, int], tuple[int, int]]


def _to_crop(T: Transform, offsets: Offsets) -> Transform:
    """A pose in canvas cells (b -> a) in the cells of the crops whose cell (0, 0) is at
    ``offsets`` ((col, row) of a's crop, of b's) in the canvases; by chain, not @ (BLAS): the
    same bits on every CPU."""
    (ca, ra), (cb, rb) = offsets
    return chain(translation(-ca, -ra), T, translation(cb, rb))


def _to_canvas(X: Any, offsets: Offsets) -> Transform:
    """The inverse of :func:`_to_crop`: a pose in crop cells in canvas cells."""
    (ca, ra), (cb, rb) = offsets
    return chain(translation(ca, ra), np.asarray(X, dtype=np.float64), translation(-cb, -rb))


def _same_place_cells() -> float:
    """How near (cells) a re-check's pose must lie to the kept one to be the same place: the
    drift a refit absorbs (``RELOCATE_TOL_CELLS``), and never under a rival's ``FAR_CELLS``."""
    return max(RELOCATE_TOL_CELLS, _semantic.FAR_CELLS)


def _consistent(res: MergeResult) -> bool:
    """The merger found its best pose consistent with the maps (refused, if at all, for
    uniqueness, pinning, shared space or a look-alike rule); False without evidence."""
    return res.evidence is not None and res.evidence.consistent


@dataclass(frozen=True)
class _Outcome:
    """What a merge attempt or re-check computed (on copies of the maps; applied later)."""

    result: MergeResult | None  # None: a re-check that dropped without running the merger
    T: Transform | None  # T_ij in full-canvas cells, None when refused
    old_now: float | None = None  # re-check: the kept transform's raw index on those maps
    held_now: float | None = None  # re-check: its noise-aware agreement (what a drop judges)
    # re-check, when held_now is under the bar: that agreement with walls up to
    # ``DRIFT_SLACK_CELLS`` apart taken as one wall (None: not computed)
    drift_held: float | None = None
    # attempt: rival poses the merger reported (canvas cells), and the remembered rivals that
    # still stand against the accepted pose on these maps (None: none were checked)
    rivals: tuple[Transform, ...] = ()
    standing: tuple[Transform, ...] | None = None
    # re-check the merger refused: its best pose (canvas cells) when that pose still places b
    # where the kept transform does, within the maps' noise and without a far rival (None:
    # not so, or the merger reports no best pose)
    refit: Transform | None = None
    # the merger's best pose (canvas cells), accepted or not (None: not reported)
    best: Transform | None = None
    # re-check: the merger's best pose lies far from the kept transform and the kept one would
    # not stand as a rival to it on these maps (the maps now prefer another place)
    outranked: bool = False
    # attempt: the merger looked only in a sighting's region (a PosePrior from the guess)
    guided: bool = False
    # CPU seconds of the thread that computed it (``time.thread_time``): a cost, never read
    # by a decision (it differs between machines and runs)
    cpu_s: float = 0.0


@dataclass(frozen=True)
class MergeWork:
    """What a tracker's merge attempts and re-checks cost in an episode
    (:attr:`MapMergeTracker.work`): those applied so far since the last :meth:`reset`.

    Attributes:
        attempts: merge attempts applied (a pair's maps handed to the merger).
        rechecks: re-checks of merged pairs applied.
        cpu_s: CPU seconds they took, in the thread that ran them (``time.thread_time``; the
            worker thread's with ``merge_latency_steps`` > 0). Machine- and load-dependent: a
            cost to compare within one run, not part of the run (nothing reads it to decide).
    """

    attempts: int = 0
    rechecks: int = 0
    cpu_s: float = 0.0

    def __add__(self, other: MergeWork) -> MergeWork:
        return MergeWork(
            self.attempts + other.attempts, self.rechecks + other.rechecks, self.cpu_s + other.cpu_s
        )


def _timed(compute: Callable[..., _Outcome], *args: Any) -> _Outcome:
    """``compute(*args)`` with the CPU time it took in this thread (``cpu_s``)."""
    t0 = time.thread_time()
    out = compute(*args)
    return replace(out, cpu_s=time.thread_time() - t0)


@dataclass(frozen=True)
class AttemptRecord:
    """One merge attempt of a pair as the tracker applied it, for diagnostics
    (:attr:`MapMergeTracker.attempt_observer`; ``studies/merge_timeline.py``).

    Attributes:
        step: the step the attempt took effect (its start + ``merge_latency_steps``).
        i, j: the pair (robot j's map into robot i's).
        result: the merger's answer (reason, score, ``overlap_cells``, info).
        T: the pose it accepted (canvas cells, j's -> i's), None when refused.
        best: its best pose, also when refused (canvas cells; None when not reported).
        standing: remembered rivals that still stand against ``T``.
        thin: ``T`` rests on fewer than ``min_accept_cells`` wall cells.
        pending: agreeing attempts in the pair's run after this one (0: no run).
        merged: the pair is merged after this attempt.
    """

    step: int
    i: int
    j: int
    result: MergeResult
    T: Transform | None
    best: Transform | None
    standing: int
    thin: bool
    pending: int
    merged: bool


@dataclass(frozen=True)
class DropRecord:
    """A kept transform the grown maps contradicted, and when the tracker let it go
    (:attr:`MapMergeTracker.drops`): how fast a merge the evidence turned against is undone.

    Attributes:
        i, j: the pair.
        contradicted_step: the first re-check that found the kept transform's noise-aware
            agreement under ``drop_below`` (kept then as drift, refitted or relocated), or the
            drop's own step when none did.
        dropped_step: the step that dropped it.
        cause: ``"contradicted"`` (the grown maps contradict it: un-merged), ``"outranked"``
            (the maps single out another place the merger refused: un-merged), ``"moved"``
            (... and accepted: the pair moved there) or ``"sighting"`` (the robots were seen
            elsewhere: un-merged).
    """

    i: int
    j: int
    contradicted_step: int
    dropped_step: int
    cause: str = "contradicted"


@dataclass
class _Job:
    """A merge attempt (``kind`` "attempt") or re-check ("recheck") of pair (i, j): started on
    the maps of one step, applied at step ``due``."""

    kind: str
    i: int
    j: int
    due: int
    bbox_j: Box | None  # j's known box when started: where two estimates are compared
    T_old: Transform | None  # re-check: the kept transform it checks
    outcome: Future[_Outcome] | _Outcome


@dataclass(frozen=True)
class TrackerOptions(Options):
    """The tuning of :class:`MapMergeTracker`: one default and one range each, validated (a
    bad value is a :class:`~mrexplore.errors.ConfigError` naming it). The in-loop decision
    rules read these; the rival rule reads the merger's own options (:func:`rival_rule`).

    Attributes:
        merge_every: try to merge unconnected pairs every this many steps (>= 1).
        recheck_every: re-check accepted transforms every this many steps (0 = never).
        confirmations: consecutive agreeing attempts needed before a transform is accepted
            (default 2; 1 accepts the first match).
        confirm_tol_cells: two attempts agree when the corners of b's known box land within
            this many cells of each other (default 2.0).
        drop_below: a re-check drops the kept transform when its noise-aware agreement on the
            current maps falls below this (default 0.85; 0 never drops).
        min_accept_cells: an attempt's pose counts towards acceptance only when it rests on at
            least this many cells (``MergeResult.overlap_cells``; the semantic merger's wall
            cells of both maps under the pose); below, it is a refusal (default 0, in the env
            too: there the merger's place test refuses a few metres of look-alike wall).
        confirm_growth: an agreeing attempt confirms the pending transform only when the shared
            wall cells under it (``MergeResult.overlap_cells``) grew by this share since the
            attempt before (default 0: any agreeing attempt on grown maps confirms).
        keep_run_on_refusal: an attempt the merger refuses although its best pose is the
            pending transform (within ``confirm_tol_cells``) and consistent with the maps, i.e.
            refused for uniqueness, pinning or shared area, keeps the run of agreeing attempts
            instead of breaking it (it does not extend the run). A rival it reported is
            remembered and must be ruled out before the run can end in a merge
            (``RIVAL_MEMORY``). Default False: every refusal breaks the run (measured in
            ``docs/merging_history.md``, "Where the first merge waits"). Semantic merger only
            (it reports whether its best pose was consistent).
        merge_latency_steps: an attempt or re-check started at step t is applied at step
            t + this, computed meanwhile in a worker thread on copies of the maps, so no step
            waits for the merger (default 0: computed and applied in the step that starts it).
            A fixed delay, not "when ready": the same seed gives the same run on any machine.
            With a delay, at most one attempt or re-check starts per step.
        rendezvous_only: try a pair only once its robots have seen each other (a sighting,
            ``update``'s ``sightings``); the maps then decide the pose within the sighting's
            region. On floors with identical rooms the maps alone merge some look-alikes before
            the robots meet, which this never does, at the cost of the merges of robots that
            never meet. None (default): on where the tracker's owner hands it sightings (the
            env with ``sighting_range_m``, :class:`~mrexplore.merge.fusion.FusionStage`), off
            for a bare tracker; False lets the maps alone merge robots that never met.

    The in-loop rules' other settings are constants of this module (one value each, measured
    on the tuning worlds; a test may set one for a run):

        REPLACE_MARGIN: a re-check replaces the kept transform only if its score beats the kept
            transform's score on the current maps by at least this (default 0.05).
        RECHECK_SLACK_CELLS: in that agreement, a wall of one map within this many cells
            beyond the one-cell tolerance of the other's walls agrees (default 2: the semantic
            merger's ``SLACK_CELLS``, the same wall seen from its two sides or eroded).
        RECHECK_MIN_RUN_CELLS: in that agreement, contradicting cells count only in 8-connected
            groups of at least this many (default 5: the semantic merger's ``MIN_RUN_CELLS``;
            a wall laid across open space, not speckle). Slack 0 and runs of 1: a drop judges
            the raw acceptance index (why not: ``docs/merging_history.md``, "The re-check
            judges a kept transform as acceptance judged it").
        RELOCATE_TOL_CELLS: a re-check that finds the kept transform contradicted keeps the
            pair merged, with the merger's new transform, when the merger accepts one whose
            placement of b's known box is within this many cells of the kept one's (default
            10.0, half a metre at 0.05 m: the drift of a long episode; 0 = always drop).
            Farther, or refused: dropped (but see ``REFIT_REFUSED``).
        REFIT_REFUSED: a contradicted transform is also kept, refitted, when the merger refuses
            but its best pose is within ``RELOCATE_TOL_CELLS`` of it, agrees within the maps'
            noise at least ``drop_below``, and beats every farther rival by the merger's margin:
            drift has bent the maps so that no rigid pose reaches the acceptance bar, yet the
            place is still the best explanation (default True; semantic merger only, which
            reports its best pose).
        DRIFT_SLACK_CELLS, DRIFT_KEEP_ABOVE: a contradicted transform that is neither relocated
            nor refitted is still kept when its noise-aware agreement, with walls up to
            ``DRIFT_SLACK_CELLS`` (default 6, 0.3 m at 0.05 m) beyond the tolerance taken as one
            wall, is at least ``DRIFT_KEEP_ABOVE`` (default 0.9): odometry drift displaces
            walls by that much over a long episode, while a look-alike place lays walls across
            open space (measurements: ``docs/merging_history.md``, "A merge that drift has
            bent is kept"). 0 cells = off.
        PRIOR_RADIUS_CELLS, PRIOR_TURN_DEG: the region around a sighting's guess (``update``'s
            ``sightings``) in which a guided attempt looks: poses that put the centre of j's
            walls within this many cells of where the guess puts it, turned by at most this
            many degrees (defaults 40 cells, 2 m at 0.05 m, and 10 degrees; the semantic
            merger's :class:`~mrexplore.merge.PosePrior`).
        SIGHTING_BINDS: a sighting of a merged pair drops a kept pose outside its region (of a
            pair merged through teammates, every edge of the chain its own sighting does not
            vouch for), and a sighted pair's re-checks move or replace its pose only inside
            the latest sighting's region (default True; False: sightings guide unmerged pairs'
            attempts only). A kept pose is judged by the seen robot's position only: drift
            bends the maps and turns a kept rigid pose from a late sighting's heading.
        SIGHTING_TURN_BINDS: a pose the maps propose for a sighted pair (an attempt's, or a
            re-check's move or replacement) must also keep the sighting's heading within
            ``PRIOR_TURN_DEG``, the window a guided attempt searches: a look-alike half a turn
            away can put the seen robot where it was seen (default True).
        SIGHTING_CONFIRMS: a pose accepted by an attempt a sighting guided is merged at once,
            whatever ``confirmations`` asks, when it puts the seen robot within
            ``confirm_tol_cells`` of where the sighting saw it: the sighting measured it
            independently of the maps (default True; False: it waits for a later agreeing
            attempt like any other, as does a pose farther from the sighting).
        RIVAL_MEMORY: rivals remembered per unmerged pair (default 8; 0 = none): a pose an
            attempt found nearly as good as its best, far from it. A later attempt's pose is
            accepted only when the maps now rule out every remembered rival (it explains less
            than half as much, or is beaten by the merger's margin; the rivals the merger no
            longer finds are checked too): evidence over time, not the search's memory.
        RETRY_GROWTH: an unmerged pair is tried again only once the two maps together know this
            share more cells than at the last attempt (default 0.02; 0 = any change).
        ROTATING_PARTNERS: each attempt round tries every robot with one partner, the offset
            between them rotating round by round (1, 2, .., n // 2, 1, ...): a team's attempts
            grow with its robots, not its pairs, and every pair gets its turn within n // 2
            rounds; teams of two or three try every pair every round either way (default
            False: every unmerged pair every round).
    """

    owner: ClassVar[str] = "MapMergeTracker"
    merge_every: int = option(MERGE_EVERY_DEFAULT, MERGE_EVERY_CHECK)
    recheck_every: int = option(RECHECK_EVERY_DEFAULT, RECHECK_EVERY_CHECK)
    confirmations: int = option(2, integer(1))
    confirm_tol_cells: float = option(2.0, positive)
    drop_below: float = option(0.85, number(0.0, 1.0))
    min_accept_cells: int = option(0, integer(0))
    confirm_growth: float = option(0.0, number(0.0, 10.0))
    keep_run_on_refusal: bool = option(False, boolean)
    merge_latency_steps: int = option(0, MERGE_LATENCY_CHECK)
    rendezvous_only: bool | None = option(None, optional(boolean))


#: The tracker's option names (:class:`TrackerOptions`' fields).
TRACKER_KEYS: frozenset[str] = frozenset(f.name for f in fields(TrackerOptions))


def tracker_options(options: TrackerOptions | None, kwargs: dict[str, Any]) -> TrackerOptions:
    """The tracker's options: ``options``, or the tracker's knobs among ``kwargs`` (removed
    from it; the old keyword form, kept for one release); both at once is a ``ConfigError``."""
    demoted = sorted(set(kwargs) & set(DEMOTED_TRACKER_OPTIONS))
    if demoted:
        names = ", ".join(f"{k} (now {DEMOTED_TRACKER_OPTIONS[k]})" for k in demoted)
        raise ConfigError(
            f"MapMergeTracker: {names} no longer an option: a constant of "
            "mrexplore.merge.tracker, chosen on the tuning worlds (docs/merging.md)"
        )
    given = {k: kwargs.pop(k) for k in sorted(TRACKER_KEYS & set(kwargs))}
    if options is None:
        return TrackerOptions.from_kwargs(**given)
    if not isinstance(options, TrackerOptions):
        raise ConfigError(
            f"MapMergeTracker: options must be a TrackerOptions or None, got {options!r}"
        )
    if given:
        raise ConfigError(
            f"MapMergeTracker: tracker knobs {sorted(given)} given both as keywords and in "
            "options=TrackerOptions(...): give them in options only"
        )
    return options


class NamedMerger:
    """``merge_maps`` with a fixed method and options, as a plain (picklable) callable."""

    def __init__(self, method: str, options: dict[str, Any]) -> None:
        self.method = method
        self.options = dict(options)

    def __call__(self, a: Int8Grid, b: Int8Grid, **extra: Any) -> MergeResult:
        return merge_maps(a, b, method=self.method, **{**self.options, **extra})


def _resolve_merger(merger: Any, options: dict[str, Any]) -> MergeFn:
    if isinstance(merger, str):
        if merger.lower() not in METHODS:
            raise ConfigError(
                f"MapMergeTracker: unknown merger {merger!r}; choose one of "
                f"{tuple(METHODS)} or pass a callable"
            )
        method = merger.lower()
        # Validate the options now (a typo should fail at construction, not 10 steps later):
        # every method reads all its options before it looks at the maps.
        probe = np.full((4, 4), -1, dtype=np.int8)
        merge_maps(probe, probe, method=method, **options)

        return NamedMerger(method, options)
    if options:
        raise ConfigError(
            f"MapMergeTracker: options {sorted(options)} only apply to a named merger, "
            f"not {merger!r}"
        )
    if hasattr(merger, "merge") and callable(merger.merge):
        return merger.merge  # type: ignore[no-any-return,unused-ignore]
    if callable(merger):
        return merger  # type: ignore[no-any-return,unused-ignore]
    raise ConfigError(
        "MapMergeTracker: merger must be a method name, a callable or have .merge(), "
        f"got {merger!r}"
    )


class MapMergeTracker:
    """Holds N robots' maps, merges pairs over time, and fuses maps every step.

    Args:
        n_robots: number of robots (>= 1).
        merger: a method name for :func:`~mrexplore.merge.merge_maps` (default "semantic"), a
            callable ``(a, b) -> MergeResult`` or an object with ``.merge(a, b)``; an object
            that also has ``merge_pair(i, j, a, b, offset_a, offset_b)`` (crop offsets
            ``(col, row)``) is called through that instead (a benchmark oracle needs the ids).
        options: the tracker's tuning (:class:`TrackerOptions`; None: its defaults).
        executor: the worker for delayed attempts (e.g. one single-thread executor shared by
            the trackers of many env copies, :mod:`mrexplore.environment.batched`); the caller
            owns it. Default None: a private single-thread worker made on first use. The
            schedule stays fixed either way, so the run does not depend on the worker.
        **merge_options: options for the named merger (validated at construction). For one
            release, the tracker's own knobs are accepted here too (``merge_every=5``, ...) and
            routed into :class:`TrackerOptions`; pass ``options=TrackerOptions(...)`` instead.

    >>> import numpy as np
    >>> tr = MapMergeTracker(2, options=TrackerOptions(merge_every=5))
    >>> m = np.full((50, 50), -1, dtype=np.int8); m[10:20, 10:20] = 0
    >>> tr.update([m, m], step=0)
    >>> tr.merged(0), tr.fused(0).shape
    (False, (50, 50))
    """

    def __init__(
        self,
        n_robots: int,
        merger: str | Merger | MergeFn | Any = "semantic",
        options: TrackerOptions | None = None,
        executor: Executor | None = None,
        **merge_options: Any,
    ) -> None:
        validate("MapMergeTracker", "n_robots", n_robots, integer(1))
        self.n = int(n_robots)
        self.options = tracker_options(options, merge_options)
        # made on first use unless given (not pickled: an unpickled tracker makes its own)
        self._pool: Executor | None = executor
        self._jobs: list[_Job] = []
        self._merge = _resolve_merger(merger, dict(merge_options))
        self._rival_rule = rival_rule(merger, merge_options)
        self._merger_obj = merger
        #: Called with an :class:`AttemptRecord` after every applied merge attempt (diagnostics;
        #: None: nothing). Not pickled with the tracker.
        self.attempt_observer: Callable[[AttemptRecord], None] | None = None
        self.reset()

    # ------------------------------------------------------------------ state
    def reset(self) -> None:
        """Forget every map, transform and result (call at episode start)."""
        for job in getattr(self, "_jobs", []):
            if isinstance(job.outcome, Future):
                job.outcome.cancel()  # one already running finishes and is discarded
        self._jobs = []
        self._queue: list[tuple[str, int, int]] = []  # waiting to start (latency > 0)
        self._px = MapCompositor(self.n)  # the pixels: change detection, patches, fused maps
        self._edges: dict[tuple[int, int], Transform] = {}  # (i, j), i < j: T_ij direct
        self._edge_score: dict[tuple[int, int], float] = {}
        # (i, j) -> (T_ij candidate, agreeing attempts so far, shared wall cells it rested on)
        self._pending: dict[tuple[int, int], tuple[Transform, int, int]] = {}
        # (i, j) -> rival poses T_ij (canvas cells) of earlier attempts, newest last
        self._rivals: dict[tuple[int, int], list[Transform]] = {}
        # (i, j) -> the last attempt's best pose T_ij (canvas cells) when it passed the
        # consistency test (a candidate a robot may go and check; never accepted from here)
        self._best: dict[tuple[int, int], Transform] = {}
        # (i, j) -> known cells of both maps at the last merge attempt
        self._last_attempt_known: dict[tuple[int, int], int] = {}
        # (i, j) -> the latest sighting of the pair (canvas cells)
        self._sighted: dict[tuple[int, int], Sighting] = {}
        self._results: dict[tuple[int, int], MergeResult] = {}
        self._paths: dict[tuple[int, int], Transform | None] | None = None
        self._groups: dict[int, set[int]] = {}  # robot -> its merged group, kept with _paths
        # per robot s, each robot v it reaches -> the robot before v on the path from s
        self._parents: dict[int, dict[int, int]] = {}
        self._links: NDArray[np.bool_] | None = None
        # (i, j) -> the first re-check that found the kept transform contradicted (cleared when
        # a re-check finds it agreeing again)
        self._contradicted: dict[tuple[int, int], int] = {}
        #: Every transform dropped this episode, oldest first.
        self.drops: list[DropRecord] = []
        self._work = MergeWork()

    # ------------------------------------------------------------------ step
    def update(
        self,
        maps: Sequence[Int8Grid],
        step: int,
        links: NDArray[np.bool_] | None = None,
        attempt: bool = True,
        changes: Sequence[MapChange | None] | None = None,
        sightings: Mapping[tuple[int, int], Transform] | None = None,
    ) -> None:
        """Take the robots' current maps (own frames) at time step ``step``.

        Args:
            maps: N int8 arrays (H_i, W_i); sizes may differ per robot.
            step: the environment's step counter (merge attempts at multiples of merge_every).
            links: (N, N) bool, ``links[i, j]`` False when robots i and j cannot communicate
                (no merge attempt, no map exchange); None = all linked.
            attempt: False = record the maps only, no merge attempt or re-check this call
                (an env's ``reset``: single-scan maps cannot be merged, and trying costs time).
            changes: optionally, per map, what its owner knows of its changes
                (:class:`mrexplore.grid.MapChange`, e.g.
                :meth:`mrexplore.mapping.OccupancyMap.change`): then the tracker takes the known
                and changed boxes from it instead of scanning the canvas. It must describe the
                array passed in ``maps``.
            sightings: ``{(i, j): T_ij}`` (i < j, canvas cells): guesses of the transform from
                robots that saw each other this step (:mod:`mrexplore.environment.sighting`).
                The latest is kept per pair, and its attempts look only near it (the
                semantic merger; other mergers ignore it); a pair's first sighting makes it due
                for an attempt at once, whatever its maps' growth. With ``SIGHTING_BINDS`` a
                merged pair's sighting drops a kept pose outside its region, and its re-checks
                look only near it.
        """
        if len(maps) != self.n:
            raise GridError(f"MapMergeTracker.update: expected {self.n} maps, got {len(maps)}")
        if links is not None:
            links = np.asarray(links, dtype=bool)
            if links.shape != (self.n, self.n):
                raise ConfigError(
                    f"MapMergeTracker.update: links must be ({self.n}, {self.n}) bool, "
                    f"got shape {links.shape}"
                )
        self._links = links
        if changes is not None and len(changes) != self.n:
            raise GridError(
                f"MapMergeTracker.update: expected {self.n} changes, got {len(changes)}"
            )
        for i, m in enumerate(maps):
            # Cheap checks only: a full value-range scan of a 1500 x 1500 canvas every step
            # would cost more than everything else here; merge_maps validates fully.
            m = check_int8_map(m, f"MapMergeTracker.update: map {i}")
            self._px.observe(i, m, None if changes is None else changes[i])
        self._apply_due(step)
        if not attempt:
            return
        seen_now = [
            (i, j, self._as_sighting(j, seen)) for (i, j), seen in (sightings or {}).items()
        ]
        for i, j, seen in seen_now:  # all of this step's sightings are known before any binds
            self._take_sighting(i, j, seen)
        for i, j, _ in seen_now:
            self._bind(i, j, step)
        if step % self.options.merge_every == 0:
            self._attempt_merges(step)
        if self.options.recheck_every and step % self.options.recheck_every == 0 and step > 0:
            self._recheck(step)
        if self.options.merge_latency_steps and self._queue:
            self._start(*self._queue.pop(0), step)  # at most one per step

    def _as_sighting(self, j: int, seen: Sighting | Transform) -> Sighting:
        """A sighting; a bare guess ``T_ij`` is taken as exact at the centre of j's known box."""
        if isinstance(seen, Sighting):
            return Sighting(np.asarray(seen.T_ij, dtype=np.float64).copy(), seen.at_j)
        box = self._px.bbox(j)
        r0, r1, c0, c1 = box if box is not None else (0, 0, 0, 0)
        return Sighting(np.asarray(seen, dtype=np.float64).copy(), ((c0 + c1) / 2, (r0 + r1) / 2))

    def _take_sighting(self, i: int, j: int, seen: Sighting) -> None:
        """Keep a sighting of pair (i, j) for the pair's attempts and, with ``SIGHTING_BINDS``,
        to judge its poses (:meth:`_bind`)."""
        if self.transform(i, j) is None:
            if (i, j) not in self._sighted:
                self._last_attempt_known.pop((i, j), None)  # due for an attempt at once
        elif not SIGHTING_BINDS:
            return
        self._sighted[(i, j)] = seen

    def _bind(self, i: int, j: int, step: int) -> None:
        """With ``SIGHTING_BINDS``, drop what pair (i, j)'s latest sighting contradicts."""
        if not SIGHTING_BINDS or (i, j) not in self._sighted:
            return
        kept = self._edges.get((i, j))
        if kept is not None:
            if self._seen_elsewhere(i, j, kept):
                # the robots saw each other where the kept pose does not put them: a look-alike
                self._drop_sighted(i, j, step)
            return
        through = self.transform(i, j)
        if through is None or not self._seen_elsewhere(i, j, through):
            return
        # Merged through teammates, and seen where that chain of merges does not put them: an
        # edge of the chain joins look-alike places. Which one the sighting cannot say, so every
        # edge that no sighting of its own pair vouches for goes.
        for a, b in self._chain_edges(i, j):
            if not self._vouched(a, b):
                self._drop_sighted(a, b, step)

    def _drop_sighted(self, i: int, j: int, step: int) -> None:
        """Un-merge the kept edge (i, j) because of a sighting (recorded in :attr:`drops`)."""
        first = self._contradicted.pop((i, j), step)
        self.drops.append(DropRecord(i, j, first, step, "sighting"))
        self._unmerge(i, j)
        self._pending.pop((i, j), None)
        self._last_attempt_known.pop((i, j), None)

    def _vouched(self, i: int, j: int) -> bool:
        """Does the latest sighting of the merged pair (i, j) put robot j where its kept pose
        does (False without a sighting)?"""
        return (i, j) in self._sighted and not self._seen_elsewhere(i, j, self._edges[(i, j)])

    def chain_edges(self, i: int, j: int) -> list[tuple[int, int]]:
        """The kept edges (low index first) whose transforms :meth:`transform` chains from
        robot i to robot j, in order (one edge when the pair is merged directly). Raises
        :class:`~mrexplore.errors.ConfigError` when the robots are not connected."""
        if not (0 <= i < self.n and 0 <= j < self.n) or i == j:
            raise ConfigError(f"chain_edges: need two robots of 0 .. {self.n - 1}, got {i}, {j}")
        if self.transform(i, j) is None:
            raise ConfigError(f"robots {i} and {j} are not merged, directly or through teammates")
        return self._chain_edges(i, j)

    def _chain_edges(self, i: int, j: int) -> list[tuple[int, int]]:
        """The kept edges (as stored, low index first) on the path that :meth:`transform`
        chains from robot i to robot j (connected)."""
        self._all_paths()
        parent = self._parents[i]
        edges = []
        v = j
        while v != i:
            u = parent[v]
            edges.append((min(u, v), max(u, v)))
            v = u
        return edges[::-1]

    def _seen_elsewhere(self, i: int, j: int, T: Transform) -> bool:
        """Does pose ``T_ij`` (canvas cells) put robot j farther than ``PRIOR_RADIUS_CELLS``
        from where robot i last saw it (``SIGHTING_BINDS``; False without a sighting)? Only the
        position at the sighting is judged: there the guess is exact up to the measurement's
        noise, while its heading differs from a kept rigid pose's by the maps' bending."""
        gap = self._sighting_gap(i, j, T) if SIGHTING_BINDS else None
        return gap is not None and gap > PRIOR_RADIUS_CELLS

    def _off_sighting(self, i: int, j: int, T: Transform) -> bool:
        """Does a pose the maps propose for pair (i, j) (not the kept one) lie outside its
        latest sighting's region: robot j put elsewhere (:meth:`_seen_elsewhere`) or, with
        ``SIGHTING_TURN_BINDS``, turned from the sighting's heading by more than
        ``PRIOR_TURN_DEG``? A new pose is held to the region a guided attempt searches; a
        look-alike half a turn away can put the seen robot where it was seen."""
        if self._seen_elsewhere(i, j, T):
            return True
        seen = self._sighted.get((i, j)) if SIGHTING_BINDS and SIGHTING_TURN_BINDS else None
        if seen is None:
            return False
        return turn_between_deg(T, seen.T_ij) > PRIOR_TURN_DEG

    def _sighting_gap(self, i: int, j: int, T: Transform) -> float | None:
        """How far (cells) pose ``T_ij`` puts robot j from where the pair's latest sighting
        saw it (None without a sighting): judged at the seen position, where the sighting's
        guess is exact up to its measurement's noise."""
        seen = self._sighted.get((i, j))
        if seen is None:
            return None
        at = np.array([seen.at_j], dtype=np.float64)
        (x1, y1), (x2, y2) = map_points(at, T), map_points(at, seen.T_ij)
        return float(np.hypot(x1 - x2, y1 - y2)[0])

    def _linked(self, i: int, j: int) -> bool:
        return self._links is None or bool(self._links[i, j] and self._links[j, i])

    def _compute(
        self,
        kind: str,
        i: int,
        j: int,
        a: Int8Grid,
        b: Int8Grid,
        offsets: tuple[tuple[int, int], tuple[int, int]],
        T_old: Transform | None,
        rivals: Sequence[Transform] = (),
        guess: Transform | None = None,
    ) -> _Outcome:
        """Run the merger on cropped maps ``a`` (robot i) and ``b`` (robot j) whose cell (0, 0)
        is at ``offsets`` (col, row) in the canvases; an attempt with a sighting's ``guess``
        (``T_ij``, canvas cells) runs the semantic merger with it as a
        :class:`~mrexplore.merge.PosePrior`. Pure: reads no tracker state that the main thread
        changes, so it may run in the worker thread."""
        (ca, ra), (cb, rb) = offsets
        old_now = held_now = drift_held = None
        guided = False
        if kind == "recheck":
            assert T_old is not None
            T_crop = _to_crop(T_old, offsets)
            codes_a, codes_b = MapCodes(a), MapCodes(b)  # shared by every verifier below
            old_now = Verifier(codes_a, codes_b)(T_crop).score
            held_now = old_now
            if RECHECK_SLACK_CELLS > 0 or RECHECK_MIN_RUN_CELLS > 1:
                noisy = Verifier(codes_a, codes_b, slack=RECHECK_SLACK_CELLS)
                held_now = noisy.structured(T_crop, RECHECK_MIN_RUN_CELLS).score
            drift_held = None
            if held_now < self.options.drop_below and DRIFT_SLACK_CELLS > 0:
                drifted = Verifier(codes_a, codes_b, slack=DRIFT_SLACK_CELLS)
                drift_held = drifted.structured(T_crop, RECHECK_MIN_RUN_CELLS).score
            if held_now < self.options.drop_below and RELOCATE_TOL_CELLS <= 0:
                return _Outcome(None, None, old_now, held_now, drift_held)
        # A merger that needs the robots' ids and crop offsets (the benchmark's oracle) says so.
        pair = getattr(self._merger_obj, "merge_pair", None)
        box_j = (rb, rb + b.shape[0], cb, cb + b.shape[1])
        prior_merge = self._merge if isinstance(self._merge, NamedMerger) else None
        if pair is not None:
            res = pair(i, j, a, b, (ca, ra), (cb, rb))
        elif guess is not None and prior_merge is not None and prior_merge.method == "semantic":
            T_guess = _to_crop(guess, offsets)
            prior = PosePrior(T_guess, PRIOR_RADIUS_CELLS, PRIOR_TURN_DEG)
            # The shared-space floor guards against a look-alike room elsewhere, which the
            # sighting's region already excludes: a guided attempt asks a few square metres.
            res = prior_merge(a, b, prior=prior, min_common_m2=GUIDED_MIN_COMMON_M2)
            guided = True
            # the sighting rules out every place outside its region, remembered rivals too
            # (the region about the centre of j's known box, in canvas cells)
            region = PosePrior(guess, PRIOR_RADIUS_CELLS, PRIOR_TURN_DEG)
            centre = np.array([(cb + cb + b.shape[1]) / 2.0, (rb + rb + b.shape[0]) / 2.0])
            rivals = [R for R in rivals if region.admits(R, centre, guess)]
        elif (
            kind == "recheck"
            and OUTRANKED_DROP
            and prior_merge is not None
            and prior_merge.method == "semantic"
        ):
            # the kept place is one of the hypotheses, refitted to the grown maps like the rest
            res = prior_merge(a, b, extra_hypotheses=[T_crop])
        else:
            res = self._merge(a, b)
        T = None
        if res.matched and res.transform is not None:
            T = _to_canvas(res.transform, offsets)
        best_T = None
        if res.evidence is not None and res.evidence.best is not None:
            best_T = _to_canvas(res.evidence.best.transform, offsets)
        if kind != "attempt":
            refit = None
            contradicted = held_now is not None and held_now < self.options.drop_below
            if T is None and T_old is not None and REFIT_REFUSED and contradicted:
                refit = self._drift_refit(res, T_old, offsets, box_j)
            outranked = (
                OUTRANKED_DROP
                and T_old is not None
                and self._outranked(Verifier(codes_a, codes_b), offsets, res, T_old, box_j)
            )
            return _Outcome(
                res, T, old_now, held_now, drift_held, refit=refit, outranked=outranked, best=best_T
            )
        ev = res.evidence
        found = tuple(_to_canvas(R.transform, offsets) for R in (() if ev is None else ev.rivals))
        standing = None
        if T is not None and rivals:
            verify = Verifier(MapCodes(a), MapCodes(b))
            standing = tuple(self._standing(verify, offsets, T, rivals, box_j))
        return _Outcome(
            res, T, old_now, held_now, rivals=found, standing=standing, best=best_T, guided=guided
        )

    def _drift_refit(
        self,
        res: MergeResult,
        T_old: Transform,
        offsets: Offsets,
        box_j: Box,
    ) -> Transform | None:
        """The pose a refused re-check keeps pair (i, j) merged at, or None (drop).

        Odometry drift bends the maps as they grow, so late in an episode no rigid pose of the
        right place reaches the acceptance bar. The place still stands when the merger's best pose
        (``evidence.best``) lies within ``RELOCATE_TOL_CELLS`` of the kept one, agrees
        within the maps' noise at least ``drop_below`` (the bar a kept pose is judged by) and
        beats every rival farther than that from the kept pose by the merger's margin in raw
        index. Pure (canvas cells in and out)."""
        ev = res.evidence
        if ev is None or ev.best is None or ev.consistency is None:
            return None  # not the semantic merger, or refused before it judged a pose
        if float(ev.consistency) < self.options.drop_below:
            return None
        agreement = ev.best.agreement
        T_best = _to_canvas(ev.best.transform, offsets)
        if not self._same(T_old, T_best, box_j, RELOCATE_TOL_CELLS):
            return None
        margin = self._rival_rule.min_margin
        for R, ag in ev.rivals:
            if self._same(T_old, _to_canvas(R, offsets), box_j, RELOCATE_TOL_CELLS):
                continue  # the same place, refitted otherwise: no rival
            if agreement.score - ag.score < margin:
                return None  # another place explains the maps about as well
        return T_best

    def _outranked(
        self,
        verify: Verifier,
        offsets: Offsets,
        res: MergeResult,
        T_old: Transform,
        box_j: Box,
    ) -> bool:
        """Do the grown maps (the crops ``verify`` compares) prefer another place to the kept
        one (``T_old``, canvas cells)? Yes when the merger's best pose is another place, consistent
        with the maps, and neither the kept place (as kept, or at any refit of it among the
        merger's hypotheses: the semantic merger is handed it) nor any other rival the merger
        reports stands against it as a rival of an accepted pose must not
        (:meth:`_standing`). So a look-alike place won while the maps were small gives way once
        they single out another place by the merger's own margins; where the maps repeat (many
        places stand) nothing changes. Pure."""
        ev = res.evidence
        if ev is None or ev.best is None or not ev.consistent:
            return False  # no place the merger finds consistent with the maps
        near = _same_place_cells()
        best = _to_canvas(ev.best.transform, offsets)
        if self._same(T_old, best, box_j, near):
            return False
        poses = [_to_canvas(h.transform, offsets) for h in ev.hypotheses]
        refits = [H for H in poses if self._same(T_old, H, box_j, near)]
        others = [_to_canvas(r.transform, offsets) for r in ev.rivals]
        return not self._standing(verify, offsets, best, [T_old, *refits, *others], box_j)

    def _standing(
        self,
        verify: Verifier,
        offsets: Offsets,
        T: Transform,
        rivals: Sequence[Transform],
        box_j: Box,
    ) -> list[Transform]:
        """The remembered ``rivals`` (canvas cells) that still stand against the accepted ``T``
        on the cropped maps ``verify`` compares: far from it, explaining at least half as much, not
        beaten by the merger's margin (raw index, contradicting wall cells) and not ruled out by
        one object (:func:`~mrexplore.merge.semantic.rival_structure`). Pure."""
        T_crop = _to_crop(T, offsets)
        best = verify(T_crop)

        def stands(R: Transform) -> bool:
            if self._same(R, T, box_j, _semantic.FAR_CELLS):
                return False  # the same place
            R_crop = _to_crop(R, offsets)
            other = verify(R_crop)
            if not stands_as_rival(best, other, verify.cells_per_sample, self._rival_rule):
                return False
            margin = best.score - other.score
            ruled_out = rival_structure(verify, T_crop, R_crop, margin, self._rival_rule)
            return ruled_out < _semantic.MIN_EVIDENCE_CELLS

        return [R for R in rivals if stands(R)]

    def _start(self, kind: str, i: int, j: int, step: int) -> None:
        """Start an attempt or re-check of (i, j) on the current maps; apply it now (latency 0)
        or hand it to the worker thread and apply it at ``step + merge_latency_steps``."""
        ci, cj = self._px.crop(i), self._px.crop(j)
        if ci is None or cj is None:
            return
        T_old = self._edges.get((i, j)) if kind == "recheck" else None
        if kind == "recheck" and T_old is None:
            return  # dropped or replaced since it was queued
        (a, oa), (b, ob) = ci, cj
        rivals = [R.copy() for R in self._rivals.get((i, j), [])] if kind == "attempt" else []
        seen = self._sighted.get((i, j)) if kind == "attempt" else None
        guess = None if seen is None else seen.T_ij
        if self.options.merge_latency_steps == 0:
            out = _timed(self._compute, kind, i, j, a, b, (oa, ob), T_old, rivals, guess)
            self._apply(_Job(kind, i, j, step, self._px.bbox(j), T_old, out))
            return
        if self._pool is None:
            self._pool = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mrexplore-merge")
        # copies: the caller may update its maps in place while the worker reads them
        fut = self._pool.submit(
            _timed, self._compute, kind, i, j, a.copy(), b.copy(), (oa, ob), T_old, rivals, guess
        )
        due = step + self.options.merge_latency_steps
        self._jobs.append(_Job(kind, i, j, due, self._px.bbox(j), T_old, fut))

    def wait_idle(self) -> None:
        """Block until every attempt started on the worker has finished. Nothing is applied:
        each result is still applied at its scheduled step, so the run does not change. For
        timing, so that a timed span holds the merge work it started."""
        wait([jb.outcome for jb in self._jobs if isinstance(jb.outcome, Future)])

    def _apply_due(self, step: int) -> None:
        """Apply the worker's jobs due by ``step``, in the order they started (waiting for any
        not finished: a fixed schedule, whatever the machine's speed)."""
        while self._jobs and self._jobs[0].due <= step:
            self._apply(self._jobs.pop(0))

    def _apply(self, job: _Job) -> None:
        out = job.outcome.result() if isinstance(job.outcome, Future) else job.outcome
        i, j = job.i, job.j
        attempt = job.kind == "attempt"
        self._work += MergeWork(int(attempt), int(not attempt), out.cpu_s)
        if out.result is not None:
            self._results[(i, j)] = out.result
        if job.kind == "attempt":
            self._decide_attempt(i, j, out, job.bbox_j)
            if self.attempt_observer is not None and out.result is not None:
                thin = out.result.overlap_cells < self.options.min_accept_cells
                pending = self._pending.get((i, j))
                self.attempt_observer(
                    AttemptRecord(
                        job.due,
                        i,
                        j,
                        out.result,
                        out.T,
                        out.best,
                        len(out.standing or ()),
                        bool(thin),
                        0 if pending is None else int(pending[1]),
                        self.transform(i, j) is not None,
                    )
                )
        else:
            self._decide_recheck(i, j, out, job.T_old, job.bbox_j, job.due)

    def _round_pairs(self, step: int) -> list[tuple[int, int]]:
        """The pairs ``(i, j)``, ``i < j``, the attempt round at ``step`` considers, in order:
        all of them, or with ``ROTATING_PARTNERS`` each robot and the one ``offset`` after it,
        the offset cycling through 1 .. n // 2 round by round."""
        n = self.n
        if not ROTATING_PARTNERS or n < 4:  # 2 or 3 robots: the rotation gives every pair
            return [(i, j) for i in range(n) for j in range(i + 1, n)]
        offset = 1 + (step // self.options.merge_every) % (n // 2)
        return sorted({(min(i, (i + offset) % n), max(i, (i + offset) % n)) for i in range(n)})

    def _attempt_merges(self, step: int) -> None:
        busy = {(jb.i, jb.j) for jb in self._jobs} | {(q[1], q[2]) for q in self._queue}
        for i, j in self._round_pairs(step):
            if not self._linked(i, j) or self.transform(i, j) is not None:
                continue
            if (i, j) in busy:
                continue  # its last attempt is still under way
            if self.options.rendezvous_only and (i, j) not in self._sighted:
                continue  # the robots have not met
            known = self._px.known_cells(i) + self._px.known_cells(j)
            last = self._last_attempt_known.get((i, j))
            if last is not None and known < last * (1.0 + RETRY_GROWTH):
                # Too little new knowledge since the last attempt: the answer would be the
                # same (profiled: with random actions, repeated attempts on barely grown maps
                # were 2/3 of the env's step time).
                continue
            self._last_attempt_known[(i, j)] = known
            if self.options.merge_latency_steps:
                self._queue.append(("attempt", i, j))
            else:
                self._start("attempt", i, j, step)

    def _decide_attempt(self, i: int, j: int, out: _Outcome, bbox_j: Box | None) -> None:
        """Accept, start or extend a run of agreeing attempts, or break it (one attempt's
        outcome)."""
        if self.transform(i, j) is not None:
            return  # connected meanwhile (through a chain of other pairs)
        pending = self._pending.get((i, j))
        if out.T is not None and self._off_sighting(i, j, out.T):
            out = replace(out, T=None)  # the robots were seen elsewhere: a refusal
        standing = self._remember_rivals(i, j, out)
        consistent = out.result is not None and (out.T is not None or _consistent(out.result))
        if consistent and out.best is not None:
            self._best[(i, j)] = out.best
        else:
            self._best.pop((i, j), None)
        thin = out.result is not None and out.result.overlap_cells < self.options.min_accept_cells
        if out.result is None or out.T is None or standing or thin:
            # a refusal breaks the run of agreements; so does a pose a remembered rival, which
            # the maps do not rule out yet, explains as well (an aisle like another aisle), or
            # one resting on too little wall to tell a place from a look-alike
            if (
                self.options.keep_run_on_refusal
                and pending is not None
                and not thin
                and out.T is None
                and out.best is not None
                and out.result is not None
                and _consistent(out.result)  # refused after the consistency test
                and self._same(pending[0], out.best, bbox_j)
            ):
                # ... but not a refusal that found the pending pose best and consistent again:
                # nothing contradicts it, and the rival it saw is remembered (above)
                return
            self._pending.pop((i, j), None)
            return
        T = out.T
        evidence = int(out.result.overlap_cells)
        count = 1
        gap = self._sighting_gap(i, j, T) if out.guided and SIGHTING_CONFIRMS else None
        if gap is not None and gap <= self.options.confirm_tol_cells:
            # the sighting is the other measurement, when the two agree as two attempts must
            count = self.options.confirmations
        elif pending is not None and self._same(pending[0], T, bbox_j):
            # The same transform again counts as a confirmation only when it now rests on
            # clearly more shared evidence (wall cells both maps see under it): a look-alike
            # match stays confined to the look-alike part, the truth spreads as the maps grow.
            # Without new evidence the run is kept, not extended.
            grown = evidence >= pending[2] * (1.0 + self.options.confirm_growth)
            if not grown:
                return
            count = pending[1] + 1
        if count >= self.options.confirmations:
            self._pending.pop((i, j), None)
            self._edges[(i, j)] = T
            self._edge_score[(i, j)] = out.result.score
            self._paths = None
        else:
            self._pending[(i, j)] = (T, count, evidence)

    def _remember_rivals(self, i: int, j: int, out: _Outcome) -> bool:
        """Update pair (i, j)'s remembered rivals with one attempt's outcome (the checked ones
        that no longer stand are forgotten, the merger's new ones added, the newest
        ``RIVAL_MEMORY`` kept); True when a remembered rival stands against its pose."""
        if RIVAL_MEMORY == 0:
            return False
        mem = self._rivals.get((i, j), [])
        if out.standing is not None:
            mem = list(out.standing)
        mem = (mem + list(out.rivals))[-RIVAL_MEMORY:]
        if mem:
            self._rivals[(i, j)] = mem
        else:
            self._rivals.pop((i, j), None)
        return bool(out.standing)

    def _same(
        self, T1: Transform, T2: Transform, bbox_j: Box | None, tol: float | None = None
    ) -> bool:
        """Do two estimates of T_ij put robot j's known box in the same place (within tolerance)?"""
        if bbox_j is None:
            return False
        r0, r1, c0, c1 = bbox_j
        corners = np.array([[c0, r0], [c1, r0], [c0, r1], [c1, r1]], dtype=np.float64)
        # elementwise, not T @ corners (BLAS): a decision on the threshold, the same on every CPU
        (x1, y1), (x2, y2) = map_points(corners, T1), map_points(corners, T2)
        dx, dy = x1 - x2, y1 - y2
        limit = self.options.confirm_tol_cells if tol is None else tol
        return bool(np.sqrt(dx**2 + dy**2).max() <= limit)

    def _recheck(self, step: int) -> None:
        for i, j in list(self._edges):
            if not self._linked(i, j):
                continue
            if self.options.merge_latency_steps:
                if ("recheck", i, j) not in self._queue:
                    self._queue.append(("recheck", i, j))
            else:
                self._start("recheck", i, j, step)

    def _decide_recheck(
        self,
        i: int,
        j: int,
        out: _Outcome,
        T_old: Transform | None,
        bbox_j: Box | None,
        step: int = 0,
    ) -> None:
        """Drop the kept transform the maps now contradict (unless the merger found it again,
        refitted, on the same maps), or replace it by a clearly better one; otherwise keep it
        (a failed re-check never drops an accepted transform)."""
        kept = self._edges.get((i, j))
        if kept is None or T_old is None or not np.array_equal(kept, T_old):
            return  # dropped or replaced since the re-check started
        assert out.old_now is not None and out.held_now is not None
        if out.outranked and not (out.best is not None and self._off_sighting(i, j, out.best)):
            # The grown maps prefer another place by the merger's margins: un-merge, or move to
            # that place at once when the merger accepted it on these maps (not a place where
            # the robots were not seen: a sighting outranks the maps).
            first = self._contradicted.pop((i, j), step)
            moved = out.T is not None and not self._same(T_old, out.T, bbox_j, _same_place_cells())
            if (
                moved
                and out.result is not None
                and out.T is not None
                and not self._off_sighting(i, j, out.T)
            ):
                self.drops.append(DropRecord(i, j, first, step, "moved"))
                self._replace_edge(i, j, out.T, out.result.score)
                return
            self.drops.append(DropRecord(i, j, first, step, "outranked"))
            self._unmerge(i, j)
            return
        if out.held_now < self.options.drop_below:
            first = self._contradicted.setdefault((i, j), step)
            if (
                out.result is not None
                and out.T is not None
                and RELOCATE_TOL_CELLS > 0
                and self._same(T_old, out.T, bbox_j, RELOCATE_TOL_CELLS)
            ):
                # The same place, refitted to maps that odometry drift has bent: keep the pair
                # merged with the merger's new pose (it passed every rule on these maps).
                self._replace_edge(i, j, out.T, out.result.score)
                return
            if out.refit is not None and out.result is not None:
                # Refused, but the best pose is still the kept place (drift, not a wrong place)
                self._replace_edge(i, j, out.refit, out.result.score)
                return
            if out.drift_held is not None and out.drift_held >= DRIFT_KEEP_ABOVE:
                # Contradicted only by walls a drift's width apart: the maps bent, the place
                # stands (a look-alike place lays walls across open space)
                return
            # The maps grew and now contradict the kept transform: un-merge this pair.
            self.drops.append(DropRecord(i, j, first, step))
            del self._contradicted[(i, j)]
            self._unmerge(i, j)
            return
        self._contradicted.pop((i, j), None)
        if out.result is None or out.T is None:
            return
        if out.result.score >= out.old_now + REPLACE_MARGIN and not self._off_sighting(i, j, out.T):
            self._replace_edge(i, j, out.T, out.result.score)

    def _unmerge(self, i: int, j: int) -> None:
        del self._edges[(i, j)]
        self._edge_score.pop((i, j), None)
        self._paths = None
        self._px.forget_pair(i, j)

    def _replace_edge(self, i: int, j: int, T: Transform, score: float) -> None:
        """Keep pair (i, j) merged with the new transform ``T`` (its fused pixels redone)."""
        self._edges[(i, j)] = T
        self._edge_score[(i, j)] = score
        self._paths = None
        self._px.forget_pair(i, j)

    def __getstate__(self) -> dict[str, Any]:
        """Pickle without the worker thread: jobs under way are waited for and kept as done."""
        state = self.__dict__.copy()
        state["_pool"] = None
        state["attempt_observer"] = None
        state["_jobs"] = [
            _Job(
                jb.kind,
                jb.i,
                jb.j,
                jb.due,
                jb.bbox_j,
                jb.T_old,
                jb.outcome.result() if isinstance(jb.outcome, Future) else jb.outcome,
            )
            for jb in self._jobs
        ]
        return state

    # ------------------------------------------------------------------ queries
    @property
    def work(self) -> MergeWork:
        """The merge attempts and re-checks applied since the last :meth:`reset`, and their
        CPU time (:class:`MergeWork`)."""
        return self._work

    def _all_paths(self) -> dict[tuple[int, int], Transform | None]:
        """T_ij for every connected (i, j), by breadth-first search over accepted edges."""
        if self._paths is not None:
            return self._paths
        adj: dict[int, list[tuple[int, Transform]]] = {k: [] for k in range(self.n)}
        for (i, j), T in self._edges.items():
            adj[i].append((j, T))  # T_ij: j -> i
            adj[j].append((i, invert_transform(T)))
        paths: dict[tuple[int, int], Transform | None] = {}
        self._parents = {}
        for s in range(self.n):
            seen: dict[int, Transform] = {s: np.eye(3)}
            parent = self._parents[s] = {}
            q = deque([s])
            while q:
                u = q.popleft()
                for v, T_uv in adj[u]:
                    if v not in seen:
                        seen[v] = chain(seen[u], T_uv)  # T_sv = T_su @ T_uv, without BLAS
                        parent[v] = u
                        q.append(v)
            for v, T in seen.items():
                if v != s:
                    paths[(s, v)] = T
        self._paths = paths
        self._groups = {s: {s} | {v for (u, v) in paths if u == s} for s in range(self.n)}
        return paths

    def transform(self, i: int, j: int) -> Transform | None:
        """3x3 float64 ``T_ij`` mapping robot j's cells into robot i's cells, or None."""
        if i == j:
            return np.eye(3)
        T = self._all_paths().get((i, j))
        return None if T is None else T.copy()

    def hypotheses(self, i: int, j: int) -> list[Transform]:
        """Where robot j's map may lie in robot i's, while the pair is not merged: ``T_ij``
        candidates (3x3, canvas cells), most likely first. The last attempt's best pose when it
        passed the consistency test (refused for uniqueness, pinning or shared space, or
        waiting for confirmation), then the rivals the tracker remembers (``RIVAL_MEMORY``).
        Empty once the pair is merged, or before any attempt found a candidate. The merger's
        own knowledge, no ground truth: for a policy that goes to where the candidates can be
        told apart (:class:`~mrexplore.policies.CoordinatedFrontierPolicy`'s ``verify_weight``).
        """
        if i == j or self.transform(i, j) is not None:
            return []
        a, b = min(i, j), max(i, j)
        best = self._best.get((a, b))
        stored = ([] if best is None else [best]) + self._rivals.get((a, b), [])
        # stored as T_ab (b's cells into a's): inverted (new arrays) for j's into i's
        return [invert_transform(T) if i > j else T.copy() for T in stored]

    def merged(self, i: int) -> bool:
        """True once robot i's map is connected to at least one teammate's."""
        self._all_paths()
        return len(self._groups[i]) > 1

    def map_version(self, i: int) -> int:
        """A counter that grows whenever robot i's map content changes (0 before any map)."""
        return self._px.version(i)

    def group(self, i: int) -> set[int]:
        """Robots whose maps are merged with robot i's (including i)."""
        self._all_paths()  # (re)computes the groups with the paths
        return set(self._groups[i])

    def last_result(self, i: int, j: int) -> MergeResult | None:
        """The last :class:`MergeResult` of merging j into i (or i into j), or None."""
        return self._results.get((min(i, j), max(i, j)))

    def fused(self, i: int) -> Int8Grid:
        """Robot i's fused map: int8, same shape and frame as its own map, composed by the
        :class:`~mrexplore.merge.compositor.MapCompositor` from the maps of the robots merged
        with i (incrementally; a read-only view of its buffer, the same object until a map or
        transform changes: copy it to keep it)."""
        if not self._px.has_map(i):
            raise GridError("MapMergeTracker.fused: call update() first")
        mates = {}
        for j in sorted(self.group(i) - {i}):
            T = self.transform(i, j)
            assert T is not None  # j is in i's group
            mates[j] = T
        return self._px.fused(i, mates, self._linked)

    def fused_known_box(self, i: int) -> Box:
        """A half-open box of robot i's last :meth:`fused` map holding every cell that is not
        unknown (possibly larger than the tightest; no scan), ``(0, 0, 0, 0)`` before any."""
        return self._px.fused_known_box(i)

    def fused_change(self, i: int) -> tuple[int, Box | None]:
        """``(composition count, box)`` of robot i's fused map: the count grows by one with
        every :meth:`fused` that recomposed it, and ``box`` (half-open, i's cells; empty when
        nothing changed, None when rebuilt whole) bounds what that composition rewrote. A reader
        that saw count k - 1 need only look at the box to follow count k."""
        return self._px.fused_change(i)

    def fused_changed_cells(self, i: int) -> NDArray[np.int64] | None:
        """The flat cells that composition changed (None: rebuilt whole); see
        :meth:`MapCompositor.fused_changed_cells`."""
        return self._px.fused_changed_cells(i)
