"""Each robot's own occupancy grid: log-odds, in the robot's own start frame.

A robot does not know the world: it maps into a canvas centred on where it started. The frame
is its start pose: origin at the start position, x along the start heading. The start position
sits at cell ``origin_cell = (c0, r0)``, so frame metres ``(x, y)`` are the continuous cell
``(c0 + x / res, r0 + y / res)`` (cell centres are integers, row 0 = lowest y). The simulator
chooses a canvas large enough for any start (see :func:`mrexplore.sim.canvas_for`).

Inverse sensor model (per scan): the cells a beam enters before its measured end are free
(``l_free``), the cell holding the end point is occupied (``l_occ``) when the beam hit; log-odds
are clamped to ``[l_min, l_max]``; every cell is updated at most once per scan, occupied winning
over free. The beams are traversed with :func:`mrexplore.traversal.traverse`, the same vectorised
grid traversal the sensor uses.

The int8 view (``-1/0/100``, :mod:`mrexplore.grid`) is kept up to date incrementally (only the
cells a scan touched), so :meth:`OccupancyMap.to_int8` is O(1) even on 1500 x 1500 canvases.

Two implementations of the update, chosen by :func:`mrexplore.kernels.enabled` at call time:
the compiled kernel :func:`mrexplore.kernels.sensing.map_update` (default; a per-scan stamp
array dedupes the cells) and the vectorised numpy path below (fallback and test oracle). With
:data:`NUMPY_TRAVERSE_DTYPE` = float64 the two give identical maps.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.errors import ConfigError, GridError
from mrexplore.grid import (
    FREE,
    FREE_THRESHOLD,
    OCCUPIED,
    OCCUPIED_THRESHOLD,
    UNKNOWN,
    MapChange,
)
from mrexplore.traversal import CORNER_EPS, SNAP_CELLS, traverse
from mrexplore.types import Box

#: Beams are traversed in two groups: those shorter than this many cells (most beams indoors)
#: with this many crossing slots, the long ones with as many as the longest needs.
SHORT_BEAM_CELLS: int = 24

#: The occupied end point is taken this far (cells) beyond the measured range, so a noise-free
#: range that ends exactly on a wall boundary lands in the wall cell, not the free one before.
_END_NUDGE_CELLS: float = 1e-3

#: Float type of the numpy path's per-slot positions (float32 is faster; float64 reproduces the
#: compiled kernel bit for bit, which the tests use).
NUMPY_TRAVERSE_DTYPE: type[np.floating] = np.float32

#: Default log-odds increments of a free and an occupied observation (see :class:`OccupancyMap`).
L_FREE_DEFAULT: float = -1.2
L_OCC_DEFAULT: float = 3.6

#: Headings whose beam directions each map keeps (see :meth:`OccupancyMap.beam_directions`).
_DIR_CACHE: int = 16

#: Cells an update lists as changed (:meth:`OccupancyMap.changed_cells`); beyond, only its box
#: tells (a scan changes ~100 cells once a robot has looked around, thousands in the first).
CHANGED_CELLS_LISTED: int = 4096

#: The per-scan stamps are uint16: scan ids wrap (and the stamps are cleared) before 2 id + 1
#: overflows.
_STAMP_WRAP: int = 32767

# The compiled update (None without numba); used while mrexplore.kernels.enabled().
_sensing = kernels.load("sensing")


@dataclass(frozen=True)
class MapRows:
    """The arrays an :class:`OccupancyMap` of ``H x W`` cells keeps its state in (all flat,
    C-contiguous): ``logodds`` float32 (H W), ``int8`` int8 (H W), ``stamp`` uint16 (H W) (the
    compiled update's per-scan stamps), ``bbox`` and ``changed`` int64 (4,) (inclusive boxes
    ``row0, row1, col0, col1``, ``row1 < 0`` for none), ``cells`` int64 (K + 1,) (the last
    update's changed cells: count, then flat indices; -1 for more than K)."""

    logodds: NDArray[np.float32]
    int8: NDArray[np.int8]
    stamp: NDArray[np.uint16]
    bbox: NDArray[np.int64]
    changed: NDArray[np.int64]
    cells: NDArray[np.int64]

    @staticmethod
    def allocate(h: int, w: int) -> MapRows:
        """Fresh arrays of an unobserved ``h x w`` map."""
        return MapStack.allocate(1, h, w).row(0)


@dataclass(frozen=True)
class MapStack:
    """The arrays of R maps of one canvas, stacked: row ``i`` of each is map ``i``'s
    :class:`MapRows`. The simulator keeps a team's own maps this way so that one compiled call
    (:func:`mrexplore.kernels.sensing.sense_world`) updates them all.

    Attributes:
        logodds: float32 (R, H W); int8: int8 (R, H W); stamp: uint16 (R, H W);
        bbox, changed: int64 (R, 4); cells: int64 (R, K + 1).
    """

    logodds: NDArray[np.float32]
    int8: NDArray[np.int8]
    stamp: NDArray[np.uint16]
    bbox: NDArray[np.int64]
    changed: NDArray[np.int64]
    cells: NDArray[np.int64]

    @staticmethod
    def allocate(n: int, h: int, w: int) -> MapStack:
        """Fresh arrays of ``n`` unobserved ``h x w`` maps."""
        none = np.array([0, -1, 0, -1], dtype=np.int64)
        return MapStack(
            logodds=np.zeros((n, h * w), dtype=np.float32),
            int8=np.full((n, h * w), UNKNOWN, dtype=np.int8),
            stamp=np.zeros((n, h * w), dtype=np.uint16),
            bbox=np.tile(none, (n, 1)),
            changed=np.tile(none, (n, 1)),
            cells=np.zeros((n, CHANGED_CELLS_LISTED + 1), dtype=np.int64),
        )

    def row(self, i: int) -> MapRows:
        """Map ``i``'s arrays (views)."""
        return MapRows(
            self.logodds[i],
            self.int8[i],
            self.stamp[i],
            self.bbox[i],
            self.changed[i],
            self.cells[i],
        )


class OccupancyMap:
    """A log-odds occupancy grid in one robot's own start frame.

    Args:
        shape: (H, W) cells of the canvas.
        resolution_m: metres per cell (> 0).
        origin_cell: (c0, r0) integer cell of the robot's start position (the frame origin).
        l_free, l_occ: log-odds increments of a free and an occupied observation. The defaults
            (-1.2, +3.6) make one observation enough to cross the int8 readers' thresholds
            (free at most 25 %, occupied at least 65 %): exploration maps each cell once or a
            few times, and a map that needs three looks per cell would lag the robot. A hit
            outweighs two passes (three leave the cell undecided): a beam grazing a wall at a
            shallow angle passes through wall cells before it ends, and with a hit worth one
            pass (+1.4, the former default) such walls were erased (``docs/mapper.md``).
        l_min, l_max: clamp of the log-odds (keeps the map able to change its mind).
        rows: the arrays to keep the map in (:class:`MapRows`; a :class:`MapStack` hands each of
            its maps one row of its stacked arrays); by default the map allocates its own.

    >>> m = OccupancyMap((21, 21), 0.05, (10, 10))
    >>> m.update((0.0, 0.0, 0.0), np.array([0.0]), np.array([0.2]), np.array([True]))
    >>> m.to_int8()[10, 10:16].tolist()  # free from the robot's cell, the wall 4 cells ahead
    [0, 0, 0, 0, 100, -1]
    """

    def __init__(
        self,
        shape: tuple[int, int],
        resolution_m: float,
        origin_cell: tuple[int, int],
        l_free: float = L_FREE_DEFAULT,
        l_occ: float = L_OCC_DEFAULT,
        l_min: float = -5.0,
        l_max: float = 5.0,
        rows: MapRows | None = None,
    ) -> None:
        h, w = int(shape[0]), int(shape[1])
        if h < 1 or w < 1:
            raise ConfigError(f"OccupancyMap shape must be positive (rows, cols), got {shape}")
        if not (math.isfinite(resolution_m) and resolution_m > 0.0):
            raise ConfigError(f"OccupancyMap resolution_m must be positive, got {resolution_m}")
        c0, r0 = int(origin_cell[0]), int(origin_cell[1])
        if not (0 <= c0 < w and 0 <= r0 < h):
            raise ConfigError(f"origin_cell {origin_cell} is outside the {h}x{w} canvas")
        if not (l_free < 0.0 < l_occ and l_min < 0.0 < l_max):
            raise ConfigError(
                f"need l_free < 0 < l_occ and l_min < 0 < l_max, got l_free={l_free}, "
                f"l_occ={l_occ}, l_min={l_min}, l_max={l_max}"
            )
        self.shape = (h, w)
        self.resolution_m = float(resolution_m)
        self.origin_cell = (c0, r0)
        self.l_free, self.l_occ = float(l_free), float(l_occ)
        self.l_min, self.l_max = float(l_min), float(l_max)
        if rows is None:
            rows = MapRows.allocate(h, w)
        #: float32 (H, W) log-odds; 0 = never observed.
        self.logodds = rows.logodds.reshape(h, w)
        self._int8 = rows.int8.reshape(h, w)
        # Scratch marks of one scan (0 none, 1 free, 2 occupied); always zero between scans.
        self._marks = np.zeros((h, w), dtype=np.uint8)
        self._delta = np.array([0.0, self.l_free, self.l_occ], dtype=np.float32)
        self._bbox: list[int] | None = None  # [row0, row1, col0, col1] inclusive
        # Compiled path: a per-cell stamp of the last scan that touched it (2 id free,
        # 2 id + 1 occupied); the bbox as an array the kernel updates in place (row1 < 0: none
        # yet).
        self._stamp = rows.stamp
        self._scan_id = 0
        self._bbox_arr = rows.bbox
        self._kdeltas = np.array(
            [self.l_free, self.l_occ, self.l_min, self.l_max], dtype=np.float32
        )
        #: Grows by one with every update that changed at least one int8 cell.
        self.version = 0
        # inclusive box of the int8 cells the last update changed (row1 < 0: none), and that of
        # the update that made ``version``
        self._changed_arr = rows.changed
        self._changed_box: Box | None = None
        # the cells of the last update (count first) and those of the update that made version
        self._cells_arr = rows.cells
        self._changed_cells: NDArray[np.int64] | None = None
        # Beam directions of the last few headings (see beam_directions): heading bits -> (cos,
        # sin), for the beam angles whose bytes are _dir_angles.
        self._dir_cache: dict[str, tuple[NDArray[np.float64], NDArray[np.float64]]] = {}
        self._dir_angles = b""

    # ------------------------------------------------------------------ queries
    def cell_of(self, x_m: float, y_m: float) -> tuple[float, float]:
        """Own-frame metres -> continuous cell ``(col, row)`` of this canvas."""
        return (
            self.origin_cell[0] + x_m / self.resolution_m,
            self.origin_cell[1] + y_m / self.resolution_m,
        )

    def to_int8(self) -> NDArray[np.int8]:
        """The map as int8 (H, W): -1 never observed, 0 free, 100 occupied, and the occupancy in
        percent for observed cells in between the :mod:`mrexplore.grid` thresholds.

        O(1): returns a read-only *view* of an array kept up to date by :meth:`update`; it
        changes with the next update, so copy it to keep a snapshot.
        """
        view = self._int8.view()
        view.flags.writeable = False
        return view

    def known_bbox(self) -> Box | None:
        """The box (half-open, :data:`mrexplore.types.Box`) of the observed cells, None if none;
        kept by the updates, no scan."""
        # both paths keep inclusive bounds internally (the kernel's and the numpy path's)
        if self._bbox_arr[1] >= 0:  # the compiled path has updated it
            b = self._bbox_arr
            box = (int(b[0]), int(b[1]), int(b[2]), int(b[3]))
            if self._bbox is not None:
                o = self._bbox
                box = (min(o[0], box[0]), max(o[1], box[1]), min(o[2], box[2]), max(o[3], box[3]))
        elif self._bbox is not None:
            box = (self._bbox[0], self._bbox[1], self._bbox[2], self._bbox[3])
        else:
            return None
        return (box[0], box[1] + 1, box[2], box[3] + 1)

    def change(self) -> MapChange:
        """The map's version, known box and last changed box (half-open boxes): what a reader
        of :meth:`to_int8` needs to follow the map without comparing canvases."""
        return MapChange(self.version, self.known_bbox(), self._changed_box, self._changed_cells)

    @property
    def changed_box(self) -> Box | None:
        """:meth:`change`'s ``changed_box`` (without its known box): the half-open box of the
        cells the update that made :attr:`version` changed, None at version 0."""
        return self._changed_box

    def changed_cells(self) -> NDArray[np.int64] | None:
        """The flat indices (read-only int64) of the cells whose int8 value the update that made
        :attr:`version` changed: the cells inside :meth:`change`'s ``changed_box`` that did
        change. None at version 0, or when that update changed more than
        :data:`CHANGED_CELLS_LISTED` cells (the box then tells)."""
        return self._changed_cells

    def note_change(self) -> None:
        """Bump :attr:`version` when the last update changed an int8 cell (its ``changed`` box):
        called after every update, also one made by a compiled call on the map's
        :class:`MapRows` (the simulator's :func:`~mrexplore.kernels.sensing.sense_world`)."""
        r0, r1, c0, c1 = self._changed_arr.tolist()
        if r1 >= 0:
            self.version += 1
            self._changed_box = (r0, r1 + 1, c0, c1 + 1)
            n = int(self._cells_arr[0])
            cells = None if n < 0 else self._cells_arr[1 : n + 1].copy()
            if cells is not None:
                cells.flags.writeable = False
            self._changed_cells = cells

    # ------------------------------------------------------------------ update
    def update(
        self,
        pose_est: tuple[float, float, float] | NDArray[np.floating],
        angles: NDArray[np.floating],
        ranges_m: NDArray[np.floating],
        hit: NDArray[np.bool_],
    ) -> None:
        """Integrate one scan taken at ``pose_est``.

        Args:
            pose_est: (x_m, y_m, theta_rad), the robot's pose estimate in its own frame.
            angles: (B,) beam angles in radians relative to the heading.
            ranges_m: (B,) measured ranges in metres (>= 0).
            hit: (B,) bool, the beam ended on an obstacle (else it reached its maximum range).
        """
        x, y, th = (float(v) for v in np.asarray(pose_est, dtype=np.float64).reshape(3))
        ang = np.asarray(angles, dtype=np.float64).reshape(-1)
        rng_m = np.asarray(ranges_m, dtype=np.float64).reshape(-1)
        hits = np.asarray(hit, dtype=bool).reshape(-1)
        if not (ang.shape == rng_m.shape == hits.shape):
            raise GridError(
                f"angles, ranges_m and hit must have the same length, got {ang.shape}, "
                f"{rng_m.shape}, {hits.shape}"
            )
        if not (np.isfinite(rng_m).all() and (rng_m >= 0.0).all()):
            raise GridError("ranges_m must be finite and non-negative")
        self.integrate_trusted(x, y, th, ang, rng_m, hits)

    def integrate_trusted(
        self,
        x: float,
        y: float,
        th: float,
        ang: NDArray[np.float64],
        rng_m: NDArray[np.floating],
        hits: NDArray[np.bool_],
    ) -> None:
        """:meth:`update` without the input checks (the simulator passes its own valid scans):
        ``ang`` (B,) float64 radians, ``rng_m`` (B,) metres (float32 or float64), ``hits`` (B,)."""
        h, w = self.shape
        res = self.resolution_m
        ox, oy = self.sensor_corner(x, y)
        t_end = np.asarray(rng_m, dtype=np.float64) / res
        if kernels.enabled():
            dx, dy = self.beam_directions(th, ang)
            self._integrate_numba(ox, oy, dx, dy, t_end, hits)
            self.note_change()
            return
        a = th + ang
        d = np.stack([np.cos(a), np.sin(a)], axis=1)
        hits = hits.copy()
        # Beams that would leave the canvas (keeping a one-cell ring) are cut at its edge and
        # lose their hit: the canvas should be big enough for this never to happen.
        ex = ox + t_end * d[:, 0]
        ey = oy + t_end * d[:, 1]
        out = (ex < 1.0) | (ex >= w - 1) | (ey < 1.0) | (ey >= h - 1)
        if out.any():
            t_end[out] = np.minimum(t_end[out], _exit_t(ox, oy, d[out], w, h))
            hits[out] = False

        flat_marks = self._marks.reshape(-1)
        origins = np.empty_like(d)
        origins[:, 0] = ox
        origins[:, 1] = oy
        touched = [np.array([int(oy) * w + int(ox)], dtype=np.int64)]  # the robot's own cell
        short = t_end < SHORT_BEAM_CELLS
        for group in (np.flatnonzero(short), np.flatnonzero(~short)):
            if group.size == 0:
                continue
            n_slots = math.ceil(float(t_end[group].max())) + 1
            tr = traverse(
                origins[group],
                d[group],
                0,
                n_slots,
                w,
                float(n_slots) + 2.0,
                dtype=NUMPY_TRAVERSE_DTYPE,
                index_bound=h * w,
            )
            touched.append(tr.selected(tr.count_before(t_end[group])))
        free_idx = np.concatenate(touched)
        flat_marks[free_idx] = 1
        # The end cell of each hit beam (occupied wins: written after the free marks).
        occ_idx = np.zeros(0, dtype=np.int64)
        if hits.any():
            te = t_end[hits] + _END_NUDGE_CELLS
            ec = np.floor(ox + te * d[hits, 0]).astype(np.int64)
            er = np.floor(oy + te * d[hits, 1]).astype(np.int64)
            occ_idx = er * w + ec
            flat_marks[occ_idx] = 2
        # Apply once per cell: duplicates in idx all read the same old value and write the same
        # new one, so no sort / unique is needed.
        idx = np.concatenate([free_idx, occ_idx])
        code = flat_marks[idx]
        flat_marks[idx] = 0
        flat_lo = self.logodds.reshape(-1)
        lo = np.clip(flat_lo[idx] + self._delta[code], self.l_min, self.l_max)
        flat_lo[idx] = lo
        flat8 = self._int8.reshape(-1)
        new8 = _logodds_to_int8(lo)
        moved = idx[flat8[idx] != new8]
        flat8[idx] = new8
        if moved.size:
            mr, mc = moved // w, moved % w
            self._changed_arr[:] = (mr.min(), mr.max(), mc.min(), mc.max())
        else:
            self._changed_arr[:] = (0, -1, 0, -1)
        listed = self._cells_arr
        moved = np.unique(moved)  # a cell may be listed twice (free and occupied marks)
        if moved.size < listed.shape[0]:
            listed[0] = moved.size
            listed[1 : moved.size + 1] = moved
        else:
            listed[0] = -1
        self.note_change()
        # Rows by a float multiply (exact for these sizes; int64 division is slower).
        rr = np.floor((idx + 0.5) * (1.0 / w)).astype(np.int64)
        cc = idx - rr * w
        if rr.size:
            box = [int(rr.min()), int(rr.max()), int(cc.min()), int(cc.max())]
            if self._bbox is None:
                self._bbox = box
            else:
                b = self._bbox
                self._bbox = [
                    min(b[0], box[0]),
                    max(b[1], box[1]),
                    min(b[2], box[2]),
                    max(b[3], box[3]),
                ]

    def move_to(self, rows: MapRows) -> None:
        """Keep the map in ``rows`` from now on, its state copied there (a simulator re-links
        its maps to one :class:`MapStack` after unpickling, which copies views apart)."""
        h, w = self.shape
        rows.logodds[:] = self.logodds.reshape(-1)
        rows.int8[:] = self._int8.reshape(-1)
        rows.stamp[:] = self._stamp
        rows.bbox[:] = self._bbox_arr
        rows.changed[:] = self._changed_arr
        rows.cells[:] = self._cells_arr
        self.logodds = rows.logodds.reshape(h, w)
        self._int8 = rows.int8.reshape(h, w)
        self._stamp = rows.stamp
        self._bbox_arr = rows.bbox
        self._changed_arr = rows.changed
        self._cells_arr = rows.cells

    def sensor_corner(self, x: float, y: float) -> tuple[float, float]:
        """The sensor at own-frame ``(x, y)`` metres in this canvas's corner coordinates
        ``(col + 0.5, row + 0.5)``, snapped (:data:`mrexplore.traversal.SNAP_CELLS`); a
        :class:`GridError` if it is not inside the canvas's one-cell ring."""
        h, w = self.shape
        res = self.resolution_m
        # snap inlined: this runs every step and numpy's scalar calls cost microseconds each
        ox = round((self.origin_cell[0] + x / res + 0.5) / SNAP_CELLS) * SNAP_CELLS
        oy = round((self.origin_cell[1] + y / res + 0.5) / SNAP_CELLS) * SNAP_CELLS
        if not (1.0 <= ox < w - 1 and 1.0 <= oy < h - 1):
            raise GridError(
                f"pose ({x:.3f}, {y:.3f}) m is outside the {h}x{w} canvas: make the canvas larger"
            )
        return ox, oy

    def next_scan_id(self) -> int:
        """The compiled update's id for the next scan (the stamps are cleared when ids wrap)."""
        self._scan_id += 1
        if self._scan_id > _STAMP_WRAP:
            self._stamp[:] = 0
            self._scan_id = 1
        return self._scan_id

    def beam_directions(
        self, th: float, ang: NDArray[np.float64]
    ) -> tuple[NDArray[np.float64], NDArray[np.float64]]:
        """Unit beam directions ``(cos(th + ang), sin(th + ang))``, each float64 (B,), for the
        heading ``th`` and beam angles ``ang`` (B,), radians; not to be written to.

        A robot turns in fixed steps, so its headings repeat: the last :data:`_DIR_CACHE`
        headings' directions are kept (keyed by the heading's bits and the angles' bytes, so a
        hit returns what numpy would compute now), saving two 360-element trig calls per scan.
        """
        raw = ang.dtype.str.encode() + ang.tobytes()
        if raw != self._dir_angles:
            self._dir_cache.clear()
            self._dir_angles = raw
        key = float(th).hex()  # the bits: -0.0 and 0.0 differ
        hit = self._dir_cache.get(key)
        if hit is not None:
            return hit
        a = th + ang
        out = (np.cos(a), np.sin(a))
        if len(self._dir_cache) >= _DIR_CACHE:
            del self._dir_cache[next(iter(self._dir_cache))]  # the oldest heading
        self._dir_cache[key] = out
        return out

    def _integrate_numba(
        self,
        ox: float,
        oy: float,
        dx: NDArray[np.float64],
        dy: NDArray[np.float64],
        t_end: NDArray[np.float64],
        hits: NDArray[np.bool_],
    ) -> None:
        """The compiled update (see :func:`mrexplore.kernels.sensing.map_update`)."""
        assert _sensing is not None
        h, w = self.shape
        scan_id = self.next_scan_id()
        _sensing.map_update(
            self.logodds.reshape(-1),
            self._int8.reshape(-1),
            self._stamp,
            scan_id,
            h,
            w,
            ox,
            oy,
            dx,
            dy,
            t_end,
            np.asarray(hits, dtype=np.bool_),
            *self.kernel_constants(),
            self._bbox_arr,
            self._changed_arr,
            self._cells_arr,
        )

    def kernel_constants(
        self,
    ) -> tuple[float, NDArray[np.float32], NDArray[np.float32], NDArray[np.int64]]:
        """The compiled update's constants, ``short_cells, deltas, thresholds, pct_clip``
        (:func:`mrexplore.kernels.sensing.map_update`)."""
        return float(SHORT_BEAM_CELLS), self._kdeltas, _KTHRESHOLDS, _KPCT

    def save(self, path_yaml: str | Path) -> Path:
        """Write the int8 map as a map_server YAML + image (needs :mod:`mrexplore.world.map_io`).

        The YAML origin is the world position of cell (0, 0)'s corner in this robot's own frame.
        """
        from mrexplore.world.map_io import write_map_yaml

        res = self.resolution_m
        origin = (-(self.origin_cell[0] + 0.5) * res, -(self.origin_cell[1] + 0.5) * res, 0.0)
        return Path(write_map_yaml(path_yaml, self._int8.copy(), res, origin_m=origin))


def _exit_t(ox: float, oy: float, d: NDArray[np.float64], w: int, h: int) -> NDArray[np.float64]:
    """Ray parameter (cells) where rays from (ox, oy) (corner coordinates) leave the box
    ``[1, w - 1) x [1, h - 1)``, minus a small margin."""
    with np.errstate(divide="ignore", invalid="ignore"):
        tx = np.where(
            d[:, 0] > 0, (w - 1 - ox) / d[:, 0], np.where(d[:, 0] < 0, (1.0 - ox) / d[:, 0], np.inf)
        )
        ty = np.where(
            d[:, 1] > 0, (h - 1 - oy) / d[:, 1], np.where(d[:, 1] < 0, (1.0 - oy) / d[:, 1], np.inf)
        )
    return np.maximum(np.minimum(tx, ty) - 10.0 * CORNER_EPS, 0.0)


#: Log-odds at the int8 thresholds of :mod:`mrexplore.grid` (logit of 25 % and 65 %).
_L_FREE_MAX: float = math.log(FREE_THRESHOLD / (100.0 - FREE_THRESHOLD))
_L_OCC_MIN: float = math.log(OCCUPIED_THRESHOLD / (100.0 - OCCUPIED_THRESHOLD))


#: The compiled path's constants: the thresholds as float32 (the numpy path compares float32
#: log-odds with Python floats, which NumPy 2 casts to float32) and the int8 values.
_KTHRESHOLDS: NDArray[np.float32] = np.array([_L_FREE_MAX, _L_OCC_MIN], dtype=np.float32)
_KPCT: NDArray[np.int64] = np.array(
    [FREE, OCCUPIED, FREE_THRESHOLD + 1, OCCUPIED_THRESHOLD - 1], dtype=np.int64
)


def _logodds_to_int8(lo: NDArray[np.float32]) -> NDArray[np.int8]:
    """Observed cells' log-odds -> int8 occupancy: FREE / OCCUPIED past the thresholds of
    :mod:`mrexplore.grid`, else the probability in percent (never UNKNOWN: they were observed).
    The thresholds are compared in log-odds; the percentage is only computed for the (few)
    undecided cells."""
    out = np.where(lo >= _L_OCC_MIN, np.int8(OCCUPIED), np.int8(FREE))
    mid = (lo > _L_FREE_MAX) & (lo < _L_OCC_MIN)
    if mid.any():
        pct = 100.0 / (1.0 + np.exp(-lo[mid].astype(np.float64)))
        out[mid] = np.clip(np.rint(pct), FREE_THRESHOLD + 1, OCCUPIED_THRESHOLD - 1).astype(np.int8)
    return out
