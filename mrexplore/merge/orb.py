"""The baseline: m-explore's ``multirobot_map_merge`` pipeline (``combine_grids/merging_pipeline``).

Features (ORB by default; m-explore prefers AKAZE, which this OpenCV build lacks), 2-NN
descriptor matching with Lowe's ratio test, RANSAC ``cv2.estimateAffinePartial2D`` (rotation,
translation and uniform scale, as m-explore), and m-explore's confidence
``inliers / (8 + 0.3 * matches)``. The transform is accepted when the confidence is at least
``min_confidence``; the default is **1.0**, m-explore's ``estimation_confidence`` default (its
ROS 2 port ships 0.6). Like m-explore it never checks that the maps agree: its ``score`` is
computed for reporting only and plays no part in the decision. Expect wrong merges on
look-alike rooms.
"""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from typing import Any, ClassVar

import cv2
import numpy as np

from mrexplore.grid import Int8Grid
from mrexplore.merge.common import MergeResult, Verifier, detector_check, to_gray
from mrexplore.merge.features import detect_and_describe
from mrexplore.options import Options, integer, number, option

ORB_DETECTORS: tuple[str, ...] = ("orb", "sift", "harris", "shi-tomasi", "fast")


@dataclass(frozen=True)
class OrbOptions(Options):
    """The options of :func:`merge_orb` (documented there)."""

    owner: ClassVar[str] = "merge_maps(method='orb')"
    detector: str | None = option(None, detector_check(ORB_DETECTORS))
    n_features: int = option(1000, integer(2, 100_000))
    ratio: float = option(0.8, number(0.0, 1.0))
    ransac_px: float = option(3.0, number(0.0, math.inf))
    min_confidence: float = option(1.0, number(0.0, math.inf))


def merge_orb(a: Int8Grid, b: Int8Grid, **options: Any) -> MergeResult:
    """m-explore-style merge. Options (all validated):

    - ``detector``: orb (default) / sift / harris / shi-tomasi / fast (non-ORB/SIFT keypoints get
      ORB descriptors).
    - ``n_features``: keypoints per map (default 1000).
    - ``ratio``: Lowe's ratio test threshold (default 0.8).
    - ``ransac_px``: RANSAC reprojection threshold in cells (default 3.0).
    - ``min_confidence``: acceptance threshold on inliers / (8 + 0.3 matches) (default 1.0).
    """
    t0 = time.perf_counter()
    o = OrbOptions.from_kwargs(**options)
    detector, n, ratio = o.detector or "orb", o.n_features, o.ratio
    ransac_px, min_conf = o.ransac_px, o.min_confidence

    def refuse(reason: str, **kw: Any) -> MergeResult:
        return MergeResult.refused(reason, method="orb", t0=t0, detector=detector, **kw)

    pa, da, norm = detect_and_describe(to_gray(a), detector, n)
    pb, db, _ = detect_and_describe(to_gray(b), detector, n)
    if da is None or db is None or len(pa) < 2 or len(pb) < 2:
        return refuse(f"too few features (a: {len(pa)}, b: {len(pb)})")
    knn = cv2.BFMatcher(norm).knnMatch(np.asarray(db), np.asarray(da), k=2)
    good = [m[0] for m in knn if len(m) == 2 and m[0].distance < ratio * m[1].distance]
    if len(good) < 3:
        return refuse(f"too few matches after the ratio test ({len(good)})")
    src = np.array([pb[m.queryIdx] for m in good], dtype=np.float64)
    dst = np.array([pa[m.trainIdx] for m in good], dtype=np.float64)
    M, inl = cv2.estimateAffinePartial2D(
        src,
        dst,
        method=cv2.RANSAC,
        ransacReprojThreshold=ransac_px,
        maxIters=2000,
        confidence=0.99,
    )
    matches = np.concatenate([dst, src], axis=1)
    if M is None or inl is None:
        return refuse("RANSAC found no transform", matches=matches, n_hypotheses=len(good))
    if not np.isfinite(M).all() or abs(float(np.linalg.det(M[:, :2]))) < 1e-6:
        return refuse("RANSAC returned a degenerate transform", matches=matches)
    inliers = inl.ravel().astype(bool)
    conf = float(inliers.sum()) / (8.0 + 0.3 * len(good))
    T = np.vstack([M, [0.0, 0.0, 1.0]]).astype(np.float64)
    score = Verifier(a, b)(T).score
    info = {"confidence": conf, "n_matches": len(good), "n_inliers": int(inliers.sum())}
    if conf < min_conf:
        return refuse(
            f"confidence {conf:.2f} < {min_conf:.2f} ({int(inliers.sum())} inliers of {len(good)})",
            score=score,
            matches=matches[inliers],
            n_hypotheses=len(good),
            info=info,
        )
    return MergeResult.accepted(
        a,
        b,
        T,
        method="orb",
        t0=t0,
        score=score,
        detector=detector,
        n_hypotheses=len(good),
        matches=matches[inliers],
        info=info,
    )
