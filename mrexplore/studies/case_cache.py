"""A disk cache of merge-bench cases, so that runs of the same code share what they simulate.

Most of a merge bench's time goes into making its cases, not merging them: one seed's 30
``lidar`` cases simulate a team exploring (~35 s of CPU), its 30 ``symmetric`` cases ~18 s,
against ~2.5 s to merge either (2026-11-27, one core). ``scripts/reproduce_paper.sh`` asks for
the cases of seeds 0-9 and 12 in five files; with ``mrexplore bench merge --case-cache DIR`` the
first run saves them and the others read them back.

A case depends only on its family, count, seed and options, and on what made it: the key holds
all of them and :func:`~mrexplore.studies.provenance.source_digest` (the package's sources,
the shipped worlds, the real maps, the libraries' versions). Change a line of ``mrexplore`` or a
pixel of a map and the cache misses. Entries are written whole (:func:`mrexplore.io_safety.
write_bytes`: a temporary file renamed into place); one that cannot be read back (cut short by
a crash) counts as a miss and is written again. The cache loads
pickles, so it must be the user's own directory: one that others may write to is refused.
"""

from __future__ import annotations

import hashlib
import json
import os
import pickle
from collections.abc import Callable, Mapping
from pathlib import Path
from typing import Any

from mrexplore.errors import ConfigError
from mrexplore.io_safety import write_bytes
from mrexplore.studies.merge_cases import MergeCase
from mrexplore.studies.provenance import source_digest


def case_key(family: str, n: int, seed: int, options: Mapping[str, Any] | None) -> str:
    """The file stem of one (family, n, seed, options) set of cases under this code."""
    what = json.dumps([family, n, seed, dict(options or {})], sort_keys=True, default=repr)
    return hashlib.sha256(f"{source_digest()}|{what}".encode()).hexdigest()[:32]


def check_cache_dir(path: str | Path) -> Path:
    """``--case-cache``'s directory, made if missing (mode 0700); a :class:`ConfigError` naming
    the problem when it is a file, cannot be made or written, or is not the user's alone (the
    cache loads pickles: a file planted there by someone else would run as the user)."""
    d = Path(path)
    if d.exists() and not d.is_dir():
        raise ConfigError(f"--case-cache {str(d)!r} is a file, not a directory")
    try:
        d.mkdir(mode=0o700, parents=True, exist_ok=True)
    except OSError as exc:
        raise ConfigError(f"--case-cache {str(d)!r} cannot be made: {exc}") from exc
    st = d.stat()
    if st.st_uid != os.getuid() or st.st_mode & 0o022:
        raise ConfigError(
            f"--case-cache {str(d)!r} must be a directory of your own that no one else may write "
            "to (the cache loads pickles)"
        )
    if not os.access(d, os.R_OK | os.W_OK | os.X_OK):
        raise ConfigError(f"--case-cache {str(d)!r} is not readable and writable")
    return d


def cached_cases(
    cache_dir: Path,
    family: str,
    n: int,
    seed: int,
    options: Mapping[str, Any] | None,
    make: Callable[[], list[MergeCase]],
) -> list[MergeCase]:
    """The cases saved under ``cache_dir`` for this key, or ``make()``'s, saved there first
    (``cache_dir`` as :func:`check_cache_dir` returns it)."""
    f = cache_dir / f"{case_key(family, n, seed, options)}.pkl"
    if f.exists():
        try:
            with f.open("rb") as fh:
                cases: list[MergeCase] = pickle.load(fh)
            return cases
        except (OSError, EOFError, pickle.UnpicklingError, AttributeError, ImportError):
            pass  # damaged or from an incompatible version: a miss, rewritten below
    cases = make()
    write_bytes(f, pickle.dumps(cases, protocol=pickle.HIGHEST_PROTOCOL))
    return cases
