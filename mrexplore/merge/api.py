"""``merge_maps``: one entry point for every merge method, with validated inputs and options."""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

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


def merge_maps(a: Int8Grid, b: Int8Grid, method: str = "semantic", **options: Any) -> MergeResult:
    """Merge occupancy map ``b`` into map ``a``'s frame.

    Args:
        a, b: int8 (H, W) maps, -1 unknown / 0 free / 100 occupied; any sizes, each in its own
            frame, same resolution (the caller checks; for files see
            :mod:`mrexplore.experiments.merge_files`).
        method: ``"semantic"`` (default; verified, any rotation, refuses ambiguous cases),
            ``"paper"`` (Durdu & Korkmaz 2019, translation only) or ``"orb"`` (m-explore baseline).
        **options: method options (see :func:`~mrexplore.merge.semantic.merge_semantic`,
            :func:`~mrexplore.merge.paper.merge_paper`, :func:`~mrexplore.merge.orb.merge_orb`),
            including ``detector=`` where the method uses one. Unknown names raise.

    Returns:
        :class:`MergeResult`; ``transform`` maps b's cells ``(col, row, 1)`` into a's cells.

    Raises:
        GridError: a or b is not a 2-D, non-empty integer map with values in -1..100 (floats,
            NaN, 3-D arrays, ...).
        ConfigError: unknown method, unknown option, bad option value, unavailable detector.

    All-unknown or featureless maps are not errors: they give ``matched=False`` with a reason.

    >>> import numpy as np
    >>> m = np.full((40, 40), -1, dtype=np.int8)
    >>> merge_maps(m, m).reason
    'map a is all unknown'
    """
    if not isinstance(method, str) or method.lower() not in METHODS:
        raise ConfigError(f"merge_maps: unknown method {method!r}; choose one of {tuple(METHODS)}")
    a = validate_grid(a, "map a")
    b = validate_grid(b, "map b")
    return METHODS[method.lower()](a, b, **options)
