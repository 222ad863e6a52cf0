"""Pieces every merge method shares: the result type, option checking, map -> image conversion,
the acceptance index (global verification of a transform) and the composition of two maps.

Conventions (see :mod:`mrexplore.grid`): maps are int8 ``(H, W)`` with ``UNKNOWN`` / ``FREE`` /
``OCCUPIED``; points are ``(col, row)``; a transform ``T_ab`` is 3x3 float64 mapping b's cells
``(col, row, 1)`` into a's cells.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from typing import Any, NamedTuple

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.grid import (
    FREE_THRESHOLD,
    OCCUPIED_THRESHOLD,
    UNKNOWN,
    Int8Grid,
    Transform,
    known_bbox,
)

# The CPU-independent transform arithmetic lives in mrexplore.grid (truth.py needs it too);
# re-exported here, where the merger's modules have always imported it from.
from mrexplore.grid import chain as chain
from mrexplore.grid import map_points as map_points
from mrexplore.grid import rigid_inverse as rigid_inverse
from mrexplore.options import Check

# The compiled verifier count (None without numba); used while mrexplore.kernels.enabled().
_merging = kernels.load("merging")

#: Detectors a method may use. ``sift`` stands in for the paper's SURF (non-free, absent from
#: OpenCV's PyPI builds); ``akaze`` is named so that asking for it gives a clear error, because
#: the OpenCV 5.0 build this project targets does not ship it.
DETECTORS: tuple[str, ...] = ("harris", "shi-tomasi", "fast", "sift", "orb", "akaze")

# Cell codes used by the verifier: one small integer per cell, so that counting where walls land
# is one bincount. "near wall" = free within one cell (8-neighbourhood) of a wall: the one-cell
# tolerance of the acceptance index lives in these codes.
CODE_UNKNOWN = 0
CODE_FREE = 1
CODE_FREE_NEAR_WALL = 2
CODE_WALL = 3


@dataclass(eq=False)
class MergeResult:
    """The outcome of merging map ``b`` into map ``a``.

    Attributes:
        matched: True when a transform was accepted.
        transform: 3x3 float64 ``T_ab`` mapping b's cells ``(col, row, 1)`` into a's cells, or
            None when not matched.
        score: acceptance index in [0, 1] of the transform: agreement / (agreement +
            disagreement) where both maps are known, counted on the wall cells of either map
            that land on a known cell of the other (a wall on a wall or within one cell of one
            agrees; a wall in open free space disagrees), see :class:`Verifier`. When not
            matched: that of the best hypothesis examined, or 0 when there was none.
        merged: int8 fused map in a's frame on a canvas grown to hold b, or None when not matched.
        offset: (dcol, drow) of a's cell (0, 0) in the ``merged`` canvas: a's cell (c, r) is
            ``merged[r + drow, c + dcol]``.
        method: "semantic", "paper" or "orb".
        detector: the keypoint detector used, or None.
        reason: why the merge was refused ("" when matched).
        time_s: wall-clock time of the call, seconds.
        n_hypotheses: how many candidate transforms were examined.
        runner_up_score: score of the best hypothesis far from the chosen one (semantic), or of
            the second-best match (paper); None when there was none.
        matches: (K, 4) float64 point pairs ``(col_a, row_a, col_b, row_b)`` that support the
            result (keypoint matches, or wall points for the semantic method), for figures.
        overlap_cells: number of cells known in both maps under the transform.
        info: method-specific extras (e.g. the candidate rotations), for debugging: free-form,
            for people and figures; code that decides reads :attr:`evidence`.
        evidence: what the semantic merger weighed, accepted or refused (its best pose, whether
            that pose was consistent with the maps, its rivals): the typed facts the every-step
            tracker decides on (:class:`MergeEvidence`). None for the other methods.
    """

    matched: bool
    transform: Transform | None
    score: float
    merged: Int8Grid | None = None
    offset: tuple[int, int] = (0, 0)
    method: str = ""
    detector: str | None = None
    reason: str = ""
    time_s: float = 0.0
    n_hypotheses: int = 0
    runner_up_score: float | None = None
    matches: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 4)))
    overlap_cells: int = 0
    info: dict[str, Any] = field(default_factory=dict)
    evidence: MergeEvidence | None = None

    @classmethod
    def refused(
        cls,
        reason: str,
        *,
        method: str,
        t0: float,
        detector: str | None = None,
        score: float = 0.0,
        **fields: Any,
    ) -> MergeResult:
        """A refusal by ``method``, timed from ``t0`` (``time.perf_counter()`` at its start)."""
        return cls(
            matched=False,
            transform=None,
            score=score,
            method=method,
            detector=detector,
            reason=reason,
            time_s=time.perf_counter() - t0,
            **fields,
        )

    @classmethod
    def accepted(
        cls,
        a: Int8Grid,
        b: Int8Grid,
        T_ab: Transform,
        *,
        method: str,
        t0: float,
        score: float,
        detector: str | None = None,
        **fields: Any,
    ) -> MergeResult:
        """The merge of ``b`` into ``a`` under ``T_ab`` by ``method`` (the fused canvas made
        here, :func:`compose`), timed from ``t0``."""
        merged, offset = compose(a, b, T_ab)
        return cls(
            matched=True,
            transform=T_ab,
            score=score,
            merged=merged,
            offset=offset,
            method=method,
            detector=detector,
            time_s=time.perf_counter() - t0,
            **fields,
        )


def detector_check(allowed: tuple[str, ...]) -> Check:
    """An :mod:`mrexplore.options` check of a ``detector`` option: None, or one of ``allowed``,
    normalised (``"Shi_Tomasi"`` -> ``"shi-tomasi"``). AKAZE and SURF get their own messages:
    OpenCV's PyPI builds lack them."""

    def check(value: Any) -> str | None:
        if value is None:
            return None
        if not isinstance(value, str):
            raise ValueError(f"a detector name, one of {allowed}")
        d = value.lower().replace("_", "-")
        d = "shi-tomasi" if d == "shitomasi" else d
        if d == "akaze":
            raise ValueError(
                f"one of {allowed}: this OpenCV build ({cv2.__version__}) has no AKAZE; "
                "use 'orb' or 'sift'"
            )
        if d == "surf":
            raise ValueError(
                f"one of {allowed}: SURF is non-free, absent from OpenCV's PyPI builds; use "
                "'sift', which stands in for it"
            )
        if d not in allowed:
            raise ValueError(f"one of {allowed} (unknown detector)")
        return d

    return check


# --------------------------------------------------------------------------------------------
# map -> image / masks
# --------------------------------------------------------------------------------------------


def to_gray(grid: Int8Grid) -> NDArray[np.uint8]:
    """The map as a map_server-like gray image: free 254, occupied 0, unknown 205, uint8 (H, W).

    Feature detectors see what a person sees in a PGM; intermediate probabilities are linearly
    mapped between free and occupied.
    """
    g = grid.astype(np.int16)
    out = (254 - np.clip(g, 0, 100) * 254 // 100).astype(np.uint8)
    out[g == UNKNOWN] = 205
    return out


def reliable_walls(grid: Int8Grid) -> NDArray[np.bool_]:
    """Wall cells (H, W) bool that have at least one wall among their 8 neighbours.

    A lone occupied cell is weak evidence: a spurious return in a real SLAM map, or one sparse
    hit of a distant wall in a lidar map (beams spread wider than a cell at range). It is not a
    verification point and no wall lands on it with any effect (:func:`cell_codes`).
    """
    return _reliable((grid >= OCCUPIED_THRESHOLD).view(np.uint8))


def _reliable(occupied: NDArray[np.uint8]) -> NDArray[np.bool_]:
    """:func:`reliable_walls` from the occupied mask (uint8 0/1)."""
    n = cv2.filter2D(occupied, -1, np.ones((3, 3), np.float32), borderType=cv2.BORDER_CONSTANT)
    return (occupied > 0) & (n >= 2)


def cell_codes(grid: Int8Grid, tolerance: int = 1, slack: int = 0) -> NDArray[np.uint8]:
    """Verifier codes (H, W) uint8: unknown / free / free within ``tolerance`` cells of a wall
    (8-neighbourhood, i.e. a square window) / wall.

    Free cells farther than ``tolerance`` but within ``tolerance + slack`` cells of a wall are
    coded unknown: a wall landing there neither agrees nor contradicts (one wall seen from its
    two sides, or eroded by grazing beams, sits a cell or two apart in two maps). Lone wall
    cells (:func:`reliable_walls`) are coded unknown too, but still make their neighbours "near
    a wall".
    """
    return MapCodes(grid).codes(tolerance, slack)


def _code_table() -> NDArray[np.uint8]:
    """:meth:`MapCodes.codes`' lookup table: index ``8 wall + 4 free + 2 near + far`` (``near``:
    within the tolerance of an occupied cell; ``far``: within tolerance + slack) -> code. A
    wall is a wall; a free cell near a wall is near a wall, one only within the slack is
    unknown, the rest free; anything else (unknown, lone occupied cells) is unknown."""
    table = np.full(256, CODE_UNKNOWN, dtype=np.uint8)
    table[8:16] = CODE_WALL
    table[4] = CODE_FREE
    table[5] = CODE_UNKNOWN
    table[6:8] = CODE_FREE_NEAR_WALL
    return table


_CODE_TABLE = _code_table()


class MapCodes:
    """One map's verifier inputs, made once and shared by every :class:`Verifier` of a merge:
    its occupied, reliable-wall and free masks (H, W), its codes per ``(tolerance, slack)``
    (:func:`cell_codes`) and the (row, col) indices of its reliable wall cells.

    A merge verifies with four codings of the same two maps (screen, quick, full, noise-aware);
    the masks and the wall-cell scan are the same for all of them.
    """

    def __init__(self, grid: Int8Grid) -> None:
        self.shape = grid.shape
        self.occupied = (grid >= OCCUPIED_THRESHOLD).view(np.uint8)
        self.wall = _reliable(self.occupied)
        self.free = (grid >= 0) & (grid <= FREE_THRESHOLD)
        self._wall_bit = self.wall.view(np.uint8) << 3
        self._free_bit = self.free.view(np.uint8) << 2
        self._near_masks: dict[int, NDArray[np.uint8]] = {}
        self._codes: dict[tuple[int, int], NDArray[np.uint8]] = {}
        self._wall_cells: tuple[NDArray[np.intp], NDArray[np.intp]] | None = None

    def _near(self, radius: int) -> NDArray[np.uint8]:
        """0/1 (H, W): within ``radius`` cells (square window) of an occupied cell (cached)."""
        if radius not in self._near_masks:
            k = 2 * radius + 1
            near = cv2.dilate(self.occupied, np.ones((k, k), np.uint8))
            self._near_masks[radius] = np.asarray(near, dtype=np.uint8)
        return self._near_masks[radius]

    def codes(self, tolerance: int = 1, slack: int = 0) -> NDArray[np.uint8]:
        """The codes (H, W) uint8 of :func:`cell_codes` (cached; do not modify)."""
        key = (int(tolerance), int(slack))
        if key not in self._codes:
            # one table lookup of the four masks' bits: wall, free, near, within the slack
            far = self._near(key[0] + key[1]) if slack > 0 else self._near(key[0])
            bits = self._wall_bit | (self._free_bit | ((self._near(key[0]) << 1) | far))
            codes = cv2.LUT(bits, _CODE_TABLE).reshape(self.shape)
            self._codes[key] = np.asarray(codes, dtype=np.uint8)
        return self._codes[key]

    def wall_cells(self) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
        """(rows, cols) of the reliable wall cells (the cells coded wall), row-major (cached)."""
        if self._wall_cells is None:
            rows, cols = np.nonzero(self.wall)
            self._wall_cells = (rows, cols)
        return self._wall_cells


def translation(dc: float, dr: float) -> Transform:
    """3x3 float64 translation by ``(dc, dr)`` cells."""
    return np.array([[1.0, 0.0, dc], [0.0, 1.0, dr], [0.0, 0.0, 1.0]])


# --------------------------------------------------------------------------------------------
# verification: Birk & Carpin's acceptance index
# --------------------------------------------------------------------------------------------


@dataclass(frozen=True)
class Agreement:
    """Agreement counts of one transform: ``score = agree / (agree + disagree)``.

    ``share`` is the fraction of b's (sampled) wall cells that landed on known cells of a.
    """

    agree: int
    disagree: int
    share: float = 0.0

    @property
    def overlap(self) -> int:
        """Wall cells that took part (landed on known cells of the other map)."""
        return self.agree + self.disagree

    @property
    def score(self) -> float:
        """Acceptance index in [0, 1]; 0 when nothing overlaps."""
        n = self.agree + self.disagree
        return self.agree / n if n else 0.0


class WeighedPose(NamedTuple):
    """A pose the merger judged: ``transform`` (3x3 float64 ``T_ab``, b's cells -> a's, full
    maps) and its :class:`Agreement` (the verifier's counts, sampled wall cells)."""

    transform: Transform
    agreement: Agreement


@dataclass(frozen=True, eq=False)
class MergeEvidence:
    """What the semantic merger weighed in one call, accepted or refused: the facts a caller
    that merges over time (:class:`~mrexplore.merge.MapMergeTracker`) decides on, typed.

    A call refused before it judged any pose (a map all unknown, too few walls, no hypothesis)
    carries ``best=None``, ``consistency=None``, ``consistent=False`` and no rivals.

    Attributes:
        best: the best pose and its raw agreement (the pose the rules judged; also when
            refused), or None.
        consistency: the best pose's noise-aware agreement (walls within the merger's
            ``slack_cells`` agree, contradictions in runs under ``min_run_cells`` do not count),
            in [0, 1]; None when no pose was judged.
        consistent: ``consistency`` reached the merger's ``min_score``: the maps do not
            contradict the best pose beyond their noise (a refusal with it True was refused for
            uniqueness, pinning, shared space or a look-alike rule, not for contradiction).
        rivals: poses far from the best that explain a comparable part of the maps, with their
            agreements, in the order the merger judged them (a repeat's moved pose last).
        hypotheses: every ranked hypothesis with its agreement, most evidence first (before a
            consistency polish moved the best).
    """

    best: WeighedPose | None = None
    consistency: float | None = None
    consistent: bool = False
    rivals: tuple[WeighedPose, ...] = ()
    hypotheses: tuple[WeighedPose, ...] = ()


def _sample(
    cells: tuple[NDArray[np.intp], NDArray[np.intp]], max_samples: int
) -> tuple[NDArray[np.float64], float]:
    """(col, row) points of the cells ``(rows, cols)`` on a regular stride (<= ~max_samples),
    and cells per point."""
    rows, cols = cells
    n = rows.size
    if max_samples and n > max_samples:
        stride = int(np.ceil(n / max_samples))
        rows, cols = rows[::stride], cols[::stride]
    return np.stack([cols, rows], axis=1).astype(np.float64), n / max(rows.size, 1)


class Verifier:
    """Scores transforms ``T_ab`` by Birk & Carpin's acceptance index, ``agr / (agr + dis)``,
    evaluated where it is informative: on the *wall* cells of both maps.

    Every wall cell of b is mapped into a (nearest cell) and every wall cell of a is mapped into
    b (through the inverse): a wall landing on a wall, or on free space within one cell of a wall
    (the one-cell tolerance), agrees; a wall landing on open free space disagrees; a wall landing
    on unknown (or outside) does not count. Checking both directions catches both kinds of
    conflict of the plain index (b's wall in a's free space, b's free space over a's wall),
    while free-on-free cells, which agree for almost any pose inside a big room and would drown
    the signal, are left out.

    ``tolerance`` widens the one-cell tolerance (the semantic method screens coarse hypotheses,
    which may be a few cells off, with a wider one). ``a`` and ``b`` may be :class:`MapCodes`,
    so several verifiers of one merge share the masks.

    Each call costs two gathers and two 16-bin ``bincount`` over at most ``max_samples`` points
    per map: a few hundred microseconds, so dozens of hypotheses cost milliseconds.
    """

    def __init__(
        self,
        a: Int8Grid | MapCodes,
        b: Int8Grid | MapCodes,
        max_samples: int = 20000,
        tolerance: int = 1,
        slack: int = 0,
    ) -> None:
        ma = a if isinstance(a, MapCodes) else MapCodes(a)
        mb = b if isinstance(b, MapCodes) else MapCodes(b)
        self.codes_a = ma.codes(tolerance, slack)
        self.codes_b = mb.codes(tolerance, slack)
        self.points_b, self.cells_per_sample = _sample(mb.wall_cells(), max_samples)
        self.points_a, _ = _sample(ma.wall_cells(), max_samples)

    @staticmethod
    def _count(
        pts: NDArray[np.float64], T: Transform, codes: NDArray[np.uint8]
    ) -> tuple[int, int, int]:
        if pts.shape[0] == 0:
            return 0, 0, 0
        px, py = map_points(pts, T)
        c = np.rint(px).astype(np.int64)
        r = np.rint(py).astype(np.int64)
        h, w = codes.shape
        inside = (c >= 0) & (c < w) & (r >= 0) & (r < h)
        hit = np.bincount(codes[r[inside], c[inside]], minlength=4)
        agree = int(hit[CODE_WALL] + hit[CODE_FREE_NEAR_WALL])
        disagree = int(hit[CODE_FREE])
        return agree, disagree, agree + disagree

    @staticmethod
    def _count_many(
        base: NDArray[np.float64], offsets: NDArray[np.float64], codes: NDArray[np.uint8]
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Agree / disagree counts (K,) of the points ``base`` (N, 2) moved by each of the K
        ``offsets`` (K, 2): one gather of K x N cells."""
        h, w = codes.shape
        c = np.rint(base[None, :, 0] + offsets[:, None, 0]).astype(np.int32)
        r = np.rint(base[None, :, 1] + offsets[:, None, 1]).astype(np.int32)
        inside = (c >= 0) & (c < w) & (r >= 0) & (r < h)
        flat = np.where(inside, r * w + c, 0)
        got = np.where(inside, codes.ravel()[flat], CODE_UNKNOWN)
        agree = np.count_nonzero((got == CODE_WALL) | (got == CODE_FREE_NEAR_WALL), axis=1)
        return agree, np.count_nonzero(got == CODE_FREE, axis=1)

    def shifted(
        self, T: Transform, shifts: NDArray[np.float64], max_points: int = 500
    ) -> tuple[NDArray[np.int64], NDArray[np.int64]]:
        """Agree / disagree counts (K,) of the K transforms ``translation(shift_k) @ T``, in one
        vectorised pass over at most ``max_points`` wall cells per map (for sliding a pose
        along walls)."""
        T = np.asarray(T, dtype=np.float64)
        shifts = np.asarray(shifts, dtype=np.float64).reshape(-1, 2)
        Ti = rigid_inverse(T)
        sb = max(1, -(-self.points_b.shape[0] // max_points))
        sa = max(1, -(-self.points_a.shape[0] // max_points))
        pb = np.stack(map_points(self.points_b[::sb], T), axis=1)
        pa = np.stack(map_points(self.points_a[::sa], Ti), axis=1)
        # translation(s) @ T maps a's points back by T^-1 (p - s) = T^-1 p - R^-1 s
        Ri = Ti.copy()
        Ri[:2, 2] = 0.0  # the rotation part alone
        back = -np.stack(map_points(shifts, Ri), axis=1)
        if kernels.enabled():
            assert _merging is not None
            ab, db = _merging.count_shifted(pb, shifts, self.codes_a)
            aa, da = _merging.count_shifted(pa, back, self.codes_b)
        else:  # the numpy reference: the same counts (tests/merge/test_verifier_kernel.py)
            ab, db = self._count_many(pb, shifts, self.codes_a)
            aa, da = self._count_many(pa, back, self.codes_b)
        return ab + aa, db + da

    def overlap_ok(self, ag: Agreement, min_share: float, min_cells: int) -> bool:
        """True when at least ``min_share`` of b's wall cells and ``min_cells`` wall cells in all
        (both maps) took part."""
        return ag.share >= min_share and ag.overlap * self.cells_per_sample >= min_cells

    @staticmethod
    def _landing(
        pts: NDArray[np.float64], T: Transform, codes: NDArray[np.uint8]
    ) -> tuple[NDArray[np.int64], NDArray[np.bool_]]:
        """Per point: the flat index (into ``codes``) of the cell it lands on under T (0 when
        outside), and whether that cell is open free space (a disagreement; False outside)."""
        px, py = map_points(pts, T)
        c = np.rint(px).astype(np.int64)
        r = np.rint(py).astype(np.int64)
        h, w = codes.shape
        inside = (c >= 0) & (c < w) & (r >= 0) & (r < h)
        flat = np.where(inside, r * w + c, 0)
        return flat, inside & (codes.ravel()[flat] == CODE_FREE)

    @staticmethod
    def _contradictions(
        pts: NDArray[np.float64], T: Transform, codes: NDArray[np.uint8]
    ) -> NDArray[np.int64]:
        """Flat indices (into ``codes``) of the cells where the points, mapped by T, land on open
        free space (the disagreeing cells), each cell once."""
        if pts.shape[0] == 0:
            return np.zeros(0, dtype=np.int64)
        flat, on_free = Verifier._landing(pts, T, codes)
        return np.unique(flat[on_free])

    @staticmethod
    def _in_runs(flat: NDArray[np.int64], shape: tuple[int, int], min_run: int) -> int:
        """How many of the cells ``flat`` belong to 8-connected groups of >= ``min_run`` cells."""
        if flat.size < min_run:
            return 0
        # only the box around the cells: every group lies in it, so the groups are those of the
        # whole map (the map can be a hundred times larger than the box)
        rows, cols = np.divmod(flat, shape[1])
        r0, c0 = int(rows.min()), int(cols.min())
        img = np.zeros((int(rows.max()) - r0 + 1, int(cols.max()) - c0 + 1), dtype=np.uint8)
        img[rows - r0, cols - c0] = 1
        _, _, stats, _ = cv2.connectedComponentsWithStats(img, connectivity=8)
        big = stats[1:, cv2.CC_STAT_AREA] >= min_run
        return int(stats[1:, cv2.CC_STAT_AREA][big].sum())

    def structured(self, T: Transform, min_run: int) -> Agreement:
        """Like :meth:`__call__`, but a disagreeing cell counts only when it belongs to a group of
        at least ``min_run`` disagreeing cells (8-connected, in the map it landed on): a wall
        placed across open space. Lone contradictions, which two lidar maps of one place show
        where grazing beams erased a wall cell in one of them, are left out of both counts."""
        T = np.asarray(T, dtype=np.float64)
        det = float(T[0, 0] * T[1, 1] - T[0, 1] * T[1, 0])
        if not np.isfinite(T).all() or abs(det) < 1e-9:
            return Agreement(0, 0, 0.0)
        Ti = rigid_inverse(T)
        if kernels.enabled():  # the same counts (tests/merge/test_verifier_kernel.py)
            assert _merging is not None
            T = np.ascontiguousarray(T)
            ab, db, nb, aa, da = _merging.count_both_ways(
                self.points_b, self.points_a, T, self.codes_a, self.codes_b
            )
        else:
            ab, db, nb = self._count(self.points_b, T, self.codes_a)
            aa, da, _ = self._count(self.points_a, Ti, self.codes_b)
        runs = self._in_runs(
            self._contradictions(self.points_b, T, self.codes_a), self.codes_a.shape, min_run
        ) + self._in_runs(
            self._contradictions(self.points_a, Ti, self.codes_b), self.codes_b.shape, min_run
        )
        # in sample units (the points are a regular subsample when a map has many wall cells)
        share = nb / self.points_b.shape[0] if self.points_b.shape[0] else 0.0
        return Agreement(ab + aa, min(db + da, runs), share)

    @staticmethod
    def _largest_group(pts: NDArray[np.float64], shape: tuple[int, int]) -> int:
        """Points (col, row) in their own map's cells: the most of them in one 8-connected
        group, a one-cell gap bridged (a wall a grazing beam broke is still one wall)."""
        if pts.shape[0] == 0:
            return 0
        img = np.zeros(shape, dtype=np.uint8)
        c, r = pts[:, 0].astype(np.intp), pts[:, 1].astype(np.intp)
        img[r, c] = 1
        n, labels = cv2.connectedComponents(
            cv2.dilate(img, np.ones((3, 3), np.uint8)), connectivity=8
        )
        return int(np.bincount(labels[r, c], minlength=n)[1:].max())

    def exclusive_groups(self, T1: Transform, T2: Transform) -> tuple[int, int]:
        """Wall cells in the largest connected group (in the map they belong to) that ``T1``
        lays on the other map's open free space and ``T2`` does not, and the same the other
        way round: one object seen in one map that the other map's free space rules out under
        one pose only."""
        on = []  # per pose: (b's points, a's points) landing on open free space
        for T in (np.asarray(T1, dtype=np.float64), np.asarray(T2, dtype=np.float64)):
            on.append(
                (
                    self._landing(self.points_b, T, self.codes_a)[1],
                    self._landing(self.points_a, rigid_inverse(T), self.codes_b)[1],
                )
            )
        hb, wb = self.codes_b.shape
        ha, wa = self.codes_a.shape

        def largest(only_b: NDArray[np.bool_], only_a: NDArray[np.bool_]) -> int:
            most = max(
                self._largest_group(self.points_b[only_b], (hb, wb)),
                self._largest_group(self.points_a[only_a], (ha, wa)),
            )
            return round(most * self.cells_per_sample)

        (b1, a1), (b2, a2) = on
        return largest(b1 & ~b2, a1 & ~a2), largest(b2 & ~b1, a2 & ~a1)

    def __call__(self, T: Transform) -> Agreement:
        """Agreement counts of ``T`` (3x3, b cells -> a cells)."""
        T = np.ascontiguousarray(T, dtype=np.float64)
        det = float(T[0, 0] * T[1, 1] - T[0, 1] * T[1, 0])
        if not np.isfinite(T).all() or abs(det) < 1e-9:
            return Agreement(0, 0, 0.0)  # a degenerate transform agrees with nothing
        if kernels.enabled():
            assert _merging is not None
            ab, db, nb, aa, da = _merging.count_both_ways(
                self.points_b, self.points_a, T, self.codes_a, self.codes_b
            )
        else:  # the numpy reference: the same counts (tests/merge/test_verifier_kernel.py)
            ab, db, nb = Verifier._count(self.points_b, T, self.codes_a)
            T_inv = rigid_inverse(T)
            aa, da, _ = Verifier._count(self.points_a, T_inv, self.codes_b)
        share = nb / self.points_b.shape[0] if self.points_b.shape[0] else 0.0
        return Agreement(ab + aa, db + da, share)

    def many(self, Ts: NDArray[np.float64]) -> list[Agreement]:
        """:meth:`__call__` of each of the K poses ``Ts`` (K, 3, 3): the same agreements, the
        kernel called once for all of them (a merge verifies thousands of poses; per call, the
        Python around the kernel cost as much as its count)."""
        Ts = np.ascontiguousarray(Ts, dtype=np.float64).reshape(-1, 3, 3)
        if not kernels.enabled() or Ts.shape[0] == 0:
            return [self(T) for T in Ts]
        assert _merging is not None
        det = Ts[:, 0, 0] * Ts[:, 1, 1] - Ts[:, 0, 1] * Ts[:, 1, 0]
        ok = np.isfinite(Ts).all(axis=(1, 2)) & (np.abs(det) >= 1e-9)
        counts = _merging.count_poses(
            self.points_b, self.points_a, Ts[ok], self.codes_a, self.codes_b
        ).tolist()
        n_b = self.points_b.shape[0]
        out = [Agreement(0, 0, 0.0)] * Ts.shape[0]  # a degenerate pose agrees with nothing
        for k, (ab, db, nb, aa, da) in zip(np.flatnonzero(ok).tolist(), counts, strict=True):
            out[k] = Agreement(ab + aa, db + da, nb / n_b if n_b else 0.0)
        return out


def agreeing_cells(
    cells: tuple[NDArray[np.intp], NDArray[np.intp]], T: Transform, codes: NDArray[np.uint8]
) -> tuple[NDArray[np.bool_], NDArray[np.int64], NDArray[np.int64]]:
    """Which of the wall ``cells`` (rows, cols) land, mapped by ``T`` to the nearest cell, on a
    wall of the other map or on free space within a cell of one (``codes``: the verifier's
    agreeing codes), and the (cols, rows) they land on."""
    rows, cols = cells
    c, r = (np.rint(x).astype(np.int64) for x in map_points(np.stack([cols, rows], axis=1), T))
    h, w = codes.shape
    inside = (c >= 0) & (c < w) & (r >= 0) & (r < h)
    got = np.full(c.size, CODE_UNKNOWN, dtype=np.uint8)
    got[inside] = codes[r[inside], c[inside]]
    return (got == CODE_WALL) | (got == CODE_FREE_NEAR_WALL), c, r


def rectangle_area(points: NDArray[np.integer]) -> float:
    """Area (cells^2) of the smallest rectangle, at any angle, around integer ``points`` (N, 2);
    0 when fewer than three or all on one line.

    Exact on any CPU: the rectangle's sides run along the edges of the points' convex hull
    (integer vectors), so its extents are integer dot products and its area one correctly
    rounded division per edge.

    >>> rectangle_area(np.array([[0, 0], [4, 0], [4, 3], [0, 3], [2, 1]]))
    12.0
    """
    extents = _edge_extents(points)
    if extents is None:
        return 0.0
    along, across, norm2 = extents
    # each edge's rectangle: extents scaled by |edge|^2, one correctly rounded division each
    return float((along * across / norm2).min())


def rectangle_sides(points: NDArray[np.integer]) -> tuple[float, float]:
    """(long, short) sides (cells) of the smallest rectangle of :func:`rectangle_area` around
    integer ``points`` (N, 2); ``(0, 0)`` when fewer than three or all on one line.

    The rectangle is chosen exactly as :func:`rectangle_area` chooses it; each side is an
    integer extent over a correctly rounded square root, so equal on any CPU.

    >>> rectangle_sides(np.array([[0, 0], [4, 0], [4, 3], [0, 3], [2, 1]]))
    (4.0, 3.0)
    """
    extents = _edge_extents(points)
    if extents is None:
        return 0.0, 0.0
    along, across, norm2 = extents
    k = int(np.argmin(along * across / norm2))
    norm = math.sqrt(float(norm2[k]))
    sides = (float(along[k]) / norm, float(across[k]) / norm)
    return max(sides), min(sides)


def _edge_extents(
    points: NDArray[np.integer],
) -> tuple[NDArray[np.int64], NDArray[np.int64], NDArray[np.int64]] | None:
    """For each edge of the convex hull of ``points``: the hull's extent along the edge and
    across it, both scaled by the edge's length, and the edge's squared length (integers);
    ``None`` when the hull has no area."""
    if points.shape[0] < 3:
        return None
    hull = cv2.convexHull(points.astype(np.int32)).reshape(-1, 2).astype(np.int64)
    if hull.shape[0] < 3:
        return None
    edges = np.roll(hull, -1, axis=0) - hull  # (H, 2) integer edge vectors
    along = hull @ edges.T  # (H, H) integer projections of every hull point on every edge
    across = hull @ np.stack([-edges[:, 1], edges[:, 0]], axis=1).T
    return (
        along.max(axis=0) - along.min(axis=0),
        across.max(axis=0) - across.min(axis=0),
        (edges**2).sum(axis=1),
    )


# --------------------------------------------------------------------------------------------
# composition
# --------------------------------------------------------------------------------------------


def warp_into(
    src: Int8Grid,
    T_dst_src: Transform,
    dst_shape: tuple[int, int],
    dst_origin: tuple[int, int] = (0, 0),
) -> Int8Grid:
    """Warp ``src`` with nearest neighbour into a ``dst_shape`` canvas; outside src -> unknown.

    ``T_dst_src`` maps src cells to destination cells; ``dst_origin`` (col, row) is the cell of the
    destination frame at canvas index (0, 0) (to warp into a sub-window of a larger frame).
    """
    M = np.asarray(T_dst_src, dtype=np.float64).copy()
    M[0, 2] -= dst_origin[0]
    M[1, 2] -= dst_origin[1]
    # A nearest-neighbour warp only copies cells: warp the int8 map as its uint8 view (OpenCV's
    # CV_8S warp is not supported everywhere), the border 255 being unknown's -1.
    out = cv2.warpAffine(
        np.asarray(src, dtype=np.int8).view(np.uint8),
        M[:2],
        (int(dst_shape[1]), int(dst_shape[0])),
        flags=cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=255,
    )
    return np.asarray(out).view(np.int8)


def fuse(a: Int8Grid, b: Int8Grid) -> Int8Grid:
    """Cell-wise fusion of two aligned maps: occupied beats free beats unknown.

    With -1 < 0 < 100 this is simply the maximum, which also keeps the higher of two
    occupancy probabilities: a wall seen by either robot stays a wall (safe for planning).
    """
    return np.maximum(a, b)


def compose(a: Int8Grid, b: Int8Grid, T_ab: Transform) -> tuple[Int8Grid, tuple[int, int]]:
    """Fuse b into a's frame on a canvas grown to hold b's known cells.

    Returns ``(merged, (dcol, drow))`` where a's cell (c, r) is ``merged[r + drow, c + dcol]``.
    """
    h, w = a.shape
    bb = known_bbox(b)
    if bb is None:
        return a.copy(), (0, 0)
    r0, r1, c0, c1 = bb
    corners = np.array([[c0, r0], [c1 - 1, r0], [c0, r1 - 1], [c1 - 1, r1 - 1]], dtype=np.float64)
    qx, qy = map_points(corners, np.asarray(T_ab, dtype=np.float64))  # not BLAS: same bits
    # nearest-neighbour cells of the corners (a small epsilon keeps exact integers exact)
    cmin = min(0, int(np.floor(qx.min() + 0.5 - 1e-6)))
    rmin = min(0, int(np.floor(qy.min() + 0.5 - 1e-6)))
    cmax = max(w, int(np.floor(qx.max() + 0.5 + 1e-6)) + 1)
    rmax = max(h, int(np.floor(qy.max() + 0.5 + 1e-6)) + 1)
    shape = (rmax - rmin, cmax - cmin)
    canvas = np.full(shape, UNKNOWN, dtype=np.int8)
    canvas[-rmin : -rmin + h, -cmin : -cmin + w] = a
    warped = warp_into(b, T_ab, shape, dst_origin=(cmin, rmin))
    return fuse(canvas, warped), (-cmin, -rmin)
