"""Assertions and loaders shared by several test modules."""

from __future__ import annotations

import importlib.util
from pathlib import Path
from types import ModuleType
from typing import Any

import numpy as np

#: The repository's ``scripts/`` folder (maintenance: results index, worlds, lock file).
SCRIPTS = Path(__file__).resolve().parents[1] / "scripts"
#: The repository's ``studies/`` folder (one script per study, documented in its README).
STUDIES = Path(__file__).resolve().parents[1] / "studies"


def load_script(name: str, folder: Path = SCRIPTS) -> ModuleType:
    """``scripts/<name>.py`` (or ``<folder>/<name>.py``) imported as a module (neither folder is
    a package)."""
    spec = importlib.util.spec_from_file_location(name, folder / f"{name}.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def load_study(name: str) -> ModuleType:
    """``studies/<name>.py`` imported as a module."""
    return load_script(name, STUDIES)


def assert_same(x: Any, y: Any, where: str) -> None:
    """Assert that two nested results (dicts, arrays, object arrays of arrays, scalars) are
    equal bit for bit, with the same dtypes and types; ``where`` names the place in messages."""
    if isinstance(x, dict):
        assert isinstance(y, dict) and x.keys() == y.keys(), (where, x.keys(), y.keys())
        for k in x:
            assert_same(x[k], y[k], f"{where}.{k}")
    elif isinstance(x, np.ndarray) or isinstance(y, np.ndarray):
        x, y = np.asarray(x), np.asarray(y)
        assert x.dtype == y.dtype or x.dtype == object or y.dtype == object, (where, x, y)
        if x.dtype == object or y.dtype == object:
            assert x.shape == y.shape, where
            for i, (a, b) in enumerate(zip(x.reshape(-1), y.reshape(-1), strict=True)):
                assert_same(a, b, f"{where}[{i}]")
        else:
            np.testing.assert_array_equal(x, y, err_msg=where)
    else:
        assert x == y and type(x) is type(y), (where, x, y)
