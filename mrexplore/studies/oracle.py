"""Mergers that know the truth, for benchmarks only (the env's options never name them).

:class:`OracleMerger` answers with the true transform as soon as the two maps share any known
cell (or, with ``min_shared_m2``, as soon as they share that much known space under the truth:
a reference held to a room's worth of evidence, as an honest merger in a world with a twin room
must be); :class:`SeededMerger` runs the semantic merger with the true pose among its hypotheses.
Both go through the env's :class:`~mrexplore.merge.MapMergeTracker` like a real merger (the same
confirmations, re-checks and drops), which calls their ``merge_pair`` with the robots' ids and
crop offsets. The loop study (:mod:`mrexplore.studies.loop_study`) compares the default
merger with them: what a perfect merger would gain, and what the search misses.
"""

from __future__ import annotations

import math
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import ConfigError
from mrexplore.grid import UNKNOWN, Int8Grid, chain
from mrexplore.merge.common import MergeResult, translation, warp_into

__all__ = ["OracleMerger", "SeededMerger"]


class OracleMerger:
    """A benchmark merger that knows the truth: the true transform as soon as the maps share
    any known cell (evaluation only; the env's options never name it).

    With ``min_shared_m2`` > 0 it waits until the maps share that much known space (m^2) under
    the true transform: what a merger could do that needs that much overlap as evidence and
    never misses it (the in-loop merger asks 20 m^2 of a pose: a match the size of a room may be
    its twin).

    Built on :meth:`mrexplore.sim.Simulation.true_transform`; call :meth:`bind` with the env
    before its ``reset`` (the env makes a new simulation at every reset; the oracle reads the
    current one at each call). The :class:`~mrexplore.merge.MapMergeTracker` calls
    :meth:`merge_pair` with the robots' ids and crop offsets, so the oracle goes through the
    same tracker as real mergers (confirmations, re-checks, drops).
    """

    def __init__(self, min_shared_m2: float = 0.0) -> None:
        if not (isinstance(min_shared_m2, (int, float)) and math.isfinite(min_shared_m2)):
            raise ConfigError(
                f"OracleMerger: min_shared_m2 must be a number, got {min_shared_m2!r}"
            )
        if min_shared_m2 < 0:
            raise ConfigError(f"OracleMerger: min_shared_m2 must be >= 0, got {min_shared_m2}")
        self.min_shared_m2 = float(min_shared_m2)
        self._env: Any = None

    def bind(self, env: Any) -> None:
        """Read the truth from ``env.sim`` (a :class:`MultiRobotExplorationEnv`)."""
        self._env = env

    def merge(self, a: Int8Grid, b: Int8Grid) -> MergeResult:
        """Not usable without robot ids: the tracker calls :meth:`merge_pair`."""
        raise ConfigError("OracleMerger needs the robots' ids: use it through MapMergeTracker")

    def _true_pose(
        self, i: int, j: int, offset_a: tuple[int, int], offset_b: tuple[int, int]
    ) -> NDArray[np.float64]:
        """The true ``T_ab`` between robot j's crop (cell (0, 0) at ``offset_b`` of its canvas)
        and robot i's (at ``offset_a``)."""
        sim = None if self._env is None else self._env.sim
        if sim is None:
            name = type(self).__name__
            raise ConfigError(f"{name} is not bound to a reset env: call bind(env) first")
        # chain, not @ (BLAS): the oracle's poses have the same bits on every CPU
        return chain(
            translation(-offset_a[0], -offset_a[1]),
            sim.true_transform(i, j),
            translation(offset_b[0], offset_b[1]),
        )

    def merge_pair(
        self,
        i: int,
        j: int,
        a: Int8Grid,
        b: Int8Grid,
        offset_a: tuple[int, int],
        offset_b: tuple[int, int],
    ) -> MergeResult:
        """Merge robot j's cropped map ``b`` into robot i's cropped map ``a``.

        ``offset_a``/``offset_b``: ``(col, row)`` of each crop's cell (0, 0) in its robot's
        canvas. Returns the true ``T_ab`` between the crops when some cell is known in both
        maps under it (``overlap_cells`` > 0) and they share at least ``min_shared_m2`` of
        known space, else a refusal.
        """
        T = self._true_pose(i, j, offset_a, offset_b)
        b_in_a = warp_into(b, T, a.shape)
        shared = int(np.count_nonzero((a != UNKNOWN) & (b_in_a != UNKNOWN)))
        if shared == 0:
            return MergeResult(
                matched=False, transform=None, score=0.0, method="oracle", reason="no shared cell"
            )
        shared_m2 = shared * float(self._env.map_resolution_m) ** 2
        if shared_m2 < self.min_shared_m2:
            return MergeResult(
                matched=False,
                transform=None,
                score=0.0,
                method="oracle",
                reason=f"the maps share {shared_m2:.1f} m^2 under the truth; "
                f"need {self.min_shared_m2:g} m^2",
            )
        return MergeResult(
            matched=True, transform=T, score=1.0, method="oracle", overlap_cells=shared
        )


class SeededMerger(OracleMerger):
    """The semantic merger with the true pose among its hypotheses (a diagnostic; evaluation
    only). Same decision rules, so a refusal here is the rules' (or the maps' evidence's), not
    the search's."""

    def __init__(self) -> None:
        super().__init__()

    def merge_pair(
        self,
        i: int,
        j: int,
        a: Int8Grid,
        b: Int8Grid,
        offset_a: tuple[int, int],
        offset_b: tuple[int, int],
    ) -> MergeResult:
        """:func:`~mrexplore.merge.semantic.merge_semantic` of the crops, the true ``T_ab``
        between them handed in as an extra hypothesis, with the options the env gives the
        semantic merger in the loop (20 m² shared, no perfect-rival test, the map's resolution)."""
        from mrexplore.merge.fusion import IN_LOOP_SEMANTIC_OPTIONS
        from mrexplore.merge.semantic import merge_semantic

        T = self._true_pose(i, j, offset_a, offset_b)
        return merge_semantic(
            a,
            b,
            extra_hypotheses=[T],
            resolution_m=float(self._env.map_resolution_m),
            **IN_LOOP_SEMANTIC_OPTIONS,
        )
