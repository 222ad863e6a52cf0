"""Keypoint detectors on occupancy maps (as gray images), behind one function.

``sift`` stands in for the paper's SURF: SURF is patented ("non-free") and absent from
OpenCV's PyPI builds; SIFT is its closest available relative. ``akaze`` is refused by
:func:`mrexplore.merge.common.check_detector` because the OpenCV 5.0 build has no AKAZE.
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


def _pad_small(gray: NDArray[np.uint8]) -> NDArray[np.uint8]:
    h, w = gray.shape
    if h >= MIN_IMAGE and w >= MIN_IMAGE:
        return gray
    out = np.full((max(h, MIN_IMAGE), max(w, MIN_IMAGE)), 205, dtype=np.uint8)
    out[:h, :w] = gray
    return out


def detect_points(gray: NDArray[np.uint8], detector: str, n: int) -> NDArray[np.float64]:
    """The best ``n`` keypoints of ``gray`` (H, W) uint8, as (K, 2) float64 ``(col, row)``, K <= n.

    ``harris`` / ``shi-tomasi`` use ``cv2.goodFeaturesToTrack`` with / without
    ``useHarrisDetector`` (quality level 0.01, minimum distance 3 cells); ``fast``, ``sift``,
    ``orb`` keep the ``n`` strongest responses. Never raises on featureless images: returns (0, 2).
    """
    if detector in ("harris", "shi-tomasi"):
        pts = cv2.goodFeaturesToTrack(
            gray,
            maxCorners=int(n),
            qualityLevel=0.01,
            minDistance=3,
            blockSize=3,
            useHarrisDetector=detector == "harris",
            k=0.04,
        )
        if pts is None:
            return np.zeros((0, 2))
        return np.asarray(pts, dtype=np.float64).reshape(-1, 2)
    kps = _keypoint_detector(detector).detect(gray, None)
    kps = sorted(kps, key=lambda k: -k.response)[: int(n)]
    if not kps:
        return np.zeros((0, 2))
    return np.array([k.pt for k in kps], dtype=np.float64)


def _keypoint_detector(detector: str) -> cv2.Feature2D:
    if detector == "fast":
        return _cv2.FastFeatureDetector_create(threshold=20)
    if detector == "sift":
        return _cv2.SIFT_create()
    if detector == "orb":
        return _cv2.ORB_create(nfeatures=2000)
    raise ValueError(f"no keypoint detector {detector!r}")  # guarded by check_detector


def detect_and_describe(
    gray: NDArray[np.uint8], detector: str, n: int
) -> tuple[NDArray[np.float64], NDArray[np.generic] | None, int]:
    """Keypoints (K, 2) ``(col, row)`` and descriptors (K, D), plus the OpenCV norm to match them.

    ``sift`` keypoints get SIFT descriptors (L2); every other detector's keypoints get ORB
    descriptors (Hamming), as m-explore pairs detectors with a binary descriptor.
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
    return np.array([k.pt for k in kps], dtype=np.float64), desc, norm
