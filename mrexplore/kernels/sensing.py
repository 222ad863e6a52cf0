"""Compiled kernels of the simulator: lidar cast + coverage marking, own-map update, motion,
and one world's whole sensing step (:func:`sense_world`).

Why compiled: the numpy versions in :mod:`mrexplore.sensors` and :mod:`mrexplore.mapping` are
vectorised, but a scan is only ~720 beams of ~40 cells, so numpy's per-call overhead (tens of
calls of ~5-30 us each) dominated: ~6 ms for the cast + map update of 2 robots. The per-beam
loops compiled here do the same work in ~0.5 ms (``mrexplore bench sensor``).

Bit-for-bit agreement with the numpy path. The kernels evaluate the *same floating-point
formulas* as :func:`mrexplore.traversal.traverse` run in float64 (crossing ``k`` of a line family
is at ``t = t0 + k * dt``; the coordinate along the lines is ``k * s + a`` with the same ``a``,
``s`` and offset; the cell is its floor, biased by ``-CORNER_EPS``). So the numba cast equals the
numpy cast with ``Lidar.dtype = float64`` exactly, and the numpy float32 default up to the float32
rounding of the per-slot positions near grid lines (see the tests). Directions (cos / sin) are
computed by numpy in the callers and passed in, so no libm difference enters.

Corner rule (shared with :func:`mrexplore.sensors.cast_ray_reference`): a crossing within
``CORNER_EPS`` cells of a grid corner tests both cells beside the crossing point, so a beam never
slips between two wall cells that touch only at a corner.

All kernels are ``cache=True`` (compiled once per machine into ``__pycache__``) and ``nogil``.
The first call in a fresh environment compiles them (a few seconds); :func:`warm_up` does it on
tiny inputs.

One module for the cast, the map update and the motion: they share ``_family`` and its float
formulas, which numba inlines only within one module.
"""

from __future__ import annotations

import math

import numba
import numpy as np
from numpy.typing import NDArray

#: Same value as :data:`mrexplore.traversal.CORNER_EPS` (kept here so this module imports nothing
#: from the package; a test checks they agree).
CORNER_EPS: float = 1e-4

#: Marking limit beyond the hit distance (cells), as the numpy path's ``count_before(limit +
#: 1e-9)``: the hit cell itself, entered exactly at the range, is observed.
_MARK_SLACK: float = 1e-9

#: The occupied end point of a beam is taken this far (cells) beyond the measured range (same as
#: ``mrexplore.mapping._END_NUDGE_CELLS``).
END_NUDGE_CELLS: float = 1e-3


@numba.njit(cache=True, nogil=True, inline="always")
def _family(
    o: float, o_other: float, d: float, d_other: float, t_cap: float
) -> tuple[bool, float, float, float, float, int, int, int, int]:
    """Setup of one line family of one ray, exactly as :func:`mrexplore.traversal.traverse`.

    Returns ``(moving, t0, dt, a, s, fo, fo_other, sgn, offset)``: crossing k is at
    ``t0 + k dt``; the position along the lines (relative, offset) is ``k s + a``; the entered
    cell across the lines is ``fo + (k + 1) sgn``, along them ``fo_other - offset + floor(pos)``.
    """
    fo = math.floor(o)
    ad = abs(d)
    moving = ad > 0.0
    inv = 1.0 / ad if moving else 0.0
    first = fo + 1.0 - o if d > 0.0 else o - fo
    t0 = first * inv if moving else math.inf
    offset = math.ceil(t_cap) + 2
    fo_other = math.floor(o_other)
    a = (o_other - fo_other) + min(first * inv, t_cap) * d_other + (offset - CORNER_EPS)
    s = min(max(inv * d_other, -t_cap), t_cap)
    sgn = 1 if d > 0.0 else -1
    return moving, t0, inv, a, s, int(fo), int(fo_other), sgn, offset


@numba.njit(cache=True, nogil=True, inline="always")
def _n_before(t0: float, dt: float, lim: float) -> int:
    """The number of crossings ``k >= 0`` of a family with ``t0 + k * dt < lim`` (cells),
    evaluated with that very formula (monotonic in k), so a counted loop visits exactly the
    crossings a ``while t < lim`` walk does; 0 when ``t0`` is not below ``lim`` (or NaN)."""
    if not (t0 < lim):
        return 0
    n = max(math.ceil((lim - t0) / dt), 1)
    while n > 1 and not (t0 + (n - 1) * dt < lim):
        n -= 1
    while t0 + n * dt < lim:
        n += 1
    return n


@numba.njit(cache=True, nogil=True, inline="always")
def _first_wall(
    table: NDArray[np.bool_],
    plane: int,
    wp: int,
    vertical: bool,
    t0: float,
    dt: float,
    a: float,
    s: float,
    across0: int,
    across_step: int,
    along0: int,
    lim: float,
    best: float,
) -> float:
    """The t (cells) of the first wall crossing of one line family of one ray before
    ``min(lim, best)``, or ``best`` when there is none (the cast's wall test, one family).

    Crossing k is at ``t0 + k dt``; the position along the lines is ``k s + a``; the entered
    cell of the padded grid is ``across0 + (k + 1) across_step`` across the lines and
    ``along0 + floor(pos)`` along them (the column and the row for ``vertical`` lines, else the
    row and the column), as set up by :func:`_family`. Within ``CORNER_EPS`` of a corner the
    table's second (vertical lines) or third plane (both cells beside the crossing) is read.
    """
    near_lim = 1.0 - 2.0 * CORNER_EPS
    near_plane = plane if vertical else 2 * plane
    for k in range(_n_before(t0, dt, min(lim, best))):
        pos = k * s + a
        cell = math.floor(pos)
        across = across0 + (k + 1) * across_step
        along = along0 + int(cell)
        idx = along * wp + across if vertical else across * wp + along
        # Outside the padded table cannot happen before the border ring; a wall anyway.
        if idx < 0 or idx >= plane:
            return t0 + k * dt
        if table[idx + near_plane if (pos - cell) >= near_lim else idx]:
            return t0 + k * dt
    return best


@numba.njit(cache=True, nogil=True, inline="always")
def _mark_family(
    observed: NDArray[np.bool_],
    team: NDArray[np.bool_],
    reach: NDArray[np.bool_],
    newly_out: NDArray[np.int64],
    i: int,
    h: int,
    w: int,
    vertical: bool,
    t0: float,
    dt: float,
    a: float,
    s: float,
    across0: int,
    across_step: int,
    along0: int,
    lim: float,
) -> int:
    """Mark the cells robot ``i`` enters at the crossings of one line family with ``t < lim``
    (cells of the padded grid as in :func:`_first_wall`; those outside the world are skipped):
    updates ``observed[i]``, ``team`` and ``newly_out[i]``; returns the number of ``reach``
    cells the team observed for the first time."""
    covered = 0
    for k in range(_n_before(t0, dt, lim)):
        across = across0 + (k + 1) * across_step
        along = along0 + math.floor(k * s + a)
        row, col = (along, across) if vertical else (across, along)
        if 1 <= row <= h and 1 <= col <= w:
            f = (row - 1) * w + (col - 1)
            if not observed[i, f]:
                observed[i, f] = True
                newly_out[i] += 1
                if not team[f]:
                    team[f] = True
                    if reach[f]:
                        covered += 1
    return covered


@numba.njit(cache=True, nogil=True)
def cast_observe(
    table: NDArray[np.bool_],
    hp: int,
    wp: int,
    corners: NDArray[np.float64],
    ch: NDArray[np.float64],
    sh: NDArray[np.float64],
    cos_b: NDArray[np.float64],
    sin_b: NDArray[np.float64],
    max_cells: float,
    res: float,
    max_range_m: float,
    noise: NDArray[np.float64],
    ranges_out: NDArray[np.float32],
    hit_out: NDArray[np.bool_],
    mark: bool,
    observed: NDArray[np.bool_],
    reach: NDArray[np.bool_],
    team: NDArray[np.bool_],
    newly_out: NDArray[np.int64],
) -> int:
    """Cast every beam of R robots on a padded wall grid; optionally mark the observed cells.

    Args:
        table: bool flat, the :class:`mrexplore.traversal.PaddedGrid` table: three planes of
            ``hp * wp`` cells (walls; walls of a cell or the one above; or the one to the right).
        hp, wp: rows and columns of the padded grid (H + 2, W + 2).
        corners: (R, 2) sensor positions in (unpadded) corner coordinates ``(col + .5, row + .5)``,
            snapped, inside the grid.
        ch, sh: (R,) cos and sin of the headings.
        cos_b, sin_b: (B,) cos and sin of the beam angles relative to the heading.
        max_cells: maximum range in cells; res: metres per cell; max_range_m: in metres.
        noise: (R, B) Gaussian range noise in metres, or an empty (0, 0) array for none; only
            added to beams that hit, then clipped to ``[0, max_range_m]`` in float32.
        ranges_out: float32 (R, B) out, metres; hit_out: bool (R, B) out.
        mark: also mark observed cells (else ``observed``, ``reach``, ``team``, ``newly_out``
            are not touched).
        observed: bool (R, H * W) per robot, the world cells observed so far (updated): the
            robot's own cell and, per beam, the cell entered at every crossing up to the hit
            (the hit cell included) or up to the maximum range.
        reach: bool (H * W), the cells that count for coverage.
        team: bool (H * W), cells observed by any robot (updated).
        newly_out: int64 (R,) out, cells robot r observed for the first time in this call.

    Returns:
        The number of ``reach`` cells the team observed for the first time in this call.
    """
    n_rob = corners.shape[0]
    n_b = cos_b.shape[0]
    plane = hp * wp
    h = hp - 2
    w = wp - 2
    t_cap = max_cells + 2.0
    has_noise = noise.shape[0] > 0
    mr32 = np.float32(max_range_m)
    covered = 0
    for i in range(n_rob):
        if mark:
            newly_out[i] = 0
        cx = corners[i, 0]
        cy = corners[i, 1]
        # The robot's own cell: a sensor inside a wall sees nothing (range 0).
        occ = math.floor(cx)
        ocr = math.floor(cy)
        origin_wall = table[(ocr + 1) * wp + occ + 1]
        if mark:
            f = ocr * w + occ
            if not observed[i, f]:
                observed[i, f] = True
                newly_out[i] += 1
                if not team[f]:
                    team[f] = True
                    if reach[f]:
                        covered += 1
        ox = cx + 1.0  # padded grid
        oy = cy + 1.0
        for b in range(n_b):
            dx = ch[i] * cos_b[b] - sh[i] * sin_b[b]
            dy = sh[i] * cos_b[b] + ch[i] * sin_b[b]
            best = math.inf
            if origin_wall:
                best = 0.0
            else:
                mx, t0x, dtx, ax, sx, fox, foox, sgx, offx = _family(ox, oy, dx, dy, t_cap)
                my, t0y, dty, ay, sy, foy, fooy, sgy, offy = _family(oy, ox, dy, dx, t_cap)
                # One line family at a time, each a counted loop, instead of merging the two in
                # t order (~10 % faster on recorded scans). The hit is the first wall crossing of
                # either family (the y walk stops at the x hit); the marked cells are those of
                # every crossing before hit + slack (an exact corner's coincident crossings
                # too), else before the range + slack: the merged walk's set, in another order.
                lim = max_cells + _MARK_SLACK
                if my and math.isnan(t0y):
                    # Unreachable for unit directions (a subnormal component); the merged walk
                    # then stopped at once: keep its result.
                    mx = my = False
                if mx:
                    best = _first_wall(
                        table, plane, wp, True, t0x, dtx, ax, sx, fox, sgx, foox - offx, lim, best
                    )
                if my:
                    best = _first_wall(
                        table, plane, wp, False, t0y, dty, ay, sy, foy, sgy, fooy - offy, lim, best
                    )
                if mark:
                    if best != math.inf:
                        lim = best + _MARK_SLACK
                    if mx:
                        covered += _mark_family(
                            observed,
                            team,
                            reach,
                            newly_out,
                            i,
                            h,
                            w,
                            True,
                            t0x,
                            dtx,
                            ax,
                            sx,
                            fox,
                            sgx,
                            foox - offx,
                            lim,
                        )
                    if my:
                        covered += _mark_family(
                            observed,
                            team,
                            reach,
                            newly_out,
                            i,
                            h,
                            w,
                            False,
                            t0y,
                            dty,
                            ay,
                            sy,
                            foy,
                            sgy,
                            fooy - offy,
                            lim,
                        )
            hit = best <= max_cells
            r32 = np.float32((best if hit else max_cells) * res)
            if has_noise and hit:
                r32 = r32 + np.float32(noise[i, b])
                if r32 < np.float32(0.0):
                    r32 = np.float32(0.0)
                if r32 > mr32:
                    r32 = mr32
            ranges_out[i, b] = r32
            hit_out[i, b] = hit
    return covered


@numba.njit(cache=True, nogil=True)
def map_update(
    logodds: NDArray[np.float32],
    int8_map: NDArray[np.int8],
    stamp: NDArray[np.uint16],
    scan_id: int,
    h: int,
    w: int,
    ox: float,
    oy: float,
    dx: NDArray[np.float64],
    dy: NDArray[np.float64],
    t_end_in: NDArray[np.float64],
    hits_in: NDArray[np.bool_],
    short_cells: float,
    deltas: NDArray[np.float32],
    thresholds: NDArray[np.float32],
    pct_clip: NDArray[np.int64],
    bbox: NDArray[np.int64],
    changed: NDArray[np.int64],
    cells: NDArray[np.int64],
) -> None:
    """Integrate one scan into a log-odds map (flat arrays of an (h, w) canvas).

    Inverse sensor model as :meth:`mrexplore.mapping.OccupancyMap.update`: the robot's cell and
    the cells each beam enters at crossings with ``t < t_end`` are free; the cell at
    ``t_end + END_NUDGE_CELLS`` is occupied when the beam hit. Each cell changes at most once
    per scan and occupied wins: occupied cells are applied first and stamped
    ``2 scan_id + 1``, free cells are applied only when their stamp is neither that nor
    ``2 scan_id`` (a per-scan stamp instead of a sort / unique).

    Args:
        logodds: float32 (h * w) log-odds (updated); int8_map: int8 (h * w) mirror (updated).
        stamp: uint16 (h * w) per-cell stamp; ``2 scan_id + 1`` must fit (caller wraps).
        ox, oy: sensor position in corner coordinates of the canvas, snapped, in
            ``[1, w - 1) x [1, h - 1)``.
        dx, dy: (B,) unit beam directions; t_end_in: (B,) ranges in cells; hits_in: (B,) bool.
        short_cells: beams shorter than this are traversed as one group (same slot windows and
            offsets as the numpy path, so its float64 arithmetic is reproduced exactly).
        deltas: float32 (4,) ``l_free, l_occ, l_min, l_max``.
        thresholds: float32 (2,) log-odds at the int8 free / occupied thresholds.
        pct_clip: int64 (4,) ``FREE, OCCUPIED, lowest, highest`` percent of an undecided cell.
        bbox: int64 (4,) ``row0, row1, col0, col1`` inclusive of the known cells (updated;
            ``row1 < 0`` when none yet).
        changed: int64 (4,) out: ``row0, row1, col0, col1`` inclusive of the cells whose int8
            value this scan changed (``row1 < 0``: none). Consumers of the int8 map (the merge
            tracker) then need not compare whole canvases to find what changed.
        cells: int64 (K + 1,) out: ``cells[0]`` the number of cells whose int8 value this scan
            changed and ``cells[1:]`` their flat indices, or ``cells[0] = -1`` when more than K
            changed (then only the box tells): a reader re-scoring the map need not visit the
            unchanged cells of the box (the truth monitor's :meth:`~mrexplore.truth.
            IncrementalScore.update_cells`).
    """
    n_b = dx.shape[0]
    cells[0] = 0
    l_free, l_occ, l_min, l_max = deltas[0], deltas[1], deltas[2], deltas[3]
    s_free = np.uint16(2 * scan_id)
    s_occ = np.uint16(2 * scan_id + 1)
    t_end = t_end_in.copy()
    hits = hits_in.copy()
    # Beams that would leave the canvas (keeping a one-cell ring) are cut at its edge and lose
    # their hit, as the numpy path.
    for b in range(n_b):
        ex = ox + t_end[b] * dx[b]
        ey = oy + t_end[b] * dy[b]
        if ex < 1.0 or ex >= w - 1 or ey < 1.0 or ey >= h - 1:
            tx = math.inf
            if dx[b] > 0:
                tx = (w - 1 - ox) / dx[b]
            elif dx[b] < 0:
                tx = (1.0 - ox) / dx[b]
            ty = math.inf
            if dy[b] > 0:
                ty = (h - 1 - oy) / dy[b]
            elif dy[b] < 0:
                ty = (1.0 - oy) / dy[b]
            cut = max(min(tx, ty) - 10.0 * CORNER_EPS, 0.0)
            t_end[b] = min(t_end[b], cut)
            hits[b] = False
    # Slot windows of the two groups (short / long beams), as the numpy path.
    max_short = -1.0
    max_long = -1.0
    for b in range(n_b):
        if t_end[b] < short_cells:
            max_short = max(max_short, t_end[b])
        else:
            max_long = max(max_long, t_end[b])
    r0, r1, c0, c1 = bbox[0], bbox[1], bbox[2], bbox[3]
    if r1 < 0:
        r0, r1, c0, c1 = h, -1, w, -1
    q0, q1, p0, p1 = h, -1, w, -1  # box of the int8 changes
    # 1) occupied end cells: applied first, stamped so that no free mark touches them.
    for b in range(n_b):
        if not hits[b]:
            continue
        te = t_end[b] + END_NUDGE_CELLS
        ec = math.floor(ox + te * dx[b])
        er = math.floor(oy + te * dy[b])
        f = er * w + ec
        r0, r1, c0, c1 = min(r0, er), max(r1, er), min(c0, ec), max(c1, ec)
        if stamp[f] != s_occ:
            stamp[f] = s_occ
            if _apply(logodds, int8_map, f, l_occ, l_min, l_max, thresholds, pct_clip):
                q0, q1, p0, p1 = min(q0, er), max(q1, er), min(p0, ec), max(p1, ec)
                _list_cell(cells, f)
    # 2) free cells: the robot's own cell, then every crossing before the end of each beam.
    orow = int(oy)
    ocol = int(ox)
    f = orow * w + ocol
    r0, r1, c0, c1 = min(r0, orow), max(r1, orow), min(c0, ocol), max(c1, ocol)
    if stamp[f] != s_occ and stamp[f] != s_free:
        stamp[f] = s_free
        if _apply(logodds, int8_map, f, l_free, l_min, l_max, thresholds, pct_clip):
            q0, q1, p0, p1 = min(q0, orow), max(q1, orow), min(p0, ocol), max(p1, ocol)
            _list_cell(cells, f)
    # Two passes over the free cells. Pass 1 walks every beam and, per crossing, only stamps
    # the cells new in this scan and lists them (branch-free: whether a cell is new is
    # unpredictable near the robot, where the beams overlap). Pass 2 applies ``l_free`` once per
    # listed cell. A cell is updated at most once per scan either way, so the map, the int8 view
    # and the changed box are those of applying at the first visit; the ~2-3x revisits near the
    # robot now cost a stamp compare instead of a log-odds, int8 and exp evaluation.
    n_slots_max = math.ceil(max(max_short, max_long, 0.0)) + 1
    fresh_cells = np.empty(2 * n_b * n_slots_max, dtype=np.int64)
    n_fresh = 0
    for b in range(n_b):
        group_max = max_short if t_end[b] < short_cells else max_long
        n_slots = math.ceil(group_max) + 1
        t_cap = float(n_slots) + 2.0
        for fam in range(2):
            if fam == 0:
                moving, t0, dt, a, s, fo, foo, sg, off = _family(ox, oy, dx[b], dy[b], t_cap)
            else:
                moving, t0, dt, a, s, fo, foo, sg, off = _family(oy, ox, dy[b], dx[b], t_cap)
            if not moving:
                continue
            # Slots k with k < (t_end - t0) / dt, as ``Traversal.count_before``.
            n = math.ceil((t_end[b] - t0) / dt)
            n = min(max(n, 0), n_slots)
            if n <= 0:
                continue
            # The cells of one family are monotonic in row and column along the beam: the
            # first and the last one bound them all (no per-cell bbox compares).
            for kk in (0, n - 1):
                other = foo - off + math.floor(kk * s + a)
                across = fo + (kk + 1) * sg
                row, col = (other, across) if fam == 0 else (across, other)
                r0, r1, c0, c1 = min(r0, row), max(r1, row), min(c0, col), max(c1, col)
            # Row / column strides of the two coordinates in the flat canvas.
            st_other = w if fam == 0 else 1
            st_across = 1 if fam == 0 else w
            base = (foo - off) * st_other + (fo + sg) * st_across
            step = sg * st_across
            for k in range(n):
                f = base + k * step + math.floor(k * s + a) * st_other
                st = stamp[f]
                # Listed at every visit, counted only when new: a select, not a jump.
                fresh_cells[n_fresh] = f
                n_fresh += 1 if (st != s_occ) & (st != s_free) else 0
                stamp[f] = st if st == s_occ else s_free
    # Pass 2, inlined rather than through ``_apply`` with the thresholds read once: the call
    # (re-reading them per cell, as the arrays may alias) cost ~7x this loop.
    thr_free, thr_occ = thresholds[0], thresholds[1]
    v_free, v_occ, v_low, v_high = pct_clip[0], pct_clip[1], pct_clip[2], pct_clip[3]
    for j in range(n_fresh):
        f = fresh_cells[j]
        lo = min(max(logodds[f] + l_free, l_min), l_max)
        logodds[f] = lo
        if lo >= thr_occ:
            v = v_occ
        elif lo > thr_free:
            pct = np.rint(100.0 / (1.0 + math.exp(-float(lo))))
            v = min(max(int(pct), v_low), v_high)
        else:
            v = v_free
        if int8_map[f] != v:
            int8_map[f] = v
            row = f // w
            col = f - row * w
            q0, q1, p0, p1 = min(q0, row), max(q1, row), min(p0, col), max(p1, col)
            _list_cell(cells, f)
    bbox[0], bbox[1], bbox[2], bbox[3] = r0, r1, c0, c1
    changed[0], changed[1], changed[2], changed[3] = q0, q1, p0, p1


@numba.njit(cache=True, nogil=True)
def sense_world(
    table: NDArray[np.bool_],
    hp: int,
    wp: int,
    corners: NDArray[np.float64],
    ch: NDArray[np.float64],
    sh: NDArray[np.float64],
    cos_b: NDArray[np.float64],
    sin_b: NDArray[np.float64],
    max_cells: float,
    res: float,
    max_range_m: float,
    noise: NDArray[np.float64],
    ranges_out: NDArray[np.float32],
    hit_out: NDArray[np.bool_],
    observed: NDArray[np.bool_],
    reach: NDArray[np.bool_],
    team: NDArray[np.bool_],
    newly_out: NDArray[np.int64],
    logodds: NDArray[np.float32],
    int8_map: NDArray[np.int8],
    stamp: NDArray[np.uint16],
    scan_ids: NDArray[np.int64],
    h: int,
    w: int,
    sensors: NDArray[np.float64],
    dx: NDArray[np.float64],
    dy: NDArray[np.float64],
    short_cells: float,
    deltas: NDArray[np.float32],
    thresholds: NDArray[np.float32],
    pct_clip: NDArray[np.int64],
    bbox: NDArray[np.int64],
    changed: NDArray[np.int64],
    cells: NDArray[np.int64],
) -> int:
    """One world's sensing step in one call: :func:`cast_observe` of R robots on the truth
    (marking), then :func:`map_update` of each robot's own map with its beams.

    Args:
        table ... newly_out: as :func:`cast_observe` with ``mark`` on.
        logodds, int8_map, stamp: the R own maps' arrays, (R, h * w) (a
            :class:`mrexplore.mapping.MapStack`); scan_ids: int64 (R,) each map's scan id.
        h, w: the maps' canvas; sensors: float64 (R, 2) each robot's sensor in its canvas's
            corner coordinates, snapped; dx, dy: float64 (R, B) its beam directions.
        short_cells, deltas, thresholds, pct_clip: as :func:`map_update` (the same for all maps).
        bbox, changed: int64 (R, 4), cells: int64 (R, K + 1): as :func:`map_update`, one row
            per map.

    Returns:
        The number of ``reach`` cells the team observed for the first time.

    The same calls as the simulator makes one by one, so the same results bit for bit; the
    ranges become cells as there (``float64(range) / res``).
    """
    covered = cast_observe(
        table,
        hp,
        wp,
        corners,
        ch,
        sh,
        cos_b,
        sin_b,
        max_cells,
        res,
        max_range_m,
        noise,
        ranges_out,
        hit_out,
        True,
        observed,
        reach,
        team,
        newly_out,
    )
    n_rob, n_b = ranges_out.shape
    t_end = np.empty(n_b)
    for r in range(n_rob):
        for b in range(n_b):
            t_end[b] = np.float64(ranges_out[r, b]) / res
        map_update(
            logodds[r],
            int8_map[r],
            stamp[r],
            scan_ids[r],
            h,
            w,
            sensors[r, 0],
            sensors[r, 1],
            dx[r],
            dy[r],
            t_end,
            hit_out[r],
            short_cells,
            deltas,
            thresholds,
            pct_clip,
            bbox[r],
            changed[r],
            cells[r],
        )
    return covered


@numba.njit(cache=True, nogil=True, inline="always")
def _list_cell(cells: NDArray[np.int64], f: int) -> None:
    """Append flat cell ``f`` to ``cells`` (count first; -1 once it is full)."""
    n = cells[0]
    if n < 0:
        return
    if n + 1 < cells.shape[0]:
        cells[n + 1] = f
        cells[0] = n + 1
    else:
        cells[0] = -1


@numba.njit(cache=True, nogil=True, inline="always")
def _apply(
    logodds: NDArray[np.float32],
    int8_map: NDArray[np.int8],
    f: int,
    delta: np.float32,
    l_min: np.float32,
    l_max: np.float32,
    thresholds: NDArray[np.float32],
    pct_clip: NDArray[np.int64],
) -> bool:
    """Add ``delta`` to cell ``f`` (float32, clamped) and refresh its int8 value, as
    ``mrexplore.mapping._logodds_to_int8`` (thresholds compared in float32). Returns whether
    the int8 value changed."""
    lo = logodds[f] + delta
    if lo < l_min:
        lo = l_min
    if lo > l_max:
        lo = l_max
    logodds[f] = lo
    if lo >= thresholds[1]:
        v = pct_clip[1]
    elif lo > thresholds[0]:
        pct = np.rint(100.0 / (1.0 + math.exp(-float(lo))))
        v = min(max(int(pct), pct_clip[2]), pct_clip[3])
    else:
        v = pct_clip[0]
    if int8_map[f] == v:
        return False
    int8_map[f] = v
    return True


@numba.njit(cache=True, nogil=True)
def motion_forward(
    blocked: NDArray[np.bool_],
    px: NDArray[np.float64],
    py: NDArray[np.float64],
    cos_th: NDArray[np.float64],
    sin_th: NDArray[np.float64],
    dist: NDArray[np.float64],
    org_x: float,
    org_y: float,
    res: float,
    snap_cells: float,
    out_x: NDArray[np.float64],
    out_y: NDArray[np.float64],
) -> NDArray[np.int64]:
    """F forward moves with collision checks, as :meth:`mrexplore.robot.Motion.step`.

    Args:
        blocked: bool (H + 2, W + 2) padded C-space (outside the world = blocked).
        px, py: (F,) start positions, world metres; cos_th, sin_th: (F,) of the headings.
        dist: (S + 1,) distance (metres) of each sub-step (``dist[0] = 0``, the start).
        org_x, org_y: world origin (metres); res: metres per cell; snap_cells: the lattice of
            :func:`mrexplore.traversal.snap`.
        out_x, out_y: (F,) out: the end positions (the start when it is blocked itself).

    Returns:
        int64 (F,): index of the last sub-step reached without a blocked cell (-1 when the
        start itself is blocked). A sub-step that changes row and column at once also needs
        both axis-aligned neighbour cells free (no squeezing through a diagonal gap).
    """
    hp, wp = blocked.shape
    h = hp - 2
    w = wp - 2
    n_f = px.shape[0]
    out = np.empty(n_f, dtype=np.int64)
    for j in range(n_f):
        last = -1
        pc = 0
        pr = 0
        out_x[j] = px[j]
        out_y[j] = py[j]
        for k in range(dist.shape[0]):
            x = px[j] + cos_th[j] * dist[k]
            y = py[j] + sin_th[j] * dist[k]
            cf = np.rint(((x - org_x) / res) / snap_cells) * snap_cells
            rf = np.rint(((y - org_y) / res) / snap_cells) * snap_cells
            c = min(max(math.floor(cf), -1), w) + 1
            r = min(max(math.floor(rf), -1), h) + 1
            bad = blocked[r, c]
            if k > 0:
                bad = bad or blocked[pr, c] or blocked[r, pc]
            if bad:
                break
            last = k
            pc = c
            pr = r
            out_x[j] = x
            out_y[j] = y
        out[j] = last
    return out
