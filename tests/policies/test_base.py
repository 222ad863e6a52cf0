"""Policy protocol pieces: the path follower, the team lift, the registry, the random policy."""

from __future__ import annotations

import math

import numpy as np
import pytest

from mrexplore.errors import ConfigError
from mrexplore.grid import FREE
from mrexplore.policies import (
    POLICIES,
    CoordinatedFrontierPolicy,
    IndependentTeam,
    RandomPolicy,
    TeamPolicy,
    follow_path,
    make_team_policy,
)
from mrexplore.policies.base import densify_path
from mrexplore.robot import Action
from mrexplore.types import RobotView

STEP = math.radians(22.5)
EAST = np.stack([np.arange(21.0), np.zeros(21)], axis=1)  # a path along +col, one point per cell


@pytest.mark.parametrize(
    ("path", "pose", "expected"),
    [
        (EAST, (0.0, 0.0, 0.0), Action.FORWARD),  # aligned
        (EAST, (0.0, 0.0, math.radians(10.0)), Action.FORWARD),  # within half a turn step
        (EAST, (0.0, 0.0, math.radians(30.0)), Action.TURN_RIGHT),  # heading left of the path
        (EAST, (0.0, 0.0, -math.radians(30.0)), Action.TURN_LEFT),  # heading right of the path
        (
            EAST,
            (0.0, 0.0, math.radians(170.0)),
            Action.TURN_RIGHT,
        ),  # almost away: clockwise is shorter
        (EAST, (0.0, 0.0, -math.radians(170.0)), Action.TURN_LEFT),  # mirrored: counter-clockwise
        (EAST, (0.0, 0.0, math.pi / 2), Action.TURN_RIGHT),  # facing +row: turn right (clockwise)
        (EAST, (19.0, 0.0, 0.0), Action.STAY),  # within 2 cells of the end: arrived
        # Beside the path at (5, -3): the waypoint is the first point 6 cells away, (11, 0), at
        # 26.6 deg: heading 30 deg goes on, heading 0 deg turns left towards it.
        (EAST, (5.0, -3.0, math.radians(30.0)), Action.FORWARD),
        (EAST, (5.0, -3.0, 0.0), Action.TURN_LEFT),
        # Farther off than the look-ahead: head straight back to the closest path point (5, 0).
        (EAST, (5.0, -8.0, math.radians(90.0)), Action.FORWARD),
    ],
)
def test_follow_path(path: np.ndarray, pose: tuple[float, float, float], expected: Action) -> None:
    assert follow_path(path, pose, turn_step_rad=STEP) == expected


def test_follow_path_blocked_ahead_turns_towards_the_waypoint_side() -> None:
    """Where FORWARD was just cut to nothing, turn one step towards the waypoint's side: the
    next heading is at most a turn step off the waypoint, on the other side of it."""
    # Beside the path at (5, -3), heading 30 deg: the waypoint is at 26.6 deg, to the right.
    pose = (5.0, -3.0, math.radians(30.0))
    assert follow_path(EAST, pose, turn_step_rad=STEP) == Action.FORWARD
    assert follow_path(EAST, pose, turn_step_rad=STEP, blocked_ahead=True) == Action.TURN_RIGHT
    pose = (5.0, -3.0, math.radians(20.0))  # waypoint to the left
    assert follow_path(EAST, pose, turn_step_rad=STEP, blocked_ahead=True) == Action.TURN_LEFT
    # Turns and arrival are unchanged.
    assert follow_path(EAST, (5.0, -3.0, 0.0), blocked_ahead=True) == Action.TURN_LEFT
    assert follow_path(EAST, (19.0, 0.0, 0.0), blocked_ahead=True) == Action.STAY


def test_follow_path_converges_on_simulated_kinematics() -> None:
    """Driving the follower with ideal discrete kinematics reaches the end of an L-shaped path."""
    path = np.array([[0.0, 0.0], [30.0, 0.0], [30.0, 30.0]])
    pose = [0.0, 0.0, math.pi]  # facing away
    for _ in range(200):
        a = follow_path(path, pose, turn_step_rad=STEP)
        if a == Action.STAY:
            break
        if a == Action.FORWARD:
            pose[0] += 2.5 * math.cos(pose[2])
            pose[1] += 2.5 * math.sin(pose[2])
        else:
            pose[2] += STEP if a == Action.TURN_LEFT else -STEP
    assert a == Action.STAY
    assert math.hypot(pose[0] - 30.0, pose[1] - 30.0) <= 2.0


def test_densify_path() -> None:
    dense = densify_path(np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 2.5]]))
    assert np.hypot(*np.diff(dense, axis=0).T).max() <= 1.0 + 1e-12
    assert dense[0].tolist() == [0.0, 0.0] and dense[-1].tolist() == [3.0, 2.5]
    assert [3.0, 0.0] in dense.tolist()  # corners are kept


def test_follow_path_empty_raises() -> None:
    with pytest.raises(ConfigError):
        follow_path(np.zeros((0, 2)), (0.0, 0.0, 0.0))


def _view(agent: str = "robot_0") -> RobotView:
    return RobotView(agent, np.full((8, 8), FREE, dtype=np.int8), 0.05, (4.0, 4.0, 0.0), 0.15)


def test_random_policy_deterministic_and_biased() -> None:
    views = {"robot_0": _view("robot_0"), "robot_1": _view("robot_1")}
    runs = []
    for _ in range(2):
        team = IndependentTeam(lambda: RandomPolicy(forward_prob=0.7), ["robot_0", "robot_1"])
        team.reset(np.random.default_rng(5))
        runs.append([team.act(views) for _ in range(300)])
    assert runs[0] == runs[1]  # same generator seed, same actions
    acts = np.array([[d["robot_0"], d["robot_1"]] for d in runs[0]])
    assert not np.array_equal(acts[:, 0], acts[:, 1])  # robots get different streams
    assert Action.STAY not in acts
    assert 0.6 < float((acts == Action.FORWARD).mean()) < 0.8
    uniform = RandomPolicy()
    uniform.reset(np.random.default_rng(0))
    seen = {uniform.act(views["robot_0"]) for _ in range(100)}
    assert seen == {int(a) for a in Action}


def test_random_policy_bad_prob() -> None:
    with pytest.raises(ConfigError):
        RandomPolicy(forward_prob=1.5)


def test_independent_team_requires_reset() -> None:
    with pytest.raises(RuntimeError):
        IndependentTeam(RandomPolicy).act({"robot_0": _view()})


@pytest.mark.parametrize("name", sorted(POLICIES))
def test_registry_builds_team_policies(name: str) -> None:
    team = make_team_policy(name, ["robot_0", "robot_1"])
    assert isinstance(team, TeamPolicy)
    team.reset(np.random.default_rng(0))
    if name == "goal":
        return  # needs a goal in the view; covered in test_policies
    actions = team.act({"robot_0": _view("robot_0"), "robot_1": _view("robot_1")})
    assert set(actions) == {"robot_0", "robot_1"}
    assert all(a in {int(x) for x in Action} for a in actions.values())


def test_registry_unknown_name() -> None:
    with pytest.raises(ConfigError, match="nearest-frontier"):
        make_team_policy("nearest", ["robot_0"])
    assert isinstance(make_team_policy("coordinated-frontier", []), CoordinatedFrontierPolicy)
