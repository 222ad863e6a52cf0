"""What one robot knows at one step: the documented accessor for policies.

A :class:`RobotView` holds only what the robot can know: its own map (or the fused map once a
merge has been accepted), its own pose estimate in its own frame, and - only after a merge -
its teammates' positions and the *estimated* transforms to their frames. It never holds the
ground truth: no true pose, no true transform, no world grid.

Get one with ``env.unwrapped.robot_view(agent)`` (PettingZoo env) after ``reset``/``step``.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from numpy.typing import NDArray


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
            cells into this robot's map cells (same set of keys as ``teammates``).
        in_range: teammates this robot can talk to now (maps, positions and chosen targets are
            exchanged only with them; ``teammates`` holds where the others were last heard).
        goal_cell: (col, row) goal in this robot's map cells for the navigation task, else None.
        time_s: simulated time since reset, seconds.
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
