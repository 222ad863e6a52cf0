"""Rotation candidates of the semantic merger (its step 1): the relative rotation of two maps
from their rotation spectra (modulo 90 degrees, half-degree bins): the directions of straight
wall segments (probabilistic Hough, length-weighted) and of blurred wall gradients. The peaks of
each pair's circular cross-correlation give theta0 + k 90 degrees.

**The same candidates on every CPU.** OpenCV and numpy pick SIMD code at run time (SSE, AVX2,
AVX-512) whose rounding differs in the last bits; a candidate that moves by 1e-5 degrees
rotates b onto a few different cells (nearest neighbour), and the search then ends elsewhere
(traced in the loop; docs/merging.md). So every continuous quantity on the way to a candidate
is exact or rounded to a grid far coarser than that noise: the blurred gradients are integer
sums (an integer Gaussian kernel, exact in float32 in any order), the directions are rounded to
:data:`ANGLE_DECIMALS`, the spectra's correlations to :data:`SPECTRUM_DIGITS` relative digits,
and the candidates to :data:`CANDIDATE_DECIMALS`, then turned into radians in the degree domain.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

#: Wall directions are rounded to this many decimals of a degree before they are binned: far
#: coarser than the last-bit noise of ``arctan2`` between SIMD paths (~1e-14 degrees).
ANGLE_DECIMALS = 6

#: Spectrum correlations are rounded to this many digits relative to their largest value
#: before their peaks are picked and refined.
SPECTRUM_DIGITS = 9

#: Rotation candidates are rounded to this many decimals of a degree (0.01: ICP and the
#: rotation polish refine them; their own accuracy is a few tenths of a degree).
CANDIDATE_DECIMALS = 2

#: Fixed-point scale of the integer Gaussian kernel of :func:`wall_normals`: small enough that
#: the blur (at most 2^10 per pass) and its Sobel gradients (at most 2^23) are integers that
#: float32 holds exactly, so OpenCV's SIMD filters give the same bits on every CPU.
_KERNEL_ONE = 1 << 10


def _integer_gaussian(sigma: float) -> NDArray[np.float32]:
    """OpenCV's Gaussian kernel for ``sigma`` (its float size rule: 8 sigma + 1 taps, odd) in
    fixed point: integers summing to about 2^10, as float32 (exact in any order)."""
    ksize = round(sigma * 8 + 1) | 1
    k = np.rint(cv2.getGaussianKernel(ksize, sigma, cv2.CV_64F) * _KERNEL_ONE)
    k = k[k > 0]  # the zero taps at the ends cost time and add nothing
    return np.asarray(k, dtype=np.float32).reshape(-1, 1)


def wall_normals(
    wall: NDArray[np.bool_], sigma: float = 2.5
) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
    """The wall-normal directions (degrees, (-180, 180], rounded to :data:`ANGLE_DECIMALS`) and
    gradient magnitudes (N,) of the cells whose blurred-wall gradient is at least 5 % of the
    largest: the input of :func:`orientation_histogram`, computed once per map when several
    histograms need it.

    The blur (``sigma`` cells, an integer kernel) and the Sobel gradients are integer sums,
    exact in float32 (below 2^24) whatever order a CPU adds them in; their squares are exact in
    float64, and the magnitudes use only IEEE square roots, so they are the same bits on every
    CPU too.
    """
    k = _integer_gaussian(sigma)
    img = cv2.sepFilter2D(wall.view(np.uint8), cv2.CV_32F, k, k)
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3)
    nz = np.flatnonzero((gx != 0) | (gy != 0))  # most cells lie far from any wall
    gxn, gyn = gx.ravel()[nz].astype(np.float64), gy.ravel()[nz].astype(np.float64)
    mag2 = gxn * gxn + gyn * gyn  # exact: integers below 2^47
    top2 = float(mag2.max()) if mag2.size else 0.0
    keep = mag2 > 0.0025 * top2  # magnitude above 5 % of the largest
    deg = np.round(np.degrees(np.arctan2(gyn[keep], gxn[keep])), ANGLE_DECIMALS)
    return np.asarray(deg, dtype=np.float64), np.sqrt(mag2[keep])


def orientation_histogram(
    wall: NDArray[np.bool_], bins: int = 90, period_deg: float = 90.0, sigma: float = 2.5
) -> NDArray[np.float64]:
    """Histogram (bins,) of wall-normal directions modulo ``period_deg``, magnitude-weighted,
    normalised to sum 1 (zeros when there is no wall).

    Modulo 90 degrees, the two wall families of a Manhattan map fall in one peak, so the relative
    rotation mod 90 shows even when the two maps happen to hold mostly different families
    (a corridor along x in one, along y in the other). The walls are blurred first (``sigma``
    cells): the staircase of a wall drawn at an angle on the grid pulls local gradients towards
    the grid axes, and the wider the blur the less (sigma 1.5 left the peak 2-3 degrees off on
    half of our lidar map pairs, 2.5 on a quarter; see docs/merging_history.md).
    """
    return direction_histogram(wall_normals(wall, sigma), bins, period_deg)


def direction_histogram(
    normals: tuple[NDArray[np.float64], NDArray[np.float64]],
    bins: int = 90,
    period_deg: float = 90.0,
) -> NDArray[np.float64]:
    """:func:`orientation_histogram` from a map's :func:`wall_normals` (computed once when a
    merge needs several histograms of one map)."""
    deg, mag = normals
    ang = deg % period_deg
    idx = (ang * bins / period_deg).astype(np.int64) % bins
    hist = np.bincount(idx, weights=mag, minlength=bins)
    # A little circular smoothing so that a wall at 0.5 deg does not split between two bins.
    hist = 0.25 * np.roll(hist, 1) + 0.5 * hist + 0.25 * np.roll(hist, -1)
    s = hist.sum()
    return np.asarray(hist / s if s > 0 else hist, dtype=np.float64)


def pool_any(wall: NDArray[np.bool_], f: int) -> NDArray[np.bool_]:
    """``wall`` pooled ``f`` x ``f``: a block is a wall when any of its cells is (ceil(H / f),
    ceil(W / f)); ``f`` = 1 returns ``wall``. Exact for f <= 16 (a uint8 block mean of one
    255 among f^2 cells is still above 0)."""
    if f <= 1:
        return wall
    if f > 16:
        raise ValueError(f"pool_any: f must be <= 16, got {f}")
    h, w = wall.shape
    H, W = -(-h // f), -(-w // f)
    cells = cv2.copyMakeBorder(
        wall.view(np.uint8) * np.uint8(255),
        0,
        H * f - h,
        0,
        W * f - w,
        cv2.BORDER_CONSTANT,
        value=0,
    )
    return np.asarray(cv2.resize(cells, (W, H), interpolation=cv2.INTER_AREA) > 0)


def hough_pool(shape_a: tuple[int, int], shape_b: tuple[int, int], max_cells: int) -> int:
    """The pooling factor of :func:`segment_histogram` for two maps: 2 when the larger one has
    more than ``max_cells`` cells, else 1 (``max_cells`` 0: always 1). Never more than 2: walls
    pooled 3 x 3 put a 1000-cell floor's candidate 0.2 degrees off, and its merge was lost
    (docs/merging_history.md, "Speed, and large maps").

    >>> hough_pool((500, 500), (400, 600), 409_600), hough_pool((1000, 1000), (10, 10), 409_600)
    (1, 2)
    """
    cells = max(h * w for h, w in (shape_a, shape_b))
    return 2 if 0 < max_cells < cells else 1


def segment_histogram(
    wall: NDArray[np.bool_],
    bins: int = 90,
    period_deg: float = 90.0,
    min_length: int = 15,
    pool: int = 1,
) -> NDArray[np.float64]:
    """Histogram (bins,) of the directions of straight wall segments modulo ``period_deg``,
    each weighted by its length and spread over its angular uncertainty (one cell over its
    length, at least a quarter degree), normalised to sum 1.

    Segments come from a probabilistic Hough transform of the wall cells (at least
    ``min_length`` cells long): the angle of a long segment, taken from its end points, does not
    suffer the staircase bias of local gradients, so this histogram contains the relative
    rotation of two lidar maps to within 2 degrees where the gradient one often misses by 2-3.

    ``pool`` > 1 runs it on the walls pooled ``pool`` x ``pool`` (:func:`pool_any`; segments
    then ``min_length`` blocks long): the Hough transform's cost grows with the wall cells, and
    on a large map the walls are long enough for the coarser end points.
    """
    hist = np.zeros(bins)
    wall = pool_any(wall, pool)
    # Accumulator at half a degree: a quarter cost twice as much and found no more; a whole
    # degree lost 4 of 140 bench cases (the angle comes from the end points either way).
    lines = cv2.HoughLinesP(
        wall.view(np.uint8) * np.uint8(255),
        1,
        np.pi / 360,
        threshold=min_length,
        minLineLength=min_length,
        maxLineGap=2,
    )
    if lines is None:
        return hist
    seg = np.asarray(lines, dtype=np.float64).reshape(-1, 4)
    dx, dy = seg[:, 2] - seg[:, 0], seg[:, 3] - seg[:, 1]
    length = np.hypot(dx, dy)
    ang = np.round(np.degrees(np.arctan2(dy, dx)), ANGLE_DECIMALS) % period_deg
    sd = np.maximum(np.round(np.degrees(np.arctan2(1.0, length)), ANGLE_DECIMALS), 0.25)
    centres = (np.arange(bins) + 0.5) * period_deg / bins
    d = (centres[None, :] - ang[:, None] + period_deg / 2) % period_deg - period_deg / 2
    hist = (length[:, None] * np.exp(-0.5 * (d / sd[:, None]) ** 2)).sum(axis=0)
    s = hist.sum()
    return np.asarray(hist / s if s > 0 else hist, dtype=np.float64)


def _circular_peaks(
    R: NDArray[np.float64], max_peaks: int, min_rel: float, sep: int
) -> list[float]:
    """Up to ``max_peaks`` local maxima of the circular signal R (bin units, parabola-refined),
    each at least ``min_rel`` of the highest and ``sep`` bins from the others. Ties in R are
    taken in bin order (a stable sort), so the answer does not depend on the platform."""
    bins = R.size
    order = np.argsort(-R, kind="stable")
    peaks: list[float] = []
    for d in order:
        if len(peaks) >= max_peaks or R[d] <= 0 or R[d] < min_rel * R[order[0]]:
            break
        left, right = R[(d - 1) % bins], R[(d + 1) % bins]
        if R[d] < left or R[d] < right:
            continue
        if any(min(abs(d - p) % bins, bins - abs(d - p) % bins) < sep for p in peaks):
            continue
        den = left - 2 * R[d] + right
        frac = 0.5 * (left - right) / den if den < 0 else 0.0
        peaks.append(float(d) + float(np.clip(frac, -0.5, 0.5)))
    return peaks


def _relative_peaks_deg(ha: NDArray[np.float64], hb: NDArray[np.float64], k: int) -> list[float]:
    """Peaks (degrees, mod 90) of the circular cross-correlation of two mod-90 histograms."""
    bins = ha.size
    R = np.fft.irfft(np.fft.rfft(ha) * np.conj(np.fft.rfft(hb)), n=bins)  # sum ha(phi) hb(phi - d)
    top = float(np.abs(R).max())
    if top > 0:  # relative rounding: the peaks and their refinement then agree on every CPU
        R = np.round(R / top, SPECTRUM_DIGITS)
    return [
        round(p * 90.0 / bins, CANDIDATE_DECIMALS)
        for p in _circular_peaks(R, k, 0.5, max(1, bins // 11))
    ]


def rotation_candidates(
    wall_a: NDArray[np.bool_],
    wall_b: NDArray[np.bool_],
    max_peaks: int = 2,
    step_deg: float = 0.0,
    normals_a: tuple[NDArray[np.float64], NDArray[np.float64]] | None = None,
    hough_max_cells: int = 0,
) -> list[float]:
    """Candidate rotations (radians, in (-pi, pi]) of b relative to a, best first.

    Two rotation spectra (mod 90 degrees): wall-normal directions from blurred gradients
    (:func:`orientation_histogram`) and directions of straight wall segments
    (:func:`segment_histogram`). The peaks of each pair's circular cross-correlation, up to
    ``max_peaks`` per spectrum and merged when within a degree, each yield d + k 90, k = 0..3:
    the verifier decides which. ``step_deg > 0`` appends a uniform sweep (maps with no straight
    walls; the ICP refinement then closes the remaining gap). ``normals_a``: a's
    :func:`wall_normals`, when the caller has them. ``hough_max_cells`` > 0: the segments of
    maps larger than this many cells come from their walls pooled 2 x 2 (:func:`hough_pool`).
    """
    bins = 180  # half-degree bins
    f = hough_pool(wall_a.shape, wall_b.shape, hough_max_cells)
    peaks = _relative_peaks_deg(
        segment_histogram(wall_a, bins, pool=f), segment_histogram(wall_b, bins, pool=f), max_peaks
    )
    for p in _relative_peaks_deg(
        direction_histogram(wall_normals(wall_a) if normals_a is None else normals_a, bins),
        orientation_histogram(wall_b, bins),
        max_peaks,
    ):
        if all(min(abs(p - q) % 90.0, 90.0 - abs(p - q) % 90.0) > 1.0 for q in peaks):
            peaks.append(p)
    degrees = [p + 90.0 * k for p in peaks for k in range(4)]
    if step_deg > 0:
        degrees += [round(float(x), CANDIDATE_DECIMALS) for x in np.arange(0.0, 360.0, step_deg)]
    # wrapped to (-180, 180] in degrees, then converted: plain IEEE arithmetic, the same bits on
    # every CPU (numpy's vectorised sin, cos and arctan2 are not)
    return [math.radians(_wrap_deg(d)) for d in degrees]


def _wrap_deg(d: float) -> float:
    """``d`` degrees wrapped to (-180, 180].

    >>> _wrap_deg(270.0), _wrap_deg(-180.0), _wrap_deg(180.0)
    (-90.0, 180.0, 180.0)
    """
    w = math.fmod(d, 360.0)
    if w > 180.0:
        w -= 360.0
    elif w <= -180.0:
        w += 360.0
    return w
