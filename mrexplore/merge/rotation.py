"""Rotation candidates of the semantic merger (its step 1): the relative rotation of two maps
from their rotation spectra (modulo 90 degrees, half-degree bins): the directions of straight
wall segments (probabilistic Hough, length-weighted) and of blurred wall gradients. The peaks of
each pair's circular cross-correlation give theta0 + k 90 degrees.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray


def wall_normals(
    wall: NDArray[np.bool_], sigma: float = 2.5
) -> tuple[NDArray[np.float32], NDArray[np.float32]]:
    """The wall-normal directions (degrees, (-180, 180]) and gradient magnitudes (N,) of the
    cells whose blurred-wall gradient is at least 5 % of the largest: the input of
    :func:`orientation_histogram`, computed once per map when several histograms need it."""
    img = cv2.GaussianBlur(wall.astype(np.float32), (0, 0), sigma)
    gx = cv2.Sobel(img, cv2.CV_32F, 1, 0, ksize=3)
    gy = cv2.Sobel(img, cv2.CV_32F, 0, 1, ksize=3)
    mag = np.hypot(gx, gy)
    top = float(mag.max()) if mag.size else 0.0
    keep = mag > 0.05 * top if top > 0 else mag > 0
    return np.degrees(np.arctan2(gy[keep], gx[keep])), mag[keep]


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
    half of our lidar map pairs, 2.5 on a quarter; see docs/merging.md).
    """
    return direction_histogram(wall_normals(wall, sigma), bins, period_deg)


def direction_histogram(
    normals: tuple[NDArray[np.float32], NDArray[np.float32]],
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


def segment_histogram(
    wall: NDArray[np.bool_], bins: int = 90, period_deg: float = 90.0, min_length: int = 15
) -> NDArray[np.float64]:
    """Histogram (bins,) of the directions of straight wall segments modulo ``period_deg``,
    each weighted by its length and spread over its angular uncertainty (one cell over its
    length, at least a quarter degree), normalised to sum 1.

    Segments come from a probabilistic Hough transform of the wall cells (at least
    ``min_length`` cells long): the angle of a long segment, taken from its end points, does not
    suffer the staircase bias of local gradients, so this histogram contains the relative
    rotation of two lidar maps to within 2 degrees where the gradient one often misses by 2-3.
    """
    hist = np.zeros(bins)
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
    ang = np.degrees(np.arctan2(dy, dx)) % period_deg
    sd = np.maximum(np.degrees(np.arctan2(1.0, length)), 0.25)
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
    return [p * 90.0 / bins for p in _circular_peaks(R, k, 0.5, max(1, bins // 11))]


def rotation_candidates(
    wall_a: NDArray[np.bool_],
    wall_b: NDArray[np.bool_],
    max_peaks: int = 2,
    step_deg: float = 0.0,
    normals_a: tuple[NDArray[np.float32], NDArray[np.float32]] | None = None,
) -> list[float]:
    """Candidate rotations (radians, in (-pi, pi]) of b relative to a, best first.

    Two rotation spectra (mod 90 degrees): wall-normal directions from blurred gradients
    (:func:`orientation_histogram`) and directions of straight wall segments
    (:func:`segment_histogram`). The peaks of each pair's circular cross-correlation, up to
    ``max_peaks`` per spectrum and merged when within a degree, each yield d + k 90, k = 0..3:
    the verifier decides which. ``step_deg > 0`` appends a uniform sweep (maps with no straight
    walls; the ICP refinement then closes the remaining gap). ``normals_a``: a's
    :func:`wall_normals`, when the caller has them.
    """
    bins = 180  # half-degree bins
    peaks = _relative_peaks_deg(
        segment_histogram(wall_a, bins), segment_histogram(wall_b, bins), max_peaks
    )
    for p in _relative_peaks_deg(
        direction_histogram(wall_normals(wall_a) if normals_a is None else normals_a, bins),
        orientation_histogram(wall_b, bins),
        max_peaks,
    ):
        if all(min(abs(p - q) % 90.0, 90.0 - abs(p - q) % 90.0) > 1.0 for q in peaks):
            peaks.append(p)
    out: list[float] = []
    for p in peaks:
        out += [np.radians(p + 90.0 * k) for k in range(4)]
    if step_deg > 0:
        out += [float(x) for x in np.radians(np.arange(0.0, 360.0, step_deg))]
    return [float(np.arctan2(np.sin(t), np.cos(t))) for t in out]
