"""Ground truth for the simulator and for evaluation only: frames, reachable space, coverage.

Nothing here may reach a robot, a policy or the merger: it knows where every robot started.

Frames. World cells are the cells of :class:`mrexplore.world.World` (``(col, row)``, integer
centres). A robot's map cells are those of its :class:`mrexplore.mapping.OccupancyMap`: its start
position at ``origin_cell``, +col along its start heading. Transforms are 3x3 float64 on
``(col, row, 1)``; ``T_ab`` maps b's cells into a's.
"""

from __future__ import annotations

import math

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import ConfigError, GridError
from mrexplore.grid import Transform, apply_transform, transform_angle
from mrexplore.robot import configuration_space, disc_kernel, largest_component
from mrexplore.world.world import World


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
    return np.asarray(world_m_to_cells @ frame_to_world_m @ map_to_frame, dtype=np.float64)


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
    return np.asarray(np.linalg.inv(t_wa) @ t_wb, dtype=np.float64)


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
    rot = abs(math.degrees(transform_angle(np.asarray(T_est) @ np.linalg.inv(T_true))))
    return float(disp.mean()), float(rot)
