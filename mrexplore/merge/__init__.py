"""Map merging: fuse two robots' occupancy grids whose relative pose is unknown.

- :func:`merge_maps` (``method="semantic" | "paper" | "orb"``) -> :class:`MergeResult`;
- :class:`MapMergeTracker`: every-step use for N robots (attempts, keeps, re-checks, fuses);
- :func:`window_size`: the seed paper's Eq. (5).
"""

from mrexplore.merge.api import METHODS, merge_maps
from mrexplore.merge.common import MergeResult
from mrexplore.merge.paper import window_size
from mrexplore.merge.tracker import MapMergeTracker

__all__ = ["METHODS", "MapMergeTracker", "MergeResult", "merge_maps", "window_size"]
