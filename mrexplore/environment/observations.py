"""Each robot's observation: a uint8 image stack in the robot's own map frame.

Everything drawn here comes from a :class:`~mrexplore.types.RobotView`, i.e. from what
the robot knows (its own map or the fused map, its own pose estimate, teammates only after a merge).
Nothing is read from the ground truth.

Layout, shape ``(8, S, S)`` with ``S = obs_size_px`` (channel-first, so SB3's ``CnnPolicy`` takes
it as is); every channel is 0..255. Both views are centred on the robot and axis-aligned with its
own map frame (+col to the right, +row "up" = increasing array row); with ``obs_heading_up=True``
they are turned so that the robot's heading points along +row instead (egocentric views, easier
for a learned policy whose actions are turn/forward):

=====  ==========================================================================================
 ch    meaning
=====  ==========================================================================================
  0    global view (``global_view_m`` wide): share of free cells per pixel
  1    global view: share of occupied cells per pixel
  2    global view: own trail (255 where the robot has been)
  3    global view: teammates' positions (disks), only once their maps are merged
  4    local view (``local_view_m`` wide, fine): share of free cells
  5    local view: share of occupied cells
  6    local view: the robot itself, a disk and a heading line
  7    local view: navigation goal direction (a line towards the goal, clipped) and the goal if
       inside the view; zeros in the exploration task
=====  ==========================================================================================
Unknown space is where channels 0/1 (or 4/5) are both 0.

Other layouts and dtypes for other clients (channels last, float in [0, 1]):
:class:`ObservationFormat`, chosen by the env options ``obs_layout`` and ``obs_dtype``.
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from typing import Any

import cv2
import gymnasium
import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.grid import FREE, FREE_THRESHOLD, OCCUPIED_THRESHOLD, UNKNOWN
from mrexplore.types import Box, RobotView

# The compiled shares and trail (None without numba); used while mrexplore.kernels.enabled(),
# else every view is drawn by the OpenCV path below.
_views = kernels.load("views")

N_CHANNELS = 8


def _window(
    grid: NDArray[np.int8], centre: tuple[float, float], side_cells: int
) -> NDArray[np.int8]:
    """Square ``side_cells`` crop of ``grid`` centred on ``centre`` (col, row); outside = unknown.

    Returns a view when the window lies inside the grid (the common case), else a padded copy.
    """
    half = side_cells // 2
    c0 = round(centre[0]) - half
    r0 = round(centre[1]) - half
    h, w = grid.shape
    if c0 >= 0 and r0 >= 0 and c0 + side_cells <= w and r0 + side_cells <= h:
        return grid[r0 : r0 + side_cells, c0 : c0 + side_cells]
    out = np.full((side_cells, side_cells), UNKNOWN, dtype=np.int8)
    rs, cs = max(r0, 0), max(c0, 0)
    re, ce = min(r0 + side_cells, h), min(c0 + side_cells, w)
    if rs < re and cs < ce:
        out[rs - r0 : re - r0, cs - c0 : ce - c0] = grid[rs:re, cs:ce]
    return out


def _shares(window: NDArray[np.int8], size: int) -> tuple[NDArray[np.uint8], NDArray[np.uint8]]:
    """Free and occupied shares of ``window`` resampled to ``size`` x ``size`` (0..255 each)."""
    if window.shape[0] >= 4 * size:
        # A coarse view of a big window (the global view: 512 cells -> 64 px): reading every
        # second cell halves the cost (measured 0.12 -> 0.06 ms) and changes a pixel's share by
        # sampling only; each pixel still averages 16 of its 64 cells.
        window = window[::2, ::2]
    # cv2.inRange on the int8 window is ~2x cheaper than numpy comparisons (measured).
    free = cv2.inRange(window, FREE, FREE_THRESHOLD)
    occ = cv2.inRange(window, OCCUPIED_THRESHOLD, 127)
    # INTER_AREA averages the cells under each pixel: a pixel's value is the share of that class.
    interp = cv2.INTER_AREA if window.shape[0] >= size else cv2.INTER_NEAREST
    free_px = cv2.resize(free, (size, size), interpolation=interp)
    occ_px = cv2.resize(occ, (size, size), interpolation=interp)
    # OpenCV's stubs type results as any-number arrays; inputs are uint8, so are the outputs.
    return free_px.astype(np.uint8, copy=False), occ_px.astype(np.uint8, copy=False)


def _class_code() -> NDArray[np.int32]:
    """Per int8 value ``v`` (at index ``v + 128``): 1 when free, ``1 << SHARE_BITS`` when
    occupied, else 0 (the classes of :func:`_shares`)."""
    v = np.arange(-128, 128)
    free = (v >= FREE) & (v <= FREE_THRESHOLD)
    occ = v >= OCCUPIED_THRESHOLD
    bits = _views.SHARE_BITS if _views is not None else 5
    return (free.astype(np.int32) + (occ.astype(np.int32) << bits)).astype(np.int32)


_CLASS_CODE = _class_code()
_CLASS_BOUNDS = np.array([FREE, FREE_THRESHOLD, OCCUPIED_THRESHOLD], dtype=np.int8)


def _area_lut(factor: int, size: int) -> NDArray[np.uint8] | None:
    """What OpenCV's INTER_AREA resize of a 0/255 mask by an integer ``factor`` (to ``size`` x
    ``size`` pixels, the size it is used at) gives a pixel whose block holds k set cells, for
    k = 0 .. factor**2; None when the value depends on more than the count (then the caller keeps
    OpenCV). Measured, not assumed: a block of k set cells is drawn at two different places in
    the block and both must agree."""
    n = factor * factor
    counts = np.arange(size * size) % (n + 1)
    lut = np.zeros(n + 1, dtype=np.uint8)
    seen = np.zeros(n + 1, dtype=bool)
    for flip in (False, True):
        order = np.arange(n)[::-1] if flip else np.arange(n)
        blocks = (order[None, :] < counts[:, None]).astype(np.uint8) * 255  # (size*size, n)
        img = (
            blocks.reshape(size, size, factor, factor)
            .transpose(0, 2, 1, 3)
            .reshape(size * factor, size * factor)
        )
        out = cv2.resize(img, (size, size), interpolation=cv2.INTER_AREA).reshape(-1)
        for k in range(n + 1):
            vals = np.unique(out[counts == k])
            if vals.size != 1 or (seen[k] and lut[k] != vals[0]):
                return None
            lut[k], seen[k] = vals[0], True
    return lut


def _known_array(grid: NDArray[np.int8], box: Box | None) -> NDArray[np.int64]:
    """A view's ``known_box`` as the int64 ``(r0, r1, c0, c1)`` the view kernel reads, the whole
    ``grid`` when the view does not give one."""
    if box is None:
        h, w = grid.shape
        box = (0, h, 0, w)
    return np.array(box, dtype=np.int64)


class ObservationBuilder:
    """Builds the ``(8, S, S)`` uint8 observation of one robot from its :class:`RobotView`.

    Args:
        resolution_m: map resolution, metres per cell.
        global_view_m: side of the coarse view, metres.
        local_view_m: side of the fine view, metres.
        size_px: pixels per side of each view (S).
    """

    def __init__(
        self,
        resolution_m: float,
        global_view_m: float,
        local_view_m: float,
        size_px: int,
        heading_up: bool = False,
    ) -> None:
        self.size = int(size_px)
        self.global_cells = max(self.size, round(global_view_m / resolution_m))
        self.local_cells = max(2, round(local_view_m / resolution_m))
        self.heading_up = bool(heading_up)
        self.shape = (N_CHANNELS, self.size, self.size)
        # heading-up scratch: the shares of the wider window, before they are turned
        big = 3 * self.size // 2
        self._big = (np.zeros((big, big), np.uint8), np.zeros((big, big), np.uint8))
        self._acc = np.zeros(big, dtype=np.int32)
        # per view side: (stride, factor, lut) of the compiled pass, or None for OpenCV's
        self._plans: dict[tuple[int, int], tuple[int, int, NDArray[np.uint8] | None]] = {}
        # the robot's disk on channel 6, drawn once per radius and copied into each observation
        self._disks: dict[int, NDArray[np.uint8]] = {}

    def build(
        self, view: RobotView, trail_cells: NDArray[np.float64] | None = None
    ) -> NDArray[np.uint8]:
        """Observation of one robot. ``trail_cells`` (T, 2): the robot's past (col, row) cells
        (default: ``view.trail``)."""
        return self.build_from(
            view.map,
            view.pose_cell,
            view.known_box,
            view.trail if trail_cells is None else trail_cells,
            view.teammates,
            view.goal_cell,
            view.robot_radius_m,
            view.resolution_m,
        )

    def build_from(
        self,
        grid: NDArray[np.int8],
        pose_cell: tuple[float, float, float],
        known_box: Box | None,
        trail_cells: NDArray[np.float64],
        teammates: Mapping[str, tuple[float, float]],
        goal_cell: tuple[float, float] | None,
        robot_radius_m: float,
        resolution_m: float,
    ) -> NDArray[np.uint8]:
        """:meth:`build` from the parts of a :class:`RobotView` it reads (the env's step
        passes them without making the view): ``grid`` (H, W) int8, ``pose_cell`` (col, row,
        theta_rad), ``known_box`` as ``RobotView.known_box``, ``trail_cells`` (T, 2),
        ``teammates`` name -> (col, row), ``goal_cell`` (col, row) or None; metres."""
        s = self.size
        obs = np.zeros(self.shape, dtype=np.uint8)
        col, row, theta = pose_cell
        # heading_up: turn the views so the robot's heading points along +row (the same way in
        # every observation), which spares a policy with turn/forward actions from learning to
        # rotate its input; otherwise the views keep the axes of the robot's own map frame.
        phi = math.pi / 2 - theta if self.heading_up else 0.0
        known = _known_array(grid, known_box)
        self._shares_view(grid, (col, row), self.global_cells, phi, obs[0], obs[1], known)
        scale_g = s / self.global_cells
        if _views is not None and kernels.enabled() and len(trail_cells):
            # one compiled pass over the trail instead of ~10 numpy calls on it
            cells = np.ascontiguousarray(trail_cells, dtype=np.float64)
            if phi == 0.0:
                _views.trail_dots(obs[2], cells, float(col), float(row), scale_g)
            else:
                cs, sn = math.cos(phi), math.sin(phi)  # as _turn
                _views.turned_trail_dots(obs[2], cells, float(col), float(row), scale_g, cs, sn)
        else:
            self._dots(obs[2], trail_cells, (col, row), scale_g, phi, radius=0)
        if teammates:
            self._dots(obs[3], list(teammates.values()), (col, row), scale_g, phi, radius=2)

        self._shares_view(grid, (col, row), self.local_cells, phi, obs[4], obs[5], known)
        scale_l = s / self.local_cells
        centre = (s // 2, s // 2)
        radius_px = max(1, round(robot_radius_m / resolution_m * scale_l))
        obs[6] = self._disk(radius_px)
        tip = (
            round(centre[0] + math.cos(theta + phi) * 2.5 * radius_px),
            round(centre[1] + math.sin(theta + phi) * 2.5 * radius_px),
        )
        cv2.line(obs[6], centre, tip, 255, 1)
        if goal_cell is not None:
            self._goal(obs[7], goal_cell, (col, row), scale_l, phi)
        return obs

    def _disk(self, radius_px: int) -> NDArray[np.uint8]:
        """Channel 6's robot disk of ``radius_px`` at the centre on zeros (drawn by OpenCV
        once per radius: the same pixels as drawing it into each observation)."""
        disk = self._disks.get(radius_px)
        if disk is None:
            disk = np.zeros((self.size, self.size), dtype=np.uint8)
            cv2.circle(disk, (self.size // 2, self.size // 2), radius_px, 255, -1)
            disk.flags.writeable = False
            self._disks[radius_px] = disk
        return disk

    def _shares_view(
        self,
        grid: NDArray[np.int8],
        centre: tuple[float, float],
        side: int,
        phi: float,
        out_free: NDArray[np.uint8],
        out_occ: NDArray[np.uint8],
        known: NDArray[np.int64],
    ) -> None:
        """Free/occupied shares of a ``side``-cell view centred on ``centre``, turned by ``phi``,
        written into ``out_free`` / ``out_occ`` (S, S); ``known`` as :func:`_known_array`."""
        s = self.size
        if phi == 0.0:
            self._shares_into(grid, centre, side, out_free, out_occ, known)
            return
        # A window 1.5x as wide (its inscribed circle covers the turned square), resampled to
        # 1.5x the pixels, turned about its centre, and cropped back to s x s.
        big_side, big_px = 3 * side // 2, 3 * s // 2
        free, occ = self._big
        self._shares_into(grid, centre, big_side, free, occ, known)
        c = (big_px - 1) / 2.0
        cs, sn = math.cos(phi), math.sin(phi)
        off = (big_px - s) // 2
        # dst = R (src - c) + c - off: turn about the centre, then shift the crop to the origin
        M = np.array([[cs, -sn, c - cs * c + sn * c - off], [sn, cs, c - sn * c - cs * c - off]])
        for im, out in ((free, out_free), (occ, out_occ)):
            out[:] = cv2.warpAffine(im, M, (s, s), flags=cv2.INTER_LINEAR, borderValue=0)

    def _shares_into(
        self,
        grid: NDArray[np.int8],
        centre: tuple[float, float],
        side: int,
        out_free: NDArray[np.uint8],
        out_occ: NDArray[np.uint8],
        known: NDArray[np.int64],
    ) -> None:
        """:func:`_shares` of :func:`_window` into ``out_free`` / ``out_occ`` (n, n): by one
        compiled pass over the window when the resize is an integer INTER_AREA factor whose
        OpenCV values the lut reproduces (the defaults: 4 for the coarse view, 2 for the fine
        one), else by the OpenCV path. The same values either way (tested)."""
        size = out_free.shape[0]
        plan = self._plans.get((side, size))
        if plan is None:
            plan = self._plans[(side, size)] = self._plan(side, size)
        stride, factor, lut = plan
        if lut is None or not kernels.enabled():
            out_free[:], out_occ[:] = _shares(_window(grid, centre, side), size)
            return
        assert _views is not None
        half = side // 2
        _views.view_shares(
            grid,
            round(centre[1]) - half,
            round(centre[0]) - half,
            stride,
            factor,
            lut,
            _CLASS_CODE,
            _CLASS_BOUNDS,
            self._acc,
            out_free,
            out_occ,
            known,
        )

    def _plan(self, side: int, size: int) -> tuple[int, int, NDArray[np.uint8] | None]:
        """How :meth:`_shares_into` resamples a ``side``-cell window to ``size`` pixels: the
        stride it reads the window at, the integer INTER_AREA factor and its lut (None: the
        OpenCV path)."""
        stride = 2 if side >= 4 * size else 1  # as _shares: every second cell of a big window
        cells = -(-side // stride)
        factor = cells // size
        fits = (
            _views is not None
            and factor >= 1
            and factor * factor < 1 << _views.SHARE_BITS
            and factor * size == cells
        )
        return stride, factor, _area_lut(factor, size) if fits else None

    def _dots(
        self,
        channel: NDArray[np.uint8],
        cells: NDArray[np.float64] | Sequence[tuple[float, float]],
        centre: tuple[float, float],
        scale: float,
        phi: float,
        radius: int,
    ) -> None:
        """Mark ``cells`` (N, 2) (col, row) on a robot-centred channel turned by ``phi``; points
        outside the view are dropped."""
        if len(cells) == 0:
            return
        s = channel.shape[0]
        if len(cells) <= _FEW_DOTS:
            # a teammate or two: numpy's per-call overhead on (1, 2) arrays cost ~25 us a robot
            # per merged step; the same IEEE operations on Python floats give the same cells
            c0, r0 = float(centre[0]), float(centre[1])
            cs, sn = math.cos(phi), math.sin(phi)
            for x, y in cells:
                dx, dy = float(x) - c0, float(y) - r0
                if phi != 0.0:
                    dx, dy = dx * cs - dy * sn, dx * sn + dy * cs
                px, py = math.floor(dx * scale + s / 2), math.floor(dy * scale + s / 2)
                if 0 <= px < s and 0 <= py < s:
                    if radius == 0:
                        channel[py, px] = 255
                    else:
                        cv2.circle(channel, (px, py), radius, 255, -1)
            return
        rel = _turn(np.asarray(cells, dtype=np.float64).reshape(-1, 2) - np.asarray(centre), phi)
        px = np.floor(rel * scale + s / 2).astype(np.int64)
        ok = (px[:, 0] >= 0) & (px[:, 0] < s) & (px[:, 1] >= 0) & (px[:, 1] < s)
        px = px[ok]
        if radius == 0:
            channel[px[:, 1], px[:, 0]] = 255
        else:
            for x, y in px:
                cv2.circle(channel, (int(x), int(y)), radius, 255, -1)

    def _goal(
        self,
        channel: NDArray[np.uint8],
        goal: tuple[float, float],
        centre: tuple[float, float],
        scale: float,
        phi: float,
    ) -> None:
        """A line from the robot towards the goal (clipped to the view) and a disk at the goal."""
        s = channel.shape[0]
        c = s // 2
        d = _turn(np.array([[goal[0] - centre[0], goal[1] - centre[1]]]), phi)[0] * scale
        dx, dy = float(d[0]), float(d[1])
        dist = math.hypot(dx, dy)
        limit = c - 1
        if dist > limit and dist > 0:
            dx, dy = dx * limit / dist, dy * limit / dist
        end = (round(c + dx), round(c + dy))
        cv2.line(channel, (c, c), end, 128, 1)
        if dist <= limit:
            cv2.circle(channel, end, 2, 255, -1)


#: Up to this many points :meth:`ObservationBuilder._dots` marks in plain Python (teammates).
_FEW_DOTS = 8


def _turn(points: NDArray[np.float64], phi: float) -> NDArray[np.float64]:
    """Rotate (N, 2) (col, row) offsets by ``phi`` radians."""
    if phi == 0.0:
        return points
    cs, sn = math.cos(phi), math.sin(phi)
    # elementwise, not points @ R (BLAS, CPU-dependent fused rounding): the same bits everywhere
    x, y = points[:, 0], points[:, 1]
    return np.stack([x * cs - y * sn, x * sn + y * cs], axis=1)


class ObservationFormat:
    """The layout and dtype a client reads (``obs_layout``, ``obs_dtype`` of ``EnvConfig``).

    The builder always draws ``(8, S, S)`` uint8; this turns it into what the client's default
    model reads without a wrapper: ``"chw"`` keeps channels first (SB3, TorchRL), ``"hwc"`` puts
    them last (RLlib); ``"float32"`` divides by 255 (values in [0, 1]) for models that take the
    input as it comes (RLlib, TorchRL), ``"uint8"`` keeps 0..255 (SB3 normalises it itself).

    >>> fmt = ObservationFormat("hwc", "float32")
    >>> o = fmt.apply(np.full((8, 64, 64), 255, dtype=np.uint8))
    >>> o.shape, o.dtype.name, float(o.max()), fmt.channel_axis
    ((64, 64, 8), 'float32', 1.0, -1)
    """

    def __init__(self, layout: str = "chw", dtype: str = "uint8") -> None:
        if layout not in ("chw", "hwc") or dtype not in ("uint8", "float32"):
            raise ValueError(f"unknown observation format {layout!r}/{dtype!r}")
        self.layout = layout
        self.dtype = np.dtype(np.uint8 if dtype == "uint8" else np.float32)
        #: the axis that holds the channels (and stacks robots in ``state()``)
        self.channel_axis = 0 if layout == "chw" else -1

    def shape(self, chw: tuple[int, ...]) -> tuple[int, ...]:
        """The client's shape of a ``(C, H, W)`` observation."""
        return chw if self.layout == "chw" else (*chw[1:], chw[0])

    def space(self, chw: tuple[int, ...]) -> gymnasium.spaces.Box:
        """The ``Box`` of a ``(C, H, W)`` uint8 observation in this format."""
        if self.dtype == np.uint8:
            return gymnasium.spaces.Box(0, 255, self.shape(chw), dtype=np.uint8)
        return gymnasium.spaces.Box(0.0, 1.0, self.shape(chw), dtype=np.float32)

    def apply(self, obs: NDArray[np.uint8]) -> NDArray[Any]:
        """``obs`` (C, H, W) uint8 in this format: the same array when nothing changes, else a
        new C-contiguous one (torch and RLlib copy strided views slowly)."""
        out: NDArray[Any] = obs
        if self.layout == "hwc":
            out = np.ascontiguousarray(out.transpose(1, 2, 0))
        if self.dtype == np.float32:
            # a true division: 255 / 255 is exactly 1.0, so the Box [0, 1] always holds
            out = np.divide(out, np.float32(255.0), dtype=np.float32)
        return out
