"""Coarse translation candidates of the semantic merger (its step 2): FFT cross-correlations
of the maps pooled to 1/scale give every translation's wall agreement and disagreement at once.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore.grid import FREE_THRESHOLD, OCCUPIED_THRESHOLD, Int8Grid

F32 = NDArray[np.float32]


def _pool(grid: Int8Grid, s: int) -> tuple[F32, F32]:
    """(wall, free) block maps at 1/s: wall = block holds a wall; free = all known and free.

    Block means by ``cv2.resize(INTER_AREA)`` on the padded masks (exact block averages since
    the padded size is a multiple of s), far cheaper than numpy reductions over a 4-D view.
    """
    h, w = grid.shape
    H, W = -(-h // s), -(-w // s)
    wall = np.zeros((H * s, W * s), dtype=np.float32)
    free = np.zeros((H * s, W * s), dtype=np.float32)
    wall[:h, :w] = grid >= OCCUPIED_THRESHOLD
    free[:h, :w] = (grid >= 0) & (grid <= FREE_THRESHOLD)
    wm = cv2.resize(wall, (W, H), interpolation=cv2.INTER_AREA)
    fm = cv2.resize(free, (W, H), interpolation=cv2.INTER_AREA)
    return (wm > 1e-6).astype(np.float32), (fm > 1.0 - 1e-4).astype(np.float32)


def _dilate(img: F32) -> F32:
    return np.asarray(cv2.dilate(img, np.ones((3, 3), np.uint8)), dtype=np.float32)


def _spectrum(img: NDArray[np.floating], shape: tuple[int, int]) -> NDArray[np.complex128]:
    """``rfft2`` of ``img`` zero-padded to ``shape``, in float64: numpy's float32 transform is
    2-3x slower than its float64 one (measured at 300-625 cells a side), and less exact."""
    return np.fft.rfft2(np.asarray(img, dtype=np.float64), shape)


class CoarseMatcher:
    """FFT cross-correlation of a's pooled maps against any (rotated) b's pooled maps.

    With ``ratio_power`` p > 0 (the default of the method): ``agree(t)`` = b's wall blocks on or
    next to a's wall blocks, ``dis(t)`` = b's walls on a's free blocks plus b's free blocks on
    a's walls, and ``S = agree * (agree / (agree + dis + 2))^p``. With p = 0 the linear score
    ``S(t) = sum_x A1(x + t) B1(x) + A2(x + t) B2(x)`` with ``B1`` = b walls, ``B2`` = b free,
    ``A1 = dil(a walls) - a free`` (wall agreement with one block of tolerance, minus wall-in-free
    disagreement) and ``A2 = w_free * a free - a walls`` (a little free agreement, minus
    free-on-wall disagreement). a's spectra are computed once.
    """

    def __init__(
        self,
        a: Int8Grid,
        s: int,
        max_b_shape: tuple[int, int],
        w_free: float,
        w_dis: float = 1.0,
        ratio_power: float = 0.0,
    ) -> None:
        self.s = s
        self.p = ratio_power
        wa, fa = _pool(a, s)
        self.ha, self.wa = wa.shape
        hb = -(-max_b_shape[0] // s)
        wb = -(-max_b_shape[1] // s)
        self.H = cv2.getOptimalDFTSize(self.ha + hb)
        self.W = cv2.getOptimalDFTSize(self.wa + wb)
        if self.p == 0:  # the linear score's two spectra (the ratio score needs three others)
            self.FA1 = _spectrum(_dilate(wa) - w_dis * fa, (self.H, self.W))
            self.FA2 = _spectrum(w_free * fa - w_dis * wa, (self.H, self.W))
        else:
            self.FAW = _spectrum(_dilate(wa), (self.H, self.W))
            # free blocks next to a wall block do not count as disagreement: a translation
            # that is not a multiple of the block size shifts every wall by up to one block
            self.FAF = _spectrum(fa * (1.0 - _dilate(wa)), (self.H, self.W))
            self.FAWW = _spectrum(wa, (self.H, self.W))

    def peaks(self, b: Int8Grid, k: int, nms: int = 2) -> list[tuple[float, float, float]]:
        """The ``k`` best separated translations ``(dc, dr, S)`` (cells, full resolution) that map
        b's cells onto a's cells."""
        s = self.s
        wb, fb = _pool(b, s)
        FB1 = np.conj(_spectrum(wb, (self.H, self.W)))
        if self.p > 0:
            FB2 = np.conj(_spectrum(fb * (1.0 - _dilate(wb)), (self.H, self.W)))
            # agreement and disagreement apart: rank by agree * (agree / (agree + dis))^p, which
            # favours clean alignments over large but contradicted overlaps (repetitive shelves)
            ag = np.fft.irfft2(self.FAW * FB1, (self.H, self.W))
            ds = np.fft.irfft2(self.FAF * FB1 + self.FAWW * FB2, (self.H, self.W))
            ag = np.maximum(ag, 0.0)
            ds = np.maximum(ds, 0.0)
            S = (ag * (ag / (ag + ds + 2.0)) ** self.p).astype(np.float32)
            return self._top(S, wb.shape, k, nms)
        FB2 = np.conj(_spectrum(fb, (self.H, self.W)))
        S = np.fft.irfft2(self.FA1 * FB1 + self.FA2 * FB2, (self.H, self.W)).astype(np.float32)
        return self._top(S, wb.shape, k, nms)

    def _top(
        self, S: F32, b_shape: tuple[int, int], k: int, nms: int
    ) -> list[tuple[float, float, float]]:
        """The k best local maxima of a circular score map as full-resolution translations."""
        s = self.s
        # Only translations where the maps can overlap: t in (-hb, ha) x (-wb, wa), circular.
        hb, wbw = b_shape
        S = np.roll(S, (hb, wbw), axis=(0, 1))[: hb + self.ha, : wbw + self.wa]
        mx = cv2.dilate(S, np.ones((2 * nms + 1, 2 * nms + 1), np.uint8))
        cand = np.flatnonzero((mx <= S).ravel() & (S.ravel() > 0))
        if cand.size == 0:
            return []
        vals = S.ravel()[cand]
        top = cand[np.argsort(vals)[::-1][:k]]
        rows, cols = np.unravel_index(top, S.shape)
        # Block t -> cells: b's block j covers cells [s j, s j + s); same for a, so t * s.
        return [
            (float((c - wbw) * s), float((r - hb) * s), float(S[r, c]))
            for r, c in zip(rows, cols, strict=True)
        ]
