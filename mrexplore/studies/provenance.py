"""What made a result: a digest of the code, worlds, maps and libraries behind it.

Two runs with the same digest and the same options give the same results, bit for bit (the
project's determinism); a result file that records its digest can therefore be reused in place
of a re-run (``mrexplore bench loop --reuse``, ``mrexplore bench merge --case-cache``) and is
refused when anything that shapes it changed.
"""

from __future__ import annotations

import hashlib
from functools import lru_cache
from pathlib import Path

_PACKAGE = Path(__file__).resolve().parents[1]


def _inputs() -> list[tuple[str, Path]]:
    """(label, root) of every tree of files a result is made from: the package's sources, the
    shipped worlds (``envs/``) and the real maps the merge bench crops."""
    from mrexplore.studies.merge_cases import SHARED_MAPS
    from mrexplore.world.registry import envs_dir

    return [("code", _PACKAGE), ("envs", envs_dir()), ("maps", SHARED_MAPS)]


@lru_cache(maxsize=1)
def source_digest() -> str:
    """SHA-256 (hex) of every ``.py`` file of the package, every file of the shipped worlds and of
    the real maps (by relative path), the versions of numpy, OpenCV and numba, and whether the
    compiled kernels are on (``MREXPLORE_NUMBA``: the numpy paths agree to a tolerance, not to
    the bit)."""
    import cv2
    import numba
    import numpy as np

    from mrexplore import kernels

    h = hashlib.sha256()
    for label, root in _inputs():
        files = root.rglob("*.py") if label == "code" else root.rglob("*")
        for f in sorted(f for f in files if f.is_file() and "__pycache__" not in f.parts):
            h.update(f"{label}/{f.relative_to(root)}".encode())
            h.update(f.read_bytes())
    h.update(f"numpy {np.__version__} cv2 {cv2.__version__} numba {numba.__version__}".encode())
    h.update(f"kernels {kernels.enabled()}".encode())
    return h.hexdigest()
