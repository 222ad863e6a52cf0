"""Observation images: what is ahead of the robot, in map-frame and heading-up views."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mrexplore.environment.observations import ObservationBuilder
from mrexplore.environment.view import RobotView
from mrexplore.grid import FREE, OCCUPIED, UNKNOWN


def _view(theta: float) -> RobotView:
    """A robot at (100, 100) in a known free square with one wall 30 cells to its +col side."""
    m = np.full((200, 200), UNKNOWN, dtype=np.int8)
    m[40:160, 40:160] = FREE
    m[60:140, 130:134] = OCCUPIED  # the wall, at +col of the robot
    return RobotView("robot_0", m, 0.05, (100.0, 100.0, theta), 0.15)


def _wall_centroid(obs: np.ndarray) -> tuple[float, float]:
    rows, cols = np.nonzero(obs[5] > 64)  # fine view, occupied share
    return float(cols.mean()), float(rows.mean())


@pytest.mark.parametrize(
    ("heading_up", "theta", "expect"),
    [
        (False, 0.0, "+col"),  # map frame: the wall stays at +col whatever the heading
        (False, 2.0, "+col"),
        (True, 0.0, "+row"),  # heading up, facing the wall: it is ahead, at +row
        (True, math.pi / 2, "+col"),  # already facing +row: nothing turns, the wall stays right
        (True, -math.pi / 2, "-col"),  # facing -row: the view turns half round, the wall to -col
        (True, math.pi, "-row"),  # facing away from the wall: it is behind
    ],
)
def test_the_wall_appears_where_it_is(heading_up: bool, theta: float, expect: str) -> None:
    b = ObservationBuilder(0.05, 12.8, 6.4, 64, heading_up=heading_up)
    obs = b.build(_view(theta), np.zeros((0, 2)))
    assert obs.shape == (8, 64, 64) and obs.dtype == np.uint8
    cx, cy = _wall_centroid(obs)
    dx, dy = cx - 31.5, cy - 31.5
    axis = {"+col": dx, "-col": -dx, "+row": dy, "-row": -dy}[expect]
    assert axis > 10 and abs(dx if expect.endswith("row") else dy) < 4, (cx, cy)


def test_heading_up_keeps_the_robot_marker_fixed() -> None:
    b = ObservationBuilder(0.05, 12.8, 6.4, 64, heading_up=True)
    markers = {b.build(_view(t), np.zeros((0, 2)))[6].tobytes() for t in (0.0, 1.0, -2.5)}
    assert len(markers) == 1
