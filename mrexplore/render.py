"""The viewer: frames drawn from a :class:`FrameSnapshot`, a window for ``"human"`` mode, and
GIF/MP4 writing.

The viewer reads a snapshot the env hands it (as jumanji's ``Viewer.render(state)``), never
the env itself, so it cannot change the episode. A snapshot shares the env's arrays: draw it
before the next step (or copy its maps to keep it).
"""

from __future__ import annotations

import warnings
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore.grid import Transform, apply_transform, free_mask, invert_transform, occupied_mask
from mrexplore.sensors import Scan
from mrexplore.types import RobotView
from mrexplore.world.world import World

#: RGB colours of robots 0, 1, 2, ... (cycled).
ROBOT_COLOURS: list[tuple[int, int, int]] = [
    (220, 50, 47),
    (38, 139, 210),
    (133, 153, 0),
    (211, 54, 130),
    (181, 137, 0),
    (42, 161, 152),
]
#: Side of every (square) map panel, pixels; a frame is ``PANEL_PX`` wide per panel.
PANEL_PX = 360
TITLE_PX = 22
#: Cells of slack around each robot's map window (odometry drift may push a map past the
#: world's outline; what falls outside the window is clipped, never rescaled).
WINDOW_MARGIN_CELLS = 12

# Cell classes, as drawn (RGB). Maps: what a robot believes; world: the truth.
MAP_UNKNOWN = (160, 160, 160)
MAP_FREE = (255, 255, 255)
MAP_OCCUPIED = (0, 0, 0)
WORLD_WALL = (40, 40, 40)
WORLD_SEEN = (200, 230, 200)
WORLD_UNSEEN = (255, 255, 255)
BEAM = (255, 200, 120)
BACKGROUND = (235, 235, 235)
_FONT = cv2.FONT_HERSHEY_SIMPLEX


def colour(i: int) -> tuple[int, int, int]:
    """RGB colour of robot ``i``."""
    return ROBOT_COLOURS[i % len(ROBOT_COLOURS)]


def format_coverage(c: float) -> str:
    """Coverage as the console and the pictures both print it (``95.3%``)."""
    return f"{c:.1%}"


def grid_to_rgb(grid: NDArray[np.int8]) -> NDArray[np.uint8]:
    """An int8 occupancy grid as RGB (unknown grey, free white, occupied black), row 0 at the
    *bottom* of the picture as on a map."""
    img = np.full((*grid.shape, 3), MAP_UNKNOWN, dtype=np.uint8)
    img[free_mask(grid)] = MAP_FREE
    img[occupied_mask(grid)] = MAP_OCCUPIED
    return np.ascontiguousarray(img[::-1])


@dataclass(frozen=True)
class PanelView:
    """Where the cells of a grid with ``rows`` rows land in a ``PANEL_PX`` square panel: cell
    ``(col, row)`` (its centre) is drawn at pixel ``(px_per_cell * col + tx,
    px_per_cell * (rows - 1 - row) + ty)``. Every panel of a frame shares ``px_per_cell``."""

    px_per_cell: float
    tx: float
    ty: float
    rows: int

    @classmethod
    def centred(cls, px_per_cell: float, centre: tuple[float, float], rows: int) -> PanelView:
        """The view that puts cell ``centre`` (col, row) in the middle of the panel."""
        mid = (PANEL_PX - 1) / 2
        cc, rc = centre
        return cls(px_per_cell, mid - px_per_cell * cc, mid - px_per_cell * (rows - 1 - rc), rows)

    def px(self, cells: NDArray[np.floating]) -> NDArray[np.int32]:
        """(N, 2) cells ``(col, row)`` -> (N, 2) int pixel ``(x, y)``."""
        cr = np.asarray(cells, dtype=np.float64).reshape(-1, 2)
        s = self.px_per_cell
        xy = np.stack([s * cr[:, 0] + self.tx, s * (self.rows - 1 - cr[:, 1]) + self.ty], 1)
        return np.rint(xy).astype(np.int32)

    def draw(self, img: NDArray[np.uint8]) -> NDArray[np.uint8]:
        """A panel of ``img`` (the grid as RGB, row 0 at the bottom: :func:`grid_to_rgb`)."""
        M = np.array([[self.px_per_cell, 0.0, self.tx], [0.0, self.px_per_cell, self.ty]])
        out = cv2.warpAffine(
            img,
            M,
            (PANEL_PX, PANEL_PX),
            flags=cv2.INTER_NEAREST,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=BACKGROUND,
        )
        return np.asarray(out, dtype=np.uint8)


@dataclass(frozen=True)
class FrameLayout:
    """The geometry of an env's frame, fixed for an episode (it depends on the world and the
    robots' start poses only, never on what has been mapped): one scale for every panel, and
    each robot's map window is the world's outline seen from that robot's frame.

    Attributes:
        world: the true-world panel's view (world cells).
        robots: robot i's own-map panel view (its map cells); the fused panel uses robot 0's.
        resolution_m: metres per cell (world and maps).
    """

    world: PanelView
    robots: tuple[PanelView, ...]
    resolution_m: float

    @property
    def px_per_cell(self) -> float:
        return self.world.px_per_cell

    @property
    def m_per_px(self) -> float:
        """Metres per pixel, the same in every panel."""
        return self.resolution_m / self.px_per_cell


@dataclass(frozen=True, eq=False)
class FrameSnapshot:
    """What one frame shows, read from the env at one step (arrays are not copied: draw it
    before the next step, or copy them).

    Attributes:
        agents: agent names, robot i = ``agents[i]``.
        world: the true world.
        seen: bool (H, W) world cells the team has observed.
        true_poses: (n, 3) true poses (world metres, radians).
        scan: the last lidar scan (beams), or None.
        maps: each robot's own int8 map, in its own frame.
        pose_cells: each robot's pose estimate (col, row, theta) in its own map cells.
        trails: each robot's driven path, (T, 2) own map cells.
        world_from_map: each robot's true 3x3 transform from its map cells to world cells.
        fused: ``robot_0``'s :class:`~mrexplore.types.RobotView` (its fused map and
            teammates), None for one robot.
        fused_error: ``robot_0``'s worst merge error against the truth, None when not merged.
        time_s: simulated seconds since reset.
        coverage: the team coverage the infos report.
    """

    agents: tuple[str, ...]
    world: World
    seen: NDArray[np.bool_]
    true_poses: NDArray[np.float64]
    scan: Scan | None
    maps: tuple[NDArray[np.int8], ...]
    pose_cells: tuple[tuple[float, float, float], ...]
    trails: tuple[NDArray[np.float64], ...]
    world_from_map: tuple[Transform, ...]
    fused: RobotView | None
    fused_error: dict[str, float] | None
    time_s: float
    coverage: float


def frame_layout(snap: FrameSnapshot) -> FrameLayout:
    """The :class:`FrameLayout` of ``snap``'s episode: the same for every step of it."""
    world = snap.world
    h, w = world.walls.shape
    corners = np.array([[-0.5, -0.5], [w - 0.5, -0.5], [-0.5, h - 0.5], [w - 0.5, h - 0.5]])
    windows = []  # (centre col, centre row, side in cells, map rows)
    for i in range(len(snap.agents)):
        mc = apply_transform(invert_transform(snap.world_from_map[i]), corners)
        lo, hi = mc.min(axis=0), mc.max(axis=0)
        side = float(np.max(hi - lo)) + 2 * WINDOW_MARGIN_CELLS
        windows.append(((lo + hi) / 2, side, snap.maps[i].shape[0]))
    side = max([float(max(h, w)) + 2.0] + [win[1] for win in windows])
    s = PANEL_PX / side
    return FrameLayout(
        world=PanelView.centred(s, ((w - 1) / 2, (h - 1) / 2), h),
        robots=tuple(PanelView.centred(s, (c[0], c[1]), rows) for c, _, rows in windows),
        resolution_m=float(world.resolution_m),
    )


def _text_width(text: str, scale: float) -> int:
    return int(cv2.getTextSize(text, _FONT, scale, 1)[0][0])


def _title(panel: NDArray[np.uint8], text: str) -> NDArray[np.uint8]:
    bar = np.full((TITLE_PX, panel.shape[1], 3), 250, dtype=np.uint8)
    scale = 0.45
    while scale > 0.3 and _text_width(text, scale) > panel.shape[1] - 8:
        scale -= 0.02
    cv2.putText(bar, text, (4, 16), _FONT, scale, (0, 0, 0), 1, cv2.LINE_AA)
    return np.vstack([bar, panel])


def _draw_robot(
    panel: NDArray[np.uint8], p: NDArray[np.int32], th: float, idx: int, big: bool = False
) -> None:
    r, tick = (5, 12) if big else (4, 10)
    x, y = int(p[0]), int(p[1])
    cv2.circle(panel, (x, y), r, colour(idx), -1, cv2.LINE_AA)
    q = (int(x + tick * np.cos(th)), int(y - tick * np.sin(th)))
    cv2.line(panel, (x, y), q, colour(idx), 2, cv2.LINE_AA)


def _trail(panel: NDArray[np.uint8], view: PanelView, cells: NDArray[np.float64], idx: int) -> None:
    if len(cells) > 1:
        pts = view.px(cells[:: max(1, len(cells) // 400)])
        cv2.polylines(panel, [pts], False, colour(idx), 1, cv2.LINE_AA)


def map_panel(
    grid: NDArray[np.int8],
    title: str,
    poses: Sequence[tuple[float, float, float, int]] = (),
    trails: Sequence[tuple[NDArray[np.float64], int]] = (),
    view: PanelView | None = None,
) -> NDArray[np.uint8]:
    """One map as a titled panel, with robots (col, row, theta, idx) and trails ((T, 2) cells,
    idx) drawn in their colours. ``view`` places it (one scale for every panel of a frame);
    without one the whole grid is fitted to the panel."""
    if view is None:
        s = PANEL_PX / max(grid.shape)
        view = PanelView.centred(
            s, ((grid.shape[1] - 1) / 2, (grid.shape[0] - 1) / 2), grid.shape[0]
        )
    panel = view.draw(grid_to_rgb(grid))
    for cells, idx in trails:
        _trail(panel, view, cells, idx)
    for c, r, th, idx in poses:
        _draw_robot(panel, view.px(np.array([[c, r]]))[0], th, idx)
    return _title(panel, title)


# --- legend ---------------------------------------------------------------------------------
_ROW_PX = 20
_SWATCH = 14


def _legend_items(agents: Sequence[str], layout: FrameLayout) -> list[tuple[str, Any, str]]:
    """(kind, colour, label) in drawing order; kind ``"break"`` starts a new row."""
    items: list[tuple[str, Any, str]] = [("text", None, "robots (tick = heading):")]
    items += [("robot", colour(i), a) for i, a in enumerate(agents)]
    items += [
        ("line", colour(0), "path driven (robot's colour)"),
        ("line", BEAM, "lidar beams"),
    ]
    px_per_m = layout.px_per_cell / layout.resolution_m
    bar_m = next((m for m in (10.0, 5.0, 2.0, 1.0, 0.5) if m * px_per_m <= 110), 0.5)
    items.append(("scale", round(bar_m * px_per_m), f"{bar_m:g} m, same scale in all panels"))
    items += [
        ("break", None, ""),
        ("text", None, "world (truth):"),
        ("box", WORLD_WALL, "wall"),
        ("box", WORLD_SEEN, "seen by the team"),
        ("box", WORLD_UNSEEN, "not yet seen"),
        ("text", None, "   robot maps:"),
        ("box", MAP_UNKNOWN, "unknown"),
        ("box", MAP_FREE, "free"),
        ("box", MAP_OCCUPIED, "occupied"),
    ]
    return items


def legend(
    agents: Sequence[str], layout: FrameLayout, width: int
) -> tuple[NDArray[np.uint8], dict[str, tuple[int, int, int, int]]]:
    """The legend strip (``width`` wide; its height depends on ``agents`` and ``width`` only)
    and, per label, the ``(x, y, w, h)`` of its swatch in the strip."""
    scale = 0.42
    placed: list[tuple[int, int, str, Any, str, int]] = []  # x, row, kind, colour, label, sw
    x, row = 8, 0
    for kind, col, label in _legend_items(agents, layout):
        if kind == "break":
            x, row = 8, row + 1
            continue
        sw = 0 if kind == "text" else (int(col) if kind == "scale" else _SWATCH + 4) + 4
        need = sw + _text_width(label, scale) + 16
        if x > 8 and x + need > width:
            x, row = 8, row + 1
        placed.append((x, row, kind, col, label, sw))
        x += need
    strip = np.full(((row + 1) * _ROW_PX + 6, width, 3), 250, dtype=np.uint8)
    swatches: dict[str, tuple[int, int, int, int]] = {}
    for x, row, kind, col, label, sw in placed:
        y0 = 4 + row * _ROW_PX + (_ROW_PX - _SWATCH) // 2
        y_mid = y0 + _SWATCH // 2
        if kind == "box":
            cv2.rectangle(strip, (x, y0), (x + _SWATCH - 1, y0 + _SWATCH - 1), col, -1)
            cv2.rectangle(strip, (x, y0), (x + _SWATCH - 1, y0 + _SWATCH - 1), (90, 90, 90), 1)
        elif kind == "robot":
            cv2.circle(strip, (x + 6, y_mid), 5, col, -1, cv2.LINE_AA)
            cv2.line(strip, (x + 6, y_mid), (x + _SWATCH + 2, y_mid), col, 2, cv2.LINE_AA)
        elif kind == "line":
            cv2.line(strip, (x, y_mid), (x + _SWATCH + 2, y_mid), col, 2, cv2.LINE_AA)
        elif kind == "scale":
            cv2.line(strip, (x, y_mid), (x + int(col), y_mid), (0, 0, 0), 2)
            for e in (x, x + int(col)):
                cv2.line(strip, (e, y_mid - 4), (e, y_mid + 4), (0, 0, 0), 2)
        if kind != "text":
            swatches[label] = (x, y0, int(col) if kind == "scale" else _SWATCH, _SWATCH)
        cv2.putText(strip, label, (x + sw, y0 + 11), _FONT, scale, (0, 0, 0), 1, cv2.LINE_AA)
    return strip, swatches


def world_title(snap: FrameSnapshot) -> str:
    """The true-world panel's title: simulated time and the env's coverage (``infos``' value)."""
    return f"world (truth)  t={snap.time_s:.1f}s  coverage {format_coverage(snap.coverage)}"


def render_frame(snap: FrameSnapshot) -> NDArray[np.uint8]:
    """The frame of ``snap``: true world | each robot's own map | fused map of robot_0, all at
    one scale and with a fixed window per episode (the frame's shape depends on the number of
    robots only), with a legend strip below."""
    world = snap.world
    n = len(snap.agents)
    layout = frame_layout(snap)
    wv = layout.world
    # --- the true world, what the team has observed, beams, trails, robots
    img = np.full((*world.walls.shape, 3), WORLD_UNSEEN, dtype=np.uint8)
    img[snap.seen & ~world.walls] = WORLD_SEEN
    img[world.walls] = WORLD_WALL
    panel = wv.draw(np.ascontiguousarray(img[::-1]))

    scan = snap.scan
    for i in range(n):
        pose = snap.true_poses[i]
        p = wv.px(world.cell_of(pose[None, :2]))[0]
        if scan is not None:
            ang = pose[2] + scan.angles[::8]
            rng_m = scan.ranges_m[i, ::8]
            ends = pose[None, :2] + np.stack([np.cos(ang), np.sin(ang)], 1) * rng_m[:, None]
            for q in wv.px(world.cell_of(ends)):
                cv2.line(panel, (int(p[0]), int(p[1])), (int(q[0]), int(q[1])), BEAM, 1)
        trail = snap.trails[i]
        if len(trail) > 1:
            _trail(panel, wv, apply_transform(snap.world_from_map[i], trail), i)
    for i in range(n):
        pose = snap.true_poses[i]
        _draw_robot(panel, wv.px(world.cell_of(pose[None, :2]))[0], float(pose[2]), i, big=True)
    panels = [_title(panel, world_title(snap))]
    # --- each robot's own map, in its own frame
    for i, a in enumerate(snap.agents):
        c, r, th = snap.pose_cells[i]
        panels.append(
            map_panel(
                snap.maps[i],
                f"{a}: own map (own frame)",
                [(c, r, th, i)],
                [(snap.trails[i], i)],
                view=layout.robots[i],
            )
        )
    # --- the fused map in robot_0's frame
    view = snap.fused
    if view is not None:
        poses = [(*view.pose_cell, 0)] + [
            (c, r, 0.0, snap.agents.index(o)) for o, (c, r) in view.teammates.items()
        ]
        err = snap.fused_error
        status = "MERGED" if view.merged else "not merged"
        if err is not None:
            status += f" err {err['translation_cells']:.1f}c {err['rotation_deg']:.1f}deg"
        panels.append(
            map_panel(
                view.map, f"fused ({view.agent} frame): {status}", poses, view=layout.robots[0]
            )
        )
    top = np.hstack(panels)
    strip, _ = legend(snap.agents, layout, top.shape[1])
    return np.ascontiguousarray(np.vstack([top, strip]))


class HumanWindow:
    """``render_mode="human"``: frames shown in a matplotlib window at ``fps``. On a headless
    machine (no interactive backend) it shows nothing and warns once. Pickles without its
    window (re-opened on demand)."""

    def __init__(self, fps: float) -> None:
        self.fps = fps
        self._figure: Any = None
        self._warned = False

    def show(self, frame: NDArray[np.uint8]) -> None:
        """Show ``frame`` (H, W, 3 uint8), opening the window on the first call."""
        try:
            import matplotlib

            if matplotlib.get_backend().lower() in ("agg", "pdf", "svg", "ps", "cairo", "template"):
                raise RuntimeError("no interactive matplotlib backend (headless machine)")
            import matplotlib.pyplot as plt
        except Exception as exc:
            if not self._warned:
                warnings.warn(
                    f"render_mode='human' shows nothing here ({exc}); use render_mode='rgb_array' "
                    "and write frames with mrexplore.render.write_video",
                    stacklevel=3,
                )
                self._warned = True
            return
        if self._figure is None:
            fig, ax = plt.subplots()
            ax.axis("off")
            self._figure = (fig, ax.imshow(frame))
        else:
            self._figure[1].set_data(frame)
        plt.pause(1.0 / self.fps)

    def close(self) -> None:
        """Close the window, if any."""
        if self._figure is not None:
            try:
                import matplotlib.pyplot as plt

                plt.close(self._figure[0])
            except Exception:  # pragma: no cover - closing a window must never raise
                pass
            self._figure = None

    def __getstate__(self) -> dict[str, Any]:
        state = dict(self.__dict__)
        state["_figure"] = None
        return state


def write_video(frames: Sequence[NDArray[np.uint8]], path: str | Path, fps: float = 8.0) -> Path:
    """Write RGB frames as an animated GIF (Pillow, if installed) or MP4 (OpenCV) by suffix."""
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    if not frames:
        raise ValueError("no frames to write")
    if path.suffix.lower() == ".gif":
        try:
            from PIL import Image
        except ImportError as exc:  # pragma: no cover
            raise ImportError(
                "writing GIFs needs Pillow: pip install pillow (or use .mp4)"
            ) from exc
        imgs = [Image.fromarray(f) for f in frames]
        imgs[0].save(path, save_all=True, append_images=imgs[1:], duration=int(1000 / fps), loop=0)
        return path
    h, w = frames[0].shape[:2]
    writer = cv2.VideoWriter(str(path), cv2.VideoWriter.fourcc(*"mp4v"), fps, (w, h))
    for f in frames:
        writer.write(cv2.cvtColor(f, cv2.COLOR_RGB2BGR))
    writer.release()
    return path
