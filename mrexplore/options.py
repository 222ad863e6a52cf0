"""One way to declare options: frozen dataclasses whose fields carry their own check.

    @dataclass(frozen=True)
    class Knobs(Options):
        owner = "Knobs"
        steps: int = option(10, integer(1))
        rate: float = option(0.5, number(0.0, 1.0))

Each knob has one default and one check, side by side; :class:`Options` turns numpy scalars
into Python ones, runs every check when an instance is made (a bad value is a
:class:`~mrexplore.errors.ConfigError` that names the owner, the option and the valid range),
then :meth:`Options.check_together` for rules that tie options together.
:meth:`Options.from_kwargs` refuses unknown names. The checks are plain callables
``(name, value) -> None``, so a knob that several objects expose shares one.

>>> from dataclasses import dataclass
>>> @dataclass(frozen=True)
... class Knobs(Options):
...     owner = "Knobs"
...     steps: int = option(10, integer(1))
>>> Knobs(steps=0)
Traceback (most recent call last):
...
mrexplore.errors.ConfigError: Knobs: option steps must be an integer >= 1, got 0
"""

from __future__ import annotations

import dataclasses
import math
import types
import typing
from collections.abc import Callable
from typing import Any, ClassVar, TypeVar

import numpy as np

from mrexplore.errors import ConfigError

#: A check: raises ``ValueError`` with what was expected (the message's tail) when ``value`` is
#: bad; :class:`Options` turns it into a ``ConfigError`` naming the owner and the option. A check
#: may return a normalised value (e.g. a lower-cased name), which then replaces the given one.
Check = Callable[[Any], Any]
_O = TypeVar("_O", bound="Options")


def is_number(v: Any) -> bool:
    """A finite int or float (not a bool)."""
    return isinstance(v, (int, float)) and not isinstance(v, bool) and math.isfinite(v)


def _is_int(v: Any) -> bool:
    return isinstance(v, int) and not isinstance(v, bool)


def positive(v: Any) -> None:
    """A finite number > 0."""
    if not (is_number(v) and v > 0):
        raise ValueError("a positive number")


def non_negative(v: Any) -> None:
    """A finite number >= 0."""
    if not (is_number(v) and v >= 0):
        raise ValueError("a non-negative number")


def integer(lo: int, hi: int | None = None) -> Check:
    """An int in ``[lo, hi]`` (no upper bound when ``hi`` is None); bools are refused."""

    def check(v: Any) -> None:
        if not (_is_int(v) and v >= lo and (hi is None or v <= hi)):
            raise ValueError(f"an integer >= {lo}" if hi is None else f"an integer in [{lo}, {hi}]")

    return check


def number(lo: float, hi: float, low_open: bool = False, hint: str = "") -> Check:
    """A finite number in ``[lo, hi]`` (``(lo, hi]`` with ``low_open``); ``hint`` (what the
    number means, its unit) is added to the message."""

    def check(v: Any) -> None:
        ok = is_number(v) and (v > lo if low_open else v >= lo) and v <= hi
        if not ok:
            raise ValueError(f"in {'(' if low_open else '['}{lo:g}, {hi:g}]{hint}")

    return check


def one_of(*choices: Any, hint: str = "") -> Check:
    """One of ``choices`` (``hint`` is added to the message, e.g. what each is for)."""

    def check(v: Any) -> None:
        if v not in choices:
            listed = " or ".join(repr(c) for c in choices)
            raise ValueError(f"{listed}{hint}")

    return check


def boolean(v: Any) -> None:
    """True or False (``"no"`` must not pass as True)."""
    if not isinstance(v, bool):
        raise ValueError("True or False")


def optional(check: Check) -> Check:
    """``check``, or None."""

    def opt(v: Any) -> None:
        if v is None:
            return
        try:
            check(v)
        except ValueError as exc:
            raise ValueError(f"{exc} or None") from None

    return opt


def anything(v: Any) -> None:
    """No check here (the value is checked where it is used, e.g. a world name or a merger)."""


# --- knobs that several objects expose (env, wrapper, fusion stage, tracker): one default and
# one check each --------------------------------------------------------------------------
#: Steps between merge attempts of an unmerged pair.
MERGE_EVERY_DEFAULT = 10
MERGE_EVERY_CHECK = integer(1)
#: Steps between re-checks of an accepted transform (0: never).
RECHECK_EVERY_DEFAULT = 100
RECHECK_EVERY_CHECK = integer(0)
#: Steps between the start of a merge attempt and its effect (0: in the step). The env runs
#: attempts off the step path (8); the tracker, the fusion stage and the wrapper default to 0
#: (one-shot users get the answer in the call).
MERGE_LATENCY_CHECK = integer(0, 10_000)


def option(default: Any, check: Check, *, factory: Callable[[], Any] | None = None) -> Any:
    """A dataclass field with ``default`` (or a ``factory`` for mutable defaults) and ``check``."""
    if factory is not None:
        return dataclasses.field(default_factory=factory, metadata={"check": check})
    return dataclasses.field(default=default, metadata={"check": check})


def validate(
    owner: str,
    name: str,
    value: Any,
    check: Check,
    kind: str = "option",
    error: type[Exception] = ConfigError,
) -> Any:
    """Run ``check`` on ``value`` (a numpy scalar as its Python value); a failure is an
    ``error`` (``ConfigError``) naming ``owner`` and ``name``. Returns the check's normalised
    value, or None when it returned none."""
    try:
        return check(value.item() if isinstance(value, np.generic) else value)
    except ValueError as exc:
        prefix = f"{owner}: {kind}" if owner else kind
        raise error(f"{prefix} {name} must be {exc}, got {value!r}") from None


def integer_argument(owner: str, name: str, value: Any, lo: int, hi: int | None = None) -> int:
    """``value`` (an int or a numpy integer) as an int in ``[lo, hi]``; a ``ConfigError`` naming
    ``owner`` and the argument otherwise (the commands' numeric arguments).

    >>> integer_argument("train", "seed", 3, 0)
    3
    >>> integer_argument("train", "seed", -1, 0)
    Traceback (most recent call last):
    ...
    mrexplore.errors.ConfigError: train: argument seed must be an integer >= 0, got -1
    """
    validate(owner, name, value, integer(lo, hi), kind="argument")
    return int(value)


_FLOAT_FIELDS: dict[type, frozenset[str]] = {}


def _float_fields(cls: type) -> frozenset[str]:
    """The fields of the options dataclass ``cls`` typed ``float`` or ``float | None`` (kept
    per class: the type hints are resolved once)."""
    if cls in _FLOAT_FIELDS:
        return _FLOAT_FIELDS[cls]
    hints = typing.get_type_hints(cls)
    out = set()
    for f in dataclasses.fields(cls):
        t = hints.get(f.name)
        if t is float or (
            typing.get_origin(t) in (typing.Union, types.UnionType) and float in typing.get_args(t)
        ):
            out.add(f.name)
    _FLOAT_FIELDS[cls] = frozenset(out)
    return _FLOAT_FIELDS[cls]


class Options:
    """Base of the option dataclasses (declare them ``@dataclass(frozen=True)``)."""

    #: Who the options belong to, as error messages name it ("" for the env's own options).
    owner: ClassVar[str] = ""
    #: What error messages call one of them, and the error raised.
    kind: ClassVar[str] = "option"
    error: ClassVar[type[Exception]] = ConfigError

    def __post_init__(self) -> None:
        floats = _float_fields(type(self))
        for f in dataclasses.fields(self):  # type: ignore[arg-type]
            v = getattr(self, f.name)
            if isinstance(v, np.bool_):
                object.__setattr__(self, f.name, bool(v))
            elif isinstance(v, np.integer):
                object.__setattr__(self, f.name, int(v))
            elif isinstance(v, np.floating):
                object.__setattr__(self, f.name, float(v))
            check = f.metadata.get("check")
            if check is not None:
                normalised = validate(
                    self.owner, f.name, getattr(self, f.name), check, self.kind, self.error
                )
                if normalised is not None:
                    object.__setattr__(self, f.name, normalised)
            v = getattr(self, f.name)
            if f.name in floats and type(v) is int:
                object.__setattr__(self, f.name, float(v))  # 1 means 1.0 where a float is due
        self.check_together()

    def check_together(self) -> None:
        """Rules that tie several options together (override; raise ``ConfigError``)."""

    @classmethod
    def from_kwargs(cls: type[_O], **kwargs: Any) -> _O:
        """An instance from keyword arguments; an unknown keyword is a :class:`ConfigError`."""
        names = {f.name for f in dataclasses.fields(cls)}  # type: ignore[arg-type]
        unknown = sorted(set(kwargs) - names)
        if unknown:
            who = f"{cls.owner}: " if cls.owner else ""
            raise cls.error(
                f"{who}unknown {cls.kind}(s) {', '.join(unknown)}; known {cls.kind}s: "
                f"{', '.join(sorted(names))}"
            )
        return cls(**kwargs)

    def to_dict(self) -> dict[str, Any]:
        """The options as a plain dict."""
        return {f.name: getattr(self, f.name) for f in dataclasses.fields(self)}  # type: ignore[arg-type]
