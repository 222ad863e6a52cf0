"""The env's evaluation against the truth: merge errors, map accuracy, time held wrongly.

For the infos, the renderer and the benchmarks only: nothing here reaches a robot, a policy or
the merger. The measures are :mod:`mrexplore.truth`'s (:func:`~mrexplore.truth.merge_error`,
:class:`~mrexplore.truth.MapScorer`); this module keeps what one episode needs to report them
every step without redoing the work: caches keyed on what changed.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence

import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.errors import ConfigError
from mrexplore.merge.fusion import FusionStage
from mrexplore.sim import Simulation
from mrexplore.truth import (
    IncrementalScore,
    MapScorer,
    known_cells,
    nearest_sampling,
    rotation_error_deg,
    transform_error,
)

# The compiled sampling of the merge errors (None without numba).
_scoring = kernels.load("scoring")

#: A merge error (mean displacement of the teammate's known cells) at least this large is a
#: wrong merge (cells; the merge benchmark's threshold too).
WRONG_MERGE_CELLS = 5.0
#: Known cells of the teammate's map on which a merge error is measured: an even sample of
#: this many to twice as many (every k-th cell, :func:`mrexplore.truth.known_cells`).
ERROR_SAMPLE_POINTS = 4096
#: Steps a merge error stays cached while its transform is unchanged (the known cells grow
#: slowly; the error is asked for every step). Each ordered pair refreshes on its own phase of
#: this period, so the pairs' refreshes (~0.15 ms each compiled, ~0.5 ms in numpy) do not pile
#: up in one step.
ERROR_REFRESH_STEPS = 10

MergeError = dict[str, float]


def _load_error_kernel() -> None:
    """Load the compiled merge-error sampler now, with the argument types of its use (a
    read-only map): its first load from numba's cache (~8 ms) otherwise fell in the step
    that applies the first merge, the slowest step of a merged team."""
    if not kernels.enabled():
        return
    assert _scoring is not None
    grid = np.zeros((2, 2), dtype=np.int8)
    grid.flags.writeable = False
    eye = np.eye(3)
    _scoring.sampled_displacements(grid, 0, 2, 0, 2, 4, eye, eye, 0.0, 0.0)


def is_wrong_merge(err: Mapping[str, float]) -> bool:
    """A merge error (``translation_cells``, ``rotation_deg``, ``drift_cells``) that drift
    cannot explain: the mean displacement exceeds ``WRONG_MERGE_CELLS`` plus the odometry-drift
    allowance.

    >>> is_wrong_merge({"translation_cells": 6.0, "rotation_deg": 2.0, "drift_cells": 3.0})
    False
    >>> is_wrong_merge({"translation_cells": 310.0, "rotation_deg": 0.0, "drift_cells": 0.0})
    True
    """
    return err["translation_cells"] >= WRONG_MERGE_CELLS + err.get("drift_cells", 0.0)


class TruthMonitor:
    """One episode's evaluation of ``agents``' maps and transforms against ``sim``'s truth.

    Args:
        agents: agent names in robot order.
        sim: the episode's simulator (reset).
        fusion: the env's fusion stage (whose fused maps are scored).
        held: also count the reachable free cells each robot holds at their true place (the
            ``coverage_mode="held"`` coverage, :meth:`held_free`).
    """

    def __init__(
        self, agents: Sequence[str], sim: Simulation, fusion: FusionStage, held: bool
    ) -> None:
        self.agents = list(agents)
        self.sim = sim
        self.fusion = fusion
        self.held = held
        self.scorer = MapScorer(sim.world.walls, sim.reachable)
        _load_error_kernel()
        #: seconds each robot has held a wrong transform
        self.wrong_s = np.zeros(len(self.agents), dtype=np.float64)
        # per robot: (fused-map version, contradiction share, held free cells or None)
        self._accuracy: dict[int, tuple[int, float, int | None]] = {}
        # per robot: the incremental scorer of its map (None: sampling not exact, warp whole)
        # and the (source, version) it last scored
        self.incremental: dict[int, IncrementalScore | None] = {}
        self._inc_seen: dict[int, tuple[str, int]] = {}
        self._errors: dict[tuple[int, int], tuple[int, NDArray[np.float64], MergeError]] = {}
        # per robot: (own-map version, held free cells of the own map alone)
        self._own_held: dict[int, tuple[int, int]] = {}
        # per agent: (step, the transforms asked about, their worst error)
        self._worst_memo: dict[
            str, tuple[int, dict[str, NDArray[np.float64]], MergeError | None]
        ] = {}

    # ------------------------------------------------------------------ merges
    def merge_errors(
        self, agent: str, transforms: Mapping[str, NDArray[np.float64]]
    ) -> dict[str, MergeError]:
        """The error of each of ``agent``'s estimated ``transforms`` (teammate -> 3x3, its cells
        into ``agent``'s): teammate -> ``{translation_cells, rotation_deg, drift_cells}``."""
        i = self.agents.index(agent)
        out: dict[str, MergeError] = {}
        for other, T in transforms.items():
            err = self._pair_error(i, self.agents.index(other), T)
            if err is not None:
                out[other] = err
        return out

    def _worst(
        self, agent: str, transforms: Mapping[str, NDArray[np.float64]]
    ) -> MergeError | None:
        worst: MergeError | None = None
        for err in self.merge_errors(agent, transforms).values():
            if worst is None or err["translation_cells"] > worst["translation_cells"]:
                worst = err
        return worst

    def merge_error(
        self, agent: str, transforms: Mapping[str, NDArray[np.float64]]
    ) -> MergeError | None:
        """The worst (largest displacement) of :meth:`merge_errors`, None when not merged. Asked
        several times a step (wrong-merge seconds, infos, frames): computed once per step and
        set of transforms."""
        memo = self._worst_memo.get(agent)
        if (
            memo is not None
            and memo[0] == self.sim.steps
            and memo[1].keys() == transforms.keys()
            and all(memo[1][k] is T for k, T in transforms.items())
        ):
            return memo[2]
        worst = self._worst(agent, transforms)
        self._worst_memo[agent] = (int(self.sim.steps), dict(transforms), worst)
        return worst

    def holds_wrong(self, agent: str, transforms: Mapping[str, NDArray[np.float64]]) -> bool:
        """Whether ``agent`` holds a wrong transform among ``transforms``: its worst merge error
        (:meth:`merge_error`) is a wrong merge (:func:`is_wrong_merge`)."""
        err = self.merge_error(agent, transforms)
        return err is not None and is_wrong_merge(err)

    def count_wrong(
        self, transforms: Mapping[str, Mapping[str, NDArray[np.float64]]], dt_s: float
    ) -> None:
        """Add ``dt_s`` to each robot that holds a wrong transform (:meth:`holds_wrong`)."""
        for i, agent in enumerate(self.agents):
            if self.holds_wrong(agent, transforms[agent]):
                self.wrong_s[i] += dt_s

    def _refresh_phase(self, i: int, j: int) -> int:
        """The step phase (mod ``ERROR_REFRESH_STEPS``) at which the error of the ordered pair
        (i, j) refreshes: the pairs spread evenly over the period."""
        n = len(self.agents)
        k = i * (n - 1) + (j if j < i else j - 1)  # 0 .. n (n - 1) - 1
        return k * ERROR_REFRESH_STEPS // (n * (n - 1))

    def _pair_error(self, i: int, j: int, T: NDArray[np.float64]) -> MergeError | None:
        """The error of ``T`` (j's cells -> i's) on an even sample of j's known cells, with the
        drift allowance. Recomputed when ``T`` changes, and at the pair's phase of every
        ``ERROR_REFRESH_STEPS`` steps."""
        sim = self.sim
        cached = self._errors.get((i, j))
        phase = self._refresh_phase(i, j)
        if (
            cached is not None
            and (cached[0] - phase) // ERROR_REFRESH_STEPS
            == (sim.steps - phase) // ERROR_REFRESH_STEPS
            and np.array_equal(cached[1], T)
        ):
            return cached[2]
        box = sim.maps[j].known_bbox()
        if box is None:
            return None
        T_true = sim.true_transform(i, j)
        grid = sim.maps[j].to_int8()
        if kernels.enabled():
            # one pass over the known box, the same figures as the numpy path below (its
            # ~0.5 ms ran in one step in ten per pair: the slowest steps of a merged team)
            assert _scoring is not None
            ox, oy = (float(v) for v in sim.maps[j].origin_cell)
            disps, radii = _scoring.sampled_displacements(
                grid, *box, ERROR_SAMPLE_POINTS, np.asarray(T, np.float64), T_true, ox, oy
            )
            if disps.size == 0:
                return None
            disp, rot = float(disps.mean()), rotation_error_deg(T, T_true)
            drift = self._drift(i, j, float(radii.mean()))
        else:
            # truth.merge_error's measure, with the sample kept for the drift allowance
            pts = known_cells(grid, box, ERROR_SAMPLE_POINTS)
            if len(pts) == 0:
                return None
            disp, rot = transform_error(T, T_true, pts)
            drift = self._drift(i, j, sim.drift_radius(j, pts))
        err = {"translation_cells": disp, "rotation_deg": rot, "drift_cells": drift}
        self._errors[(i, j)] = (int(sim.steps), np.array(T, copy=True), err)
        return err

    def _drift(self, i: int, j: int, radius: float) -> float:
        """The drift allowance (cells) of robot i's transform of j's map, for cells at mean
        distance ``radius`` (cells) from j's start: the pair's own, or, when the tracker holds
        it through teammates, the sum over the merged pairs of that chain, since each of them
        may be off by its own two robots' drift (a middle robot's map is bent too)."""
        tracker = getattr(self.fusion, "tracker", None)
        if tracker is None or tracker.transform(i, j) is None:
            return self.sim.drift_allowance_at(i, j, radius)
        return sum(self.sim.drift_allowance_at(a, b, radius) for a, b in tracker.chain_edges(i, j))

    # ------------------------------------------------------------------ maps
    def held_free(self, i: int, transforms: Mapping[str, NDArray[np.float64]]) -> int:
        """The reachable free cells robot i is credited with (``coverage_mode="held"``): those
        its map holds at their true place (the map warped into the world with the true
        transform; :meth:`~mrexplore.truth.MapScorer.held_free`: marked free, or occupied beside
        a true wall). The map is its own-or-fused map while all its ``transforms`` (teammate ->
        3x3, as :meth:`merge_errors` takes them) are right; its own map alone while it holds a
        wrong one (:meth:`holds_wrong`): it cannot tell which of its teammates' knowledge is
        right, and a wrongly placed teammate map's free cells often land on true free space
        (a twin room on its twin, a corridor along itself), where they would count.

        Correct path: :meth:`map_accuracy`'s incremental count. Wrong path (rare): a whole warp
        of the own map, cached on its version."""
        if not self.held:
            raise ConfigError("TruthMonitor.held_free needs held=True (coverage_mode='held')")
        if not self.holds_wrong(self.agents[i], transforms):
            n = self.map_accuracy(i)[1]
            assert n is not None  # held
            return n
        own = self.sim.maps[i]
        cached = self._own_held.get(i)
        if cached is not None and cached[0] == own.version:
            return cached[1]
        warped = self.scorer.warp(own.to_int8(), self.sim.world_from_map(i))
        n_own = self.scorer.scores(warped, held=True)[1]
        assert n_own is not None  # held=True
        self._own_held[i] = (own.version, n_own)
        return n_own

    def map_accuracy(self, i: int) -> tuple[float, int | None]:
        """Robot i's own-or-fused map against the truth: (contradiction share, NaN when the
        map claims nothing inside the world; reachable free cells it holds at the true
        place when ``held``, else None). Cached on the fused-map version. The held coverage
        credits a robot that holds a wrong transform with its own map only: see
        :meth:`held_free`."""
        agent = self.agents[i]
        version = self.fusion.fused_version(agent)
        cached = self._accuracy.get(i)
        if cached is not None and cached[0] == version:
            return cached[1], cached[2]
        fused = self.fusion.fused(agent)
        if i not in self.incremental:
            T = self.sim.world_from_map(i)
            # the incremental scorer is compiled only; without the kernels, whole warps
            sample = (
                nearest_sampling(T, self.sim.canvas_shape, self.scorer.shape)
                if kernels.enabled()
                else None
            )
            self.incremental[i] = (
                None if sample is None else IncrementalScore(self.scorer, T, sample)
            )
        inc = self.incremental[i]
        if inc is None:
            warped = self.scorer.warp(fused, self.sim.world_from_map(i))
            share, held = self.scorer.scores(warped, held=self.held)
        else:
            share, held = self._rescore(i, inc, fused)
        self._accuracy[i] = (version, share, held)
        return share, held

    def _rescore(
        self, i: int, inc: IncrementalScore, fused: NDArray[np.int8]
    ) -> tuple[float, int | None]:
        """Re-score only the world cells that sample the part of robot i's map that changed
        since the version last scored (the same figures as warping the whole map)."""
        fc = self.fusion.fused_change(self.agents[i])
        cells = None
        if fc is None:
            own = self.sim.maps[i]
            source, ver, box, cells = "own", own.version, own.changed_box, own.changed_cells()
        else:
            source, (ver, box) = "fused", fc
            cells = self.fusion.fused_changed_cells(self.agents[i])
        seen = self._inc_seen.get(i)
        if seen is None or seen[0] != source or ver > seen[1] + 1 or ver < seen[1]:
            box, cells = None, None  # a new source or a skipped version: score it whole
        elif ver == seen[1]:
            box, cells = (0, 0, 0, 0), None
        if cells is not None:  # the next version: only the cells it changed
            share, n_held = inc.update_cells(fused, cells)
        else:
            share, n_held = inc.update(fused, box)
        self._inc_seen[i] = (source, ver)
        return share, (n_held if self.held else None)
