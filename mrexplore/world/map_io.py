"""Read and write ROS ``map_server`` maps (YAML + PGM/PNG); turn them into :class:`World` objects.

This is the *only* module that flips rows: an image has row 0 at the top of the map, while every
array in mrexplore has row 0 at the lowest y (``nav_msgs/OccupancyGrid`` order).

Loading follows ROS 1 ``map_server`` (``image_loader.cpp``) exactly:

* keys ``image`` (relative to the YAML's folder unless absolute), ``resolution`` (m/cell),
  ``origin`` ``[x, y, yaw]`` (lower-left corner of the map), ``negate``, ``occupied_thresh``,
  ``free_thresh``, optional ``mode`` (``trinary`` default, ``scale``, ``raw``);
* a pixel's value is the mean of its channels (in trinary mode the alpha channel is averaged in
  too, as map_server does; in scale/raw modes it is not); with ``negate`` the value is
  ``255 - value``;
* ``raw``: the value is the cell (values outside 0..100 become unknown, as Nav2's loader does,
  instead of wrapping around in int8);
* otherwise ``p = (255 - value) / 255``; ``p > occupied_thresh`` -> 100, ``p < free_thresh`` -> 0,
  else unknown (-1) in trinary mode, and in scale mode ``99 * (p - free) / (occ - free)``
  truncated to an integer as ROS Noetic's map_server does (a fully transparent pixel stays
  unknown).

Saving follows ``map_saver``: free (0..25 %) -> 254, occupied (>= 65 %) -> 0, anything else -> 205,
with ``occupied_thresh: 0.65`` and ``free_thresh: 0.196``, so a trinary grid round-trips exactly.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
import yaml
from numpy.typing import NDArray

from mrexplore.errors import GridError, MapFileError, MapFileNotFoundError, WorldError
from mrexplore.grid import (
    FREE,
    FREE_THRESHOLD,
    OCCUPIED,
    OCCUPIED_THRESHOLD,
    UNKNOWN,
    Int8Grid,
    validate_grid,
)
from mrexplore.io_safety import write_bytes, write_text
from mrexplore.world.world import World

__all__ = [
    "OccupancyFile",
    "read_map_yaml",
    "world_from_file",
    "world_to_file",
    "write_map_yaml",
]

_MODES = ("trinary", "scale", "raw")
#: map_saver's pixel values for free, occupied and unknown cells.
_PIX_FREE = 254
_PIX_OCCUPIED = 0
_PIX_UNKNOWN = 205
#: map_saver's thresholds: 205 gives p = 50/255 = 0.19608 which is *not* below 0.196, so unknown.
_SAVE_OCC_THRESH = 0.65
_SAVE_FREE_THRESH = 0.196
#: Key of the YAML block holding generator facts (twin room boxes, ...); map_server ignores it.
_META_KEY = "mrexplore"
#: World.meta entries written to / read from that block; boxes are (col, row, w, h) in cells.
_META_BOXES = ("twin_rooms", "rooms", "corridor_boxes")
_META_BOX = ("corridor_box",)
_META_PLAIN = ("generator", "twin_rotation_deg", "corridor_width_m", "seed", "options")


@dataclass(frozen=True, eq=False)
class OccupancyFile:
    """A map read from a map_server YAML.

    Attributes:
        grid: int8 (H, W) in the -1/0/100 convention (values between in scale/raw modes); row 0 is
            the lowest y (the image's bottom row).
        resolution_m: metres per cell (> 0).
        origin_m: (x_m, y_m, yaw_rad) of the lower-left corner of cell (0, 0), as in the YAML.
        path: the YAML file it came from (resolved).
        extra: the YAML's ``mrexplore`` block (generator facts), empty for plain map_server files.
        image_path: the image file the YAML names (absolute), None when built by hand.
    """

    grid: Int8Grid
    resolution_m: float
    origin_m: tuple[float, float, float]
    path: Path
    extra: dict[str, Any] = field(default_factory=dict)
    image_path: Path | None = None


def _number(doc: dict[str, Any], key: str, path: Path, default: float | None = None) -> float:
    """A finite float from the YAML, or :class:`MapFileError` naming the key."""
    if key not in doc:
        if default is None:
            raise MapFileError(f"map file {path}: missing required key '{key}'")
        return default
    value = doc[key]
    # bool is an int in Python; "resolution: true" is a typo, not 1.0.
    if isinstance(value, bool) or not isinstance(value, (int, float, str)):
        raise MapFileError(f"map file {path}: '{key}' must be a number, got {value!r}")
    try:
        # PyYAML (YAML 1.1) reads "1e-05" as a string where map_server's yaml-cpp reads a number.
        out = float(value)
    except ValueError:
        raise MapFileError(f"map file {path}: '{key}' must be a number, got {value!r}") from None
    if not math.isfinite(out):
        raise MapFileError(f"map file {path}: '{key}' must be finite, got {value!r}")
    return out


def _load_yaml(path: Path) -> dict[str, Any]:
    if not path.is_file():
        raise MapFileNotFoundError(f"map YAML not found: {path}")
    try:
        doc = yaml.safe_load(path.read_text(encoding="utf-8"))
    except (yaml.YAMLError, UnicodeDecodeError) as exc:
        raise MapFileError(f"map file {path}: not valid YAML ({exc})") from exc
    if not isinstance(doc, dict):
        raise MapFileError(
            f"map file {path}: expected a YAML mapping with keys image, resolution, ..."
        )
    return doc


def _read_image(image_path: Path, yaml_path: Path) -> NDArray[np.uint8]:
    """The image as uint8 (H, W) or (H, W, C), row 0 at the top."""
    if not image_path.is_file():
        raise MapFileNotFoundError(f"map file {yaml_path}: image not found: {image_path}")
    # np.fromfile + imdecode instead of imread: imread returns None silently for many failures
    # and does not handle every path encoding; imdecode lets us say exactly what went wrong.
    raw = np.fromfile(str(image_path), dtype=np.uint8)
    img = cv2.imdecode(raw, cv2.IMREAD_UNCHANGED) if raw.size else None
    if img is None:
        raise MapFileError(
            f"map file {yaml_path}: cannot decode image {image_path} (not a PGM/PNG?)"
        )
    if img.dtype != np.uint8:
        raise MapFileError(
            f"map file {yaml_path}: image {image_path} has {img.dtype} pixels; "
            "only 8-bit images are supported"
        )
    if img.ndim not in (2, 3) or img.size == 0:
        raise MapFileError(
            f"map file {yaml_path}: image {image_path} has unusable shape {img.shape}"
        )
    return np.asarray(img, dtype=np.uint8)


def read_map_yaml(path: str | Path) -> OccupancyFile:
    """Read a map_server YAML and its image into an int8 grid (row 0 = lowest y).

    Raises:
        MapFileNotFoundError: the YAML or the image it names does not exist.
        MapFileError: a key is missing or has a bad value, or the image cannot be decoded.
    """
    yaml_path = Path(path).expanduser().resolve()
    doc = _load_yaml(yaml_path)

    image = doc.get("image")
    if image is None:
        raise MapFileError(f"map file {yaml_path}: missing required key 'image'")
    if not isinstance(image, str) or not image.strip():
        raise MapFileError(f"map file {yaml_path}: 'image' must be a file name, got {image!r}")
    resolution = _number(doc, "resolution", yaml_path)
    if resolution <= 0.0:
        raise MapFileError(f"map file {yaml_path}: 'resolution' must be positive, got {resolution}")
    if "origin" not in doc:  # map_server requires it: a silent 0 would misplace the map
        raise MapFileError(f"map file {yaml_path}: missing required key 'origin' [x, y, yaw]")
    origin_raw = doc["origin"]
    if not isinstance(origin_raw, (list, tuple)) or len(origin_raw) != 3:
        raise MapFileError(
            f"map file {yaml_path}: 'origin' must be [x, y, yaw], got {origin_raw!r}"
        )
    origin_vals = [_number({"origin": v}, "origin", yaml_path) for v in origin_raw]
    negate = doc.get("negate", 0)
    if isinstance(negate, bool):
        negate = int(negate)
    if negate not in (0, 1):
        raise MapFileError(f"map file {yaml_path}: 'negate' must be 0 or 1, got {negate!r}")
    occ_th = _number(doc, "occupied_thresh", yaml_path, default=0.65)
    free_th = _number(doc, "free_thresh", yaml_path, default=0.196)
    if not (0.0 <= free_th <= occ_th <= 1.0):
        raise MapFileError(
            f"map file {yaml_path}: thresholds must satisfy "
            "0 <= free_thresh <= occupied_thresh <= 1, "
            f"got free_thresh={free_th}, occupied_thresh={occ_th}"
        )
    mode = doc.get("mode", "trinary")
    if mode not in _MODES:
        raise MapFileError(f"map file {yaml_path}: 'mode' must be one of {_MODES}, got {mode!r}")

    image_path = Path(image).expanduser()
    if not image_path.is_absolute():
        image_path = yaml_path.parent / image_path
    img = _read_image(image_path, yaml_path)

    grid = _pixels_to_grid(img, mode=mode, negate=bool(negate), occ_th=occ_th, free_th=free_th)
    extra = doc.get(_META_KEY, {})
    if not isinstance(extra, dict):
        raise MapFileError(f"map file {yaml_path}: '{_META_KEY}' must be a mapping, got {extra!r}")
    return OccupancyFile(
        grid=np.ascontiguousarray(grid[::-1]),  # image row 0 is the top: flip to row 0 = lowest y
        resolution_m=resolution,
        origin_m=(origin_vals[0], origin_vals[1], origin_vals[2]),
        path=yaml_path,
        extra=extra,
        image_path=image_path.resolve(),
    )


def _pixels_to_grid(
    img: NDArray[np.uint8], *, mode: str, negate: bool, occ_th: float, free_th: float
) -> Int8Grid:
    """map_server's per-pixel rule, vectorised: ``img`` (H, W) or (H, W, C) uint8, rows kept."""
    alpha: NDArray[np.uint8] | None = None
    if img.ndim == 2:
        value = img.astype(np.float64)
    else:
        channels = img.shape[2]
        has_alpha = channels in (2, 4)
        if has_alpha:
            alpha = img[:, :, -1]
        # map_server averages alpha in with the colours in trinary mode (kept for compatibility).
        used = img if (mode == "trinary" or not has_alpha) else img[:, :, :-1]
        value = used.astype(np.float64).mean(axis=2)
    if negate:
        value = 255.0 - value

    if mode == "raw":
        cells = np.rint(value)
        return np.where((cells >= FREE) & (cells <= OCCUPIED), cells, UNKNOWN).astype(np.int8)

    p = (255.0 - value) / 255.0
    out = np.full(p.shape, UNKNOWN, dtype=np.int8)
    if mode == "scale":
        span = occ_th - free_th
        if span > 0.0:
            # C++ assigns the double to an int8 cell: truncation towards zero.
            mid = np.trunc(99.0 * (p - free_th) / span)
            out = np.clip(mid, 0, 99).astype(np.int8)
        if alpha is not None:
            out[alpha < 1] = UNKNOWN
    out[p > occ_th] = OCCUPIED
    out[p < free_th] = FREE
    return out


def _grid_to_pixels(grid: Int8Grid) -> NDArray[np.uint8]:
    """map_saver's rule (row order kept): free -> 254, occupied -> 0, anything else -> 205."""
    pix = np.full(grid.shape, _PIX_UNKNOWN, dtype=np.uint8)
    pix[(grid >= FREE) & (grid <= FREE_THRESHOLD)] = _PIX_FREE
    pix[grid >= OCCUPIED_THRESHOLD] = _PIX_OCCUPIED
    return pix


def _yaml_float(x: float) -> str:
    """Shortest exact text of a finite float that YAML 1.1 and 1.2 both read as that float.

    ``repr`` is exact but writes ``1e-05``, which YAML 1.1 (PyYAML) reads as a string.
    """
    text = repr(float(x))
    mantissa, e, exponent = text.partition("e")
    if e and "." not in mantissa:
        text = f"{mantissa}.0e{exponent}"
    return text


def write_map_yaml(
    path_yaml: str | Path,
    grid: Int8Grid,
    resolution_m: float,
    origin_m: tuple[float, float, float] | tuple[float, float] = (0.0, 0.0, 0.0),
    image_format: str = "pgm",
    extra: Mapping[str, Any] | None = None,
) -> Path:
    """Write ``grid`` (int8 (H, W), row 0 = lowest y) as a trinary map_server YAML + image.

    The image is written beside the YAML with the same stem (``name.yaml`` -> ``name.pgm``) and
    named relatively in the YAML, so the pair can be moved together. Output is byte-for-byte
    deterministic. ``extra`` (plain YAML-able data) is stored under the key ``mrexplore``, which
    map_server ignores; :func:`world_from_file` reads it back into ``World.meta``. Returns the
    YAML path.

    Raises:
        GridError: ``grid`` is not a valid int8 occupancy grid.
        MapFileError: bad resolution, origin or image format.
    """
    arr = validate_grid(grid, "grid")
    res = float(resolution_m)
    if not math.isfinite(res) or res <= 0.0:
        raise MapFileError(f"resolution_m must be a positive number of metres, got {resolution_m}")
    if len(origin_m) not in (2, 3):
        raise MapFileError(f"origin_m must be (x, y) or (x, y, yaw), got {origin_m!r}")
    origin = [float(v) for v in origin_m] + ([0.0] if len(origin_m) == 2 else [])
    if not all(math.isfinite(v) for v in origin):
        raise MapFileError(f"origin_m must be finite, got {origin_m!r}")
    fmt = image_format.lower().lstrip(".")
    if fmt not in ("pgm", "png"):
        raise MapFileError(f"image_format must be 'pgm' or 'png', got {image_format!r}")

    yaml_path = Path(path_yaml).expanduser()
    if yaml_path.suffix.lower() not in (".yaml", ".yml"):
        raise MapFileError(f"map path must end in .yaml or .yml, got {yaml_path}")
    yaml_path.parent.mkdir(parents=True, exist_ok=True)
    image_path = yaml_path.with_suffix("." + fmt)

    pixels = np.ascontiguousarray(_grid_to_pixels(arr)[::-1])  # row 0 = lowest y -> image top row
    ok, encoded = cv2.imencode("." + fmt, pixels)
    if not ok:  # pragma: no cover - OpenCV always encodes 8-bit grey PGM/PNG
        raise MapFileError(f"OpenCV could not encode {image_path}")
    write_bytes(image_path, encoded.tobytes())
    text = (
        f"image: {image_path.name}\n"
        f"mode: trinary\n"
        f"resolution: {_yaml_float(res)}\n"
        f"origin: [{', '.join(_yaml_float(v) for v in origin)}]\n"
        f"negate: 0\n"
        f"occupied_thresh: {_SAVE_OCC_THRESH}\n"
        f"free_thresh: {_SAVE_FREE_THRESH}\n"
    )
    if extra:
        try:
            text += yaml.safe_dump(
                {_META_KEY: dict(extra)}, sort_keys=True, default_flow_style=None
            )
        except yaml.YAMLError as exc:
            raise MapFileError(f"extra map data is not plain YAML data: {exc}") from exc
    write_text(yaml_path, text)
    return yaml_path


def world_from_file(path: str | Path, name: str | None = None) -> World:
    """Load a map_server YAML as a :class:`World`.

    Free cells (0..25 %) are free; occupied *and unknown* cells become walls (unknown space is
    outside the world for a simulator). If any free cell lies on the map's edge, a 1-cell wall
    border is added all round (and the origin moved by one cell) so robots cannot leave the grid.
    The YAML's yaw is kept in ``meta["origin_yaw_rad"]`` only: worlds are axis-aligned.

    Raises:
        MapFileNotFoundError, MapFileError: as :func:`read_map_yaml`.
        WorldError: the map has no free cell.
    """
    occ = read_map_yaml(path)
    free = (occ.grid >= FREE) & (occ.grid <= FREE_THRESHOLD)
    world_name = name if name is not None else occ.path.stem
    if not free.any():
        raise WorldError(f"world '{world_name}' from {occ.path} has no free cell")
    walls = ~free
    ox, oy = occ.origin_m[0], occ.origin_m[1]
    edge_free = bool(free[0].any() or free[-1].any() or free[:, 0].any() or free[:, -1].any())
    if edge_free:
        walls = np.pad(walls, 1, mode="constant", constant_values=True)
        ox -= occ.resolution_m
        oy -= occ.resolution_m
    meta: dict[str, Any] = {k: occ.extra[k] for k in _META_PLAIN if k in occ.extra}
    shift = 1 if edge_free else 0  # boxes move with the added border

    def _box(v: Any) -> tuple[int, int, int, int]:
        if not (
            isinstance(v, (list, tuple)) and len(v) == 4 and all(isinstance(x, int) for x in v)
        ):
            raise MapFileError(f"map file {occ.path}: a room box must be 4 integers, got {v!r}")
        return (v[0] + shift, v[1] + shift, v[2], v[3])

    for key in _META_BOXES:
        if key in occ.extra:
            meta[key] = [_box(b) for b in occ.extra[key]]
    for key in _META_BOX:
        if key in occ.extra:
            meta[key] = _box(occ.extra[key])
    meta.update(source=str(occ.path), origin_yaw_rad=occ.origin_m[2], border_added=edge_free)
    return World(
        walls=walls,
        resolution_m=occ.resolution_m,
        origin_m=(ox, oy),
        name=world_name,
        meta=meta,
    )


def _plain(value: Any) -> Any:
    """Tuples -> lists, numpy scalars -> Python, recursively: what yaml.safe_dump accepts."""
    if isinstance(value, Mapping):
        return {str(k): _plain(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [_plain(v) for v in value]
    if isinstance(value, np.generic):
        return value.item()
    return value


def world_to_file(world: World, path_yaml: str | Path, image_format: str = "pgm") -> Path:
    """Write a :class:`World` as a trinary map (walls occupied, free free); returns the YAML path.

    The generator facts of ``world.meta`` (twin room boxes, corridor, generator, seed, options)
    go to the YAML's ``mrexplore`` block, so a shipped world keeps its ``twin_rooms``.
    """
    grid = np.where(world.walls, OCCUPIED, FREE).astype(np.int8)
    keys = _META_PLAIN + _META_BOXES + _META_BOX
    extra = {k: _plain(world.meta[k]) for k in keys if k in world.meta}
    try:
        return write_map_yaml(
            path_yaml,
            grid,
            world.resolution_m,
            (world.origin_m[0], world.origin_m[1], 0.0),
            image_format,
            extra=extra,
        )
    except GridError as exc:  # pragma: no cover - a World's grid is always valid
        raise WorldError(f"world '{world.name}': {exc}") from exc
