"""MapMergeWrapper on a foreign ParallelEnv written here: two agents see growing crops of a world
with two look-alike rooms, each in its own frame at an offset the wrapper does not know."""

from __future__ import annotations

from typing import Any, ClassVar

import cv2
import gymnasium
import numpy as np
import pytest
from numpy.typing import NDArray
from pettingzoo import ParallelEnv

from mrexplore.errors import ConfigError
from mrexplore.grid import FREE, OCCUPIED, UNKNOWN, apply_transform, make_transform
from mrexplore.merge import MergeResult
from mrexplore.wrappers import MapMergeWrapper
from mrexplore.wrappers.merge_wrapper import check_map_protocol, fused_map_image

H, W = 100, 220  # world size, cells (rows, cols)
MARGIN = 40  # canvas = world + MARGIN on each axis, so both crops fit in either frame
ROWS_TOP = 97  # both crops span rows [row0(t), ROWS_TOP)
ROW0_START = 48  # at t = 0 the crops start just below the rooms (rooms span rows 50..95)
ROW0_SPEED = 2  # rows added per step
# Column ranges of the crops: a sees both rooms; b sees only the right room and its margins.
COLS_A = (4, 216)
COLS_B = (116, 214)
# Offsets (col, row) of world cells in each agent's canvas: own = world + offset.
OFF_A = (7, 31)
OFF_B = (33, 4)
# The first row of the distinctive structures below the rooms (the pillar under the right
# room ends at row 32, the block under the left room at row 28): a crop shows them when
# row0(t) <= 31, i.e. from t = 9. Before that the two crops share only look-alike parts.
FIRST_DISTINCT_T = 9


def _rect(world: NDArray[np.int8], c0: int, r0: int, c1: int, r1: int, t: int = 2) -> None:
    """Wall outline (thickness t) of the box [c0, c1) x [r0, r1)."""
    world[r0 : r0 + t, c0:c1] = OCCUPIED
    world[r1 - t : r1, c0:c1] = OCCUPIED
    world[r0:r1, c0 : c0 + t] = OCCUPIED
    world[r0:r1, c1 - t : c1] = OCCUPIED


def _room(world: NDArray[np.int8], c0: int) -> None:
    """One of the twin rooms at columns [c0, c0 + 90), rows [50, 95): cell-for-cell identical
    copies; furniture off-centre so that no rotation maps a room onto itself."""
    _rect(world, c0, 50, c0 + 90, 95)
    world[50:52, c0 + 60 : c0 + 72] = FREE  # door in the bottom wall
    _rect(world, c0 + 8, 58, c0 + 28, 70)  # a table
    _rect(world, c0 + 40, 78, c0 + 52, 90)  # a cupboard
    world[60:75, c0 + 70 : c0 + 72] = OCCUPIED  # a partition


def make_world() -> NDArray[np.int8]:
    """The truth: free floor, outer walls, twin rooms, and different things below each room."""
    world = np.full((H, W), FREE, dtype=np.int8)
    _rect(world, 0, 0, W, H)
    _room(world, 10)
    _room(world, 120)
    _rect(world, 20, 10, 50, 28)  # a block below the left room only
    _rect(world, 160, 18, 200, 32)  # a pillar below the right room only
    world[8:24, 100:102] = OCCUPIED  # a low wall between them
    return world


def true_T_ab() -> NDArray[np.float64]:
    """b's cells -> a's cells: own = world + offset, so a = b - OFF_B + OFF_A."""
    return make_transform(0.0, OFF_A[0] - OFF_B[0], OFF_A[1] - OFF_B[1])


class CropsEnv(ParallelEnv):  # type: ignore[type-arg]
    """Two agents, 'a' and 'b'; agent X's map is the truth inside its crop window, in its own
    canvas at offset OFF_X; the windows widen downwards by ROW0_SPEED rows per step."""

    metadata: ClassVar[dict[str, Any]] = {"name": "crops_v0", "render_modes": []}

    def __init__(self, max_steps: int = 24, with_pose: bool = False) -> None:
        self.possible_agents = ["a", "b"]
        self.agents: list[str] = []
        self.world = make_world()
        self.max_steps = max_steps
        self.t = 0
        self._obs_space = gymnasium.spaces.Box(0, 1000, (1,), dtype=np.float32)
        self._act_space = gymnasium.spaces.Discrete(1)
        self.map_resolution_m = 0.05
        self._cols = {"a": COLS_A, "b": COLS_B}
        self._off = {"a": OFF_A, "b": OFF_B}
        if with_pose:
            # Bind the optional method only when asked, so both protocol variants are tested.
            self.own_pose_cell = self._own_pose_cell

    def observation_space(self, agent: str) -> gymnasium.spaces.Box:
        return self._obs_space

    def action_space(self, agent: str) -> gymnasium.spaces.Discrete:
        return self._act_space

    def row0(self) -> int:
        return max(2, ROW0_START - ROW0_SPEED * self.t)

    def local_map(self, agent: str) -> NDArray[np.int8]:
        canvas = np.full((H + MARGIN, W + MARGIN), UNKNOWN, dtype=np.int8)
        c0, c1 = self._cols[agent]
        r0, r1 = self.row0(), ROWS_TOP
        oc, orow = self._off[agent]
        canvas[r0 + orow : r1 + orow, c0 + oc : c1 + oc] = self.world[r0:r1, c0:c1]
        return canvas

    def _own_pose_cell(self, agent: str) -> tuple[float, float, float]:
        # The agent stands in the middle of its crop's top rows (a fixed world cell).
        c0, c1 = self._cols[agent]
        oc, orow = self._off[agent]
        return ((c0 + c1) / 2 + oc, 75.0 + orow, 0.0)

    def _obs(self) -> dict[str, NDArray[np.float32]]:
        return {a: np.array([self.t], dtype=np.float32) for a in self.agents}

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, Any], dict[str, dict[str, Any]]]:
        self.t = 0
        self.agents = list(self.possible_agents)
        return self._obs(), {a: {"t": 0} for a in self.agents}

    def step(self, actions: dict[str, Any]) -> tuple[Any, Any, Any, Any, Any]:
        self.t += 1
        obs = self._obs()
        trunc = self.t >= self.max_steps
        agents = list(self.agents)
        if trunc:
            self.agents = []
        return (
            obs,
            dict.fromkeys(agents, 0.0),
            dict.fromkeys(agents, False),
            dict.fromkeys(agents, trunc),
            {a: {"t": self.t} for a in agents},
        )


def test_fused_observation_appears_only_once_unambiguous() -> None:
    # This toy world is 5 x 11 m: the in-loop minimum of shared known space (40 m^2, sized for
    # real floors) cannot be met; 5 m^2 still exceeds nothing look-alike here but the rooms.
    env = MapMergeWrapper(CropsEnv(), merger="semantic", merge_every=1, min_common_m2=5.0)
    obs, infos = env.reset(seed=0)
    history: list[tuple[int, bool, bool]] = []
    t = 0
    while env.agents:
        history.append((t, infos["a"]["merged"], infos["b"]["merged"]))
        if t < FIRST_DISTINCT_T:
            # Only look-alike parts are shared: b's room fits both rooms of a equally well.
            assert not infos["a"]["merged"], f"merged at t={t} on look-alike rooms only"
            assert infos["a"]["transform"] == {"b": None}
            assert infos["a"]["score"] is None
            # ... and refused because it is ambiguous, not for lack of overlap: the best pose
            # was examined and agrees fully (the twin room's pose agrees as well).
            res = env.fusion.tracker.last_result(0, 1)
            assert res is not None and not res.matched and res.score > 0.9
            # Unmerged: the image is a's own map, nothing more.
            own = env.unwrapped.local_map("a")
            np.testing.assert_array_equal(obs["a"], fused_map_image(own, None, None, 64))
        obs, _, _, _, infos = env.step({a: 0 for a in env.agents})
        t += 1
    history.append((t, infos["a"]["merged"], infos["b"]["merged"]))
    assert infos["a"]["merged"] and infos["b"]["merged"], f"never merged: {history}"
    assert infos["a"]["t"] == t  # the env's own info keys survive
    assert 0.0 <= infos["a"]["score"] <= 1.0
    T_ab = np.array(infos["a"]["transform"]["b"])
    T_ba = np.array(infos["b"]["transform"]["a"])
    # b's crop corners (own cells) must land within 2 cells of where they truly are in a.
    corners_b = np.array(
        [[COLS_B[0] + OFF_B[0], 2 + OFF_B[1]], [COLS_B[1] + OFF_B[0], ROWS_TOP + OFF_B[1]]],
        dtype=np.float64,
    )
    err = np.linalg.norm(
        apply_transform(T_ab, corners_b) - apply_transform(true_T_ab(), corners_b), axis=1
    )
    assert err.max() < 2.0, (err, T_ab)
    np.testing.assert_allclose(T_ab @ T_ba, np.eye(3), atol=1e-6)
    # The fused observation is there: a's image is drawn from the fused map (b's crop lies
    # inside a's, so the fused map holds a's cells with b's walls laid over them).
    fused = env.fusion.fused("a")
    assert obs["a"].shape == (3, 64, 64)
    np.testing.assert_array_equal(obs["a"], fused_map_image(fused, None, None, 64))
    warped_b = cv2.warpAffine(
        env.unwrapped.local_map("b").view(np.uint8),
        T_ab[:2],
        fused.shape[::-1],
        flags=cv2.INTER_NEAREST,
        borderMode=cv2.BORDER_CONSTANT,
        borderValue=255,
    ).view(np.int8)
    assert (fused >= np.maximum(env.unwrapped.local_map("a"), warped_b)).all()
    first = next(tt for tt, ma, _ in history if ma)
    assert first >= FIRST_DISTINCT_T


def _oracle(T_true_crops: Any) -> Any:
    def run(a: NDArray[np.int8], b: NDArray[np.int8]) -> MergeResult:
        return MergeResult(matched=True, transform=T_true_crops(a, b), score=0.99)

    return run


def test_pose_channel_places_teammate_through_the_estimated_transform() -> None:
    inner = CropsEnv(with_pose=True)
    inner.reset()

    # The tracker merges the maps cropped to their known boxes; an oracle that knows the crop
    # origins returns the true transform between the crops.
    def crop_T(a: NDArray[np.int8], b: NDArray[np.int8]) -> NDArray[np.float64]:
        ca = (COLS_A[0] + OFF_A[0], inner.row0() + OFF_A[1])
        cb = (COLS_B[0] + OFF_B[0], inner.row0() + OFF_B[1])
        # crop_b -> own_b -> own_a -> crop_a
        return make_transform(0, -ca[0], -ca[1]) @ true_T_ab() @ make_transform(0, cb[0], cb[1])

    # confirmations=1: the oracle is right at once (the default waits for a second agreeing look)
    env = MapMergeWrapper(
        inner, merger=_oracle(crop_T), merge_every=1, view_m=12.0, confirmations=1
    )
    obs, infos = env.reset()
    assert env.observation_space("a").shape == (4, 64, 64)
    assert infos["a"]["merged"] and infos["a"]["score"] == pytest.approx(0.99)
    np.testing.assert_allclose(np.array(infos["a"]["transform"]["b"]), true_T_ab(), atol=1e-9)
    robots = obs["a"][3]
    side = round(12.0 / 0.05)  # 240 cells shown in 64 px
    scale = 64 / side
    # a at the centre; b where its own pose maps through T_ab, relative to a's window origin.
    col, row, _ = inner.own_pose_cell("a")
    origin = np.array([round(col) - side // 2, round(row) - side // 2])
    pb = apply_transform(true_T_ab(), np.array([inner.own_pose_cell("b")[:2]]))[0]
    px_b = np.floor((pb - origin + 0.5) * scale).astype(int)
    px_a = np.floor((np.array([col, row]) - origin + 0.5) * scale).astype(int)
    assert robots[px_a[1], px_a[0]] == 255
    assert robots[px_b[1], px_b[0]] == 128
    assert set(np.unique(robots)) == {0, 128, 255}


def test_augment_mode_keeps_the_original_observation_and_caches_spaces() -> None:
    env = MapMergeWrapper(CropsEnv(), merger=None, mode="augment", obs_size_px=40)
    space = env.observation_space("a")
    assert space is env.observation_space("a")  # cached: the same object
    assert isinstance(space, gymnasium.spaces.Dict)
    assert space["fused_map"].shape == (3, 40, 40)
    obs, infos = env.reset()
    assert space.contains(obs["a"])
    np.testing.assert_array_equal(obs["b"]["obs"], [0.0])
    obs, *_ = env.step({"a": 0, "b": 0})
    assert space.contains(obs["b"])
    assert obs["b"]["obs"][0] == 1.0
    # merger=None never merges, but the keys are there.
    assert infos["a"] == {"t": 0, "merged": False, "transform": {"b": None}, "score": None}


class _NoProtocol(CropsEnv):
    local_map = None  # type: ignore[assignment]

    def __getattribute__(self, name: str) -> Any:
        if name == "map_resolution_m":
            raise AttributeError(name)
        return super().__getattribute__(name)


def test_wrap_time_error_names_what_is_missing() -> None:
    with pytest.raises(ConfigError, match=r"local_map\(agent\).*map_resolution_m") as err:
        MapMergeWrapper(_NoProtocol())
    assert "_NoProtocol" in str(err.value)


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"mode": "overlay"}, "mode"),  # a mode that does not exist
        ({"obs_size_px": 0}, "obs_size_px"),  # an empty image
        ({"merge_every": 0}, "merge_every"),  # never attempting would be a silent no-op
        ({"view_m": -1.0}, "view_m"),  # a negative window
        ({"comm_range_fn": 3}, "comm_range_fn"),  # not callable
    ],
)
def test_bad_options(kwargs: dict[str, Any], match: str) -> None:
    with pytest.raises(ConfigError, match=match):
        MapMergeWrapper(CropsEnv(), merger=None, **kwargs)


def test_bad_resolution_is_refused() -> None:
    env = CropsEnv()
    env.map_resolution_m = 0.0
    with pytest.raises(ConfigError, match="map_resolution_m"):
        check_map_protocol(env)


def test_links_function_blocks_merging() -> None:
    # Out of range all the time: no merge even once the crops are unambiguous.
    env = MapMergeWrapper(CropsEnv(), merge_every=1, comm_range_fn=lambda u: np.eye(2, dtype=bool))
    env.reset()
    infos: dict[str, Any] = {}
    while env.agents:
        _, _, _, _, infos = env.step({a: 0 for a in env.agents})
    assert not infos["a"]["merged"]


@pytest.mark.parametrize(
    ("grid", "expected"),
    [
        # all free 4x4 -> free channel full, others empty
        (np.zeros((4, 4), np.int8), (255, 0, 0)),
        # all occupied
        (np.full((4, 4), 100, np.int8), (0, 255, 0)),
        # all unknown
        (np.full((4, 4), -1, np.int8), (0, 0, 255)),
        # 50 % occupancy is neither free nor occupied: counted unknown
        (np.full((4, 4), 50, np.int8), (0, 0, 255)),
    ],
)
def test_fused_map_image_classes(grid: NDArray[np.int8], expected: tuple[int, int, int]) -> None:
    img = fused_map_image(grid, None, None, 8)
    assert img.shape == (3, 8, 8) and img.dtype == np.uint8
    for ch, v in enumerate(expected):
        assert (img[ch] == v).all()


def test_fused_map_image_window_and_padding() -> None:
    grid = np.full((6, 10), UNKNOWN, dtype=np.int8)
    grid[0, 0] = OCCUPIED  # bottom-left cell
    # A 2x2 window centred at (0, 0) covers cells (-1..0, -1..0): only (0, 0) is inside.
    img = fused_map_image(grid, (0.0, 0.0), 2, 2)
    np.testing.assert_array_equal(img[1], [[0, 0], [0, 255]])
    np.testing.assert_array_equal(img[2], [[255, 255], [255, 0]])
    # Whole map (no centre): a 10x10 window centred on the grid; share averaging down to 5 px.
    img = fused_map_image(np.zeros((10, 10), np.int8), None, None, 5)
    assert (img[0] == 255).all()


def test_wrapping_an_env_that_merges_itself_is_refused() -> None:
    import mrexplore

    with pytest.raises(ConfigError, match=r"already merges its maps.*merger=None"):
        MapMergeWrapper(mrexplore.parallel_env(world="small_office", n_robots=2))
    # one robot, or merger=None: nothing to merge twice
    MapMergeWrapper(mrexplore.parallel_env(world="small_office", n_robots=2, merger=None))
