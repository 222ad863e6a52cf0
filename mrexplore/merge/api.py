"""``merge_maps``: one entry point for every merge method, with validated inputs and options."""

from __future__ import annotations

import math
from collections.abc import Callable
from typing import Any

import numpy as np

from mrexplore.errors import ConfigError
from mrexplore.grid import Int8Grid, validate_grid
from mrexplore.merge.common import MergeResult
from mrexplore.merge.orb import merge_orb
from mrexplore.merge.paper import merge_paper
from mrexplore.merge.semantic import merge_semantic

#: method name -> implementation ``f(a, b, **options) -> MergeResult``.
METHODS: dict[str, Callable[..., MergeResult]] = {
    "semantic": merge_semantic,
    "paper": merge_paper,
    "orb": merge_orb,
}


#: Metres per cell assumed when ``merge_maps`` is not told (the worlds' and the paper's 0.05).
DEFAULT_RESOLUTION_M = 0.05


def merge_maps(
    a: Int8Grid,
    b: Int8Grid,
    method: str = "semantic",
    *,
    resolution_m: float | None = None,
    **options: Any,
) -> MergeResult:
    """Merge occupancy map ``b`` into map ``a``'s frame.

    Args:
        a, b: int8 (H, W) maps, -1 unknown / 0 free / 100 occupied; any sizes, each in its own
            frame, same resolution (the caller checks; for files see
            :mod:`mrexplore.experiments.merge_files`).
        method: ``"semantic"`` (default; verified, any rotation, refuses ambiguous cases),
            ``"paper"`` (Durdu & Korkmaz 2019, translation only) or ``"orb"`` (m-explore baseline).
        resolution_m: metres per cell of both maps. The semantic method measures its
            ``min_common_m2`` and ``min_wall_area_m2`` guards in square metres at this
            resolution, so pass the maps' own
            (``mrexplore merge`` takes it from the YAML). None assumes
            :data:`DEFAULT_RESOLUTION_M` (0.05); the result says which was used
            (``info["resolution_m"]``, and ``info["resolution_assumed"]`` is True when assumed).
        **options: method options (see :func:`~mrexplore.merge.semantic.merge_semantic`,
            :func:`~mrexplore.merge.paper.merge_paper`, :func:`~mrexplore.merge.orb.merge_orb`),
            including ``detector=`` where the method uses one. Unknown names raise.

    Returns:
        :class:`MergeResult`; ``transform`` maps b's cells ``(col, row, 1)`` into a's cells;
        ``info["resolution_m"]`` the resolution used.

    Raises:
        GridError: a or b is not a 2-D, non-empty integer map with values in -1..100 (floats,
            NaN, 3-D arrays, ...).
        ConfigError: unknown method, unknown option, bad option value (``resolution_m`` not a
            positive finite number), unavailable detector.

    All-unknown or featureless maps are not errors: they give ``matched=False`` with a reason.

    >>> import numpy as np
    >>> m = np.full((40, 40), -1, dtype=np.int8)
    >>> merge_maps(m, m).reason
    'map a is all unknown'
    """
    if not isinstance(method, str) or method.lower() not in METHODS:
        raise ConfigError(f"merge_maps: unknown method {method!r}; choose one of {tuple(METHODS)}")
    assumed = resolution_m is None
    res_m = DEFAULT_RESOLUTION_M if resolution_m is None else resolution_m
    if (
        isinstance(res_m, (bool, np.bool_))
        or not isinstance(res_m, (int, float, np.integer, np.floating))
        or not math.isfinite(float(res_m))
        or float(res_m) <= 0.0
    ):
        raise ConfigError(
            f"merge_maps: resolution_m={resolution_m!r} must be a positive number of metres/cell"
        )
    a = validate_grid(a, "map a")
    b = validate_grid(b, "map b")
    if method.lower() == "semantic":
        options["resolution_m"] = float(res_m)
    result = METHODS[method.lower()](a, b, **options)
    result.info["resolution_m"] = float(res_m)
    result.info["resolution_assumed"] = assumed
    return result
