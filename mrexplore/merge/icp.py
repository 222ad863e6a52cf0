"""Wall ICP of the semantic merger (its step 3): trimmed point-to-point ICP of b's wall cells
onto a's nearest wall cells, compiled (:func:`mrexplore.kernels.merging.wall_icp`) with its
numpy reference.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.grid import Transform, make_transform
from mrexplore.merge.common import translation

# The compiled wall ICP (None without numba); used while mrexplore.kernels.enabled().
_merging = kernels.load("merging")


class WallICP:
    """Trimmed point-to-point ICP of b's wall cells onto a's nearest wall cells."""

    def __init__(
        self, wall_a: NDArray[np.bool_], wall_b: NDArray[np.bool_], max_points: int
    ) -> None:
        self.h, self.w = wall_a.shape
        _, labels = cv2.distanceTransformWithLabels(
            (~wall_a).astype(np.uint8), cv2.DIST_L2, 5, labelType=cv2.DIST_LABEL_PIXEL
        )
        # Labels number a's wall cells in row-major order starting at 1.
        rr, cc = np.nonzero(wall_a)
        self.lut = np.concatenate([[[0.0, 0.0]], np.stack([cc, rr], axis=1)]).astype(np.float64)
        self.labels = labels
        self.labels_flat = np.ascontiguousarray(labels.ravel(), dtype=np.int32)
        rb, cb = np.nonzero(wall_b)
        self.cells_b = (rb, cb)  # all of b's wall cells (row, col), row-major: for the caller
        if max_points and rb.size > max_points:
            stride = int(np.ceil(rb.size / max_points))
            rb, cb = rb[::stride], cb[::stride]
        self.pb = np.stack([cb, rb], axis=1).astype(np.float64)
        self.has_walls = rr.size > 0 and rb.size > 0

    def _points(self, n_points: int) -> NDArray[np.float64]:
        p = self.pb
        if n_points and p.shape[0] > n_points:
            p = p[:: int(np.ceil(p.shape[0] / n_points))]
        return p

    def __call__(self, T: Transform, iters: int, max_dist: float, n_points: int = 0) -> Transform:
        """Refine ``T`` (b cells -> a cells); pairs farther than ``max_dist`` cells are ignored.

        ``n_points > 0`` uses only about that many of b's wall cells (a cheap first polish).
        Runs the compiled :func:`mrexplore.kernels.merging.wall_icp` (10x faster than
        :meth:`reference`, the same formulas in numpy: its test oracle, and the path when the
        kernels are off).
        """
        if not self.has_walls:
            return T
        if not kernels.enabled():
            return self.reference(T, iters, max_dist, n_points)
        assert _merging is not None
        return np.asarray(
            _merging.wall_icp(
                np.ascontiguousarray(T, dtype=np.float64),
                np.ascontiguousarray(self._points(n_points)),
                self.labels_flat,
                self.lut,
                self.w,
                self.h,
                int(iters),
                float(max_dist),
            ),
            dtype=np.float64,
        )

    def reference(self, T: Transform, iters: int, max_dist: float, n_points: int = 0) -> Transform:
        """:meth:`__call__` in numpy (the oracle of the compiled kernel's tests)."""
        if not self.has_walls:
            return T
        p = self._points(n_points)
        px, py = p[:, 0], p[:, 1]
        labels = self.labels.ravel()
        lut_c, lut_r = self.lut[:, 0], self.lut[:, 1]
        w, h = self.w, self.h
        md2 = max_dist * max_dist
        for _ in range(iters):
            qx = T[0, 0] * px + T[0, 1] * py + T[0, 2]
            qy = T[1, 0] * px + T[1, 1] * py + T[1, 2]
            c = np.rint(qx).astype(np.int64)
            r = np.rint(qy).astype(np.int64)
            inside = (c >= 0) & (c < w) & (r >= 0) & (r < h)
            lab = labels[(r * w + c)[inside]]
            mx, my = lut_c[lab], lut_r[lab]
            keep = (qx[inside] - mx) ** 2 + (qy[inside] - my) ** 2 <= md2
            n = int(np.count_nonzero(keep))
            if n < 10:
                return T
            # Point-to-line step (Gauss-Newton on the distance to the nearest wall cell, i.e.
            # on a's distance field): unlike point-to-point ICP it does not stall when walls
            # slide along each other (a 2-cell offset across a long wall is fixed in one step).
            qxk, qyk = qx[inside][keep], qy[inside][keep]
            mx, my = mx[keep], my[keep]
            ex, ey = qxk - mx, qyk - my
            d = np.sqrt(ex * ex + ey * ey)
            ok = d > 1e-6
            if np.count_nonzero(ok) < 10:
                return T
            nx, ny, dd = ex[ok] / d[ok], ey[ok] / d[ok], d[ok]
            ux, uy = qxk[ok], qyk[ok]
            cx, cy = float(ux.mean()), float(uy.mean())
            J = np.empty((dd.size, 3))
            J[:, 0], J[:, 1] = nx, ny
            J[:, 2] = ny * (ux - cx) - nx * (uy - cy)
            # residual = distance to the nearest wall-cell centre, along the normal
            dtx, dty, dth = (
                float(x) for x in np.linalg.solve(J.T @ J + 1e-6 * np.eye(3), -(J.T @ dd))
            )
            step = (
                translation(cx + dtx, cy + dty)
                @ make_transform(dth, 0.0, 0.0)
                @ translation(-cx, -cy)
            )
            T_new = step @ T
            # nearest-cell residuals jitter at the sub-cell level: stop at 0.05 cell / 0.03 deg
            done = abs(dtx) + abs(dty) < 0.05 and abs(dth) < 5e-4
            T = T_new
            if done:
                break
        return T
