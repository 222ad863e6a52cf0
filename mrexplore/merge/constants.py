"""The merge rules' constants, set for one run: ablations of the in-loop merger.

The semantic merger's and the tracker's rule settings that are not options are upper-case
module constants (:data:`mrexplore.merge.semantic.DEMOTED_OPTIONS`,
:data:`mrexplore.merge.tracker.DEMOTED_TRACKER_OPTIONS`, and the tracker's rule switches). A
study that judges a rule sets them by name for its episodes, e.g. ``OUTRANKED_DROP=False``,
and puts them back afterwards (:func:`rule_constants`).

>>> from mrexplore.merge import tracker
>>> with rule_constants({"OUTRANKED_DROP": False}):
...     tracker.OUTRANKED_DROP
False
>>> tracker.OUTRANKED_DROP
True
"""

from __future__ import annotations

from collections.abc import Iterator, Mapping
from contextlib import contextmanager
from types import ModuleType
from typing import Any

from mrexplore.errors import ConfigError
from mrexplore.merge import semantic, tracker

__all__ = ["is_constant", "rule_constants", "split_constants"]


def _modules() -> tuple[ModuleType, ...]:
    return (semantic, tracker)


def _owner(name: str) -> ModuleType | None:
    for module in _modules():
        value = getattr(module, name, None)
        if name.isupper() and isinstance(value, (bool, int, float)):
            return module
    return None


def is_constant(name: str) -> bool:
    """Is ``name`` a rule constant (upper case, a number or a switch) of the merger or the
    tracker?"""
    return _owner(name) is not None


def split_constants(options: Mapping[str, Any]) -> tuple[dict[str, Any], dict[str, Any]]:
    """``options`` -> (the options proper, the upper-case rule constants); an upper-case name
    that is no rule constant is a :class:`~mrexplore.errors.ConfigError` naming it."""
    proper = {k: v for k, v in options.items() if not k.isupper()}
    constants = {k: v for k, v in options.items() if k.isupper()}
    bad = sorted(k for k in constants if not is_constant(k))
    if bad:
        raise ConfigError(
            f"{bad} are not rule constants of the merger or the tracker (upper-case names in "
            "mrexplore.merge.semantic and mrexplore.merge.tracker)"
        )
    for k, v in constants.items():
        kind = type(getattr(_owner(k), k))
        if kind is bool and not isinstance(v, bool):
            raise ConfigError(f"rule constant {k} is a switch (true or false), got {v!r}")
        if kind is not bool and (isinstance(v, bool) or not isinstance(v, (int, float))):
            raise ConfigError(f"rule constant {k} is a number, got {v!r}")
    return proper, constants


@contextmanager
def rule_constants(constants: Mapping[str, Any]) -> Iterator[None]:
    """Set the named rule constants (validated as :func:`split_constants` does) for the block
    and restore them after it, also on an error."""
    split_constants(constants)
    saved: list[tuple[ModuleType, str, Any]] = []
    try:
        for name, value in constants.items():
            module = _owner(name)
            assert module is not None
            saved.append((module, name, getattr(module, name)))
            kind = type(getattr(module, name))
            setattr(module, name, kind(value))
        yield
    finally:
        for module, name, value in reversed(saved):
            setattr(module, name, value)
