"""Check a map_server map before running on it: ``mrexplore world check MAP.yaml``.

A map can load and still be a poor world: no walls (a wrong ``negate`` or thresholds), free
space in parts the robots never reach (coverage counts only the part they start in), or a
resolution so coarse that the robot is less than a cell wide and the lidar sees a few cells.
:func:`check_map` measures these with the env's own rules (:func:`mrexplore.truth.reachable_free`,
the default robot radius and lidar of :class:`mrexplore.environment.config.EnvConfig`) and names
each problem; ``mrexplore task-time`` prints the same lines before it runs on a map file.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from pathlib import Path

import cv2
import numpy as np

from mrexplore.errors import ConfigError
from mrexplore.grid import free_mask
from mrexplore.world.map_io import read_map_yaml, world_from_file

__all__ = [
    "MIN_CELLS_ACROSS_ROBOT",
    "MIN_DISCONNECTED_SHARE",
    "MIN_RANGE_CELLS",
    "MapCheck",
    "check_map",
    "warn_map",
]

#: A robot narrower than this many cells collides and plans on a caricature of its body.
MIN_CELLS_ACROSS_ROBOT = 3.0
#: A lidar range shorter than this many cells sees too few cells per scan to map walls.
MIN_RANGE_CELLS = 10.0
#: Free space out of reach above this share of the reachable area is a problem (below: a note);
#: coverage, and so task time, counts the reachable part only.
MIN_DISCONNECTED_SHARE = 0.10


@dataclass(frozen=True)
class MapCheck:
    """What :func:`check_map` found (areas in m^2, lengths in m).

    Attributes:
        path: the YAML checked.
        shape: (rows, cols) of the map image.
        resolution_m: metres per cell.
        free_m2: all free floor in the map.
        reachable_m2: free floor the robots reach from the largest free component (what coverage
            counts).
        parts: free parts the robots never reach (4-connected, no reachable cell), largest first,
            in m^2.
        has_walls: any non-free cell (occupied or unknown, both walls to the simulator).
        radius_m, max_range_m, n_beams, fov_deg: the robots' body and lidar checked against.
        problems: why the map is not usable as it is (empty = usable).
        notes: facts worth knowing that do not stop a run.
    """

    path: Path
    shape: tuple[int, int]
    resolution_m: float
    free_m2: float
    reachable_m2: float
    parts: list[float]
    has_walls: bool
    radius_m: float
    max_range_m: float
    n_beams: int
    fov_deg: float
    problems: list[str] = field(default_factory=list)
    notes: list[str] = field(default_factory=list)

    @property
    def ok(self) -> bool:
        """True when no problem was found."""
        return not self.problems

    def report(self) -> str:
        """The human-readable report ``mrexplore world check`` prints."""
        rows, cols = self.shape
        res = self.resolution_m
        unreached = sum(self.parts)
        lines = [
            f"map: {self.path}",
            f"size: {cols} x {rows} cells, {cols * res:g} x {rows * res:g} m at {res:g} m/cell",
            f"free floor: {self.free_m2:.1f} m^2; reachable: {self.reachable_m2:.1f} m^2 "
            "(what coverage counts)",
            f"disconnected free parts: {len(self.parts)} ({unreached:.1f} m^2)",
            f"walls: {'yes' if self.has_walls else 'none'}",
            f"robots: radius {self.radius_m:g} m = {self.radius_m / res:.1f} cells; lidar "
            f"{self.n_beams} beams over {self.fov_deg:g} deg, range {self.max_range_m:g} m = "
            f"{self.max_range_m / res:.1f} cells",
        ]
        lines += [f"note: {n}" for n in self.notes]
        lines += [f"problem: {p}" for p in self.problems]
        lines.append("usable" if self.ok else f"not usable: {len(self.problems)} problem(s)")
        return "\n".join(lines)


def _env_defaults() -> tuple[float, float, int, float]:
    """The env's default robot radius, lidar range, beams and field of view."""
    from mrexplore.environment.config import EnvConfig

    cfg = EnvConfig()
    return cfg.radius_m, cfg.max_range_m, cfg.n_beams, cfg.fov_deg


def _positive(name: str, value: object) -> float:
    """``value`` as a positive finite float, or a ConfigError naming ``name``."""
    try:
        out = float(value)  # type: ignore[arg-type]
    except (TypeError, ValueError):
        out = math.nan
    if isinstance(value, bool) or not (math.isfinite(out) and out > 0.0):
        raise ConfigError(f"world check: {name} must be a positive number, got {value!r}")
    return out


def check_map(
    path: str | Path, radius_m: float | None = None, max_range_m: float | None = None
) -> MapCheck:
    """Measure a map_server map against the robots the env simulates.

    Args:
        path: the map's YAML.
        radius_m, max_range_m: the robot radius and lidar range to check against (default: the
            env's defaults, 0.15 m and 4 m).

    Raises:
        ConfigError: ``radius_m`` or ``max_range_m`` is not a positive number.
        MapFileNotFoundError, MapFileError: the YAML or its image does not load (as
            :func:`mrexplore.world.read_map_yaml`).
    """
    from mrexplore.truth import reachable_free

    occ = read_map_yaml(path)
    d_radius, d_range, n_beams, fov_deg = _env_defaults()
    radius = _positive("radius_m", d_radius if radius_m is None else radius_m)
    max_range = _positive("max_range_m", d_range if max_range_m is None else max_range_m)
    res = occ.resolution_m
    cell_m2 = res * res
    free = free_mask(occ.grid)
    problems: list[str] = []
    notes: list[str] = []
    reachable_m2 = 0.0
    parts: list[float] = []
    if not free.any():
        problems.append("no free cell: nothing to explore (is 'negate' or 'free_thresh' right?)")
    else:
        world = world_from_file(occ.path)
        reach = reachable_free(world, radius)
        reachable_m2 = float(np.count_nonzero(reach)) * cell_m2
        n, labels = cv2.connectedComponents(world.free.astype(np.uint8), connectivity=4)
        counts = np.bincount(labels.ravel(), minlength=n)
        reached = set(np.unique(labels[reach]).tolist())
        parts = sorted(
            (float(counts[i]) * cell_m2 for i in range(1, n) if i not in reached), reverse=True
        )
        if reachable_m2 == 0.0:
            problems.append(
                f"no free space a robot of radius {radius:g} m can stand in: every gap is "
                "narrower than the robot"
            )
    has_walls = bool((~free).any())
    if not has_walls:
        problems.append(
            "no walls: every cell is free (the simulator adds a 1-cell border); the lidar "
            "finds nothing to hit and the merger nothing to match (is 'negate' right?)"
        )
    unreached = sum(parts)
    if parts:
        text = (
            f"{len(parts)} free part(s) the robots never reach ({unreached:.1f} m^2, largest "
            f"{parts[0]:.1f} m^2): coverage counts only the {reachable_m2:.1f} m^2 reachable"
        )
        if reachable_m2 > 0.0 and unreached >= MIN_DISCONNECTED_SHARE * reachable_m2:
            problems.append(text)
        else:
            notes.append(text)
    across = 2.0 * radius / res
    if across < MIN_CELLS_ACROSS_ROBOT - 1e-9:  # 0.3 m at 0.1 m/cell is 2.999... cells
        problems.append(
            f"too coarse for the robot: {across:.1f} cells across a {2 * radius:g} m robot "
            f"(at least {MIN_CELLS_ACROSS_ROBOT:g}; at most {2 * radius / 3:.3g} m/cell)"
        )
    range_cells = max_range / res
    if range_cells < MIN_RANGE_CELLS - 1e-9:
        problems.append(
            f"too coarse for the lidar: its {max_range:g} m range is {range_cells:.1f} cells "
            f"(at least {MIN_RANGE_CELLS:g}; at most {max_range / MIN_RANGE_CELLS:.3g} m/cell)"
        )
    if not problems and not math.isclose(res, 0.05):
        notes.append(
            f"{res:g} m/cell: the merger's guards are tuned for 0.05 m/cell (the shipped worlds)"
        )
    return MapCheck(
        path=occ.path,
        shape=(int(occ.grid.shape[0]), int(occ.grid.shape[1])),
        resolution_m=res,
        free_m2=float(np.count_nonzero(free)) * cell_m2,
        reachable_m2=reachable_m2,
        parts=parts,
        has_walls=has_walls,
        radius_m=radius,
        max_range_m=max_range,
        n_beams=n_beams,
        fov_deg=fov_deg,
        problems=problems,
        notes=notes,
    )


def warn_map(
    path: str | Path, radius_m: float | None = None, max_range_m: float | None = None
) -> list[str]:
    """The problem and note lines of :func:`check_map` (what ``task-time`` prints first)."""
    found = check_map(path, radius_m, max_range_m)
    return [f"problem: {p}" for p in found.problems] + [f"note: {n}" for n in found.notes]
