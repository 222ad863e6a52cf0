"""Find a world by name, path or generator spec: the one entry point the environment calls.

Shipped worlds are ``name.yaml`` + image in the top-level ``envs/`` folder of a checkout, which a
wheel installs as the package ``mrexplore.envs``; :func:`importlib.resources.files` resolves both
(the editable install maps ``mrexplore.envs`` to ``envs/``).
"""

from __future__ import annotations

import importlib.resources
from pathlib import Path
from typing import Any
from urllib.parse import parse_qsl

import numpy as np
import yaml

from mrexplore.errors import WorldError
from mrexplore.world.family import FAMILY_GENERATORS, FAMILY_PREFIX, family_world, parse_family_spec
from mrexplore.world.generators import GENERATORS
from mrexplore.world.map_io import world_from_file
from mrexplore.world.world import World

__all__ = ["list_worlds", "load_world"]

_RANDOM_PREFIX = "random:"
#: What ``random:<name>`` draws from: the floor generators and the world families (the
#: families live in their own module, which builds on the generators' rooms, so they are
#: joined here rather than in :data:`GENERATORS`).
RANDOM_GENERATORS = {**GENERATORS, **FAMILY_GENERATORS}


def envs_dir() -> Path:
    """The folder of shipped worlds (checkout ``envs/`` or installed ``mrexplore.envs``)."""
    try:
        root = importlib.resources.files("mrexplore.envs")
    except ModuleNotFoundError as exc:  # pragma: no cover - a broken install
        raise WorldError("the shipped worlds package 'mrexplore.envs' is not installed") from exc
    # Shipped worlds are plain files (never zipped: setuptools installs package data as files).
    return Path(str(root))


def list_worlds() -> list[str]:
    """Names of the shipped worlds, sorted (each is ``envs/<name>.yaml``)."""
    return sorted(p.stem for p in envs_dir().glob("*.yaml"))


def _parse_value(text: str) -> Any:
    """A query value as YAML scalar: ``10`` -> int, ``2.5`` -> float, ``false`` -> bool."""
    try:
        return yaml.safe_load(text) if text else text
    except yaml.YAMLError:
        return text


def _random_world(spec: str, rng: np.random.Generator | None) -> World:
    body = spec[len(_RANDOM_PREFIX) :]
    gen_name, _, query = body.partition("?")
    if gen_name not in RANDOM_GENERATORS:
        raise WorldError(
            f"unknown generator '{gen_name}' in '{spec}'; available: {sorted(RANDOM_GENERATORS)}"
        )
    if rng is None:
        raise WorldError(f"world spec '{spec}' needs a numpy Generator (rng) to draw a fresh world")
    options: dict[str, Any] = {}
    for key, value in parse_qsl(query, keep_blank_values=True, strict_parsing=False):
        if key in options:
            raise WorldError(f"option '{key}' given twice in '{spec}'")
        options[key] = _parse_value(value)
    if query and not options:
        raise WorldError(f"cannot parse the options '{query}' in '{spec}' (expected key=value&...)")
    try:
        return RANDOM_GENERATORS[gen_name](rng, **options)
    except TypeError as exc:  # e.g. a non-numeric width handed to a keyword parameter
        raise WorldError(f"bad options in '{spec}': {exc}") from exc


def load_world(spec: World | str | Path, rng: np.random.Generator | None = None) -> World:
    """Resolve ``spec`` into a :class:`World`.

    Args:
        spec: a :class:`World` (returned as is); a shipped name (``"symmetric_office"``, see
            :func:`list_worlds`); a path (str or Path) to a map_server YAML; or
            ``"random:<generator>"`` / ``"random:<generator>?width_m=10&height_m=8"`` for a fresh
            world from a generator of :data:`RANDOM_GENERATORS` with those options; or
            ``"family:<family>/<part>/<index>"`` (``"family:paper_like/test/7"``) for world
            ``index`` of a family's tune or test part, drawn from its world seed alone
            (:mod:`mrexplore.world.family`).
        rng: the Generator that draws ``random:`` worlds (required for them, unused otherwise).

    Raises:
        WorldError: unknown name (the message lists the shipped ones), unknown generator, a
            ``random:`` spec without ``rng``, bad generator options, or a ``family:`` spec with
            an unknown family or part or a bad index.
        MapFileNotFoundError, MapFileError: a path spec that does not load.
    """
    if isinstance(spec, World):
        return spec
    if isinstance(spec, Path):
        return world_from_file(spec)
    if not isinstance(spec, str):
        raise WorldError(f"world spec must be a World, a name or a path, got {type(spec).__name__}")
    if spec.startswith(_RANDOM_PREFIX):
        return _random_world(spec, rng)
    if spec.startswith(FAMILY_PREFIX):
        return family_world(*parse_family_spec(spec))
    if spec.lower().endswith((".yaml", ".yml")) or "/" in spec or "\\" in spec:
        return world_from_file(spec)
    shipped = envs_dir() / f"{spec}.yaml"
    if shipped.is_file():
        return world_from_file(shipped, name=spec)
    raise WorldError(
        f"unknown world '{spec}'; shipped worlds: {list_worlds()}; or a path to a map YAML, "
        f"or 'random:<generator>' with generators {sorted(RANDOM_GENERATORS)}, or "
        f"'family:<family>/<part>/<index>' with families {sorted(FAMILY_GENERATORS)}"
    )
