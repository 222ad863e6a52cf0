"""The verified merger (``method="semantic"``, the default): any rotation, many hypotheses, each
checked over the whole overlap, refusal when ambiguous, sub-cell / sub-degree refinement.

Pipeline (all on the maps cropped to their known bounding boxes):

1. **Rotation candidates** from two rotation spectra (modulo 90 degrees, half-degree bins): the
   directions of straight wall segments (probabilistic Hough, length-weighted; unbiased by the
   staircase of walls drawn at an angle) and of blurred wall gradients. The peaks of each
   pair's circular cross-correlation give theta0 + k 90; ``ROTATION_STEP_DEG`` adds a sweep.
2. **Translation candidates**, coarse: per rotation, FFT cross-correlations of the maps pooled
   to 1/``SCALE`` give every translation's wall agreement and disagreement; the
   ``PEAKS_PER_ROTATION`` best of ``agree * (agree / (agree + disagree))^2`` become hypotheses
   (``paper_candidates=True`` adds the seed paper's trusted-point matches).
3. **Local alignment**: point-to-line ICP of b's wall cells on a's, then a small rotation sweep
   (+-0.5, +-1 degree) of the two best, re-polished.
4. **Verification**: Birk & Carpin's acceptance index ``agree / (agree + disagree)`` on the
   wall cells of both maps with a one-cell tolerance (:class:`~mrexplore.merge.common.Verifier`;
   lone occupied cells, the speckle of real maps, take no part). The best pose is also slid
   along a's wall directions (``SLIDE_STEP``), so ridges of repetitive layouts are examined.
5. **Decision** (the rules of :data:`_RULES`, in order). *Consistent*: under the best pose
   (most agreeing minus 10 x disagreeing wall cells) the maps contradict each other no more
   than their noise explains: a wall within ``1 + slack_cells`` cells of the other map's wall (a
   wall seen from its two sides, eroded by grazing beams) and lone contradictions (groups under
   ``MIN_RUN_CELLS``) are noise, and what remains must leave an index >= ``min_score``.
   *Unique*: the strongest far pose (``FAR_CELLS`` mean displacement) that explains at least
   ``RIVAL_SUPPORT`` as much is beaten by ``min_margin`` in index and ``MIN_EVIDENCE_CELLS``
   disagreeing cells. Two look-alike rooms pass the first and fail the second: refused, to be
   merged later once more is known. Enough shared knowledge (``min_overlap``,
   ``MIN_OVERLAP_CELLS``, ``min_common_m2``) is asked for too, walls that pin the pose without a
   slide along them, nor through one small thing (``min_cross_cells``, ``LONE_PIN_TEST``),
   evidence that is more than one object (``min_wall_area_m2``, ``min_object_m2``,
   ``OBJECT_HULL_FREE``), and last the poses that move the best by either map's repeats must
   be beaten as rivals are (``REPEAT_RIVALS``).
   Measurements behind each default: ``docs/merging.md``.

The steps' machinery lives beside this module (:mod:`~mrexplore.merge.rotation`,
:mod:`~mrexplore.merge.coarse`, :mod:`~mrexplore.merge.icp`, :mod:`~mrexplore.merge.repeats`,
:mod:`~mrexplore.merge.pinning`, the verifier in :mod:`~mrexplore.merge.common`). Here:
the options, and :func:`merge_semantic` as four stages read top to bottom: :class:`_Pair`
(the crops and the verifiers they share), :func:`_search` (steps 1-4), :func:`_judge` (the
best pose and its rivals) and the decision rules :data:`_RULES`, each a small function that
returns the reason to refuse or None.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from typing import Any, ClassVar

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.errors import ConfigError
from mrexplore.grid import (
    OCCUPIED_THRESHOLD,
    UNKNOWN,
    Int8Grid,
    Transform,
    chain_each,
)
from mrexplore.merge.coarse import CoarseMatcher
from mrexplore.merge.common import (
    Agreement,
    MapCodes,
    MergeEvidence,
    MergeResult,
    Verifier,
    WeighedPose,
    chain,
    detector_check,
    known_bbox,
    map_points,
    translation,
    warp_into,
)
from mrexplore.merge.icp import WallICP
from mrexplore.merge.pinning import (
    CROSS_GUARD_CELLS,
    PinTerms,
    agreeing_area,
    slide_direction,
)
from mrexplore.merge.places import PLACES_LEFT_OUT, beyond_places
from mrexplore.merge.repeats import (
    OBJECT_CLUTTER_M,
    OBJECT_WIDTH_M,
    ByStructure,
    Structures,
    agreement_by_structure,
    one_object_area,
    outside_object,
    repeat_shifts,
    ruled_out_structure,
)
from mrexplore.merge.rotation import direction_histogram, rotation_candidates, wall_normals
from mrexplore.options import Options, boolean, integer, number, option
from mrexplore.types import Box

F32 = NDArray[np.float32]

# The compiled wall ICP (None without numba); used while mrexplore.kernels.enabled().
_merging = kernels.load("merging")

#: Keypoint detectors of the seed paper's candidates (``paper_candidates=True``).
SEMANTIC_DETECTORS = ("harris", "shi-tomasi", "fast", "sift", "orb")


@dataclass
class _Hypothesis:
    T: Transform  # cropped-b cells -> cropped-a cells
    source: str
    agreement: Agreement | None = None
    shared_cells: int = 0  # cells known in both maps under T (counted for the ranking)
    shared_bonus: float = 0.0  # the final ranking's credit for them (see below)

    @property
    def score(self) -> float:
        return self.agreement.score if self.agreement is not None else 0.0

    @property
    def evidence(self) -> float:
        """Agreeing minus 10 x disagreeing wall cells (plus, in the final ranking, the credit
        for shared known space): the support of the pose."""
        ag = self.agreement
        if ag is None:
            return -1e18
        return float(ag.agree - 10 * ag.disagree) + self.shared_bonus


@dataclass(frozen=True)
class PosePrior:
    """A rough guess of where b lies in a, for maps of look-alike places the merger cannot tell
    apart alone (as m-explore's map merge takes known initial poses).

    ``T_ab``: the guessed pose (3x3, b's cells -> a's cells, both maps' full grids). A pose is
    considered only when it puts the centre of b's walls within ``radius_cells`` of where the
    guess puts it and turns b by at most ``turn_deg`` from the guess. Every other rule but the
    room match holds inside that region: consistency, a unique best (a rival inside the region
    still refuses), the pin, the wall area and the object rules; the room match, which guards
    against a look-alike room elsewhere, is what the guess rules out. A wrong guess can make a
    wrong merge: the merger trusts it.

    >>> PosePrior(np.eye(3), radius_cells=-1.0)
    Traceback (most recent call last):
    ...
    mrexplore.errors.ConfigError: PosePrior: radius_cells must be a number > 0, got -1.0
    """

    T_ab: Transform
    radius_cells: float = 40.0
    turn_deg: float = 10.0

    def __post_init__(self) -> None:
        T = np.asarray(self.T_ab, dtype=np.float64)
        if T.shape != (3, 3) or not np.isfinite(T).all():
            raise ConfigError(f"PosePrior: T_ab must be a finite 3x3 transform, got {self.T_ab!r}")
        for name in ("radius_cells", "turn_deg"):
            v = getattr(self, name)
            if not isinstance(v, int | float) or not math.isfinite(v) or v <= 0:
                raise ConfigError(f"PosePrior: {name} must be a number > 0, got {v!r}")
        object.__setattr__(self, "T_ab", T)

    def admits(self, T: Transform, centre: NDArray[np.float64], prior_T: Transform) -> bool:
        """Whether pose ``T`` lies in the region around ``prior_T`` (both in the same frames;
        ``centre`` (2,): the centre of b's walls in b's cells)."""
        p = np.stack(map_points(centre.reshape(1, 2), T), axis=1)[0]
        q = np.stack(map_points(centre.reshape(1, 2), prior_T), axis=1)[0]
        return (
            math.hypot(p[0] - q[0], p[1] - q[1]) <= self.radius_cells
            and turn_between_deg(T, prior_T) <= self.turn_deg
        )


def turn_between_deg(T: Transform, U: Transform) -> float:
    """The angle (degrees, 0-180) between the rotations of two 3x3 poses, from ``math.atan2``
    (the C library's, the same on every CPU)."""
    turn = math.atan2(T[1, 0], T[0, 0]) - math.atan2(U[1, 0], U[0, 0])
    return math.degrees(abs((turn + math.pi) % (2 * math.pi) - math.pi))


# --------------------------------------------------------------------------------------------
# the method
# --------------------------------------------------------------------------------------------


def _rigid(theta_rad: float) -> Transform:
    """The rotation by ``theta_rad`` as a 3x3 transform, from ``math.cos``/``math.sin`` (the C
    library's; numpy's vectorised ones round differently on different CPUs)."""
    c, s = math.cos(theta_rad), math.sin(theta_rad)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _turn_about(deg: float, cx: float, cy: float) -> Transform:
    """A turn by ``deg`` degrees about the cell ``(cx, cy)``."""
    return chain(translation(cx, cy), _rigid(math.radians(deg)), translation(-cx, -cy))


def _rotation_about(theta: float, shape: tuple[int, int]) -> tuple[Transform, tuple[int, int]]:
    """Rotation of a (h, w) grid by ``theta`` about its centre, shifted so the result fits in a
    canvas starting at (0, 0); returns (T_rot, canvas shape)."""
    h, w = shape
    R = _rigid(theta)
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], dtype=np.float64)
    # rounded before floor and ceil: at a multiple of 90 degrees a corner lands within 1e-13 of
    # an integer, on either side depending on the CPU's rounding, which would shift the canvas
    q = np.round(np.stack(map_points(corners, R), axis=1), 6)
    lo = np.floor(q.min(axis=0))
    hi = np.ceil(q.max(axis=0))
    T = chain(translation(-lo[0], -lo[1]), R)
    return T, (int(hi[1] - lo[1]) + 1, int(hi[0] - lo[0]) + 1)


def _mean_shift(T1: Transform, T2: Transform, pts: NDArray[np.float64]) -> float:
    dx, dy = map_points(pts, np.asarray(T1) - np.asarray(T2))
    # rounded: it is compared with thresholds (far_cells, 1 cell)
    return round(float(np.mean(np.sqrt(dx * dx + dy * dy))), 6)


def _paper_hypotheses(
    a: Int8Grid, b_rot: Int8Grid, T_rot: Transform, n: int, k: int, detector: str = "harris"
) -> list[Transform]:
    """The seed paper's Algorithm 1 + 2 as a candidate generator on rotated b: the ``k`` best
    trusted-point pairs by gradient-window correlation, each giving a translation.

    Measured on 8 bench cases (4 symmetric, 4 real): it changed no outcome and cost 10-90x
    more time (one detection and window extraction per rotation candidate), so it is off by
    default (``paper_candidates=True`` turns it on).
    """
    from mrexplore.merge.common import to_gray
    from mrexplore.merge.features import detect_points
    from mrexplore.merge.paper import correlation_matrix, gradient_windows, trusted_points

    f = 41  # smaller than Eq. (5)'s 60: cropped partial maps are small
    pa = detect_points(to_gray(a), detector, n)
    pb = detect_points(to_gray(b_rot), detector, n)
    ta = pa[trusted_points(a, pa, f, 0.3)]
    tb = pb[trusted_points(b_rot, pb, f, 0.3)]
    if len(ta) == 0 or len(tb) == 0:
        return []
    C = correlation_matrix(gradient_windows(a, ta, f), gradient_windows(b_rot, tb, f))
    top = np.lexsort((np.arange(C.size), -np.round(C.ravel(), 9)))[:k]  # ties in raster order
    ii, jj = np.unravel_index(top, C.shape)
    return [chain(translation(*(ta[i] - tb[j])), T_rot) for i, j in zip(ii, jj, strict=True)]


def _slide_shifts(
    normals_a: tuple[NDArray[np.float64], NDArray[np.float64]],
    b_shape: tuple[int, int],
    step: float,
) -> NDArray[np.float64]:
    """Shifts (K, 2), cells in a, that slide a pose along a's two wall directions: multiples of
    ``step`` along a's dominant wall direction and its normal, both ways, up to b's diagonal.

    Rows of identical shelves or a long corridor make a *ridge* in the coarse score: sliding b
    along the walls keeps every wall on a wall, and the coarse peak sits where the overlap is
    largest, which need not be the truth (seen on the warehouse map: a perfectly consistent
    pose 140 cells from the truth). The best pose moved by these shifts
    (:func:`_shifted_hypotheses`) puts the other poses on the ridge into the verification:
    either one explains more (it becomes the best) or one explains as much (the rival test
    refuses).
    """
    hist = direction_histogram(normals_a)
    phi = math.radians(float(np.argmax(hist)))  # wall normal direction mod 90 deg
    h, w = b_shape
    reach = math.hypot(h, w)
    ks = np.arange(step, reach, step)
    cos_phi, sin_phi = math.cos(phi), math.sin(phi)
    dirs = np.array([[cos_phi, sin_phi], [-sin_phi, cos_phi]])
    return np.concatenate([s * ks[:, None] * d[None, :] for d in dirs for s in (1.0, -1.0)])


def _repeat_moves(
    T: Transform,
    repeats_a: Sequence[tuple[float, float]],
    repeats_b: Sequence[tuple[float, float]],
) -> NDArray[np.float64]:
    """Shifts (K, 2), cells in a, that move the pose ``T`` by either map's repeats
    (:mod:`.repeats`): b laid on the next copy of what it matched in a (a's repeat), or b's next
    copy of what it showed laid where the first one was (b's repeat, turned into a's frame by
    the pose's rotation: ``T @ translation(s) = translation(R s) @ T``).

    A map that shows one rack twice makes every pose on one copy ambiguous with the other, and
    the coarse search's few peaks per rotation need not include it: the merger judges the
    moved poses as rivals of the best (a moved pose that explains more refuses too; it never
    becomes the best, so this check can come last and cost only a pose about to be merged).
    """
    R = np.asarray(T, dtype=np.float64)[:2, :2]
    moves = [np.asarray(s, dtype=np.float64) for s in repeats_a]
    moves += [R @ np.asarray(s, dtype=np.float64) for s in repeats_b]
    return np.stack(moves) if moves else np.zeros((0, 2), dtype=np.float64)


def _shifted_hypotheses(
    best: _Hypothesis,
    shifts: NDArray[np.float64],
    source: str,
    screen: Verifier,
    quick: Verifier,
    verify: Verifier,
    icp: WallICP,
    min_overlap: float,
    min_overlap_cells: int,
    keep: int = 2,
) -> list[_Hypothesis]:
    """The best pose moved by each of the (K, 2) ``shifts`` (cells in a, ``translation(s) @
    T``): all screened in one pass, the ``3 keep`` best polished by a short ICP, and the
    ``keep`` best of those refined fully and verified; those that still overlap enough."""
    agree, disagree = screen.shifted(best.T, shifts)
    order = np.argsort(-(agree - 10 * disagree), kind="stable")[: 3 * keep]  # ties: shift order
    out = [
        _Hypothesis(
            chain(translation(*shifts[k]), best.T),
            source,
            Agreement(int(agree[k]), int(disagree[k])),
        )
        for k in order
        if agree[k] > 0
    ]
    refined: list[_Hypothesis] = []
    for hyp in out:
        hyp.T = icp(hyp.T, iters=4, max_dist=3.0, n_points=400)
        hyp.agreement = quick(hyp.T)
    out.sort(key=lambda h: -h.evidence)
    for hyp in out[:keep]:
        hyp.T = icp(hyp.T, iters=10, max_dist=3.0)
        hyp.T = icp(hyp.T, iters=5, max_dist=1.5)
        hyp.agreement = verify(hyp.T)
        if verify.overlap_ok(hyp.agreement, min_overlap, min_overlap_cells):
            refined.append(hyp)
    return refined


def _rotation_polish(
    hyp: _Hypothesis,
    icp: WallICP,
    verify: Verifier,
    b_shape: tuple[int, int],
    offsets_deg: tuple[float, ...] = (-1.0, -0.5, 0.5, 1.0),
) -> None:
    """Try ``hyp`` turned by small ``offsets_deg`` about b's centre, each re-polished by ICP;
    keep whichever explains most (in place).

    ICP on wall cells can settle half a degree off when it starts a cell or two off in
    translation (thick walls and clutter give it a flat valley); the rotation candidates are
    only good to a few tenths of a degree, so the best hypotheses get this small sweep.
    """
    if hyp.agreement is None:
        return
    cy, cx = (b_shape[0] - 1) / 2.0, (b_shape[1] - 1) / 2.0
    for d in offsets_deg:
        turn = _turn_about(d, cx, cy)
        T = icp(icp(chain(hyp.T, turn), iters=10, max_dist=3.0), iters=5, max_dist=1.5)
        ag = verify(T)
        if ag.agree - 10 * ag.disagree > hyp.agreement.agree - 10 * hyp.agreement.disagree:
            hyp.T, hyp.agreement = T, ag


#: The shifts of :func:`_consistency_polish`'s grid, (25, 3, 3): rows, then columns, -2..2 cells.
_POLISH_SHIFTS = np.stack([translation(dc, dr) for dr in range(-2, 3) for dc in range(-2, 3)])


def _consistency_polish(
    T: Transform,
    slack_verify: Verifier,
    consistency: Callable[[Transform], float],
    centre: tuple[float, float],
    keep: int = 5,
    start: float | None = None,
) -> tuple[Transform, float]:
    """The most consistent pose within 2 cells and 1 degree of ``T`` (b cells -> a cells):
    ``(pose, consistency)``.

    ICP settles where b's wall cells are nearest a's on average, which on maps bent by
    odometry drift can be a cell and a degree from where they contradict each other least
    (traced in the loop: a best pose at 0.96 beside one at 0.99). The 125 poses of the grid
    (shifts -2..2 cells, turns -1..1 degree by halves about ``centre``) are ranked by the cheap
    slack count, and the ``keep`` best by the noise-aware ``consistency``. ``start``: the
    consistency of ``T`` when the caller has it already (not computed again).
    """
    cx, cy = centre
    turns = np.stack([_turn_about(d, cx, cy) for d in (-1.0, -0.5, 0.0, 0.5, 1.0)])
    # chain(translation(dc, dr), T, turn) for every turn, then dr, then dc (the grid's order)
    poses = chain_each(chain_each(_POLISH_SHIFTS, T)[None], turns[:, None]).reshape(-1, 3, 3)
    scores = [ag.score for ag in slack_verify.many(poses)]
    order = sorted(range(len(scores)), key=lambda k: (-scores[k], k))  # ties in grid order
    best_T, best_c = T, consistency(T) if start is None else start
    for k in order[:keep]:
        c = consistency(poses[k])
        if c > best_c:
            best_T, best_c = poses[k], c
    return best_T, best_c


def stands_as_rival(
    best: Agreement, other: Agreement, cells_per_sample: float, o: SemanticOptions
) -> bool:
    """Does a far pose with agreement ``other`` stand as a rival to the best pose (``best``)?
    It does when it explains at least ``RIVAL_SUPPORT`` of the best's agreeing wall cells and
    is not beaten by ``o.min_margin`` in index and ``MIN_EVIDENCE_CELLS`` more contradicting
    wall cells (``cells_per_sample``: wall cells per verified sample)."""
    if other.agree < RIVAL_SUPPORT * best.agree:
        return False
    excess = (other.disagree - best.disagree) * cells_per_sample
    return best.score - other.score < o.min_margin or excess < MIN_EVIDENCE_CELLS


#: Slides (cells, each way) of :func:`_standing_slide`: from beyond a wrong merge's 5 cells to
#: the length of a room, where the coarse search's peaks take over.
SLIDES_CELLS = (5.0, 10.0, 20.0, 40.0)


def _standing_slide(
    verify: Verifier,
    best: _Hypothesis,
    wall_a: NDArray[np.bool_],
    wall_b: NDArray[np.bool_],
    cells_b: tuple[NDArray[np.intp], NDArray[np.intp]],
    o: SemanticOptions,
) -> float | None:
    """The first slide (cells, signed) of the best pose along its least pinned direction that
    stands as a rival to it (:func:`stands_as_rival`), 0.0 when no wall of b lands on one of a
    (nothing pins it), or None when the maps contradict every slide of :data:`SLIDES_CELLS`
    both ways: the pose is pinned by what the wall normals miss (door gaps, wall ends, free
    space beyond them)."""
    assert best.agreement is not None
    v = slide_direction(wall_a, wall_b, best.T, cells_b)
    if v is None:
        return 0.0
    for d in SLIDES_CELLS:
        for sign in (1.0, -1.0):
            moved = chain(translation(sign * d * float(v[0]), sign * d * float(v[1])), best.T)
            if stands_as_rival(best.agreement, verify(moved), verify.cells_per_sample, o):
                return sign * d
    return None


class _SharedSpace:
    """Counts a's cells known in a and in b warped by a pose (nearest neighbour): the known
    space two maps share under it. The known masks are made once per merge, not per pose."""

    def __init__(self, a: Int8Grid, b: Int8Grid) -> None:
        self.known_a = (a != UNKNOWN).view(np.uint8)
        self.known_b = (b != UNKNOWN).view(np.uint8)
        self.size = (a.shape[1], a.shape[0])

    def smaller_known_cells(self) -> int:
        """The known cells of the map that knows fewer."""
        return min(int(cv2.countNonZero(self.known_a)), int(cv2.countNonZero(self.known_b)))

    def __call__(self, T_ab: NDArray[np.float64]) -> int:
        # only the window of a that b's canvas can cover under the pose is warped and counted
        T = np.asarray(T_ab, dtype=np.float64)
        hb, wb = self.known_b.shape
        corners = np.stack(
            map_points(np.array([[-1.0, -1.0], [wb, -1.0], [-1.0, hb], [wb, hb]]), T), axis=1
        )
        w, h = self.size
        c0, r0 = np.maximum(np.floor(corners.min(axis=0)), 0).astype(int)
        c1, r1 = np.minimum(np.ceil(corners.max(axis=0)) + 1, (w, h)).astype(int)
        if c1 <= c0 or r1 <= r0:
            return 0
        M = T[:2].copy()
        M[:, 2] -= (c0, r0)
        warped = cv2.warpAffine(
            self.known_b,
            M,
            (int(c1 - c0), int(r1 - r0)),
            flags=cv2.INTER_NEAREST,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=0,
        )
        return int(cv2.countNonZero(cv2.bitwise_and(warped, self.known_a[r0:r1, c0:c1])))


# --- the rules' settings that are not options: one value each, chosen and measured on the
# tuning worlds (what each does and its measured effect: docs/merging.md; how each was chosen:
# docs/merging_history.md). Read where they are used, so a test or a bench ablation may set
# one for a run (``mrexplore bench merge --semantic-variant SLACK_CELLS=0``). ----------------
#: Contradicting wall cells (beyond the best's) that beat a rival, with ``MIN_MARGIN``'s index: a
#: wall's worth, not speckle.
MIN_EVIDENCE_CELLS: int = 20
#: A rival beaten by less is still ruled out by one object of ``MIN_EVIDENCE_CELLS`` wall cells on
#: the other map's free space (a notch tells two half-turns apart).
STRUCTURE_TEST: bool = True
#: Cells b's walls move on average between two poses for them to be two places, not one refitted.
FAR_CELLS: float = 5.0
#: Share of the best's agreeing wall cells a far pose must explain to be a rival (a corner match by
#: coincidence is not).
RIVAL_SUPPORT: float = 0.5
#: Cells between the slide search's shifts along a's walls (0: no slide search).
SLIDE_STEP: float = 8.0
#: Wall cells of b on a's known cells every hypothesis needs, beside ``min_overlap``'s share.
MIN_OVERLAP_CELLS: int = 80
#: Cells per block of the coarse search (its cost against its precision, ~scale/2 cells).
SCALE: int = 4
#: Map cells (640 x 640) beyond which the rotation spectrum pools walls 2 x 2 (its cost on large
#: maps; 0: never).
HOUGH_MAX_CELLS: int = 409_600
#: Translation peaks kept per candidate rotation by the coarse search.
PEAKS_PER_ROTATION: int = 12
#: Rotation peaks per spectrum (a hexagonal map folds into three equal peaks modulo 90 degrees).
MAX_ROTATION_PEAKS: int = 3
#: A sweep of rotations every this many degrees beside the spectrum's peaks (0: no sweep).
ROTATION_STEP_DEG: float = 0.0
#: Hypotheses refined (ICP) after polishing.
N_REFINE: int = 8
#: Hypotheses polished (a short ICP) after the coarse search.
N_POLISH: int = 24
#: Wall cells per map the judging verifier samples (0: all).
MAX_SAMPLES: int = 20_000
#: The linear coarse score's weight of b's walls on a's free cells (used when ``RATIO_POWER`` is 0).
W_FREE: float = 0.2
#: The linear coarse score's weight of disagreement (used when ``RATIO_POWER`` is 0).
W_DISAGREE: float = 1.0
#: The coarse score's power of the agreement ratio (0: the linear score).
RATIO_POWER: float = 2.0
#: A room-sized match (under ``room_match_m2``) passes when it covers this share of the smaller map.
ROOM_MATCH_SHARE: float = 0.3
#: The ranking's credit for known space both maps share under a pose, wall cells per shared cell.
SHARED_WEIGHT: float = 0.04
#: Cells beyond the one-cell tolerance within which two walls agree in the consistency index (a wall
#: seen from both sides, eroded).
SLACK_CELLS: int = 2
#: Contradicting cells count in the consistency index only in 8-connected groups this large (a wall,
#: not speckle).
MIN_RUN_CELLS: int = 5
#: An inconsistent best pose is replaced by the most consistent pose within 2 cells and 1 degree.
CONSISTENCY_POLISH: bool = True
#: A polished pose must clear ``min_score`` by this (the best of 125 nearby poses scores higher by
#: selection alone).
POLISH_MARGIN: float = 0.01
#: Each map's strongest repeats by which the pose about to be merged is moved and judged as rivals
#: (0: off).
REPEAT_RIVALS: int = 4
#: With the place test on (the loop), a far pose, a rival the search found or the best moved by a
#: repeat of either map, stands unless the maps contradict it beyond their noise (its noise-aware
#: index under ``min_score``), however little it explains or however much its raw index trails.
RIVALS_CONTRADICTED: bool = True
#: With the place test on (the loop), a pose is refused when either map shows a thing (a wall
#: structure) the other map rules out: none of it agrees, and most of it, ``MIN_RUN_CELLS``
#: cells or more, lands on floor the other robot has seen open.
THINGS_RULED_OUT: bool = True
#: A match on one structure seen from outside (free cells under this share of its hull) is refused
#: (0: off).
OBJECT_HULL_FREE: float = 0.2
#: A pinned pose must stay pinned with any one of b's small things left out (a post beside every
#: aisle).
LONE_PIN_TEST: bool = True

#: The former options that are now the constants above (lower-case name -> constant name).
DEMOTED_OPTIONS: dict[str, str] = {
    "min_evidence_cells": "MIN_EVIDENCE_CELLS",
    "structure_test": "STRUCTURE_TEST",
    "far_cells": "FAR_CELLS",
    "rival_support": "RIVAL_SUPPORT",
    "slide_step": "SLIDE_STEP",
    "min_overlap_cells": "MIN_OVERLAP_CELLS",
    "scale": "SCALE",
    "hough_max_cells": "HOUGH_MAX_CELLS",
    "peaks_per_rotation": "PEAKS_PER_ROTATION",
    "max_rotation_peaks": "MAX_ROTATION_PEAKS",
    "rotation_step_deg": "ROTATION_STEP_DEG",
    "n_refine": "N_REFINE",
    "n_polish": "N_POLISH",
    "max_samples": "MAX_SAMPLES",
    "w_free": "W_FREE",
    "w_disagree": "W_DISAGREE",
    "ratio_power": "RATIO_POWER",
    "room_match_share": "ROOM_MATCH_SHARE",
    "shared_weight": "SHARED_WEIGHT",
    "slack_cells": "SLACK_CELLS",
    "min_run_cells": "MIN_RUN_CELLS",
    "consistency_polish": "CONSISTENCY_POLISH",
    "polish_margin": "POLISH_MARGIN",
    "repeat_rivals": "REPEAT_RIVALS",
    "object_hull_free": "OBJECT_HULL_FREE",
    "lone_pin_test": "LONE_PIN_TEST",
}


@dataclass(frozen=True)
class SemanticOptions(Options):
    """The options of :func:`merge_semantic` (documented there, measured in
    ``docs/merging.md``): one default and one range each."""

    owner: ClassVar[str] = "merge_maps(method='semantic')"
    detector: str | None = option(None, detector_check(SEMANTIC_DETECTORS))
    min_score: float = option(0.97, number(0.0, 1.0))
    min_margin: float = option(0.03, number(0.0, 1.0))
    min_overlap: float = option(0.15, number(0.0, 1.0))
    paper_candidates: bool = option(False, boolean)
    min_common_m2: float = option(10.0, number(0.0, math.inf))
    room_match_m2: float = option(20.0, number(0.0, math.inf))
    resolution_m: float = option(0.05, number(1e-6, math.inf))
    min_cross_cells: float = option(10.0, number(0.0, math.inf))
    slide_test: bool = option(False, boolean)
    rival_perfect_cells: int = option(250, integer(0))
    min_wall_area_m2: float = option(4.0, number(0.0, math.inf))
    min_object_m2: float = option(20.0, number(0.0, math.inf))
    place_test: bool = option(False, boolean)

    @classmethod
    def from_kwargs(cls, **kwargs: Any) -> SemanticOptions:
        """As :meth:`Options.from_kwargs`; a former option, now a constant of this module, is a
        :class:`ConfigError` naming the constant."""
        demoted = sorted(set(kwargs) & set(DEMOTED_OPTIONS))
        if demoted:
            names = ", ".join(f"{k} (now {DEMOTED_OPTIONS[k]})" for k in demoted)
            raise ConfigError(
                f"{cls.owner}: {names} no longer an option: a constant of "
                "mrexplore.merge.semantic, chosen on the tuning worlds (docs/merging.md)"
            )
        return super().from_kwargs(**kwargs)

    def check_together(self) -> None:
        if self.detector is not None and not self.paper_candidates:
            raise ConfigError(f"{self.owner}: detector= is used only with paper_candidates=True")


def rival_structure(
    verify: Verifier, T_best: Transform, T_rival: Transform, margin: float, o: SemanticOptions
) -> int:
    """Wall cells of the largest object that rules the rival pose out, 0 when the test is off
    (``STRUCTURE_TEST``) or does not apply: a connected group of one map's wall cells that,
    under ``T_rival`` and not under ``T_best`` (crop cells, b -> a), lies on the other map's
    open free space. It applies only when the best is ahead in index (``margin`` > 0) and
    leaves no group of ``MIN_RUN_CELLS`` contradicting cells of its own. A rival is ruled
    out when this reaches ``MIN_EVIDENCE_CELLS``."""
    if not STRUCTURE_TEST or margin <= 0.0:
        return 0
    against_best, against_rival = verify.exclusive_groups(T_best, T_rival)
    return 0 if against_best >= MIN_RUN_CELLS else against_rival


def merge_semantic(
    a: Int8Grid,
    b: Int8Grid,
    *,
    extra_hypotheses: Sequence[Transform] = (),
    prior: PosePrior | None = None,
    **options: Any,
) -> MergeResult:
    """Verified merge of b into a (int8 maps, any sizes). Options (validated; why each default
    is what it is, with the measurements: ``docs/merging.md``) in lower case; the rules' other
    settings, in upper case, are constants of this module (:data:`DEMOTED_OPTIONS`), not
    options:

    - decision: ``min_score`` (0.97) on the noise-aware consistency index, with ``SLACK_CELLS``
      (2) and ``MIN_RUN_CELLS`` (5) defining the noise; ``min_margin`` (0.03) and
      ``MIN_EVIDENCE_CELLS`` (20) against every rival, a pose ``FAR_CELLS`` (5.0) cells away
      on average with ``RIVAL_SUPPORT`` (0.5) of the best's agreeing wall cells, or with no
      disagreeing wall cell and at least ``rival_perfect_cells`` (250; 0 = off) agreeing ones;
      ``STRUCTURE_TEST`` (True): a rival beaten by less than that is still ruled out when one
      object, a connected group of ``MIN_EVIDENCE_CELLS`` wall cells of one map, lies on the
      other's open free space under it and not under the best, and the best, ahead in index,
      leaves no group of ``MIN_RUN_CELLS`` contradicting cells (a notch tells two half-turns
      of a symmetric arena apart; noise contradicts in scattered cells);
    - shared knowledge: ``min_overlap`` (0.15) of b's wall cells on a's known cells,
      ``MIN_OVERLAP_CELLS`` (80), ``min_common_m2`` (10.0) m^2 known in both at
      ``resolution_m`` (0.05) m/cell (0 in the loop: the place test waits for a third place);
    - ``room_match_m2`` (20.0; 0 = off) and ``ROOM_MATCH_SHARE`` (0.3): without a ``prior``,
      refuse a pose whose shared known space is under 20 m^2 **and** under 0.3 of the smaller
      map's known space: a room-sized match in maps of several rooms may be a look-alike room
      (a twin-wings corridor was merged on its twin at 13.1 m^2, 0.24 of the smaller map; with
      the own maps' hit weight 3.6, a twin-wings room on its twin at 16.2 m^2);
    - search: ``MAX_ROTATION_PEAKS`` (3: a hexagonal map's spectrum folds into three equal
      peaks modulo 90 degrees) per rotation spectrum, ``ROTATION_STEP_DEG`` (0 = no
      sweep), ``HOUGH_MAX_CELLS`` (409,600: 640 x 640; 0 = never) beyond which the wall
      segments of the rotation spectrum come from walls pooled 2 x 2 (its cost on large maps),
      ``SCALE`` (4) cells per coarse block, ``PEAKS_PER_ROTATION`` (12), ``N_POLISH``
      (24) and ``N_REFINE`` (8) hypotheses polished and refined, ``SLIDE_STEP`` (8.0) cells
      (0 = no slide search), ``MAX_SAMPLES`` (20000) wall cells per map in the verifier;
    - coarse score: ``RATIO_POWER`` (2.0), or the linear score with ``W_FREE`` (0.2) and
      ``W_DISAGREE`` (1.0) when it is 0;
    - ``CONSISTENCY_POLISH`` (True): an inconsistent best pose is replaced by the most
      consistent pose within 2 cells and 1 degree of it, if that one reaches ``min_score`` +
      ``POLISH_MARGIN`` (0.01: the best of 125 nearby poses scores higher by selection alone);
    - ``min_cross_cells`` (10; 0 = off): refuse a pose whose agreeing walls pin it less than this
      (:func:`~mrexplore.merge.pinning.cross_support`, wall cells) across their direction: one
      straight wall or a corridor slides;
    - ``slide_test`` (False): a pose under ``min_cross_cells`` is still pinned when the maps
      contradict every slide of it along that direction by 5, 10, 20 and 40 cells both ways
      (each beaten as a rival is: ``min_margin`` and ``MIN_EVIDENCE_CELLS``): door gaps, wall
      ends and the floor beyond them pin a corridor the wall normals cannot;
    - ``min_wall_area_m2`` (4.0; 0 = off): refuse a pose whose agreeing walls fit in a smaller
      rectangle (:func:`agreeing_area`, m^2): one object, a rack or a pillar, fits every copy of
      it;
    - ``min_object_m2`` (20.0; 0 = off): refuse a pose whose agreeing walls lie (95 %) on one
      connected wall structure in each map, when the larger of the two fits in a smaller
      rectangle (:func:`~mrexplore.merge.repeats.one_object_area`, m^2): a rack seen whole
      matches every copy of it, and the copies may lie where neither map has looked;
    - ``LONE_PIN_TEST`` (True): a pose that ``min_cross_cells`` finds pinned must stay pinned
      with any one of b's small things (under 1.5 m: a post, a box) left out
      (:func:`~mrexplore.merge.pinning.lone_pin_support`): rack sides pinned along only by the
      post beside them match every aisle's post;
    - ``OBJECT_HULL_FREE`` (0.2; 0 = off): refuse a pose whose agreeing walls lie (95 %), in
      either map, on one structure seen from outside (at least 1 m across, the map's free
      cells under this share of its convex hull) plus at most one thing under 1.5 m
      (:func:`~mrexplore.merge.repeats.outside_object`): a rack with a post beside it, larger
      than ``min_object_m2``, is what a warehouse repeats;
    - ``REPEAT_RIVALS`` (4; 0 = off): last, move the pose about to be merged by each map's 4
      strongest repeats (:func:`~mrexplore.merge.repeats.repeat_shifts`, at least 4 ``SCALE``
      cells long) and judge the moved poses as rivals: a copy the coarse search never tried;
    - ``place_test`` (False; the every-step tracker sets it): without a ``prior``, the
      agreement outside the two places of each map that hold most of it (rooms, halls,
      stretches of corridor, cut at passages narrower than half their clearance:
      :mod:`~mrexplore.merge.places`) must pin the pose by itself (``min_cross_cells``). A
      match confined to one repeated unit of either map may lay it on its twin whatever its
      size; a single call cannot wait for other places, a tracker can;
    - ``paper_candidates`` (False): add the seed paper's trusted-point matches as hypotheses
      (``detector``, default harris, picks their keypoints; 3-4x slower, one more correct merge
      in 166 bench pairs).

    ``prior``: a :class:`PosePrior`, a rough guess of b's pose from outside the maps; only
    poses near it are considered (and the guess itself is one more hypothesis).

    ``extra_hypotheses``: poses ``T_ab`` (3x3, b's cells -> a's) added to the search's own and
    always polished and refined, judged by the same rules. For diagnostics: the loop study's
    ``seeded`` variant hands it the true pose, to tell what the search misses from what the
    decision rules refuse. The env never sets it.
    """
    t0 = time.perf_counter()
    o = SemanticOptions.from_kwargs(**options)
    info: dict[str, Any] = {}
    detector = (o.detector or "harris") if o.paper_candidates else None
    judged: _Judged | None = None
    try:
        pair = _Pair.of(a, b, o)
        found = _search(pair, o, info, [*extra_hypotheses], prior)
        judged = _judge(pair, found, o, info)
        for rule in _RULES:
            reason = rule(judged)
            if reason is not None:
                raise _Refused(reason, judged.best.score, **judged.common)
    except _Refused as refusal:
        return MergeResult.refused(
            refusal.reason,
            method="semantic",
            t0=t0,
            detector=detector,
            score=refusal.score,
            info=info,
            evidence=MergeEvidence() if judged is None else judged.evidence(),
            **refusal.fields,
        )
    return _accepted(a, b, pair, judged, detector, t0)


# --------------------------------------------------------------------------------------------
# the pipeline's stages: crop, search, judge (the rules), accept
# --------------------------------------------------------------------------------------------


class _Refused(Exception):
    """A refusal from inside a stage: the reason and the figures the result carries."""

    def __init__(self, reason: str, score: float = 0.0, **fields: Any) -> None:
        super().__init__(reason)
        self.reason, self.score, self.fields = reason, score, fields


@dataclass
class _Pair:
    """The two maps cropped to their known boxes (all the work is on the crops), with what
    every stage reads: wall masks, codes, a's wall normals and the verifiers.

    Verifiers: ``verify`` on up to ``MAX_SAMPLES`` wall cells (the judgement), ``quick`` on
    2,000 (polishing), ``screen`` on 2,000 with a tolerance for the coarse poses' ~scale/2
    cells of error.
    """

    box_a: Box
    box_b: Box
    ac: Int8Grid
    bc: Int8Grid
    wall_a: NDArray[np.bool_]
    wall_b: NDArray[np.bool_]
    codes_a: MapCodes
    codes_b: MapCodes
    normals_a: tuple[NDArray[np.float64], NDArray[np.float64]]
    verify: Verifier
    quick: Verifier
    screen: Verifier
    shared: _SharedSpace
    icp: WallICP

    @classmethod
    def of(cls, a: Int8Grid, b: Int8Grid, o: SemanticOptions) -> _Pair:
        """Crop both maps; refuses a map with nothing known or under 20 wall cells."""
        bba, bbb = known_bbox(a, margin=1), known_bbox(b, margin=1)
        if bba is None or bbb is None:
            raise _Refused(f"map {'a' if bba is None else 'b'} is all unknown")
        ac = a[bba[0] : bba[1], bba[2] : bba[3]]
        bc = b[bbb[0] : bbb[1], bbb[2] : bbb[3]]
        wall_a, wall_b = ac >= OCCUPIED_THRESHOLD, bc >= OCCUPIED_THRESHOLD
        n_wall_a, n_wall_b = int(wall_a.sum()), int(wall_b.sum())
        if min(n_wall_a, n_wall_b) < 20:
            raise _Refused(f"too few wall cells to align (a: {n_wall_a}, b: {n_wall_b}; need 20)")
        codes_a, codes_b = MapCodes(ac), MapCodes(bc)  # shared by all the verifiers
        quick_samples = min(MAX_SAMPLES, 2000) if MAX_SAMPLES else 2000
        return cls(
            box_a=bba,
            box_b=bbb,
            ac=ac,
            bc=bc,
            wall_a=wall_a,
            wall_b=wall_b,
            codes_a=codes_a,
            codes_b=codes_b,
            normals_a=wall_normals(wall_a),  # the rotation spectrum and the slide
            verify=Verifier(codes_a, codes_b, max_samples=MAX_SAMPLES),
            quick=Verifier(codes_a, codes_b, max_samples=quick_samples),
            screen=Verifier(codes_a, codes_b, max_samples=2000, tolerance=max(1, SCALE // 2 + 1)),
            shared=_SharedSpace(ac, bc),
            icp=WallICP(wall_a, wall_b, max_points=1500),
        )

    def to_full(self, T: Transform) -> Transform:
        """A pose between the crops as one between the full maps (b's cells -> a's)."""
        bba, bbb = self.box_a, self.box_b
        return chain(translation(bba[2], bba[0]), T, translation(-bbb[2], -bbb[0]))

    def to_crops(self, T: Transform) -> Transform:
        """A pose between the full maps as one between the crops."""
        bba, bbb = self.box_a, self.box_b
        return chain(translation(-bba[2], -bba[0]), T, translation(bbb[2], bbb[0]))

    def overlaps(self, h: _Hypothesis, verifier: Verifier, o: SemanticOptions) -> bool:
        """Whether ``h``'s agreement (by ``verifier``) has the shared walls asked for."""
        return h.agreement is not None and verifier.overlap_ok(
            h.agreement, o.min_overlap, MIN_OVERLAP_CELLS
        )

    def moved(
        self, h: _Hypothesis, shifts: NDArray[np.float64], source: str, o: SemanticOptions
    ) -> list[_Hypothesis]:
        """``h`` moved by each of ``shifts``, screened and refined with this pair's tools."""
        return _shifted_hypotheses(
            h,
            shifts,
            source,
            self.screen,
            self.quick,
            self.verify,
            self.icp,
            o.min_overlap,
            MIN_OVERLAP_CELLS,
        )


@dataclass
class _Found:
    """What the search found: every candidate it tried (``tried``) and the refined, distinct
    ones that overlap enough (``chosen``), with the prior's region when one was given."""

    tried: list[_Hypothesis]
    chosen: list[_Hypothesis]
    region: _Region | None

    def in_prior(self, h: _Hypothesis) -> bool:
        """Whether ``h`` lies in the prior's region (always, without a prior)."""
        return _in_region(self.region, h)


#: A prior's region in the crops' cells: the prior, its guess between the crops and the centre
#: (2,) of b's walls it is judged about.
_Region = tuple[PosePrior, Transform, NDArray[np.float64]]


def _in_region(region: _Region | None, h: _Hypothesis) -> bool:
    """Whether ``h`` lies in ``region`` (always, without one)."""
    return region is None or region[0].admits(h.T, region[2], region[1])


def _coarse_hypotheses(pair: _Pair, o: SemanticOptions, info: dict[str, Any]) -> list[_Hypothesis]:
    """Steps 1 and 2: the rotation candidates, and per rotation the coarse translation peaks
    (and with ``paper_candidates`` the seed paper's trusted-point matches)."""
    thetas = rotation_candidates(
        pair.wall_a,
        pair.wall_b,
        MAX_ROTATION_PEAKS,
        ROTATION_STEP_DEG,
        pair.normals_a,
        hough_max_cells=HOUGH_MAX_CELLS,
    )
    info["rotations_deg"] = [round(float(np.degrees(t)), 2) for t in thetas]
    if not thetas:
        raise _Refused("no wall edges to estimate a rotation from (add rotation_step_deg to sweep)")
    rots = [_rotation_about(t, pair.bc.shape) for t in thetas]
    max_shape = (max(s[0] for _, s in rots), max(s[1] for _, s in rots))
    coarse = CoarseMatcher(pair.ac, SCALE, max_shape, W_FREE, W_DISAGREE, RATIO_POWER)
    hyps: list[_Hypothesis] = []
    for T_rot, shape in rots:
        b_rot = warp_into(pair.bc, T_rot, shape)
        peaks = coarse.peaks(b_rot, PEAKS_PER_ROTATION)
        if peaks:
            # pooled blocks are anchored at the corner: half a block of ambiguity, which ICP removes
            shifts = np.stack([translation(dc, dr) for dc, dr, _ in peaks])
            hyps += [_Hypothesis(T, "coarse") for T in chain_each(shifts, T_rot)]
        if o.paper_candidates:
            hyps += [
                _Hypothesis(T, "paper")
                for T in _paper_hypotheses(pair.ac, b_rot, T_rot, 150, 3, o.detector or "harris")
            ]
    return hyps


def _search(
    pair: _Pair,
    o: SemanticOptions,
    info: dict[str, Any],
    given: list[Transform],
    prior: PosePrior | None,
) -> _Found:
    """Steps 1-4: candidates (coarse, handed in, the prior's guess), screened with a wide
    tolerance, the best ``N_POLISH`` polished by a short ICP, the ``N_REFINE`` best distinct
    ones refined fully (the two best also turned by small angles), slid along a's walls; those
    that overlap enough (and lie near the prior's guess). Refuses when none does."""
    hyps = _coarse_hypotheses(pair, o, info)
    # the guess of a prior is one more pose handed in
    given = [*given, *([prior.T_ab] if prior is not None else [])]
    if not hyps and not given:
        raise _Refused("no candidate alignment (the maps share no structure)")

    # --- 3. screen the raw hypotheses with a wide tolerance (they are up to ~scale/2 cells off),
    # polish the best few with a short ICP, re-verify; 4. refine the best fully ---
    for hyp, ag in zip(hyps, pair.screen.many(np.array([h.T for h in hyps])), strict=True):
        hyp.agreement = ag
    hyps.sort(key=lambda h: -(h.agreement.agree - h.agreement.disagree if h.agreement else 0))

    region: _Region | None = None
    if prior is not None:
        # only poses near the guess; the coarse ones with room for their ~scale/2 cells of error
        prior_crop = pair.to_crops(prior.T_ab)
        centre = np.asarray(pair.verify.points_b, dtype=np.float64).mean(axis=0)
        loose = PosePrior(prior_crop, prior.radius_cells + 2 * SCALE, prior.turn_deg + 2.0)
        hyps = [h for h in hyps if loose.admits(h.T, centre, prior_crop)]
        region = (prior, prior_crop, centre)
        info["prior"] = True

    # poses handed in go first, so that they are always polished (and judged like the rest)
    hyps = [
        _Hypothesis(pair.to_crops(np.asarray(T, dtype=np.float64)), "given") for T in given
    ] + hyps
    handed = hyps[: len(given)]
    for hyp, ag in zip(handed, pair.screen.many(np.array([h.T for h in handed])), strict=True):
        hyp.agreement = ag
    icp, quick, verify = pair.icp, pair.quick, pair.verify
    for hyp in hyps[:N_POLISH]:
        hyp.T = icp(hyp.T, iters=4, max_dist=1.5 * SCALE, n_points=400)
        hyp.agreement = quick(hyp.T)
    ok = [h for h in hyps[:N_POLISH] if pair.overlaps(h, quick, o)]
    if SHARED_WEIGHT > 0:  # the credit of the final ranking (in _judge), so the truth is kept
        _credit_shared_space(ok, pair, o)
    ok.sort(key=lambda h: -h.evidence)
    # keep distinct hypotheses only (ICP often pulls several peaks to the same pose)
    chosen: list[_Hypothesis] = []
    for h in ok:
        # a cell apart on average: the quick verifier's 2,000 walls estimate it as well as all
        if all(_mean_shift(h.T, c.T, quick.points_b) >= 1.0 for c in chosen):
            chosen.append(h)
        if len(chosen) >= N_REFINE:
            break
    for h in chosen:
        h.T = icp(h.T, iters=10, max_dist=3.0)
        h.T = icp(h.T, iters=5, max_dist=1.5)
        h.agreement = verify(h.T)
    chosen.sort(key=lambda h: -h.evidence)
    for h in chosen[:2]:
        _rotation_polish(h, icp, verify, pair.bc.shape)
    chosen = [h for h in chosen if pair.overlaps(h, verify, o)]
    if SLIDE_STEP > 0 and chosen:
        best_so_far = max(chosen, key=lambda h: h.evidence)
        shifts = _slide_shifts(pair.normals_a, pair.bc.shape, SLIDE_STEP)
        chosen += pair.moved(best_so_far, shifts, "slide", o)
    chosen = [h for h in chosen if _in_region(region, h)]  # refined and slid: still near?
    found = _Found(hyps, chosen, region)
    info["n_candidates"] = len(hyps)
    if not found.chosen:
        best_any = max((h.score for h in hyps), default=0.0)
        raise _Refused(
            f"no hypothesis overlaps enough (need {o.min_overlap:.0%} of b's wall cells on "
            f"a's known cells and {MIN_OVERLAP_CELLS} wall cells in all)",
            score=best_any,
            n_hypotheses=len(hyps),
        )
    return found


def _credit_shared_space(hs: list[_Hypothesis], pair: _Pair, o: SemanticOptions) -> None:
    """Count the known space the maps share under each pose, and its credit in the ranking."""
    for h in hs:
        h.shared_cells = pair.shared(h.T)
        h.shared_bonus = SHARED_WEIGHT * h.shared_cells


@dataclass
class _Judged:
    """The best pose and its rivals, with what the decision rules (:data:`_RULES`) read.

    The rules also write: each records its figure in ``info`` (so the order of ``_RULES`` is the
    order of those keys), and b's wall structures, labelled at most once, are shared by the
    lone-pin and object rules (:meth:`structures_b`).
    """

    pair: _Pair
    found: _Found
    o: SemanticOptions
    info: dict[str, Any]
    best: _Hypothesis
    T_full: Transform  # the best pose between the full maps (b's cells -> a's)
    consistency: float
    rivals: list[_Hypothesis]
    common: dict[str, Any]  # the figures every refusal from here on carries
    # what the result's evidence reports (full-map poses): every ranked hypothesis, and the
    # rivals (the rules may add one: a repeat's moved pose)
    hypotheses: tuple[WeighedPose, ...] = ()
    rival_poses: list[WeighedPose] = field(default_factory=list)
    # the noise-aware verifier the consistency test used (walls SLACK_CELLS apart agree)
    noisy: Verifier | None = None
    _structures_b: Structures | None = None
    _structures_a: Structures | None = None
    _by_structure: ByStructure | None = None

    def evidence(self) -> MergeEvidence:
        """The typed facts of this judgement (:attr:`MergeResult.evidence`)."""
        return MergeEvidence(
            best=WeighedPose(self.T_full, self.agreement),
            consistency=self.consistency,
            consistent=bool(self.consistency >= self.o.min_score),
            rivals=tuple(self.rival_poses),
            hypotheses=self.hypotheses,
        )

    @property
    def agreement(self) -> Agreement:
        """The best pose's agreement (the verifier's, on up to ``MAX_SAMPLES`` wall cells)."""
        assert self.best.agreement is not None
        return self.best.agreement

    @property
    def common_m2(self) -> float:
        """The known space the maps share under the best pose, m^2."""
        return self.best.shared_cells * self.o.resolution_m**2

    @property
    def prior_given(self) -> bool:
        """Whether the caller gave a :class:`PosePrior` (its region bounds every pose)."""
        return self.found.region is not None

    def away(self, h: _Hypothesis) -> float:
        """Mean displacement (cells) of b's walls between ``h``'s pose and the best's."""
        return _mean_shift(h.T, self.best.T, self.pair.verify.points_b)

    def structures_b(self) -> Structures:
        """b's wall structures (connected groups of wall cells), labelled once."""
        if self._structures_b is None:
            self._structures_b = Structures(self.pair.codes_b)
        return self._structures_b

    def structures_a(self) -> Structures:
        """a's wall structures, labelled once."""
        if self._structures_a is None:
            self._structures_a = Structures(self.pair.codes_a)
        return self._structures_a

    def by_structure(self) -> ByStructure:
        """Each map's agreement under the best pose by structure, computed once for the two
        object rules."""
        if self._by_structure is None:
            self._by_structure = agreement_by_structure(
                self.pair.codes_a,
                self.pair.codes_b,
                self.best.T,
                structures_b=self.structures_b(),
                structures_a=self.structures_a(),
            )
        return self._by_structure


def _perfect(h: _Hypothesis, verify: Verifier, o: SemanticOptions) -> bool:
    """A far pose the maps do not contradict at all, on ``rival_perfect_cells`` of wall or more:
    a rival however much more the best explains (b's rest may lie in a's unseen part)."""
    assert h.agreement is not None
    return (
        o.rival_perfect_cells > 0
        and h.agreement.disagree == 0
        and h.agreement.agree * verify.cells_per_sample >= o.rival_perfect_cells
    )


def _judge(pair: _Pair, found: _Found, o: SemanticOptions, info: dict[str, Any]) -> _Judged:
    """Step 5's ranking: the best pose (consistency-polished when that makes it consistent)
    and its rivals, recorded in ``info``."""
    # The best explains the most: agreement minus heavily weighted disagreement, plus a credit
    # for known space both maps share under the pose (one wall cell's worth per
    # ``1 / shared_weight`` shared cells). Ranking by the index alone ties every small,
    # uncontradicted overlap (a corner on a corner) with the truth; ranking by walls alone
    # prefers a long wall laid on a's wall from outside (b's rooms over a's unknown) to the
    # true pose whose rooms coincide but whose walls a bent map blurs.
    chosen = found.chosen
    _credit_shared_space(chosen, pair, o)  # their poses moved in the refinement: count again
    chosen.sort(key=lambda h: -h.evidence)
    hypotheses = []
    for h in chosen:
        assert h.agreement is not None
        hypotheses.append(WeighedPose(pair.to_full(h.T), h.agreement))
    info["hypotheses"] = [tuple(p) for p in hypotheses]
    best = chosen[0]
    assert best.agreement is not None
    verify = pair.verify
    # Consistency of the best pose with the maps' noise: walls within ``slack`` more cells of
    # the other map's walls (a wall seen from its two sides, a wall eroded by grazing beams) and
    # lone contradictions (groups under ``min_run`` cells) are noise, not evidence against it.
    consistent_v = Verifier(pair.codes_a, pair.codes_b, max_samples=MAX_SAMPLES, slack=SLACK_CELLS)
    best_consistency = consistent_v.structured(best.T, MIN_RUN_CELLS).score
    if best_consistency < o.min_score and CONSISTENCY_POLISH:
        # the best pose as ICP left it may sit a cell and a degree from where the maps agree
        # within their noise; the nearby pose that does is the same place, not a new match
        # (the rival test below still judges it, with its own agreement)
        T_pol, c_pol = _consistency_polish(
            best.T,
            consistent_v,
            lambda T: consistent_v.structured(T, MIN_RUN_CELLS).score,
            tuple(np.asarray(verify.points_b, dtype=np.float64).mean(axis=0)),
            start=best_consistency,
        )
        # The polished pose stands in for the best, so it must pass the overlap floor every
        # hypothesis passed: a pose that buys consistency by leaving b's walls over a's unknown
        # is not the same match (a twin-wing pose went from 18 % to 8 % of b's walls and was
        # accepted, wrongly; docs/merging_history.md, "The consistency polish keeps the
        # overlap floor").
        # The best of 125 nearby poses is consistent by selection as well as by place, so it
        # must clear the bar by a margin (a twin-wing pose polished from 0.949 to 0.971 was
        # merged 123 cells off; the correct polished poses of the bench reach 0.98-1.00).
        if c_pol >= o.min_score + POLISH_MARGIN and verify.overlap_ok(
            ag_pol := verify(T_pol), o.min_overlap, MIN_OVERLAP_CELLS
        ):
            best.T, best_consistency = T_pol, c_pol
            best.agreement = ag_pol
            best.shared_cells = pair.shared(T_pol)
            info["consistency_polished"] = True

    # A rival is a pose far from the best that explains a comparable part of the maps: at least
    # ``RIVAL_SUPPORT`` of the best's agreeing wall cells. A pose that matches only a corner (b
    # mostly hanging over a's unknown) agrees perfectly with little, which any corridor end or
    # room corner does by coincidence; it does not make the best ambiguous. (Walls only, not the
    # shared-space credit of the ranking: with the credit, a pose laid on one of a warehouse's
    # repeated rack rows lost its rivals and merged wrongly in the loop; docs/merging_history.md,
    # the second pass.)
    # A far pose the maps do not contradict at all, on 12.5 m of wall or more, is a rival
    # however much more the best explains: b's rest may lie in a's unseen part (a warehouse
    # shelf row explained 3x as much as the truth and was merged 342 cells off).
    pts = verify.points_b
    rivals = [
        h
        for h in chosen[1:]
        if _mean_shift(h.T, best.T, pts) >= FAR_CELLS
        and h.agreement is not None
        and (h.agreement.agree >= RIVAL_SUPPORT * best.agreement.agree or _perfect(h, verify, o))
    ]
    rivals.sort(key=lambda h: not _perfect(h, verify, o))  # a perfect rival is judged (stable)
    # every rival's pose (b's cells -> a's), for a caller that weighs them over time (the tracker)
    rival_poses = []
    for h in rivals:
        assert h.agreement is not None
        rival_poses.append(WeighedPose(pair.to_full(h.T), h.agreement))
    info["rivals"] = [p.transform for p in rival_poses]
    info["rival_agreements"] = [p.agreement for p in rival_poses]
    info["best_agreement"] = best.agreement
    info["runner_up_agreement"] = rivals[0].agreement if rivals else None
    T_full = pair.to_full(best.T)
    info["best_transform"] = T_full  # the pose judged below, also when refused
    info["best_source"] = best.source
    info["consistency"] = best_consistency
    info["consistent"] = bool(best_consistency >= o.min_score)
    common = dict(
        n_hypotheses=len(found.tried),
        runner_up_score=rivals[0].score if rivals else None,
        overlap_cells=int(best.agreement.overlap * verify.cells_per_sample),
    )
    return _Judged(
        pair,
        found,
        o,
        info,
        best,
        T_full,
        best_consistency,
        rivals,
        common,
        hypotheses=tuple(hypotheses),
        rival_poses=rival_poses,
        noisy=consistent_v,
    )


# --- 5. the decision: each rule returns the reason to refuse, or None; run in this order ---


def _rule_consistent(j: _Judged) -> str | None:
    """The maps contradict each other under the best pose no more than their noise explains."""
    if j.consistency < j.o.min_score:
        return (
            f"best hypothesis agrees only {j.consistency:.2f} < {j.o.min_score:.2f} "
            f"(raw index {j.best.score:.2f})"
        )
    return None


def _rule_unique(j: _Judged) -> str | None:
    """The rival judged (a perfect one if any, else the one explaining most; see :func:`_judge`)
    is beaten by ``min_margin`` in index and ``MIN_EVIDENCE_CELLS`` more contradicting wall
    cells, or ruled out by one object the maps show (a notch, a post:
    ``MIN_EVIDENCE_CELLS`` wall cells in one group), while noise contradicts in scattered
    cells (docs/merging_history.md, "A rival ruled out by one object")."""
    o, best = j.o, j.best
    if not j.rivals:
        return None
    if o.place_test and RIVALS_CONTRADICTED:
        for h in j.rivals:
            if _uncontradicted(j, h):
                return (
                    f"ambiguous: a pose {j.away(h):.0f} cells away that the maps do not "
                    f"contradict beyond their noise (raw index {h.score:.3f} against the best's "
                    f"{best.score:.3f})"
                )
    rival = j.rivals[0]
    margin = best.score - rival.score
    evidence = 0
    if rival.agreement is not None:
        evidence = int(
            (rival.agreement.disagree - j.agreement.disagree) * j.pair.verify.cells_per_sample
        )
    if margin >= o.min_margin and evidence >= MIN_EVIDENCE_CELLS:
        return None
    structure = rival_structure(j.pair.verify, best.T, rival.T, margin, o)
    j.info["rival_structure_cells"] = structure
    if structure >= MIN_EVIDENCE_CELLS:
        return None
    return (
        f"ambiguous: best {best.score:.3f} vs {rival.score:.3f} for a pose "
        f"{j.away(rival):.0f} cells away "
        f"(margin {margin:.3f}, {evidence} more disagreeing wall cells"
        + (f", the largest object ruling it out {structure}" if STRUCTURE_TEST else "")
        + f"; need {o.min_margin} and {MIN_EVIDENCE_CELLS}"
        + (f", or one object of {MIN_EVIDENCE_CELLS})" if STRUCTURE_TEST else ")")
    )


def _rule_shared_space(j: _Judged) -> str | None:
    """The maps share ``min_common_m2`` of known space under the best pose."""
    common_m2 = j.common_m2
    j.info["common_known_m2"] = common_m2
    if common_m2 < j.o.min_common_m2:
        return (
            f"the maps share only {common_m2:.1f} m^2 of known space under the best pose; need "
            f"{j.o.min_common_m2:.0f} m^2 (a match no larger than a room may be a look-alike room)"
        )
    return None


def _rule_room_match(j: _Judged) -> str | None:
    """Without a prior, a room's worth of shared space is little evidence when each map holds
    several rooms: one of the others may be its look-alike (a guess of the pose rules those
    out). Refused under ``room_match_m2`` and under ``ROOM_MATCH_SHARE`` of the smaller map."""
    o = j.o
    common_m2 = j.common_m2
    if j.prior_given or common_m2 >= o.room_match_m2:
        return None
    smaller_m2 = j.pair.shared.smaller_known_cells() * o.resolution_m**2
    if common_m2 >= ROOM_MATCH_SHARE * smaller_m2:
        return None
    return (
        f"the maps share only {common_m2:.1f} m^2 of known space under the best pose, "
        f"under {ROOM_MATCH_SHARE:g} of the smaller map's {smaller_m2:.1f} m^2 (need "
        f"{o.room_match_m2:g} m^2 or that share): a match the size of a room, in maps "
        "of several rooms, may be one room's look-alike"
    )


def _rule_pinned(j: _Judged) -> str | None:
    """The agreeing walls pin the pose along them (``min_cross_cells``; or, with
    ``slide_test``, the maps contradict every slide of it), and not only through one small thing
    (``LONE_PIN_TEST``): a slide along one straight wall or a corridor explains the maps as
    well as the pose, and a post beside rack sides matches every aisle's post."""
    o, pair, info = j.o, j.pair, j.info
    if o.min_cross_cells <= 0:
        return None
    pins = PinTerms(pair.wall_a, pair.wall_b, j.best.T, pair.icp.cells_b)
    cross = pins.cross(False)
    if abs(cross - o.min_cross_cells) < CROSS_GUARD_CELLS or cross < o.min_cross_cells:
        # near the threshold, or refused (its figure is printed): the CPU-independent value
        cross = pins.cross(True)
    cross = round(cross, 2)
    info["cross_cells"] = cross
    pinned, slid = cross >= o.min_cross_cells, None
    if not pinned and o.slide_test:
        # few walls cross the slide direction, but door gaps and wall ends may still pin the
        # pose: slide it along that direction and ask whether the maps contradict every slide
        slid = _standing_slide(pair.verify, j.best, pair.wall_a, pair.wall_b, pair.icp.cells_b, o)
        info["slide_rival_cells"] = slid
        pinned = slid is None
    if not pinned:
        slide = "" if slid is None else f"; a slide of {slid:+g} cells stands as a rival"
        return (
            f"the agreeing walls do not pin the pose along them (cross support {cross:.1f} "
            f"wall cells < {o.min_cross_cells:g}{slide}): a slide along one wall or "
            "corridor fits as well"
        )
    if not LONE_PIN_TEST or cross < o.min_cross_cells:  # pinned by the slide test only
        return None
    small_cells = OBJECT_CLUTTER_M / o.resolution_m
    lone = pins.lone_pin(False, j.structures_b(), small_cells)
    if lone is not None and lone[0] < o.min_cross_cells + CROSS_GUARD_CELLS:
        # near the threshold or under it: the CPU-independent value decides
        lone = pins.lone_pin(True, j.structures_b(), small_cells)
    if lone is None or round(lone[0], 2) >= o.min_cross_cells:
        return None
    info["lone_pin_cells"] = round(lone[0], 2)
    return (
        f"the agreeing walls pin the pose along them only through one small thing "
        f"(cross support {lone[0]:.1f} wall cells without its {lone[1]}; need "
        f"{o.min_cross_cells:g}): a post or a box beside a wall matches every copy "
        "of it"
    )


def _rule_beyond_places(j: _Judged) -> str | None:
    """Without a prior, the agreement outside the places of each map that hold most of it (a
    room, a hall, a stretch of corridor: :mod:`~mrexplore.merge.places`) pins the pose by
    itself (``min_cross_cells``): a pose whose evidence lies in one repeated unit of either map
    may lay it on its twin, whatever its size; it waits until other places agree too
    (``place_test``)."""
    o, pair = j.o, j.pair
    if not o.place_test or j.prior_given or o.min_cross_cells <= 0:
        return None
    support_a, support_b = beyond_places(pair.ac, pair.bc, pair.codes_a, pair.codes_b, j.best.T)
    j.info["beyond_place_cells"] = (round(support_a, 2), round(support_b, 2))
    if min(support_a, support_b) >= o.min_cross_cells:
        return None
    which = "a" if support_a < support_b else "b"
    return (
        f"the agreement beyond the {PLACES_LEFT_OUT} places of map {which} that hold most of it "
        f"pins the pose by only {min(support_a, support_b):.1f} wall cells (need "
        f"{o.min_cross_cells:g}): the match may lay one room on its twin; waiting for other "
        "places to agree"
    )


def _rule_ruled_out(j: _Judged) -> str | None:
    """In the loop, no thing either map shows lands, without a cell of it agreeing, on floor
    the other map has seen open: a repeated room's agreement does not outvote the one thing
    that differs (``THINGS_RULED_OUT``)."""
    if not (j.o.place_test and THINGS_RULED_OUT):
        return None
    cells = ruled_out_structure(
        j.pair.codes_a,
        j.pair.codes_b,
        j.best.T,
        SLACK_CELLS,
        structures_b=j.structures_b(),
        structures_a=j.structures_a(),
    )
    j.info["ruled_out_cells"] = cells
    if cells < MIN_RUN_CELLS:
        return None
    return (
        f"a thing one map shows lands on floor the other map has seen open ({cells} wall "
        "cells, none agreeing): the maps are not of the same place under this pose"
    )


def _rule_wall_area(j: _Judged) -> str | None:
    """The agreeing walls cover ``min_wall_area_m2``: one object fits every copy of it."""
    o = j.o
    if o.min_wall_area_m2 <= 0:
        return None
    area_m2 = agreeing_area(j.pair.codes_a, j.pair.codes_b, j.best.T) * o.resolution_m**2
    j.info["wall_area_m2"] = area_m2
    if area_m2 < o.min_wall_area_m2:
        return (
            f"the walls that agree fit in {area_m2:.2f} m^2 (need {o.min_wall_area_m2:g} "
            "m^2): one object, a rack or a pillar, fits every copy of it"
        )
    return None


def _rule_one_object(j: _Judged) -> str | None:
    """Unless the agreeing walls lie (95 %) on one structure in each map whose larger one fits
    in a rectangle under ``min_object_m2``: a rack seen whole matches every copy of it, and the
    copies may lie where neither map looked."""
    o = j.o
    if o.min_object_m2 <= 0:
        return None
    object_cells = one_object_area(
        j.pair.codes_a, j.pair.codes_b, j.best.T, by_structure=j.by_structure()
    )
    if object_cells is None:
        return None
    object_m2 = object_cells * o.resolution_m**2
    j.info["object_m2"] = object_m2
    if object_m2 < o.min_object_m2:
        return (
            f"the walls that agree lie on one structure in each map, no larger than "
            f"{object_m2:.1f} m^2 (need {o.min_object_m2:g} m^2): an object matches "
            "every copy of it, seen or not"
        )
    return None


def _rule_outside_object(j: _Judged) -> str | None:
    """The agreeing walls are not, in either map, one structure seen from outside plus at most
    one small thing (``OBJECT_HULL_FREE``): a rack and its post are what a warehouse repeats."""
    o = j.o
    if OBJECT_HULL_FREE <= 0 or not outside_object(
        j.pair.codes_a,
        j.pair.codes_b,
        j.best.T,
        OBJECT_HULL_FREE,
        clutter_cells=OBJECT_CLUTTER_M / o.resolution_m,
        min_width_cells=OBJECT_WIDTH_M / o.resolution_m,
        by_structure=j.by_structure(),
    ):
        return None
    j.info["outside_object"] = True
    return (
        "the walls that agree lie, in one map, on one object seen from outside (free "
        f"space fills under {OBJECT_HULL_FREE:g} of its hull) and at most one small "
        "thing beside it: a rack and its post match every copy of them, seen or not"
    )


def _uncontradicted(j: _Judged, h: _Hypothesis) -> bool:
    """The maps agree with pose ``h`` within their noise (the consistency test the best pose
    passed, with its verifier: walls ``SLACK_CELLS`` apart agree, contradictions count in
    groups of ``MIN_RUN_CELLS``)."""
    assert j.noisy is not None
    return bool(j.noisy.structured(h.T, MIN_RUN_CELLS).score >= j.o.min_score)


def _rule_repeats(j: _Judged) -> str | None:
    """The poses that move the best by either map's ``REPEAT_RIVALS`` strongest repeats are
    beaten as rivals are: a copy the coarse search never tried. Last, since it costs an
    autocorrelation of each map (~2 ms) and only a pose about to be merged needs it; it only
    refuses, never picks the best."""
    o, pair, best = j.o, j.pair, j.best
    if REPEAT_RIVALS <= 0:
        return None
    shifts = _repeat_moves(
        best.T,
        repeat_shifts(pair.ac, SCALE, REPEAT_RIVALS, 4.0 * SCALE),
        repeat_shifts(pair.bc, SCALE, REPEAT_RIVALS, 4.0 * SCALE),
    )
    for h in pair.moved(best, shifts, "repeat", o) if len(shifts) else []:
        assert h.agreement is not None
        away = j.away(h)
        if (
            not j.found.in_prior(h)
            or away < FAR_CELLS
            or not (
                _perfect(h, pair.verify, o)
                or stands_as_rival(j.agreement, h.agreement, pair.verify.cells_per_sample, o)
                or (o.place_test and RIVALS_CONTRADICTED and _uncontradicted(j, h))
            )
        ):
            continue
        moved = WeighedPose(pair.to_full(h.T), h.agreement)
        j.rival_poses.append(moved)
        j.info["rivals"].append(moved.transform)
        j.info["rival_agreements"].append(moved.agreement)
        return (
            f"ambiguous: the maps repeat: best {best.score:.3f} vs {h.score:.3f} for a pose "
            f"{away:.0f} cells away, moved by a repeat of a map "
            f"({h.agreement.agree} agreeing, {h.agreement.disagree} disagreeing wall "
            f"samples against {j.agreement.agree} and {j.agreement.disagree})"
        )
    return None


#: The decision rules, in the order they are asked (the cheap and the most telling first; the
#: repeats last, as they cost most and only a pose about to be merged needs them).
_RULES: tuple[Callable[[_Judged], str | None], ...] = (
    _rule_consistent,
    _rule_unique,
    _rule_shared_space,
    _rule_room_match,
    _rule_pinned,
    _rule_beyond_places,
    _rule_ruled_out,
    _rule_wall_area,
    _rule_one_object,
    _rule_outside_object,
    _rule_repeats,
)


def _accepted(
    a: Int8Grid, b: Int8Grid, pair: _Pair, j: _Judged, detector: str | None, t0: float
) -> MergeResult:
    """The merge under the best pose, with b's wall cells that land on a's walls: the point
    pairs that support it (for figures)."""
    T_full = j.T_full
    pb_full = pair.icp.pb + np.array([pair.box_b[2], pair.box_b[0]])
    pa_full = np.stack(map_points(pb_full, T_full), axis=1)  # not BLAS: same cells on any CPU
    c, r = np.rint(pa_full[:, 0]).astype(np.int64), np.rint(pa_full[:, 1]).astype(np.int64)
    inside = (c >= 0) & (c < a.shape[1]) & (r >= 0) & (r < a.shape[0])
    on_wall = np.zeros(len(c), dtype=bool)
    on_wall[inside] = a[r[inside], c[inside]] >= OCCUPIED_THRESHOLD
    sel = np.flatnonzero(on_wall)
    sel = sel[:: max(1, sel.size // 60)]
    matches = np.concatenate([pa_full[sel], pb_full[sel]], axis=1)
    return MergeResult.accepted(
        a,
        b,
        T_full,
        method="semantic",
        t0=t0,
        score=j.best.score,
        detector=detector,
        matches=matches,
        info=j.info,
        evidence=j.evidence(),
        **j.common,
    )
