"""A disk cache of merge-bench cases, so that runs of the same code share what they simulate.

Most of a merge bench's time goes into making its cases, not merging them: one seed's 30
``lidar`` cases simulate a team exploring (~35 s of CPU), its 30 ``symmetric`` cases ~18 s,
against ~2.5 s to merge either (2026-11-27, one core). ``scripts/reproduce_paper.sh`` asks for
the cases of seeds 0-9 and 12 in five files; with ``mrexplore bench merge --case-cache DIR`` the
first run saves them and the others read them back.

A case depends only on its family, count, seed and options, and on what made it: the key holds
all of them, the rest as a digest of every source file of the package, of the shipped worlds
(``envs/``) and the real maps the crops come from, and of the versions of the libraries that
shape a map (numpy, OpenCV, numba). Change a line of ``mrexplore`` or a pixel of a map and the
cache misses. Entries are written whole or not at all (a temporary file
renamed into place), so a run stopped midway leaves no half-written case behind.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
import tempfile
from collections.abc import Callable, Mapping
from functools import lru_cache
from importlib import metadata
from pathlib import Path
from typing import Any

from mrexplore.errors import ConfigError
from mrexplore.experiments.merge_cases import MergeCase

#: Distributions whose versions are part of a case's key (they decide the maps' bits).
KEYED_DISTRIBUTIONS: tuple[str, ...] = ("numpy", "opencv-python-headless", "numba")
_PACKAGE = Path(__file__).resolve().parents[1]


def _inputs() -> list[tuple[str, Path]]:
    """(label, root) of every tree of files a case is made from: the package's sources, the
    shipped worlds (``envs/``) and the real maps the crops come from."""
    from mrexplore.experiments.merge_cases import SHARED_MAPS
    from mrexplore.world.registry import _envs_dir

    return [("code", _PACKAGE), ("envs", _envs_dir()), ("maps", SHARED_MAPS)]


@lru_cache(maxsize=1)
def code_digest() -> str:
    """SHA-256 (hex) of every ``.py`` file of the package, every file of the shipped worlds and
    of the real maps (by relative path), and of the versions of :data:`KEYED_DISTRIBUTIONS`:
    what must be equal for a saved case to be reused."""
    h = hashlib.sha256()
    for label, root in _inputs():
        files = root.rglob("*.py") if label == "code" else root.rglob("*")
        for f in sorted(f for f in files if f.is_file() and "__pycache__" not in f.parts):
            h.update(f"{label}/{f.relative_to(root)}".encode())
            h.update(f.read_bytes())
    for dist in KEYED_DISTRIBUTIONS:
        try:
            version = metadata.version(dist)
        except metadata.PackageNotFoundError:
            version = "absent"
        h.update(f"{dist}=={version}".encode())
    return h.hexdigest()


def case_key(family: str, n: int, seed: int, options: Mapping[str, Any] | None) -> str:
    """The file stem of one (family, n, seed, options) set of cases under this code."""
    what = json.dumps([family, n, seed, dict(options or {})], sort_keys=True, default=repr)
    return hashlib.sha256(f"{code_digest()}|{what}".encode()).hexdigest()[:32]


def check_cache_dir(path: str | Path) -> Path:
    """``--case-cache``'s directory, made if missing; a :class:`ConfigError` naming the problem
    when it is a file or cannot be written."""
    d = Path(path)
    if d.exists() and not d.is_dir():
        raise ConfigError(f"--case-cache {str(d)!r} is a file, not a directory")
    try:
        d.mkdir(parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"--case-cache {str(d)!r} cannot be made: {exc}") from exc
    if not os.access(d, os.W_OK):
        raise ConfigError(f"--case-cache {str(d)!r} is not writable")
    return d


def cached_cases(
    cache_dir: Path,
    family: str,
    n: int,
    seed: int,
    options: Mapping[str, Any] | None,
    make: Callable[[], list[MergeCase]],
) -> list[MergeCase]:
    """The cases saved under ``cache_dir`` for this key, or ``make()``'s, saved there first.

    The cache holds only what this function wrote (pickles of :class:`MergeCase` lists):
    point it at a directory of your own, not at files from elsewhere.
    """
    f = cache_dir / f"{case_key(family, n, seed, options)}.pkl"
    if f.exists():
        with f.open("rb") as fh:
            cases: list[MergeCase] = pickle.load(fh)
        return cases
    cases = make()
    fd, tmp = tempfile.mkstemp(dir=cache_dir, suffix=".tmp")
    try:
        with os.fdopen(fd, "wb") as fh:
            pickle.dump(cases, fh, protocol=pickle.HIGHEST_PROTOCOL)
        os.replace(tmp, f)
    except BaseException:
        Path(tmp).unlink(missing_ok=True)
        raise
    return cases
