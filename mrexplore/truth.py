"""Ground truth for the simulator and for evaluation only: frames, reachable space, coverage.

Nothing here may reach a robot, a policy or the merger: it knows where every robot started.

Frames. World cells are the cells of :class:`mrexplore.world.World` (``(col, row)``, integer
centres). A robot's map cells are those of its :class:`mrexplore.mapping.OccupancyMap`: its start
position at ``origin_cell``, +col along its start heading. Transforms are 3x3 float64 on
``(col, row, 1)``; ``T_ab`` maps b's cells into a's.

Map accuracy (:class:`MapScorer`, :func:`map_contradiction`): a robot's map (its own or its
fused map) is warped into the world frame with the *true* transform and compared with the walls,
so a map merged with a wrong transform shows as knowledge that contradicts the truth.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore import kernels
from mrexplore.errors import ConfigError, GridError
from mrexplore.grid import (
    FREE,
    FREE_THRESHOLD,
    OCCUPIED_THRESHOLD,
    UNKNOWN,
    Int8Grid,
    Transform,
    apply_transform,
    chain,
    invert_transform,
    transform_angle,
)
from mrexplore.robot import configuration_space, disc_kernel, largest_component
from mrexplore.types import Box
from mrexplore.world.world import World

# The compiled scoring (None without numba); used while mrexplore.kernels.enabled().
_scoring = kernels.load("scoring")


def T_world_from_map(
    start_pose_world: tuple[float, float, float] | NDArray[np.floating],
    origin_cell: tuple[float, float],
    map_resolution_m: float,
    world: World,
) -> Transform:
    """3x3 transform from a robot's map cells ``(col, row, 1)`` to world cells.

    Map cell -> own-frame metres ``((c - c0) res_m, (r - r0) res_m)`` -> rotate by the start
    heading and translate to the start position (world metres) -> world cells.
    """
    x, y, th = (float(v) for v in np.asarray(start_pose_world, dtype=np.float64).reshape(3))
    if not (math.isfinite(map_resolution_m) and map_resolution_m > 0.0):
        raise ConfigError(f"map_resolution_m must be positive, got {map_resolution_m}")
    c0, r0 = float(origin_cell[0]), float(origin_cell[1])
    rm = map_resolution_m
    map_to_frame = np.array([[rm, 0.0, -c0 * rm], [0.0, rm, -r0 * rm], [0.0, 0.0, 1.0]])
    c, s = math.cos(th), math.sin(th)
    frame_to_world_m = np.array([[c, -s, x], [s, c, y], [0.0, 0.0, 1.0]])
    rw = world.resolution_m
    ox, oy = world.origin_m
    world_m_to_cells = np.array(
        [[1.0 / rw, 0.0, -ox / rw - 0.5], [0.0, 1.0 / rw, -oy / rw - 0.5], [0.0, 0.0, 1.0]]
    )
    # chain, not @: the product carries the resolutions' scale, the same bits on every CPU
    return chain(world_m_to_cells, frame_to_world_m, map_to_frame)


def true_transform(
    start_a: tuple[float, float, float] | NDArray[np.floating],
    origin_cell_a: tuple[float, float],
    start_b: tuple[float, float, float] | NDArray[np.floating],
    origin_cell_b: tuple[float, float],
    world: World,
    resolution_m: float,
) -> Transform:
    """``T_ab``: robot b's map cells -> robot a's map cells (both maps at ``resolution_m``)."""
    t_wa = T_world_from_map(start_a, origin_cell_a, resolution_m, world)
    t_wb = T_world_from_map(start_b, origin_cell_b, resolution_m, world)
    # t_wa scales (map and world resolutions): the affine inverse, not a rigid one; no LAPACK
    return chain(invert_transform(t_wa), t_wb)


def reachable_cspace(
    world: World,
    radius_m: float,
    seeds_cells: NDArray[np.integer] | None = None,
) -> NDArray[np.bool_]:
    """bool (H, W): free configuration-space cells (4-connected) in the components holding the
    seeds (integer ``(col, row)`` cells, e.g. the starts), or the largest component if None.
    A seed in collision contributes nothing."""
    free_cs = ~configuration_space(world.walls, radius_m / world.resolution_m)
    if seeds_cells is None:
        return largest_component(free_cs)
    seeds = np.asarray(seeds_cells, dtype=np.int64).reshape(-1, 2)
    h, w = world.shape
    if ((seeds[:, 0] < 0) | (seeds[:, 0] >= w) | (seeds[:, 1] < 0) | (seeds[:, 1] >= h)).any():
        raise GridError(f"seed cells {seeds.tolist()} outside the {h}x{w} world")
    _, labels = cv2.connectedComponents(free_cs.astype(np.uint8), connectivity=4)
    ids = np.unique(labels[seeds[:, 1], seeds[:, 0]])
    ids = ids[ids > 0]  # label 0 = blocked
    return np.asarray(np.isin(labels, ids))


def reachable_free(
    world: World,
    radius_m: float,
    seeds_cells: NDArray[np.integer] | None = None,
) -> NDArray[np.bool_]:
    """bool (H, W): the free world cells that count for coverage.

    The robots' centres move in the connected components of the free configuration space
    (4-connected) that contain the seeds (integer ``(col, row)`` cells, e.g. the starts; default:
    the largest component). The cells that count are the free cells the robots' bodies can
    reach: those components dilated by the radius plus one cell (so the free cells along the
    walls of every room a robot can enter are included), intersected with the free cells.
    Space a robot can see but never enter (behind a gap narrower than the robot) does not count.
    """
    r_cells = radius_m / world.resolution_m
    comp = reachable_cspace(world, radius_m, seeds_cells)
    body = cv2.dilate(comp.astype(np.uint8), disc_kernel(r_cells + 1.0)).astype(bool)
    return body & world.free


def coverage(observed: NDArray[np.bool_], reachable: NDArray[np.bool_]) -> float:
    """Share in [0, 1] of the ``reachable`` cells that are ``observed`` (both bool (H, W))."""
    if observed.shape != reachable.shape:
        raise GridError(
            f"observed {observed.shape} and reachable {reachable.shape} differ in shape"
        )
    n = int(np.count_nonzero(reachable))
    if n == 0:
        return 0.0
    return float(np.count_nonzero(observed & reachable)) / n


def transform_error(
    T_est: Transform, T_true: Transform, points_b: NDArray[np.floating]
) -> tuple[float, float]:
    """``(mean displacement in cells, rotation error in degrees)`` of an estimated ``T_ab``
    against the truth, measured on b's cells ``points_b`` (N, 2)."""
    pts = np.asarray(points_b, dtype=np.float64).reshape(-1, 2)
    if pts.shape[0] == 0:
        raise GridError("transform_error needs at least one point")
    disp = np.linalg.norm(apply_transform(T_est, pts) - apply_transform(T_true, pts), axis=1)
    return float(disp.mean()), rotation_error_deg(T_est, T_true)


def rotation_error_deg(T_est: Transform, T_true: Transform) -> float:
    """How far the rotation of ``T_est`` is from that of ``T_true``: ``|angle|`` in degrees of
    ``T_est T_true^-1`` (:func:`transform_error`'s second figure)."""
    return float(abs(math.degrees(transform_angle(chain(T_est, invert_transform(T_true))))))


def known_cells(
    grid: Int8Grid,
    box: Box | None = None,
    max_points: int | None = None,
) -> NDArray[np.float64]:
    """The known cells of an int8 map as ``(N, 2)`` float64 ``(col, row)``, row-major; inside
    ``box`` (half-open :data:`~mrexplore.types.Box`; the map's known box spares a scan) if
    given; with ``max_points``, an even sample: every k-th cell, ``k = n // max_points`` (so
    between ``max_points`` and ``2 max_points - 1`` cells when there are more).

    >>> g = np.full((3, 4), UNKNOWN, dtype=np.int8); g[1, 2] = 0; g[2, 0] = 100
    >>> known_cells(g).tolist()
    [[2.0, 1.0], [0.0, 2.0]]
    """
    r0, c0 = (0, 0) if box is None else (box[0], box[2])
    sub = grid if box is None else grid[box[0] : box[1], box[2] : box[3]]
    rows, cols = np.nonzero(sub != UNKNOWN)
    step = 1 if max_points is None else max(1, len(rows) // max_points)
    return np.stack([cols[::step] + c0, rows[::step] + r0], axis=1).astype(np.float64)


def merge_error(
    T_est: Transform,
    T_true: Transform,
    b: Int8Grid,
    box: Box | None = None,
    max_points: int | None = None,
) -> tuple[float, float] | None:
    """The error of a merge: :func:`transform_error` of the estimated ``T_ab`` measured on b's
    known cells (:func:`known_cells` with ``box`` and ``max_points``), None when b knows
    nothing. The one measure of the env's infos, the renderer and the merge benchmark (under 2
    cells is a correct merge, 5 or more a wrong one)."""
    pts = known_cells(b, box, max_points)
    if len(pts) == 0:
        return None
    return transform_error(T_est, T_true, pts)


def map_in_world(
    map_grid: Int8Grid, T_world_from_map: Transform, world_shape: tuple[int, int]
) -> Int8Grid:
    """A robot's int8 map (H_m, W_m) warped into the world's cells: int8 ``world_shape``.

    Nearest neighbour: each world cell takes the value of the map cell its centre falls in
    (``T_world_from_map`` maps map cells ``(col, row, 1)`` to world cells); world cells whose
    preimage lies outside the map are unknown. The cost is one pass over the world's cells,
    whatever the size of the map's canvas (no copy or conversion of the map).
    """
    m = np.ascontiguousarray(map_grid)
    if m.dtype != np.int8 or m.ndim != 2:
        raise GridError(f"map_in_world needs a 2-D int8 map, got {m.dtype} {m.shape}")
    # int8 viewed as uint8: unknown (-1) becomes 255, 0..100 stay; the border is unknown too.
    out = cv2.warpAffine(
        m.view(np.uint8),
        np.asarray(T_world_from_map, dtype=np.float64)[:2],
        (int(world_shape[1]), int(world_shape[0])),
        flags=cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=int(np.int8(UNKNOWN).view(np.uint8)),
    )
    return np.asarray(out).view(np.int8)


class MapScorer:
    """Scores robots' maps against one world's truth (evaluation only).

    Args:
        walls: bool (H, W) the world's wall grid (True = wall, obstacle or outside).
        reachable: bool (H, W) the free cells that count for coverage (for :meth:`held_free`);
            None if not needed.

    A map's *claims* are its known-free cells (occupancy 0..``FREE_THRESHOLD`` %) and its
    known-occupied cells (>= ``OCCUPIED_THRESHOLD`` %), warped into the world by
    :func:`map_in_world`. A claim *contradicts* the truth when it is

    - a free claim on a true wall cell, or
    - an occupied claim with no true wall cell within 1 cell (its 3x3 neighbourhood, so a wall
      seen one cell off, by range noise or the nearest-neighbour warp, is not a contradiction).

    Claims that land outside the world's grid are not counted (a map placed by a correct
    transform lies inside it, the world's outer walls included).
    """

    def __init__(
        self, walls: NDArray[np.bool_], reachable: NDArray[np.bool_] | None = None
    ) -> None:
        w = np.asarray(walls)
        if w.dtype != np.bool_ or w.ndim != 2 or w.size == 0:
            raise GridError(f"walls must be a non-empty 2-D bool array, got {w.dtype} {w.shape}")
        if reachable is not None and np.shape(reachable) != w.shape:
            raise GridError(f"reachable {np.shape(reachable)} and walls {w.shape} differ in shape")
        self.walls = w
        self.shape = (int(w.shape[0]), int(w.shape[1]))
        # cells with a true wall within 1 cell (8-neighbourhood); outside the grid counts as wall
        self.near_wall = cv2.dilate(
            w.astype(np.uint8),
            np.ones((3, 3), np.uint8),
            borderType=cv2.BORDER_CONSTANT,
            borderValue=1,
        ).astype(bool)
        self.reachable = None if reachable is None else np.asarray(reachable, dtype=bool)

    def warp(self, map_grid: Int8Grid, T_world_from_map: Transform) -> Int8Grid:
        """:func:`map_in_world` onto this world's grid."""
        return map_in_world(map_grid, T_world_from_map, self.shape)

    def contradiction(self, in_world: Int8Grid) -> float:
        """Share in [0, 1] of the claims of a warped map (int8 (H, W)) that contradict the truth
        (see the class doc); NaN when it makes no claim inside the world."""
        free = (in_world >= FREE) & (in_world <= FREE_THRESHOLD)
        occ = in_world >= OCCUPIED_THRESHOLD
        n = int(np.count_nonzero(free)) + int(np.count_nonzero(occ))
        if n == 0:
            return float("nan")
        bad = int(np.count_nonzero(free & self.walls)) + int(
            np.count_nonzero(occ & ~self.near_wall)
        )
        return bad / n

    def scores(self, in_world: Int8Grid, held: bool = False) -> tuple[float, int | None]:
        """``(contradiction(in_world), held_free(in_world) if held else None)`` in one compiled
        pass over the world's cells (the env scores every robot's map every step it changed);
        the same integers, hence the same figures, as the two methods."""
        if held and self.reachable is None:
            raise GridError("MapScorer.held_free needs the reachable cells (reachable=...)")
        m = np.ascontiguousarray(in_world)
        if m.shape != self.shape or m.dtype != np.int8:
            raise GridError(f"in_world must be int8 {self.shape}, got {m.dtype} {m.shape}")
        if not kernels.enabled():
            return self.contradiction(m), (self.held_free(m) if held else None)
        assert _scoring is not None
        reach = self.reachable if self.reachable is not None else self.near_wall
        n, bad, n_held = _scoring.claim_counts(
            m, self.walls, self.near_wall, reach, FREE_THRESHOLD, OCCUPIED_THRESHOLD, held
        )
        share = float("nan") if n == 0 else bad / n
        return share, (int(n_held) if held else None)

    def held_free(self, in_world: Int8Grid) -> int:
        """Reachable free cells that a warped map (int8 (H, W)) holds at their true place: it
        claims them without contradicting the truth, as free, or as occupied with a true wall
        within one cell (a wall the mapper drew a cell onto the floor beside it is no wrong
        knowledge; a fused map of two robots draws each wall from both sides)."""
        if self.reachable is None:
            raise GridError("MapScorer.held_free needs the reachable cells (reachable=...)")
        free = (in_world >= FREE) & (in_world <= FREE_THRESHOLD)
        beside = (in_world >= OCCUPIED_THRESHOLD) & self.near_wall
        return int(np.count_nonzero((free | beside) & self.reachable))


def nearest_sampling(
    T_world_from_map: Transform, map_shape: tuple[int, int], world_shape: tuple[int, int]
) -> NDArray[np.int32] | None:
    """For every world cell, the flat index of the map cell :func:`map_in_world` copies into it
    (int32 ``world_shape``; -1 where it copies the unknown border), or None if that could not
    be established exactly.

    The index image is warped as four uint8 channels with the same nearest-neighbour warp; the
    three index bytes are then checked against single-channel warps of each byte plane, which
    sample exactly as :func:`map_in_world` does: a mismatch (an OpenCV whose multi-channel path
    rounds differently) gives None, and the caller warps the map itself."""
    h, w = int(map_shape[0]), int(map_shape[1])
    if h * w >= 1 << 24:
        return None  # three index bytes
    M = np.asarray(T_world_from_map, dtype=np.float64)[:2]
    size = (int(world_shape[1]), int(world_shape[0]))
    idx = np.arange(h * w, dtype=np.int32).reshape(h, w)
    planes = idx.view(np.uint8).reshape(h, w, 4)  # little-endian bytes; byte 3 is 0
    warped = cv2.warpAffine(
        planes,
        M,
        size,
        flags=cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=(255, 255, 255, 255),
    )
    out = np.ascontiguousarray(warped).view(np.int32).reshape(world_shape)
    for b in range(3):
        one = cv2.warpAffine(
            np.ascontiguousarray(planes[:, :, b]),
            M,
            size,
            flags=cv2.INTER_NEAREST,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=255,
        )
        if not np.array_equal(one, warped[:, :, b]):
            return None
    return np.asarray(out, dtype=np.int32)


class IncrementalScore:
    """:meth:`MapScorer.scores` of one robot's map kept up to date from the boxes that changed.

    Built once per episode for a robot whose map-to-world transform is fixed: each world cell's
    source cell (:func:`nearest_sampling`) is known, so a change of the map inside a box only
    re-scores the world cells that sample from it. The figures equal a full warp and count.

    Args:
        scorer: the episode's :class:`MapScorer` (with ``reachable`` for the held cells).
        T_world_from_map: the robot's map cells -> world cells.
        sample: :func:`nearest_sampling` of that transform.
    """

    def __init__(
        self, scorer: MapScorer, T_world_from_map: Transform, sample: NDArray[np.int32]
    ) -> None:
        self.scorer = scorer
        self.T = np.asarray(T_world_from_map, dtype=np.float64)
        # its entries as Python floats: the box of every step is mapped in plain Python
        self._t = tuple(float(v) for v in self.T[:2].reshape(-1))
        self._t_arr = np.array(self._t)
        self._rigid = bool(np.allclose(self.T[:2, :2] @ self.T[:2, :2].T, np.eye(2)))
        self.sample = sample
        self.cls = np.zeros(scorer.shape, dtype=np.uint8)
        self.counts = np.zeros(3, dtype=np.int64)
        self._reach = scorer.reachable if scorer.reachable is not None else scorer.near_wall

    def update(self, map_grid: Int8Grid, box: Box | None) -> tuple[float, int]:
        """Re-score after ``map_grid`` changed inside ``box`` (map cells, half-open
        ``(r0, r1, c0, c1)``; None = anywhere). Returns ``(contradiction share or NaN, reachable
        free claims)``, as :meth:`MapScorer.scores`. Compiled only: without the kernels the
        env scores whole warps instead."""
        assert _scoring is not None

        src = np.ascontiguousarray(map_grid).reshape(-1)
        H, W = self.scorer.shape
        if box is None:
            region: Box | None = (0, H, 0, W)
        elif box[1] <= box[0] or box[3] <= box[2]:
            region = None  # nothing changed
        else:
            region = self._world_box(box)
        if region is not None:
            r0, r1, c0, c1 = region
            _scoring.score_region(
                src,
                self.sample,
                self.cls,
                self.scorer.walls,
                self.scorer.near_wall,
                self._reach,
                r0,
                r1,
                c0,
                c1,
                FREE_THRESHOLD,
                OCCUPIED_THRESHOLD,
                self.counts,
            )
        n, bad, held = self.counts.tolist()
        return (float("nan") if n == 0 else bad / n), held

    def update_cells(self, map_grid: Int8Grid, cells: NDArray[np.int64]) -> tuple[float, int]:
        """:meth:`update` after ``map_grid`` changed in the cells ``cells`` only (flat indices,
        e.g. :meth:`mrexplore.mapping.OccupancyMap.changed_cells`): only the world cells that
        sample them are re-scored, with the same figures (a scan changes ~100 cells of a box of
        ~10,000). Needs a rigid map-to-world transform, the map at the world's resolution (the
        simulator's): the world cells of a map cell are then found around its image."""
        assert _scoring is not None
        if not self._rigid:
            raise GridError("IncrementalScore.update_cells needs a rigid map-to-world transform")
        _scoring.score_cells(
            np.ascontiguousarray(map_grid).reshape(-1),
            map_grid.shape[1],
            self.sample,
            self.cls,
            self.scorer.walls,
            self.scorer.near_wall,
            self._reach,
            self._t_arr,
            np.asarray(cells, dtype=np.int64),
            FREE_THRESHOLD,
            OCCUPIED_THRESHOLD,
            self.counts,
        )
        n, bad, held = self.counts.tolist()
        return (float("nan") if n == 0 else bad / n), held

    def _world_box(self, box: Box) -> Box | None:
        """World cells that may sample from map ``box``: the image of its cell centres with two
        cells of slack (nearest sampling moves a cell by at most ~0.71), clipped."""
        r0, r1, c0, c1 = box
        a, b, tx, c, d, ty = self._t
        corners = ((c0, r0), (c1 - 1, r0), (c0, r1 - 1), (c1 - 1, r1 - 1))
        xs = [a * x + b * y + tx for x, y in corners]
        ys = [c * x + d * y + ty for x, y in corners]
        H, W = self.scorer.shape
        wr0, wr1 = max(0, math.floor(min(ys)) - 2), min(H, math.ceil(max(ys)) + 3)
        wc0, wc1 = max(0, math.floor(min(xs)) - 2), min(W, math.ceil(max(xs)) + 3)
        return (wr0, wr1, wc0, wc1) if wr1 > wr0 and wc1 > wc0 else None


def map_contradiction(
    map_grid: Int8Grid, T_world_from_map: Transform, walls: NDArray[np.bool_]
) -> float:
    """Share in [0, 1] of a robot's map's claims that contradict the truth (evaluation only).

    Args:
        map_grid: int8 (H_m, W_m) the robot's own or fused map in its own frame (-1/0/100).
        T_world_from_map: 3x3 true transform from the map's cells to world cells
            (:meth:`mrexplore.sim.Simulation.world_from_map`).
        walls: bool (H, W) the world's walls.

    The map is warped into the world (nearest neighbour, the world's size). Its claims are its
    known-free cells (occupancy <= ``FREE_THRESHOLD`` %) and known-occupied cells
    (>= ``OCCUPIED_THRESHOLD`` %); a free claim on a true wall cell, or an occupied claim with no
    true wall within 1 cell (3x3 neighbourhood), contradicts the truth. Returns
    ``contradicting claims / claims`` inside the world, NaN when there is no claim there.
    Builds a :class:`MapScorer` each call; the env keeps one per episode.

    >>> walls = np.zeros((5, 5), dtype=bool); walls[:, 0] = True
    >>> m = np.full((5, 5), -1, dtype=np.int8); m[:, 0] = 100; m[:, 1:3] = 0
    >>> map_contradiction(m, np.eye(3), walls)
    0.0
    >>> m[0, 0] = 0; m[2, 3] = 100  # a free cell on a wall; a wall with no wall near it
    >>> round(map_contradiction(m, np.eye(3), walls), 3)
    0.125
    """
    scorer = MapScorer(walls)
    return scorer.contradiction(scorer.warp(map_grid, T_world_from_map))
