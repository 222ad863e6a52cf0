"""The env's ``infos[agent]``: the same flat keys on every reset and step.

Each value is a bool, an int or a float, ``UNKNOWN_INFO`` (-1.0) where unknown: never NaN
(Gymnasium's and PettingZoo's checkers compare infos with ``==``), None or a nested dict, so
TorchRL and Gymnasium's vector envs turn them into one array per key. The table with units is in
``docs/clients.md``.
"""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

#: The keys of ``infos[agent]``, on every reset and step, in this order (plus ``"extra"`` with
#: ``info_extra=True``).
INFO_KEYS = (
    "coverage",
    "task_time_s",
    "step",
    "merged",
    "score",
    "first_merge_time_s",
    "merge_error_cells",
    "merge_error_deg",
    "merge_error_drift_cells",
    "collisions",
    "collided",
    "fused_contradiction",
    "merged_wrongly_s",
    "goal_given",
    "goal_reached",
    "TimeLimit.truncated",
)

#: The value of a float info that is not known (yet): never merged, no map claim. Every such
#: value is >= 0 when known.
UNKNOWN_INFO = -1.0


def known_or_unknown(value: float | None) -> float:
    """``value`` as a float, ``UNKNOWN_INFO`` for None, NaN or a negative (unknown) value.

    >>> known_or_unknown(None), known_or_unknown(0.25), known_or_unknown(float("nan"))
    (-1.0, 0.25, -1.0)
    """
    return float(value) if value is not None and value >= 0 else UNKNOWN_INFO


def merge_error_infos(err: Mapping[str, float] | None) -> dict[str, float]:
    """The three flat merge-error keys of a merge error dict (None: not merged).

    >>> merge_error_infos(None)["merge_error_cells"]
    -1.0
    """
    if err is None:
        return dict.fromkeys(INFO_KEYS[6:9], UNKNOWN_INFO)
    return {
        "merge_error_cells": err["translation_cells"],
        "merge_error_deg": err["rotation_deg"],
        "merge_error_drift_cells": err["drift_cells"],
    }


def merge_error_of(info: Mapping[str, Any]) -> dict[str, float] | None:
    """The merge error dict (``translation_cells``, ``rotation_deg``, ``drift_cells``) of one
    agent's flat infos, or None when it holds no transform (the flat keys are -1).

    >>> merge_error_of({"merge_error_cells": 0.5, "merge_error_deg": 0.2,
    ...                 "merge_error_drift_cells": 0.0})
    {'translation_cells': 0.5, 'rotation_deg': 0.2, 'drift_cells': 0.0}
    >>> merge_error_of({"merge_error_cells": -1.0, "merge_error_deg": -1.0,
    ...                 "merge_error_drift_cells": -1.0}) is None
    True
    """
    cells = float(info["merge_error_cells"])
    if cells < 0:
        return None
    return {
        "translation_cells": cells,
        "rotation_deg": float(info["merge_error_deg"]),
        "drift_cells": float(info["merge_error_drift_cells"]),
    }
