"""Coarse translation candidates of the semantic merger (its step 2): FFT cross-correlations
of the maps pooled to 1/scale give every translation's wall agreement and disagreement at once.
"""

from __future__ import annotations

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.grid import FREE_THRESHOLD, OCCUPIED_THRESHOLD, Int8Grid

# The compiled pooling and ratio score (None without numba); used while kernels.enabled().
_merging = kernels.load("merging")

F32 = NDArray[np.float32]
F64 = NDArray[np.float64]

#: Coarse scores are rounded to this many decimals (the linear score's terms are multiples of
#: ``w_free`` and ``w_disagree``; the ratio score's are exact counts) so that the FFT's last-bit
#: noise, which differs between CPUs, cannot reorder two peaks.
SCORE_DECIMALS = 6


def _pool(grid: Int8Grid, s: int) -> tuple[F32, F32]:
    """(wall, free) block maps at 1/s: wall = block holds a wall; free = all known and free.

    The masks are block-averaged by ``cv2.resize(INTER_AREA)`` (exact block means: the padded
    size is a multiple of s), far cheaper than numpy reductions over a 4-D view. As uint8 0/255
    masks for s <= 16: a wall among s^2 cells averages >= 255 / 256, which rounds above 0, and a
    block short of one free cell <= 255 - 255 / 256, which rounds below 255; larger blocks as
    float32 0/1 masks. With the kernels on, :func:`mrexplore.kernels.merging.pool_blocks`
    computes the same any / all in one pass (this path is its test oracle).
    """
    if kernels.enabled():
        assert _merging is not None
        wall_k, free_k = _merging.pool_blocks(
            np.ascontiguousarray(grid).view(np.uint8), s, OCCUPIED_THRESHOLD, FREE_THRESHOLD
        )
        return wall_k, free_k
    h, w = grid.shape
    H, W = -(-h // s), -(-w // s)
    cells = grid.view(np.uint8)  # unknown (-1) is 255, above every occupancy value (<= 100)
    if (H * s, W * s) != (h, w):  # padded with unknown, which is neither wall nor free
        cells = np.asarray(
            cv2.copyMakeBorder(cells, 0, H * s - h, 0, W * s - w, cv2.BORDER_CONSTANT, value=255),
            dtype=np.uint8,
        )
    masks = cv2.inRange(cells, OCCUPIED_THRESHOLD, 127), cv2.inRange(cells, 0, FREE_THRESHOLD)
    small = s <= 16
    means = []
    for mask in masks:
        block = mask if small else mask.astype(np.float32) / np.float32(255.0)
        means.append(cv2.resize(block, (W, H), interpolation=cv2.INTER_AREA))
    full = 255.0 if small else 1.0
    wall = means[0] > (0.5 if small else 1e-6)
    free = means[1] > full - (0.5 if small else 1e-4)
    return wall.astype(np.float32), free.astype(np.float32)


def _dilate(img: F32) -> F32:
    return np.asarray(cv2.dilate(img, np.ones((3, 3), np.uint8)), dtype=np.float32)


def _spectrum(img: NDArray[np.floating], shape: tuple[int, int]) -> F64:
    """The DFT of ``img`` zero-padded to ``shape``, as OpenCV's packed real spectrum (CCS), in
    float64. OpenCV's transform is 2-3x faster than numpy's ``rfft2`` at 375-720 cells a side
    (its float32 transform is slower still); ``nonzeroRows`` skips the padding rows."""
    padded = np.zeros(shape, dtype=np.float64)
    padded[: img.shape[0], : img.shape[1]] = img
    return np.asarray(cv2.dft(padded, nonzeroRows=img.shape[0]), dtype=np.float64)


def _correlation(*pairs: tuple[F64, F64]) -> F64:
    """Circular cross-correlation ``sum_x a(x + t) b(x)`` summed over the (spectrum of a,
    spectrum of b) ``pairs``: products with b conjugated, one inverse transform."""
    products = [np.asarray(cv2.mulSpectrums(fa, fb, 0, conjB=True), np.float64) for fa, fb in pairs]
    total = products[0]
    for product in products[1:]:
        total = total + product
    return np.asarray(cv2.idft(total, flags=cv2.DFT_REAL_OUTPUT | cv2.DFT_SCALE), np.float64)


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
        self._wa = wa
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

    def peaks(self, b: Int8Grid | None, k: int, nms: int = 2) -> list[tuple[float, float, float]]:
        """The ``k`` best separated translations ``(dc, dr, S)`` (cells, full resolution) that map
        b's cells onto a's cells. ``b=None``: a itself (its repeats, with the ratio score; b's
        two spectra are then a's own, not computed again)."""
        s = self.s
        shape = (self.H, self.W)
        if b is None:
            if self.p == 0:
                raise ValueError("CoarseMatcher.peaks(None, ...) needs the ratio score (p > 0)")
            wb, FB1, FB2 = self._wa, self.FAWW, self.FAF
        else:
            wb, fb = _pool(b, s)
            FB1 = _spectrum(wb, shape)
            if self.p > 0:
                FB2 = _spectrum(fb * (1.0 - _dilate(wb)), shape)
        if self.p > 0:
            # agreement and disagreement apart: rank by agree * (agree / (agree + dis))^p, which
            # favours clean alignments over large but contradicted overlaps (repetitive shelves)
            # both are counts of 0/1 blocks: rounded, they are exact on every CPU (the FFT's
            # last bits are not), and so is the score computed from them
            ag_raw = _correlation((self.FAW, FB1))
            ds_raw = _correlation((self.FAF, FB1), (self.FAWW, FB2))
            if self.p == 2.0 and kernels.enabled():  # the default power: one compiled pass
                assert _merging is not None
                return self._top(_merging.ratio_scores(ag_raw, ds_raw), wb.shape, k, nms)
            ag = np.maximum(np.rint(ag_raw), 0.0)
            ds = np.maximum(np.rint(ds_raw), 0.0)
            # S = agree * (agree / (agree + dis + 2))^p, in place (the same operations in the
            # same order as the plain expression, so the same bits)
            ds += ag
            ds += 2.0
            np.divide(ag, ds, out=ds)
            np.power(ds, self.p, out=ds)
            np.multiply(ag, ds, out=ds)
            S = np.round(ds, SCORE_DECIMALS, out=ds)
            return self._top(S.astype(np.float32), wb.shape, k, nms)
        FB2 = _spectrum(fb, shape)
        S = np.round(_correlation((self.FA1, FB1), (self.FA2, FB2)), SCORE_DECIMALS)
        return self._top(S.astype(np.float32), wb.shape, k, nms)

    def _top(
        self, S: F32, b_shape: tuple[int, int], k: int, nms: int
    ) -> list[tuple[float, float, float]]:
        """The k best local maxima of a circular score map as full-resolution translations."""
        s = self.s
        # Only translations where the maps can overlap: t in (-hb, ha) x (-wb, wa), circular.
        hb, wbw = b_shape
        # (np.roll's window, copied once: rows -hb..ha-1 and columns -wb..wa-1, circularly)
        S = np.concatenate((S[self.H - hb :], S[: self.ha]), axis=0)
        S = np.ascontiguousarray(np.concatenate((S[:, self.W - wbw :], S[:, : self.wa]), axis=1))
        mx = cv2.dilate(S, np.ones((2 * nms + 1, 2 * nms + 1), np.uint8))
        cand = np.flatnonzero((mx <= S).ravel() & (S.ravel() > 0))
        if cand.size == 0:
            return []
        # best first, ties in raster order: numpy's default sort orders ties differently on
        # different CPUs (its SIMD sorts), and ties are common (scores of small block counts)
        top = cand[np.lexsort((cand, -S.ravel()[cand]))[:k]]
        rows, cols = np.unravel_index(top, S.shape)
        # Block t -> cells: b's block j covers cells [s j, s j + s); same for a, so t * s.
        return [
            (float((c - wbw) * s), float((r - hb) * s), float(S[r, c]))
            for r, c in zip(rows, cols, strict=True)
        ]
