"""Worlds: the ground-truth floor (:class:`World`), map_server file I/O, generators, the registry.

>>> import numpy as np
>>> from mrexplore.world import load_world
>>> w = load_world("random:symmetric_office?width_m=10&height_m=8", rng=np.random.default_rng(0))
>>> w.shape
(160, 200)
>>> len(w.meta["twin_rooms"])
2
>>> load_world("family:paper_like/test/7").name
'paper_like/test/0007'
"""

from __future__ import annotations

from mrexplore.world.family import (
    FAMILIES,
    FAMILY_GENERATORS,
    PARTS,
    family_seeds,
    family_spec,
    family_world,
    office_row,
    paper_like,
    radial,
)
from mrexplore.world.generators import GENERATORS, symmetric_office, twin_wings
from mrexplore.world.map_io import (
    OccupancyFile,
    read_map_yaml,
    world_from_file,
    world_to_file,
    write_map_yaml,
)
from mrexplore.world.registry import list_worlds, load_world
from mrexplore.world.world import World

__all__ = [
    "FAMILIES",
    "FAMILY_GENERATORS",
    "GENERATORS",
    "PARTS",
    "OccupancyFile",
    "World",
    "family_seeds",
    "family_spec",
    "family_world",
    "list_worlds",
    "load_world",
    "office_row",
    "paper_like",
    "radial",
    "read_map_yaml",
    "symmetric_office",
    "twin_wings",
    "world_from_file",
    "world_to_file",
    "write_map_yaml",
]
