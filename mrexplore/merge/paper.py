"""The seed paper's semantic map merging, faithfully (Durdu & Korkmaz 2019, section 3.3).

Algorithm 1 (trusted points): detect the best ``n`` keypoints of each map; around each, an
``f x f`` window L; the point is *trusted* when L holds few unknown cells.

Eq. (4) as printed reads ``#L(x,y)|unknown / f <= f`` which cannot be meant literally (it is true
for every window, since #unknown <= f^2). We read it as the *share* of unknown cells in the
window being at most a threshold: ``#unknown(L) / f^2 <= max_unknown`` (default 0.3, the value
used in the design notes' earlier measurement). Cells of the window outside the map count as
unknown: the robot did not see them either.

Eq. (5): ``f[px] = c_w[m] / r[m/px] + alpha[px]`` (:func:`window_size`), 3 m at 0.05 m/cell -> 60.

Algorithm 2: the gradients (d/dx, d/dy; 3x3 Sobel) of the windows around the trusted points of
both maps; the Pearson correlation C(i, j) of every pair (i in a, j in b), computed as ONE
matrix product of z-scored, flattened windows (:func:`correlation_matrix`); the arg-max pair gives
the match when C >= ``min_correlation`` ("positively high"; default 0.6), else "No matching".
The result is a translation only, as in the paper: the method cannot recover a rotation.

Ties: windows with identical content (two wall stubs) correlate equally, to the last bit or
within BLAS rounding, and an arg-max then picks whichever comes first, which differed between
machines. The paper does not say; our rule (:func:`best_pair`): pairs within
:data:`TIE_TOL` of the best are tied, and the tie goes to the translation that the most pairs
with C >= ``min_correlation`` agree with (within one cell); then to the smaller translation.
"""

from __future__ import annotations

import time
from dataclasses import dataclass
from typing import Any, ClassVar

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import ConfigError
from mrexplore.grid import UNKNOWN, Int8Grid
from mrexplore.merge.common import (
    MergeResult,
    Verifier,
    detector_check,
    to_gray,
    translation,
)
from mrexplore.merge.features import detect_points
from mrexplore.options import Options, integer, number, option

PAPER_DETECTORS: tuple[str, ...] = ("harris", "shi-tomasi", "fast", "sift", "orb")

#: Correlations closer than this to the best one count as a tie (BLAS rounding is ~1e-15).
TIE_TOL = 1e-9


def window_size(
    corridor_width_m: float = 3.0, resolution_m: float = 0.05, alpha_px: int = 0
) -> int:
    """Eq. (5): the filter (window) size ``f`` in cells.

    ``f = corridor_width_m / resolution_m + alpha_px``; the paper uses a 3 m corridor at
    0.05 m/cell (f = 60) and a confidence interval alpha of +-10 px.

    >>> window_size(3.0, 0.05)
    60
    >>> window_size(3.0, 0.05, alpha_px=-10)
    50
    """
    if not (corridor_width_m > 0 and resolution_m > 0):
        raise ConfigError(
            f"window_size: corridor width ({corridor_width_m} m) and resolution "
            f"({resolution_m} m/cell) must be positive"
        )
    f = round(corridor_width_m / resolution_m) + int(alpha_px)
    if f < 3:
        raise ConfigError(f"window_size: f = {f} cells is too small (need >= 3)")
    return f


def _window_index(points: NDArray[np.float64], f: int) -> tuple[NDArray[np.intp], NDArray[np.intp]]:
    """Row and column index arrays (K, f, f) of the f x f windows centred on ``points`` in an
    image padded by ``f`` on every side (so every window exists)."""
    c = np.rint(points[:, 0]).astype(np.intp) + f - f // 2
    r = np.rint(points[:, 1]).astype(np.intp) + f - f // 2
    off = np.arange(f)
    rows = r[:, None, None] + off[None, :, None]
    cols = c[:, None, None] + off[None, None, :]
    return np.broadcast_to(rows, (len(points), f, f)), np.broadcast_to(cols, (len(points), f, f))


def unknown_share(grid: Int8Grid, points: NDArray[np.float64], f: int) -> NDArray[np.float64]:
    """Share (K,) of unknown cells in the f x f window around each point (outside = unknown)."""
    if len(points) == 0:
        return np.zeros(0)
    unknown = np.pad(grid == UNKNOWN, f, constant_values=True)
    rows, cols = _window_index(points, f)
    return np.asarray(unknown[rows, cols].reshape(len(points), -1).mean(axis=1), dtype=np.float64)


def trusted_points(
    grid: Int8Grid, points: NDArray[np.float64], f: int, max_unknown: float = 0.3
) -> NDArray[np.bool_]:
    """Algorithm 1 / Eq. (4): mask (K,) of points whose window's unknown share is at most
    ``max_unknown``."""
    return unknown_share(grid, points, f) <= max_unknown


def gradient_windows(grid: Int8Grid, points: NDArray[np.float64], f: int) -> NDArray[np.float64]:
    """Algorithm 2 lines 4-5: the (d/dx, d/dy) Sobel gradients of the f x f windows, flattened.

    Returns (K, 2 f^2) float64. Gradients are taken on the map's gray image scaled to [0, 1]
    (free 1, unknown 0.8, occupied 0), as the paper works on the map picture.
    """
    img = to_gray(grid).astype(np.float32) / 255.0
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3)
    gx = np.pad(gx, f)
    gy = np.pad(gy, f)
    rows, cols = _window_index(points, f)
    k = len(points)
    return np.concatenate(
        [gx[rows, cols].reshape(k, -1), gy[rows, cols].reshape(k, -1)], axis=1
    ).astype(np.float64)


def correlation_matrix(X: NDArray[np.float64], Y: NDArray[np.float64]) -> NDArray[np.float64]:
    """Pearson correlation of every row of X (Ka, D) with every row of Y (Kb, D): (Ka, Kb).

    One matrix product of z-scored rows: ``C = Zx @ Zy.T / D``. A constant row (no gradient at
    all) has no defined correlation; it gets 0 so it can never be the arg-max.
    """

    def z(M: NDArray[np.float64]) -> NDArray[np.float64]:
        mu = M.mean(axis=1, keepdims=True)
        sd = M.std(axis=1, keepdims=True)
        out = np.zeros_like(M)
        ok = sd[:, 0] > 1e-12
        out[ok] = (M[ok] - mu[ok]) / sd[ok]
        return out

    if X.shape[1] != Y.shape[1]:
        raise ValueError(f"correlation_matrix: row lengths differ ({X.shape[1]} vs {Y.shape[1]})")
    return np.asarray(z(X) @ z(Y).T / X.shape[1], dtype=np.float64)


def best_pair(
    C: NDArray[np.float64], ta: NDArray[np.float64], tb: NDArray[np.float64], min_corr: float
) -> tuple[int, int]:
    """The arg-max pair ``(i, j)`` of C (Ka, Kb) with ties broken by a stated rule.

    Tied pairs (within :data:`TIE_TOL` of the best) are ranked by support: how many pairs with
    ``C >= min_corr`` give a translation ``ta[i] - tb[j]`` within one cell of theirs; then by the
    translation's length, then its (x, y). Independent of keypoint order.

    >>> C = np.array([[1.0, 1.0], [0.0, 0.9]])
    >>> ta = np.array([[10.0, 0.0], [20.0, 5.0]]); tb = np.array([[0.0, 0.0], [10.0, 5.0]])
    >>> best_pair(C, ta, tb, 0.6)  # (0, 0) and (1, 1) agree on (10, 0); (0, 1) gives (0, -5)
    (0, 0)
    """
    best = float(C.max())
    ti, tj = np.nonzero(best - TIE_TOL <= C)
    if len(ti) == 1:
        return int(ti[0]), int(tj[0])
    si, sj = np.nonzero(min(min_corr, best - TIE_TOL) <= C)
    t_tied = ta[ti] - tb[tj]  # (T, 2)
    t_all = ta[si] - tb[sj]  # (S, 2)
    support = (np.abs(t_tied[:, None, :] - t_all[None, :, :]).max(axis=2) <= 1.0).sum(axis=1)
    length = np.hypot(t_tied[:, 0], t_tied[:, 1])
    k = np.lexsort((t_tied[:, 1], t_tied[:, 0], length, -support))[0]
    return int(ti[k]), int(tj[k])


@dataclass(frozen=True)
class PaperOptions(Options):
    """The options of :func:`merge_paper` (documented there)."""

    owner: ClassVar[str] = "merge_maps(method='paper')"
    detector: str | None = option(None, detector_check(PAPER_DETECTORS))
    window: int = option(window_size(), integer(3, 1001))
    n_features: int = option(200, integer(1, 100_000))
    max_unknown: float = option(0.3, number(0.0, 1.0))
    min_correlation: float = option(0.6, number(-1.0, 1.0))


def merge_paper(a: Int8Grid, b: Int8Grid, **options: Any) -> MergeResult:
    """The paper's method (translation only). Options (all validated):

    - ``detector``: harris (default) / shi-tomasi / fast / sift (stands in for SURF) / orb.
    - ``window``: f in cells (default :func:`window_size` () = 60).
    - ``n_features``: best n keypoints per map (default 200).
    - ``max_unknown``: Eq. (4) threshold on the unknown share of a window (default 0.3).
    - ``min_correlation``: "positively high" threshold on the best C (default 0.6).
    """
    t0 = time.perf_counter()
    o = PaperOptions.from_kwargs(**options)
    detector, f, n = o.detector or "harris", o.window, o.n_features
    max_unknown, min_corr = o.max_unknown, o.min_correlation

    def refuse(reason: str, **kw: Any) -> MergeResult:
        return MergeResult.refused(reason, method="paper", t0=t0, detector=detector, **kw)

    pa = detect_points(to_gray(a), detector, n)
    pb = detect_points(to_gray(b), detector, n)
    ta = pa[trusted_points(a, pa, f, max_unknown)]
    tb = pb[trusted_points(b, pb, f, max_unknown)]
    if len(ta) == 0 or len(tb) == 0:
        return refuse(f"no trusted points (a: {len(ta)} of {len(pa)}, b: {len(tb)} of {len(pb)})")
    C = correlation_matrix(gradient_windows(a, ta, f), gradient_windows(b, tb, f))
    i, j = best_pair(C, ta, tb, min_corr)
    best = float(C[i, j])
    # the ten strongest pairs for the figure, in a stated order (C, then index)
    order = np.lexsort((np.arange(C.size), -C.ravel()))
    runner = float(C.flat[order[1]]) if C.size > 1 else None
    ii, jj = np.unravel_index(order[: min(10, C.size)], C.shape)
    matches = np.concatenate([ta[ii], tb[jj]], axis=1)
    T = translation(*(ta[i] - tb[j]))
    score = Verifier(a, b)(T).score
    info = {"n_trusted": (len(ta), len(tb)), "n_points": (len(pa), len(pb)), "correlation": best}
    if best < min_corr:
        return refuse(
            f"no matching: best correlation {best:.2f} < {min_corr:.2f}",
            score=score,
            n_hypotheses=int(C.size),
            runner_up_score=runner,
            matches=matches,
            info=info,
        )
    return MergeResult.accepted(
        a,
        b,
        T,
        method="paper",
        t0=t0,
        score=score,
        detector=detector,
        n_hypotheses=int(C.size),
        runner_up_score=runner,
        matches=matches,
        info=info,
    )
