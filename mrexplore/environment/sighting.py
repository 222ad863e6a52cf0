"""Sightings: robots that see each other measure where the other one is (off by default).

A rendezvous is how real teams learn the transform between their maps when the maps alone
cannot tell look-alike places apart (Zhou & Roumeliotis, "Multi-robot SLAM with unknown
initial correspondence: the robot rendezvous case", IROS 2006). This is a sensor like the
lidar: physics decides whether robot i sees robot j (the true distance within
``range_m`` and the segment between them free of walls in the world), and what i measures is
j's pose in i's body frame with noise (range, bearing, relative heading). From it and the two
robots' own pose estimates (odometry, in their own maps) follows a guess of the transform
between their maps, which the merge tracker takes as a :class:`~mrexplore.merge.PosePrior`.
No true pose or transform reaches a robot or the merger: only the noisy measurement, chained
with what each robot already knows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numpy.typing import NDArray

from mrexplore.grid import Transform, chain
from mrexplore.sensors import cast_ray_reference
from mrexplore.types import Sighting


@dataclass(frozen=True)
class SightingSensor:
    """Who sees whom, and what they measure.

    Args:
        range_m: a robot sees a teammate within this true distance, in metres, with no wall
            between their centres.
        noise_range_m: standard deviation of the measured distance, metres.
        noise_bearing_rad: standard deviation of the measured bearing, radians.
        noise_heading_rad: standard deviation of the measured relative heading, radians.
    """

    range_m: float
    noise_range_m: float = 0.05
    noise_bearing_rad: float = 0.02
    noise_heading_rad: float = 0.05

    def visible(
        self, walls: NDArray[np.bool_], cell_i: tuple[float, float], cell_j: tuple[float, float]
    ) -> bool:
        """Whether the segment between two world cells ``(col, row)`` (continuous) crosses no
        wall (the exact ray traversal of the lidar's reference cast)."""
        dc, dr = cell_j[0] - cell_i[0], cell_j[1] - cell_i[1]
        dist = math.hypot(dc, dr)
        if dist == 0.0:
            return True
        # the reference cast starts at a cell index's centre: shift by half a cell
        _, hit = cast_ray_reference(
            walls, (cell_i[0] - 0.5, cell_i[1] - 0.5), math.atan2(dr, dc), dist
        )
        return not hit

    def measure(
        self, pose_i: NDArray[np.float64], pose_j: NDArray[np.float64], rng: np.random.Generator
    ) -> tuple[float, float, float]:
        """Robot j's pose in robot i's body frame ``(x_m, y_m, theta_rad)`` from their true
        world poses ``[x_m, y_m, theta]``, with noise drawn from ``rng`` (three normals)."""
        xi, yi, ti = (float(v) for v in pose_i)
        xj, yj, tj = (float(v) for v in pose_j)
        dx, dy = xj - xi, yj - yi
        c, s = math.cos(ti), math.sin(ti)
        bx, by = c * dx + s * dy, -s * dx + c * dy
        e_range, e_bearing, e_heading = rng.normal(size=3)
        rho = math.hypot(bx, by) + self.noise_range_m * float(e_range)
        beta = math.atan2(by, bx) + self.noise_bearing_rad * float(e_bearing)
        return (
            rho * math.cos(beta),
            rho * math.sin(beta),
            tj - ti + self.noise_heading_rad * float(e_heading),
        )


def _pose(c: float, r: float, th: float) -> Transform:
    """The 3x3 transform of a pose ``(col, row, theta)``: its body cells -> map cells."""
    cs, sn = math.cos(th), math.sin(th)
    return np.array([[cs, -sn, c], [sn, cs, r], [0.0, 0.0, 1.0]])


def guess_from_sighting(
    est_i: tuple[float, float, float],
    est_j: tuple[float, float, float],
    z: tuple[float, float, float],
    resolution_m: float,
) -> Transform:
    """``T_ij`` (j's map cells -> i's map cells) from robot i's and j's own pose estimates in
    their map cells ``(col, row, theta)`` and i's measurement ``z`` of j (``measure``): j sits
    at ``est_i`` composed with ``z`` in i's map, and at ``est_j`` in its own."""
    x, y, th = z
    in_i = chain(_pose(*est_i), _pose(x / resolution_m, y / resolution_m, th))
    c, r, t = est_j
    cs, sn = math.cos(t), math.sin(t)
    # a rigid pose inverts by its transpose: no division by the determinant that
    # grid.invert_transform's general closed form does
    inv_j = np.array([[cs, sn, -(cs * c + sn * r)], [-sn, cs, sn * c - cs * r], [0.0, 0.0, 1.0]])
    return chain(in_i, inv_j)


def sightings(
    sensor: SightingSensor,
    walls: NDArray[np.bool_],
    true_poses: NDArray[np.float64],
    world_cells: NDArray[np.float64],
    est_cells: list[tuple[float, float, float]],
    resolution_m: float,
    pairs: list[tuple[int, int]],
    rng: np.random.Generator,
) -> dict[tuple[int, int], Sighting]:
    """This step's sightings (guess ``T_ij`` and where j was in its map) for the ``pairs``
    (i < j) whose robots see each other.

    Args:
        sensor: the sensor.
        walls: (H, W) bool world grid (truth: only physics reads it).
        true_poses: (R, 3) ``[x_m, y_m, theta]`` world poses (truth: only physics reads it).
        world_cells: (R, 2) the robots' world cells ``(col, row)``, continuous.
        est_cells: per robot, its own pose estimate in its map cells ``(col, row, theta)``.
        resolution_m: metres per cell of the robots' maps.
        pairs: the pairs to look at, in order (noise is drawn in this order, three normals
            per pair seen).
        rng: the env's generator.
    """
    out = {}
    for i, j in pairs:
        d_m = math.hypot(*(true_poses[j, :2] - true_poses[i, :2]))
        if d_m > sensor.range_m:
            continue
        ci, cj = world_cells[i], world_cells[j]
        if not sensor.visible(walls, (float(ci[0]), float(ci[1])), (float(cj[0]), float(cj[1]))):
            continue
        z = sensor.measure(true_poses[i], true_poses[j], rng)
        guess = guess_from_sighting(est_cells[i], est_cells[j], z, resolution_m)
        out[(i, j)] = Sighting(guess, (float(est_cells[j][0]), float(est_cells[j][1])))
    return out
