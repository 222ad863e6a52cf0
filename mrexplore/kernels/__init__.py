"""All numba kernels of the package, and the one switch that turns them on or off.

=================  ===========================================================================
``sensing``        lidar cast + coverage marking, own-map update, motion (the simulator)
``views``          occupancy shares per view block and the trail channel (the observation)
``scoring``        map accuracy against the truth (evaluation only)
``merging``        the merger's verifier count, wall ICP, coarse pooling and places
``planning``       the frontier planners: frontiers, planning grid, distances, paths, follower
=================  ===========================================================================

The switch: :data:`USE_NUMBA` (read at call time) chooses the compiled kernels or the
vectorised numpy paths of :mod:`mrexplore.sensors`, :mod:`mrexplore.mapping`,
:mod:`mrexplore.robot`, the observation builder, :mod:`mrexplore.truth` and the planners of
:mod:`mrexplore.policies`, which compute the same figures (the tests hold the kernels to them
and to the one-ray reference :func:`mrexplore.sensors.cast_ray_reference`). The environment
variable ``MREXPLORE_NUMBA=0`` turns the kernels off at import, and the package then runs
without numba installed (the merger's verifier keeps its numpy path too); CI runs a rollout
that way. Each kernel is
``cache=True`` (compiled once per machine into ``__pycache__``) and ``nogil``.
"""

from __future__ import annotations

import importlib
import importlib.util
import os
from types import ModuleType
from typing import Any

import numpy as np


def _numba_installed() -> bool:
    try:
        return importlib.util.find_spec("numba") is not None
    except (ImportError, ValueError):  # blocked (sys.modules["numba"] = None) or broken
        return False


#: numba can be imported here.
HAVE_NUMBA: bool = _numba_installed()
#: Use the compiled kernels (read at call time; ``MREXPLORE_NUMBA=0`` sets it False at import).
USE_NUMBA: bool = HAVE_NUMBA and os.environ.get("MREXPLORE_NUMBA", "1") != "0"


def load(name: str) -> ModuleType | None:
    """The kernel module ``name`` (``"sensing"``, ``"views"``, ``"scoring"``, ``"merging"``,
    ``"planning"``), or None when numba is not installed (callers then take their numpy path)."""
    if not HAVE_NUMBA:
        return None
    return importlib.import_module(f"mrexplore.kernels.{name}")


def enabled() -> bool:
    """Whether the compiled kernels are in use now (:data:`USE_NUMBA` and numba present)."""
    return USE_NUMBA and HAVE_NUMBA


def warm_up() -> None:
    """Compile (or load from the cache) the simulator's, the views' and the scorer's kernels on
    tiny inputs (the merger's compile on first use)."""
    from mrexplore.kernels import scoring, sensing, views

    table = np.zeros(3 * 4 * 4, dtype=np.bool_)
    table[:16] = True
    table[5] = table[6] = table[9] = table[10] = False
    one = np.ones(1)
    zero = np.zeros(1)
    # one robot at (1, 1) of a 2 x 2 grid, one beam; its outputs; the map update's constants
    corner = np.array([[1.0, 1.0]])
    cast_in: tuple[Any, ...] = (table, 4, 4, corner, one, zero, one, zero, 1.0, 1.0, 1.0)
    noise = np.zeros((0, 0))
    ranges, hit = np.zeros((1, 1), dtype=np.float32), np.zeros((1, 1), dtype=np.bool_)
    marks: tuple[Any, ...] = (np.zeros((1, 4), dtype=np.bool_), np.zeros(4, dtype=np.bool_))
    team, newly = np.zeros(4, dtype=np.bool_), np.zeros(1, dtype=np.int64)
    consts: tuple[Any, ...] = (
        24.0,
        np.array([-1.0, 1.0, -5.0, 5.0], dtype=np.float32),
        np.array([-1.0, 0.6], dtype=np.float32),
        np.array([0, 100, 26, 64], dtype=np.int64),
    )
    stack: tuple[Any, ...] = (  # one 5 x 5 map: logodds, int8, stamp
        np.zeros((1, 25), dtype=np.float32),
        np.full((1, 25), -1, dtype=np.int8),
        np.zeros((1, 25), dtype=np.uint16),
    )
    none = np.array([[0, -1, 0, -1]], dtype=np.int64)
    boxes: tuple[Any, ...] = (none, none.copy())  # known and changed boxes
    cells = np.zeros((1, 9), dtype=np.int64)
    # whole argument lists as tuples: each kernel's arguments in its order
    cast: tuple[Any, ...] = (*cast_in, noise, ranges, hit, True, *marks, team, newly)
    update: tuple[Any, ...] = (
        *(a[0] for a in stack), 1, 5, 5, 2.5, 2.5, one, zero, one, hit[0], *consts,
        *(b[0] for b in boxes), cells[0],
    )  # fmt: skip
    world: tuple[Any, ...] = (
        *cast_in, noise, ranges, hit, *marks, team, newly, *stack, np.ones(1, dtype=np.int64),
        5, 5, np.array([[2.5, 2.5]]), np.ones((1, 1)), np.zeros((1, 1)), *consts, *boxes, cells,
    )  # fmt: skip
    sensing.cast_observe(*cast)
    sensing.map_update(*update)
    sensing.sense_world(*world)
    views.view_shares(
        np.zeros((4, 4), dtype=np.int8),
        0,
        0,
        1,
        2,
        np.arange(5, dtype=np.uint8),
        np.zeros(256, dtype=np.int32),
        np.array([0, 25, 65], dtype=np.int8),
        np.zeros(2, dtype=np.int32),
        np.zeros((2, 2), dtype=np.uint8),
        np.zeros((2, 2), dtype=np.uint8),
        np.array([0, 4, 0, 4], dtype=np.int64),
    )
    views.trail_dots(np.zeros((2, 2), dtype=np.uint8), np.zeros((1, 2)), 0.0, 0.0, 1.0)
    views.turned_trail_dots(
        np.zeros((2, 2), dtype=np.uint8), np.zeros((1, 2)), 0.0, 0.0, 1.0, 1.0, 0.0
    )
    no = np.zeros((1, 1), dtype=np.bool_)
    scoring.claim_counts(np.zeros((1, 1), dtype=np.int8), no, no, no, 25, 65, True)
    scoring.score_region(
        np.zeros(1, dtype=np.int8),
        np.zeros((1, 1), dtype=np.int32),
        np.zeros((1, 1), dtype=np.uint8),
        no,
        no,
        no,
        0,
        1,
        0,
        1,
        25,
        65,
        np.zeros(3, dtype=np.int64),
    )
    sensing.motion_forward(
        np.zeros((3, 3), dtype=np.bool_),
        zero,
        zero,
        one,
        zero,
        np.array([0.0, 0.5]),
        0.0,
        0.0,
        1.0,
        1e-9,
        np.zeros(1),
        np.zeros(1),
    )
