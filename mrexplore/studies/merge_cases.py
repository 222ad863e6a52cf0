"""Seeded map-merge cases with the true transform known: the merge benchmark's and tests' inputs.

Two families:

- :func:`real_map_case`: two overlapping crops of a real map from ``../shared/maps``
  (``$MREXPLORE_MAPS``) (or any int8 map), the second rotated by a random angle, their borders
  damaged a little (random unknown blobs near the crop edges, as partial SLAM maps fray at
  their rims).
- :func:`symmetric_case`: two robots explore overlapping parts of a generated symmetric world
  (``symmetric_office`` or ``twin_wings``: two cell-for-cell identical rooms) with the lidar and
  their own-frame maps; half the cases rotate b's map by a random angle on top of the robots'
  own start headings.

Every case carries ``T_ab`` (b's cells -> a's cells, truth) and ``overlap``: the share of b's
known cells that land on a's known cells under the truth.
"""

from __future__ import annotations

import os
from collections.abc import Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import cv2
import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import ConfigError
from mrexplore.grid import (
    UNKNOWN,
    Int8Grid,
    Transform,
    chain,
    invert_transform,
    make_transform,
    map_points,
)
from mrexplore.merge.common import translation, warp_into

#: Real maps used for cases (paths relative to the shared maps folder), with crop sizes in cells.
REAL_MAPS: dict[str, tuple[int, int]] = {
    "nav2/depot.yaml": (170, 300),
    "turtlebot3/office_raw.yaml": (120, 200),
    "nav2/tb3_sandbox.yaml": (120, 200),
    "nav2/warehouse.yaml": (250, 450),
}


def _default_maps_dir() -> Path:
    """``$MREXPLORE_MAPS``, else ``shared/maps`` beside the checkout (the team's layout)."""
    env = os.environ.get("MREXPLORE_MAPS")
    if env:
        return Path(env)
    return Path(__file__).resolve().parents[3] / "shared" / "maps"


#: Folder of the real maps (``$MREXPLORE_MAPS`` or ``../shared/maps`` beside the checkout).
SHARED_MAPS = _default_maps_dir()


@dataclass(eq=False)
class MergeCase:
    """One merge problem with its answer.

    Attributes:
        a, b: int8 maps (each in its own frame).
        T_ab: 3x3 float64 truth, b's cells -> a's cells.
        overlap: share of b's known cells on a's known cells under the truth, in [0, 1].
        family: "real" or "symmetric".
        name: source map / world and seed, for tables.
        meta: extras (rotation applied in degrees, whether b sees both twin rooms, ...).
    """

    a: Int8Grid
    b: Int8Grid
    T_ab: Transform
    overlap: float
    family: str
    name: str
    meta: dict[str, Any] = field(default_factory=dict)
    resolution_m: float = 0.05


def overlap_share(a: Int8Grid, b: Int8Grid, T_ab: Transform) -> float:
    """Share of b's known cells that land (nearest cell) on a known cell of a under ``T_ab``."""
    rows, cols = np.nonzero(b != UNKNOWN)
    if rows.size == 0:
        return 0.0
    # elementwise, not BLAS: the same cells on every CPU
    p = np.stack(map_points(np.stack([cols, rows], axis=1).astype(np.float64), T_ab), axis=1)
    c, r = np.rint(p[:, 0]).astype(np.int64), np.rint(p[:, 1]).astype(np.int64)
    h, w = a.shape
    inside = (c >= 0) & (c < w) & (r >= 0) & (r < h)
    known = np.zeros(rows.size, dtype=bool)
    known[inside] = a[r[inside], c[inside]] != UNKNOWN
    return float(known.mean())


def rotate_map(grid: Int8Grid, theta_rad: float) -> tuple[Int8Grid, Transform]:
    """Rotate a map by ``theta_rad`` about its centre (nearest neighbour) onto a canvas that holds
    it all; returns (rotated map, T mapping original cells -> rotated cells)."""
    h, w = grid.shape
    R = make_transform(theta_rad, 0.0, 0.0)
    corners = np.array([[0, 0], [w - 1, 0], [0, h - 1], [w - 1, h - 1]], dtype=np.float64)
    # chain/map_points, not BLAS: the case (canvas, warp) has the same bits on every CPU
    q = np.stack(map_points(corners, R), axis=1)
    lo, hi = np.floor(q.min(axis=0)), np.ceil(q.max(axis=0))
    T = chain(translation(-lo[0] + 2, -lo[1] + 2), R)
    shape = (int(hi[1] - lo[1]) + 5, int(hi[0] - lo[0]) + 5)
    return warp_into(grid, T, shape), T


def damage_borders(grid: Int8Grid, rng: np.random.Generator, n_blobs: int = 6) -> Int8Grid:
    """Copy of ``grid`` with ``n_blobs`` random unknown discs (radius 3-12 cells) centred near the
    edges of its known area (within 12 % of its size from the known bounding box's rim)."""
    out = grid.copy()
    rows, cols = np.nonzero(grid != UNKNOWN)
    if rows.size == 0:
        return out
    r0, r1, c0, c1 = rows.min(), rows.max(), cols.min(), cols.max()
    h, w = max(r1 - r0, 1), max(c1 - c0, 1)
    rr, cc = np.mgrid[0 : grid.shape[0], 0 : grid.shape[1]]
    for _ in range(n_blobs):
        side = int(rng.integers(4))
        u = rng.uniform(0, 1)
        d = rng.uniform(0, 0.12)
        if side == 0:
            cr, ccol = r0 + d * h, c0 + u * w
        elif side == 1:
            cr, ccol = r1 - d * h, c0 + u * w
        elif side == 2:
            cr, ccol = r0 + u * h, c0 + d * w
        else:
            cr, ccol = r0 + u * h, c1 - d * w
        rad = rng.uniform(3, 12)
        out[(rr - cr) ** 2 + (cc - ccol) ** 2 <= rad * rad] = UNKNOWN
    return out


# --------------------------------------------------------------------------------------------
# symmetric worlds: lidar scans along random waypoint paths
# --------------------------------------------------------------------------------------------


def _bfs_distance(free: NDArray[np.bool_], start: tuple[int, int]) -> NDArray[np.int32]:
    """4-connected BFS distance (cells) from ``start`` (row, col) over ``free``; -1 unreachable.

    Vectorised wavefront: one dilation of the frontier per distance step.
    """
    dist = np.full(free.shape, -1, dtype=np.int32)
    if not free[start]:
        return dist
    dist[start] = 0
    frontier = np.zeros(free.shape, dtype=np.uint8)
    frontier[start] = 1
    cross = np.array([[0, 1, 0], [1, 1, 1], [0, 1, 0]], dtype=np.uint8)
    d = 0
    while True:
        d += 1
        grown = cv2.dilate(frontier, cross).astype(bool) & free & (dist < 0)
        if not grown.any():
            return dist
        dist[grown] = d
        frontier = grown.view(np.uint8)


def _path(dist: NDArray[np.int32], goal: tuple[int, int]) -> list[tuple[int, int]]:
    """Cells (row, col) from the BFS source to ``goal`` by steepest descent of ``dist``."""
    r, c = goal
    out = [(r, c)]
    h, w = dist.shape
    while dist[r, c] > 0:
        for dr, dc in ((1, 0), (-1, 0), (0, 1), (0, -1)):
            rr, cc = r + dr, c + dc
            if 0 <= rr < h and 0 <= cc < w and dist[rr, cc] == dist[r, c] - 1:
                r, c = rr, cc
                break
        out.append((r, c))
    return out[::-1]


def explore_partial_map(
    walls: NDArray[np.bool_],
    rng: np.random.Generator,
    resolution_m: float,
    n_waypoints: int = 3,
    scan_every: int = 8,
    max_range_m: float = 4.0,
    radius_m: float = 0.2,
    start: tuple[int, int] | None = None,
) -> Int8Grid:
    """World-frame partial map of one robot: lidar scans every ``scan_every`` cells along shortest
    paths through ``n_waypoints`` random reachable waypoints (cells visible to the beams become
    free or occupied, everything else stays unknown). int8 (H, W) like ``walls``."""
    from mrexplore.sensors import Lidar, LidarConfig

    inflated = cv2.dilate(
        walls.view(np.uint8),
        np.ones((3, 3), np.uint8),
        iterations=max(1, round(radius_m / resolution_m)),
    )
    free = ~inflated.astype(bool)
    cells = np.argwhere(free)
    if start is None:
        k = int(rng.integers(len(cells)))
        start = (int(cells[k, 0]), int(cells[k, 1]))
    views: list[tuple[int, int]] = []
    cur: tuple[int, int] = start
    for _ in range(n_waypoints):
        dist = _bfs_distance(free, cur)
        reach = np.argwhere(dist > 0)
        if reach.size == 0:
            break
        k = int(rng.integers(len(reach)))
        goal = (int(reach[k, 0]), int(reach[k, 1]))
        views += _path(dist, goal)[::scan_every]
        cur = goal
    views.append(cur)
    org = np.array([[c, r] for r, c in views], dtype=np.float64)
    lidar = Lidar(LidarConfig(n_beams=360, max_range_m=max_range_m, noise_std_m=0.0))
    scan = lidar.cast(walls, org, np.zeros(len(org)), resolution_m)
    # Visible area of one scan = the star-shaped polygon of its beam end points (filled by
    # OpenCV: much cheaper than collecting every traversed cell), plus the wall cells hit.
    ang = scan.angles[None, :]
    rng_cells = scan.ranges_m.astype(np.float64) / resolution_m
    ends_c = org[:, :1] + rng_cells * np.cos(ang)
    ends_r = org[:, 1:] + rng_cells * np.sin(ang)
    seen = np.zeros(walls.shape, dtype=np.uint8)
    polys = [
        np.rint(np.stack([ends_c[k], ends_r[k]], axis=1)).astype(np.int32) for k in range(len(org))
    ]
    cv2.fillPoly(seen, polys, 1)
    # The cell just beyond each hit end point is the wall that stopped the beam.
    hc = np.rint(org[:, :1] + (rng_cells + 0.5) * np.cos(ang)).astype(np.int64)[scan.hit]
    hr = np.rint(org[:, 1:] + (rng_cells + 0.5) * np.sin(ang)).astype(np.int64)[scan.hit]
    h, w = walls.shape
    ok = (hc >= 0) & (hc < w) & (hr >= 0) & (hr < h)
    seen[hr[ok], hc[ok]] = 1
    known = seen.astype(bool)
    out = np.full(walls.shape, UNKNOWN, dtype=np.int8)
    out[known] = np.where(walls[known], 100, 0).astype(np.int8)
    return out


def _crop_known(grid: Int8Grid, margin: int = 3) -> tuple[Int8Grid, tuple[int, int]]:
    rows, cols = np.nonzero(grid != UNKNOWN)
    r0, c0 = max(0, rows.min() - margin), max(0, cols.min() - margin)
    r1, c1 = rows.max() + margin + 1, cols.max() + margin + 1
    return grid[r0:r1, c0:c1].copy(), (int(c0), int(r0))


def symmetric_case(
    rng: np.random.Generator, generator: str = "symmetric_office", rotate: bool = True
) -> MergeCase:
    """Two robots' partial maps of a fresh symmetric world (``symmetric_office`` / ``twin_wings``).

    Robot A and robot B start at random free cells and each follows 2-4 random waypoints, so
    the overlap ranges from none to most of the map and often includes one or both twin rooms.
    a is A's map cropped to its known box (a translated frame); b is B's map cropped and, when
    ``rotate``, rotated by a uniform random angle. ``meta["twins_seen"]`` gives, per twin room,
    the share of its cells known in (a, b).
    """
    from mrexplore.world import generators

    make = {"symmetric_office": generators.symmetric_office, "twin_wings": generators.twin_wings}
    if generator not in make:
        raise ConfigError(
            f"symmetric_case: unknown generator {generator!r}; choose one of {tuple(make)}"
        )
    world = make[generator](rng)
    walls = world.walls
    ma = explore_partial_map(walls, rng, world.resolution_m, n_waypoints=int(rng.integers(2, 5)))
    mb = explore_partial_map(walls, rng, world.resolution_m, n_waypoints=int(rng.integers(2, 5)))
    a, (ca, ra) = _crop_known(ma)
    bc, (cb, rb) = _crop_known(mb)
    theta = float(rng.uniform(-np.pi, np.pi)) if rotate else 0.0
    if rotate:
        b, T_rot = rotate_map(bc, theta)
    else:
        b, T_rot = bc, np.eye(3)
    T_ab = chain(translation(cb - ca, rb - ra), invert_transform(T_rot))
    twins = []
    for c0, r0, w, h in world.meta.get("twin_rooms", []):
        box = (slice(r0, r0 + h), slice(c0, c0 + w))
        twins.append((float((ma[box] != UNKNOWN).mean()), float((mb[box] != UNKNOWN).mean())))
    return MergeCase(
        a=a,
        b=b,
        T_ab=T_ab,
        overlap=overlap_share(a, b, T_ab),
        family="symmetric",
        name=generator,
        meta={"rotation_deg": float(np.degrees(theta)), "twins_seen": twins},
    )


def symmetric_cases(n: int, seed: int) -> list[MergeCase]:
    """``n`` symmetric-world cases alternating the two generators; every other pair rotated."""
    if n < 0:
        raise ConfigError(f"symmetric_cases: n must be >= 0, got {n}")
    rng = np.random.default_rng(seed)
    out = []
    for i in range(n):
        gen = "symmetric_office" if i % 4 < 2 else "twin_wings"
        case = symmetric_case(rng, gen, rotate=i % 2 == 1)
        case.name = f"{gen}#{i}"
        out.append(case)
    return out


def load_real_map(rel: str, maps_dir: Path = SHARED_MAPS) -> Int8Grid:
    """A shared real map as int8, row 0 = lowest y (read by ``map_io.read_map_yaml``)."""
    from mrexplore.world.map_io import read_map_yaml

    return read_map_yaml(maps_dir / rel).grid


def real_map_case(
    full: Int8Grid,
    rng: np.random.Generator,
    crop: tuple[int, int] = (120, 200),
    rotate: bool = True,
    name: str = "map",
    min_known: float = 0.25,
) -> MergeCase:
    """Two overlapping square-ish crops of ``full``; b rotated (uniform angle) when ``rotate``.

    Crop edges are drawn in ``crop`` (min, max) cells; b's crop is a's shifted by up to 70 % of
    the crop size, so the overlap ranges from large to small. Crops are re-drawn (up to 50 times)
    until each is at least ``min_known`` known.
    """
    H, W = full.shape
    lo, hi = crop
    for _ in range(50):
        ha, wa = (int(x) for x in rng.integers(lo, min(hi, H, W) + 1, size=2))
        ra, ca = int(rng.integers(0, H - ha + 1)), int(rng.integers(0, W - wa + 1))
        hb, wb = (int(x) for x in rng.integers(lo, min(hi, H, W) + 1, size=2))
        rb = int(np.clip(ra + rng.uniform(-0.7, 0.7) * ha, 0, H - hb))
        cb = int(np.clip(ca + rng.uniform(-0.7, 0.7) * wa, 0, W - wb))
        a = full[ra : ra + ha, ca : ca + wa]
        mb = full[rb : rb + hb, cb : cb + wb]
        if (a != UNKNOWN).mean() >= min_known and (mb != UNKNOWN).mean() >= min_known:
            break
    theta = float(rng.uniform(-np.pi, np.pi)) if rotate else 0.0
    if rotate:
        b, T_rot = rotate_map(mb, theta)
    else:
        b, T_rot = mb.copy(), np.eye(3)
    a = damage_borders(a, rng)
    b = damage_borders(b, rng)
    T_ab = chain(translation(cb - ca, rb - ra), invert_transform(T_rot))
    return MergeCase(
        a=np.ascontiguousarray(a),
        b=b,
        T_ab=T_ab,
        overlap=overlap_share(a, b, T_ab),
        family="real",
        name=name,
        meta={"rotation_deg": float(np.degrees(theta))},
    )


def real_cases(n: int, seed: int, maps_dir: Path = SHARED_MAPS) -> list[MergeCase]:
    """``n`` real-map cases, cycling over :data:`REAL_MAPS`; half of them rotated."""
    if n < 0:
        raise ConfigError(f"real_cases: n must be >= 0, got {n}")
    rng = np.random.default_rng(seed)
    from mrexplore.world.map_io import read_map_yaml

    if not Path(maps_dir).is_dir():
        raise ConfigError(
            f"real maps folder {maps_dir} not found: set $MREXPLORE_MAPS to the folder holding "
            "nav2/ and turtlebot3/ (the team's shared/maps)"
        )
    files = {k: read_map_yaml(maps_dir / k) for k in REAL_MAPS}
    keys = list(REAL_MAPS)
    out = []
    for i in range(n):
        k = keys[i % len(keys)]
        case = real_map_case(files[k].grid, rng, REAL_MAPS[k], rotate=i % 2 == 0, name=f"{k}#{i}")
        case.resolution_m = files[k].resolution_m
        out.append(case)
    return out


# --------------------------------------------------------------------------------------------
# noisy, non-Manhattan real-map crops
# --------------------------------------------------------------------------------------------


def add_map_noise(
    grid: Int8Grid,
    rng: np.random.Generator,
    ragged: float = 0.1,
    speckle: float = 0.0005,
    bend_cells: float = 1.0,
) -> Int8Grid:
    """A copy of ``grid`` degraded the way real SLAM maps are.

    - ragged walls: the wall mask is blurred (sigma 0.7 cells), Gaussian noise of std
      ``ragged`` is added and it is thresholded again on the known cells, so walls thicken, thin
      and break in places;
    - speckle: a share ``speckle`` of free cells become occupied (spurious returns);
    - drift: the map is bent by a smooth displacement field, up to ``bend_cells`` at its rim
      (odometry drift along a trajectory), so no single rigid transform fits every cell.
    """
    h, w = grid.shape
    known = grid != UNKNOWN
    wall = (grid >= 50).astype(np.float32)
    soft = cv2.GaussianBlur(wall, (0, 0), 0.7) + rng.normal(0.0, ragged, size=(h, w))
    out = np.where(known, np.where(soft > 0.3, 100, 0), UNKNOWN).astype(np.int8)
    free = np.flatnonzero((out == 0).ravel())
    k = int(speckle * free.size)
    if k:
        out.ravel()[rng.choice(free, size=k, replace=False)] = 100
    if bend_cells > 0:
        yy, xx = np.mgrid[0:h, 0:w].astype(np.float32)
        u, v = (xx - w / 2) / max(w / 2, 1), (yy - h / 2) / max(h / 2, 1)
        sx, sy = rng.choice([-1.0, 1.0], size=2)
        map_x = xx + float(sx * bend_cells) * v * v
        map_y = yy + float(sy * bend_cells) * u * u
        bent = cv2.remap(
            out.view(np.uint8),
            map_x,
            map_y,
            cv2.INTER_NEAREST,
            borderMode=cv2.BORDER_CONSTANT,
            borderValue=255,
        )
        out = bent.view(np.int8)
    return out


def noisy_real_cases(
    n: int, seed: int, maps_dir: Path = SHARED_MAPS, min_overlap: float = 0.4
) -> list[MergeCase]:
    """``n`` hard real-map cases: the whole map is first turned by a random angle (its walls are
    no longer on the grid axes, as in a SLAM map started at an angle), two crops overlapping by
    at least ``min_overlap`` are taken, b is turned by another random angle, and both get
    :func:`add_map_noise`. Cycles over :data:`REAL_MAPS`."""
    if n < 0:
        raise ConfigError(f"noisy_real_cases: n must be >= 0, got {n}")
    rng = np.random.default_rng(seed)
    from mrexplore.world.map_io import read_map_yaml

    files = {k: read_map_yaml(maps_dir / k) for k in REAL_MAPS}
    keys = list(REAL_MAPS)
    out: list[MergeCase] = []
    i = 0
    while len(out) < n:
        k = keys[i % len(keys)]
        i += 1
        phi = float(rng.uniform(-np.pi, np.pi))
        turned, _ = rotate_map(files[k].grid, phi)
        case = real_map_case(turned, rng, REAL_MAPS[k], rotate=True, name=f"{k}@noisy#{i}")
        a = add_map_noise(case.a, rng)
        b = add_map_noise(case.b, rng)
        ov = overlap_share(a, b, case.T_ab)
        if ov < min_overlap:
            continue
        out.append(
            MergeCase(
                a=a,
                b=b,
                T_ab=case.T_ab,
                overlap=ov,
                family="noisy",
                name=case.name,
                meta={**case.meta, "map_turn_deg": float(np.degrees(phi))},
                resolution_m=files[k].resolution_m,
            )
        )
    return out


# --------------------------------------------------------------------------------------------
# large maps: where the merger's cost bounds (coarse_max_blocks, hough_max_cells) act
# --------------------------------------------------------------------------------------------

#: Crop sizes (cells) of the large family: 500-900 cells a side, so that b, rotated, spans up
#: to ~1,270 cells, past the semantic merger's 640 x 640 cells where its large-map rules start.
LARGE_CROP: tuple[int, int] = (500, 900)


def large_cases(n: int, seed: int, maps_dir: Path = SHARED_MAPS) -> list[MergeCase]:
    """``n`` large-map cases, cycling over five kinds: generated ``symmetric_office`` and
    ``twin_wings`` floors (fully known, 0.05 m/cell, with their identical rooms), crops of the
    real ``nav2/warehouse`` map (0.03 m/cell, rows of identical racks), and noisy versions
    (:func:`add_map_noise`) of a generated floor and of the warehouse. Crops of
    :data:`LARGE_CROP` cells, b rotated at random."""
    if n < 0:
        raise ConfigError(f"large_cases: n must be >= 0, got {n}")
    from mrexplore.world import symmetric_office, twin_wings
    from mrexplore.world.map_io import read_map_yaml

    rng = np.random.default_rng(seed)
    warehouse = read_map_yaml(maps_dir / "nav2/warehouse.yaml")
    kinds = ("symmetric_office", "twin_wings", "warehouse", "noisy_office", "noisy_warehouse")
    out: list[MergeCase] = []
    for i in range(n):
        kind = kinds[i % len(kinds)]
        resolution = 0.05
        if kind.endswith("warehouse"):
            full, resolution = warehouse.grid, warehouse.resolution_m
        else:
            gen = twin_wings if kind == "twin_wings" else symmetric_office
            side_m = round(float(rng.uniform(1.0, 1.4)) * LARGE_CROP[1] * 0.05, 1)
            world = gen(rng, width_m=side_m, height_m=side_m)
            full = np.where(world.walls, 100, 0).astype(np.int8)
        case = real_map_case(full, rng, LARGE_CROP, rotate=True, name=f"{kind}#{i}")
        if kind.startswith("noisy"):
            case.a, case.b = add_map_noise(case.a, rng), add_map_noise(case.b, rng)
            case.overlap = overlap_share(case.a, case.b, case.T_ab)
        case.family = "large"
        case.resolution_m = resolution
        out.append(case)
    return out


# --------------------------------------------------------------------------------------------
# look-alike places that do not overlap: the right answer is a refusal
# --------------------------------------------------------------------------------------------

#: Real maps of the aliased family (rows of identical racks) and their crop sizes in cells.
ALIASED_MAPS: dict[str, tuple[int, int]] = {
    "nav2/depot.yaml": (100, 150),
    "nav2/warehouse.yaml": (150, 300),
}


def aliased_cases(n: int, seed: int, maps_dir: Path = SHARED_MAPS) -> list[MergeCase]:
    """``n`` pairs of crops of one repetitive real map (:data:`ALIASED_MAPS`) that do **not**
    overlap (disjoint rectangles, at least 10 cells apart), b rotated at random: two robots in
    two look-alike aisles. The truth places b away from a, so any accepted transform is wrong
    (``classify`` reads it as such); the right answer is a refusal. Crops are re-drawn until
    each is at least a quarter known."""
    if n < 0:
        raise ConfigError(f"aliased_cases: n must be >= 0, got {n}")
    from mrexplore.world.map_io import read_map_yaml

    rng = np.random.default_rng(seed)
    files = {k: read_map_yaml(maps_dir / k) for k in ALIASED_MAPS}
    keys = list(ALIASED_MAPS)
    out: list[MergeCase] = []
    for i in range(n):
        k = keys[i % len(keys)]
        full = files[k].grid
        H, W = full.shape
        lo, hi = ALIASED_MAPS[k]
        for _ in range(200):
            ha, wa, hb, wb = (int(x) for x in rng.integers(lo, min(hi, H, W) + 1, size=4))
            ra, ca = int(rng.integers(0, H - ha + 1)), int(rng.integers(0, W - wa + 1))
            rb, cb = int(rng.integers(0, H - hb + 1)), int(rng.integers(0, W - wb + 1))
            apart = (
                rb >= ra + ha + 10 or ra >= rb + hb + 10 or cb >= ca + wa + 10 or ca >= cb + wb + 10
            )
            a = full[ra : ra + ha, ca : ca + wa]
            mb = full[rb : rb + hb, cb : cb + wb]
            if apart and (a != UNKNOWN).mean() >= 0.25 and (mb != UNKNOWN).mean() >= 0.25:
                break
        else:
            raise ConfigError(f"aliased_cases: no two disjoint known crops of {k} found")
        theta = float(rng.uniform(-np.pi, np.pi))
        b, T_rot = rotate_map(mb, theta)
        T_ab = chain(translation(cb - ca, rb - ra), invert_transform(T_rot))
        out.append(
            MergeCase(
                a=np.ascontiguousarray(damage_borders(a, rng)),
                b=damage_borders(b, rng),
                T_ab=T_ab,
                overlap=0.0,
                family="aliased",
                name=f"{k}@apart#{i}",
                meta={"rotation_deg": float(np.degrees(theta))},
                resolution_m=files[k].resolution_m,
            )
        )
    return out


# --------------------------------------------------------------------------------------------
# lidar pairs from our simulator (own-frame maps, random headings, noise on)
# --------------------------------------------------------------------------------------------

#: Sensor and odometry noise of the lidar family: 2 cm range noise and light odometry drift
#: (0.5 % of the distance, 0.002 rad per radian turned, 0.0005 rad per metre), so the maps bend
#: by a few cells over a few minutes, not by tens (the in-loop study's noise is twice this).
LIDAR_NOISE: dict[str, float] = {
    "range_noise_m": 0.02,
    "odom_noise_trans": 0.005,
    "odom_noise_rot": 0.002,
    "odom_noise_rot_per_m": 0.0005,
}


def lidar_cases(
    n: int,
    seed: int,
    worlds: Sequence[str] = ("symmetric_office", "twin_wings", "tb3_office", "depot"),
    times_s: Sequence[float] = (60.0, 100.0, 140.0, 180.0, 220.0, 260.0),
    env_options: Mapping[str, Any] | None = None,
) -> list[MergeCase]:
    """``n`` pairs of the two robots' own maps, as the merger sees them in the loop.

    Two robots with random start headings explore a world (coordinated frontiers, no merging,
    env options ``env_options``: :data:`LIDAR_NOISE` by default); at each of ``times_s``
    (simulated s) the two maps, cropped to their known boxes, become a case with the true
    transform from the simulator. Worlds are cycled, one episode each, seeded from ``seed``;
    snapshots whose maps share no known cell under the truth are skipped.

    With odometry noise each map is bent by its robot's drift, so even a perfect merge sits off
    the start-frame truth: ``meta["drift_cells"]`` holds how far drift alone can move it (both
    robots' position drift plus their heading drift times the mean distance of b's cells from
    b's start), and :func:`mrexplore.studies.merge_bench.classify` widens its thresholds by
    it. 0 without odometry noise.
    """
    from mrexplore.environment.parallel_env import MultiRobotExplorationEnv
    from mrexplore.policies import make_team_policy

    if n < 0:
        raise ConfigError(f"lidar_cases: n must be >= 0, got {n}")
    kw: dict[str, Any] = dict(LIDAR_NOISE if env_options is None else env_options)
    out: list[MergeCase] = []
    episode = 0
    while len(out) < n:
        world = worlds[episode % len(worlds)]
        ep_seed = seed * 1000 + episode
        episode += 1
        options: dict[str, Any] = {"aligned_headings": False, "merger": None, **kw}
        env = MultiRobotExplorationEnv(
            world=world, n_robots=2, max_time_s=max(times_s) + 1.0, target_coverage=1.0, **options
        )
        env.reset(seed=ep_seed)
        team = make_team_policy("coordinated-frontier", env.possible_agents)
        team.reset(np.random.default_rng([ep_seed, 1]))
        snap = {round(t / env.config.dt_s) for t in times_s}
        step, done = 0, False
        while not done and len(out) < n and step < max(snap):
            _, _, terms, truncs, _ = env.step(team.act({a: env.robot_view(a) for a in env.agents}))
            step += 1
            done = bool(terms["robot_0"] or truncs["robot_0"])
            if step not in snap:
                continue
            case = _lidar_snapshot(env, f"{world}#{ep_seed}@{step * env.config.dt_s:.0f}s")
            if case is not None:
                out.append(case)
    return out


def _lidar_snapshot(env: Any, name: str) -> MergeCase | None:
    """The env's two own maps now, cropped, with the truth and the drift allowance."""
    from mrexplore.merge.common import known_bbox

    sim = env.sim
    a, b = env.local_map("robot_0"), env.local_map("robot_1")
    ba, bb = known_bbox(a), known_bbox(b)
    if ba is None or bb is None:
        return None
    ac = np.ascontiguousarray(a[ba[0] : ba[1], ba[2] : ba[3]])
    bc = np.ascontiguousarray(b[bb[0] : bb[1], bb[2] : bb[3]])
    T = chain(translation(-ba[2], -ba[0]), sim.true_transform(0, 1), translation(bb[2], bb[0]))
    ov = overlap_share(ac, bc, T)
    if ov <= 0.0:
        return None
    rows, cols = np.nonzero(bc != UNKNOWN)
    drift = sim.drift_allowance(0, 1, np.stack([cols + bb[2], rows + bb[0]], axis=1))
    return MergeCase(
        a=ac,
        b=bc,
        T_ab=T,
        overlap=ov,
        family="lidar",
        name=name,
        meta={"t_s": sim.steps * env.config.dt_s, "drift_cells": drift},
        resolution_m=sim.resolution_m,
    )
