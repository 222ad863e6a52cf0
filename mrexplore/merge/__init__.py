"""Map merging: fuse two robots' occupancy grids whose relative pose is unknown.

- :func:`merge_maps` (``method="semantic" | "paper" | "orb"``) -> :class:`MergeResult`, whose
  :class:`MergeEvidence` (semantic) holds the poses the merger weighed;
- :class:`MapMergeTracker`: every-step use for N robots (attempts, keeps, re-checks, fuses),
  tuned by :class:`TrackerOptions`; :class:`MergeWork`, what its attempts cost;
- :class:`SemanticOptions`, :class:`TrackerOptions`: the typed options of the semantic merger
  and the tracker; :func:`in_loop_semantic_options` and :func:`in_loop_tracker_options` give
  the loop's (the env's ``semantic_options`` and ``tracker_options``);
- :func:`window_size`: the seed paper's Eq. (5);
- :class:`PosePrior`: a rough guess of the relative pose, for maps of look-alike places.
"""

from mrexplore.merge.api import METHODS, merge_maps
from mrexplore.merge.common import MergeEvidence, MergeResult, WeighedPose
from mrexplore.merge.fusion import in_loop_semantic_options, in_loop_tracker_options
from mrexplore.merge.paper import window_size
from mrexplore.merge.semantic import PosePrior, SemanticOptions
from mrexplore.merge.tracker import MapMergeTracker, MergeWork, TrackerOptions

__all__ = [
    "METHODS",
    "MapMergeTracker",
    "MergeEvidence",
    "MergeResult",
    "MergeWork",
    "PosePrior",
    "SemanticOptions",
    "TrackerOptions",
    "WeighedPose",
    "in_loop_semantic_options",
    "in_loop_tracker_options",
    "merge_maps",
    "window_size",
]
