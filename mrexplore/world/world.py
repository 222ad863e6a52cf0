"""The ground-truth world: a wall/free grid with a resolution. Simulator and evaluation only.

Nothing a robot, a policy or the merger sees is read from here directly: robots see the world
only through their range sensor.
"""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

import numpy as np
from numpy.typing import NDArray

from mrexplore.errors import WorldError


@dataclass(frozen=True, eq=False)
class World:
    """A 2-D indoor world.

    Attributes:
        walls: bool array (H, W); ``True`` = wall, obstacle or outside. Row 0 is the bottom
            (lowest y), as in ``nav_msgs/OccupancyGrid``.
        resolution_m: edge of one cell in metres (> 0).
        origin_m: world (x, y) in metres of the lower-left *corner* of cell (0, 0), as the
            ``origin`` of a map_server YAML. The centre of cell (c, r) is at
            ``origin_m + (c + 0.5, r + 0.5) * resolution_m``.
        name: a human-readable name (the registry name or the file stem).
        meta: free-form facts from the generator, e.g. ``{"twin_rooms": [(col, row, w, h), ...]}``
            (cell boxes of the identical rooms). For tests and evaluation only.
    """

    walls: NDArray[np.bool_]
    resolution_m: float = 0.05
    origin_m: tuple[float, float] = (0.0, 0.0)
    name: str = "world"
    meta: dict[str, Any] = field(default_factory=dict)

    def __post_init__(self) -> None:
        walls = np.asarray(self.walls)
        if walls.ndim != 2 or walls.size == 0:
            raise WorldError(
                f"world '{self.name}': walls must be a non-empty 2-D array, got shape {walls.shape}"
            )
        if walls.dtype != np.bool_:
            raise WorldError(
                f"world '{self.name}': walls must be a bool array, got dtype {walls.dtype}"
            )
        res = float(self.resolution_m)
        if not np.isfinite(res) or res <= 0.0:
            raise WorldError(
                f"world '{self.name}': resolution must be a positive number of metres, "
                f"got {self.resolution_m}"
            )
        if walls.all():
            raise WorldError(f"world '{self.name}' has no free cell")
        object.__setattr__(self, "walls", np.ascontiguousarray(walls))
        object.__setattr__(self, "resolution_m", res)
        object.__setattr__(self, "origin_m", (float(self.origin_m[0]), float(self.origin_m[1])))

    @property
    def shape(self) -> tuple[int, int]:
        """(rows, cols) of the grid."""
        return (int(self.walls.shape[0]), int(self.walls.shape[1]))

    @property
    def free(self) -> NDArray[np.bool_]:
        """bool (H, W): cells that are not walls."""
        return ~self.walls

    @property
    def size_m(self) -> tuple[float, float]:
        """(width, height) in metres."""
        return (self.shape[1] * self.resolution_m, self.shape[0] * self.resolution_m)

    def cell_of(self, xy_m: NDArray[np.floating]) -> NDArray[np.float64]:
        """World metres (N, 2) -> continuous cells (col, row) (N, 2); cell centres are integers."""
        xy = np.asarray(xy_m, dtype=np.float64).reshape(-1, 2)
        return (xy - np.asarray(self.origin_m)) / self.resolution_m - 0.5

    def xy_of(self, cells: NDArray[np.floating]) -> NDArray[np.float64]:
        """Continuous cell coordinates (col, row) (N, 2) -> world metres (N, 2)."""
        cr = np.asarray(cells, dtype=np.float64).reshape(-1, 2)
        return (cr + 0.5) * self.resolution_m + np.asarray(self.origin_m)
