"""The package's shared names, importable without the env, the simulator or OpenCV.

Policies, wrappers and the merger's clients type against these: :class:`RobotView` (what one
robot knows), :data:`AgentID`, :data:`Box` (the one box convention), :data:`Transform` and the
:class:`Merger` protocol (what the env and the tracker accept as ``merger``).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Protocol, runtime_checkable

import numpy as np
from numpy.typing import NDArray

#: An agent's name: ``robot_0``, ``robot_1``, ...
AgentID = str
#: ``(row0, row1, col0, col1)``, half-open (``grid[row0:row1, col0:col1]``): a block of grid
#: cells. The one box convention of the package.
Box = tuple[int, int, int, int]
#: 3x3 float64 homogeneous transform on ``(col, row, 1)`` cells; ``T_ab`` maps b's cells into a's.
Transform = NDArray[np.float64]
#: An occupancy grid: int8 (H, W), -1 unknown, 0 free, 100 occupied (ROS ``OccupancyGrid``).
Int8Grid = NDArray[np.int8]


class MergeOutcome(Protocol):
    """What a merger returns (:class:`mrexplore.merge.MergeResult` is one): whether it
    accepted a transform, the transform ``T_ab`` (b's cells into a's) or None, and a score."""

    @property
    def matched(self) -> bool: ...

    @property
    def transform(self) -> Transform | None: ...

    @property
    def score(self) -> float: ...


@dataclass(frozen=True, eq=False)
class Sighting:
    """What robot i measured when it saw robot j (:mod:`mrexplore.environment.sighting`).

    Attributes:
        T_ij: (3, 3) the guess of the transform from j's map cells to i's map cells.
        at_j: ``(col, row)``, continuous: where j was in its own map cells when seen, the point
            at which the guess is exact up to the measurement's noise (elsewhere its heading
            error and the maps' bending add up with the distance).
    """

    T_ij: Transform
    at_j: tuple[float, float]


@runtime_checkable
class Merger(Protocol):
    """A map merger: ``merge(a, b)`` aligns map ``b`` to map ``a`` (both :data:`Int8Grid`).
    Pass one as the env's or the tracker's ``merger`` instead of a method name."""

    def merge(self, a: Int8Grid, b: Int8Grid) -> MergeOutcome: ...


@dataclass(frozen=True, eq=False)
class RobotView:
    """One robot's knowledge, all in its own map frame (cells, ``(col, row)``; row 0 = lowest y).

    Attributes:
        agent: the agent name, ``robot_0``, ...
        map: int8 (H, W), -1 unknown / 0 free / 100 occupied: the fused map when ``merged``
            else the robot's own map. Same shape and frame as the robot's own map canvas.
        resolution_m: metres per cell.
        pose_cell: (col, row, theta_rad): the robot's own pose estimate in its map cells; theta is
            the heading in radians from the +col axis towards +row.
        robot_radius_m: the robot's radius in metres (for inflating walls when planning).
        merged: True once this robot's map has been fused with at least one teammate's.
        teammates: teammate name -> (col, row) position in *this* robot's map cells, only for
            teammates whose maps are merged with this one (estimated, never the truth).
        transforms: teammate name -> 3x3 float64 estimated transform from that teammate's map
            cells into this robot's map cells, for every merged teammate (``teammates`` holds
            those of them whose position was heard at least once).
        in_range: teammates this robot can talk to now (maps, positions and chosen targets are
            exchanged only with them; ``teammates`` holds where the others were last heard).
        goal_cell: (col, row) goal in this robot's map cells for the navigation task, else None.
        time_s: simulated time since reset, seconds.
        trail: (T, 2) float64 read-only: the robot's own estimated path, (col, row) map cells.
        hypotheses: teammate name -> (candidate transforms, that teammate's map) for teammates
            in range whose maps are *not* merged with this one yet: the merger's unconfirmed
            candidates for where the teammate's map lies (3x3 float64, its cells into this
            robot's, most likely first; the tracker's ``hypotheses``) and the teammate's own
            map (int8, read-only), as exchanged for merging. The merger's knowledge, never the
            truth: a policy may go where the candidates can be told apart.
        known_box: a half-open box ``(row0, row1, col0, col1)`` of ``map`` that holds every
            cell that is not unknown (it may be larger than the tightest such box; ``(0, 0, 0,
            0)`` when nothing is known), or None when not given: readers then scan the map.
    """

    agent: str
    map: NDArray[np.int8]
    resolution_m: float
    pose_cell: tuple[float, float, float]
    robot_radius_m: float
    merged: bool = False
    teammates: dict[str, tuple[float, float]] = field(default_factory=dict)
    transforms: dict[str, NDArray[np.float64]] = field(default_factory=dict)
    in_range: frozenset[str] = frozenset()
    goal_cell: tuple[float, float] | None = None
    time_s: float = 0.0
    trail: NDArray[np.float64] = field(default_factory=lambda: np.zeros((0, 2)))
    hypotheses: dict[str, tuple[list[NDArray[np.float64]], NDArray[np.int8]]] = field(
        default_factory=dict
    )
    known_box: Box | None = None
