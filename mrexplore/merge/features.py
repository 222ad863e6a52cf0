"""Keypoint detectors on occupancy maps (as gray images), behind one function.

``sift`` stands in for the paper's SURF: SURF is patented ("non-free") and absent from
OpenCV's PyPI builds; SIFT is its closest available relative. ``akaze`` is refused by
:func:`mrexplore.merge.common.detector_check` because the OpenCV 5.0 build has no AKAZE.

**Deterministic order.** OpenCV computes corner responses with CPU-specific SIMD code (SSE,
AVX2, AVX-512) whose rounding differs in the last bits, and sorts them with an unstable sort:
the same map gave a different keypoint order on two machines, and so a different match.
Every detector here therefore returns its points in one stated order: responses
rounded to :data:`RESPONSE_DIGITS` significant digits relative to the strongest, strongest
first, ties by row then column. Harris and Shi-Tomasi selection (``goodFeaturesToTrack``'s
rule) is done here, on that order, rather than inside OpenCV.
"""

from __future__ import annotations

from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

#: cv2 seen as untyped: the type stubs shipped with OpenCV 5.0 lack the feature factories
#: (``SIFT_create``, ``ORB_create``) although the module has them.
_cv2: Any = cv2

#: OpenCV's ORB/SIFT pyramids fail on images smaller than their border (an OpenCV assertion, not
#: a clear error): tiny maps are padded to this size with the unknown grey, which is flat and
#: adds no keypoint; coordinates are unchanged (padding on the right and bottom).
MIN_IMAGE = 64

#: Responses are compared after rounding to this many significant digits (relative to the
#: strongest response): far coarser than SIMD rounding noise (~1e-7 in float32), far finer than
#: any difference that means something.
RESPONSE_DIGITS = 5

#: goodFeaturesToTrack's parameters, stated explicitly (OpenCV's defaults could change).
QUALITY_LEVEL = 0.01
MIN_DISTANCE = 3.0
BLOCK_SIZE = 3
HARRIS_K = 0.04


def _pad_small(gray: NDArray[np.uint8]) -> NDArray[np.uint8]:
    h, w = gray.shape
    if h >= MIN_IMAGE and w >= MIN_IMAGE:
        return gray
    out = np.full((max(h, MIN_IMAGE), max(w, MIN_IMAGE)), 205, dtype=np.uint8)
    out[:h, :w] = gray
    return out


def stable_order(response: NDArray[Any], pts: NDArray[np.float64]) -> NDArray[np.intp]:
    """Indices sorting points by response (strongest first), ties by row then column.

    ``response`` (K,), ``pts`` (K, 2) ``(col, row)``. Responses are rounded to
    :data:`RESPONSE_DIGITS` significant digits of the largest magnitude first, so two machines
    whose SIMD rounding differs in the last bits still agree.

    >>> pts = np.array([[0.0, 0.0], [5.0, 1.0], [3.0, 1.0]])
    >>> stable_order(np.array([1.0, 2.0, 2.0 + 1e-9]), pts).tolist()  # a tie: column decides
    [2, 1, 0]
    """
    if len(response) == 0:
        return np.zeros(0, dtype=np.intp)
    r = np.asarray(response, dtype=np.float64)
    scale = float(np.abs(r).max()) or 1.0
    q = np.rint(r / scale * 10.0**RESPONSE_DIGITS)
    # lexsort: last key is primary
    return np.lexsort((pts[:, 0], pts[:, 1], -q)).astype(np.intp)


def _corners(gray: NDArray[np.uint8], n: int, harris: bool) -> NDArray[np.float64]:
    """goodFeaturesToTrack's rule with a stated order: local maxima (3x3) of the corner
    response above ``QUALITY_LEVEL`` x the strongest, strongest first, each at least
    ``MIN_DISTANCE`` cells from every stronger one kept, at most ``n``."""
    img = gray.astype(np.float32)
    if harris:
        resp = np.asarray(_cv2.cornerHarris(img, BLOCK_SIZE, 3, HARRIS_K), dtype=np.float32)
    else:
        resp = np.asarray(_cv2.cornerMinEigenVal(img, BLOCK_SIZE, ksize=3), dtype=np.float32)
    top = float(resp.max()) if resp.size else 0.0
    if not top > 0.0:
        return np.zeros((0, 2))
    resp[resp < QUALITY_LEVEL * top] = 0.0
    peak = (resp > 0.0) & (resp >= cv2.dilate(resp, np.ones((3, 3), np.uint8)))
    peak[[0, -1], :] = False  # OpenCV skips the one-cell border too
    peak[:, [0, -1]] = False
    rows, cols = np.nonzero(peak)
    pts = np.stack([cols, rows], axis=1).astype(np.float64)
    pts = pts[stable_order(resp[rows, cols], pts)]
    kept: list[int] = []
    d2 = MIN_DISTANCE * MIN_DISTANCE
    for k in range(len(pts)):
        if kept:
            dd = pts[kept] - pts[k]
            if float((dd * dd).sum(axis=1).min()) < d2:
                continue
        kept.append(k)
        if len(kept) >= n:
            break
    return pts[kept]


def detect_points(gray: NDArray[np.uint8], detector: str, n: int) -> NDArray[np.float64]:
    """The best ``n`` keypoints of ``gray`` (H, W) uint8, as (K, 2) float64 ``(col, row)``, K <= n.

    ``harris`` / ``shi-tomasi`` follow ``cv2.goodFeaturesToTrack`` (quality level 0.01, minimum
    distance 3 cells, block 3, Harris k 0.04); ``fast``, ``sift``, ``orb`` keep the ``n``
    strongest responses. Order: :func:`stable_order`. Never raises on featureless images:
    returns (0, 2).
    """
    if detector in ("harris", "shi-tomasi"):
        return _corners(gray, int(n), harris=detector == "harris")
    kps = _keypoint_detector(detector).detect(gray, None)
    if not kps:
        return np.zeros((0, 2))
    pts = np.array([k.pt for k in kps], dtype=np.float64)
    order = stable_order(np.array([k.response for k in kps]), pts)
    return pts[order[: int(n)]]


def _keypoint_detector(detector: str) -> cv2.Feature2D:
    if detector == "fast":
        return _cv2.FastFeatureDetector_create(threshold=20, nonmaxSuppression=True)
    if detector == "sift":
        return _cv2.SIFT_create()
    if detector == "orb":
        return _cv2.ORB_create(nfeatures=2000)
    raise ValueError(f"no keypoint detector {detector!r}")  # guarded by detector_check


def detect_and_describe(
    gray: NDArray[np.uint8], detector: str, n: int
) -> tuple[NDArray[np.float64], NDArray[np.generic] | None, int]:
    """Keypoints (K, 2) ``(col, row)`` and descriptors (K, D), plus the OpenCV norm to match them.

    ``sift`` keypoints get SIFT descriptors (L2); every other detector's keypoints get ORB
    descriptors (Hamming), as m-explore pairs detectors with a binary descriptor. Keypoints come
    in :func:`stable_order`, so matching and RANSAC see the same input on every machine.
    Returns descriptors None when there is no keypoint.
    """
    gray = _pad_small(gray)
    if detector == "sift":
        sift = _cv2.SIFT_create(nfeatures=int(n))
        kps, desc = sift.detectAndCompute(gray, None)
        norm = cv2.NORM_L2
    else:
        orb = _cv2.ORB_create(nfeatures=int(n))
        if detector == "orb":
            kps, desc = orb.detectAndCompute(gray, None)
        else:
            pts = detect_points(gray, detector, n)
            kps = [cv2.KeyPoint(float(c), float(r), 31.0) for c, r in pts]
            kps, desc = orb.compute(gray, kps) if kps else ([], None)
        norm = cv2.NORM_HAMMING
    if desc is None or len(kps) == 0:
        return np.zeros((0, 2)), None, norm
    pts = np.array([k.pt for k in kps], dtype=np.float64)
    order = stable_order(np.array([k.response for k in kps]), pts)
    return pts[order], np.asarray(desc)[order], norm
