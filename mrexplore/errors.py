"""The project's exceptions: one clear type per kind of bad input.

Every error derives from :class:`MrexploreError` and from the builtin a caller would expect
(``ValueError`` for malformed values, ``FileNotFoundError`` for missing files), so
``except ValueError`` keeps working for users who do not know our types.
"""

from __future__ import annotations


class MrexploreError(Exception):
    """Base class of every error raised on purpose by mrexplore."""


class GridError(MrexploreError, ValueError):
    """An occupancy grid array is malformed (wrong dtype, shape, NaN, values out of range)."""


class WorldError(MrexploreError, ValueError):
    """A world is unusable: no free cell, bad resolution, unknown name, bad generator option."""


class MapFileError(MrexploreError, ValueError):
    """A map_server YAML/PGM pair is malformed (missing key, unreadable image, bad value)."""


class MapFileNotFoundError(MrexploreError, FileNotFoundError):
    """A map_server YAML or the image it names does not exist."""


class ConfigError(MrexploreError, ValueError):
    """An option is unknown or has a bad value (a typo in a keyword argument, a negative range)."""


class OutputExistsError(MrexploreError, FileExistsError):
    """An output would overwrite an input or an existing result (pass ``--force`` to allow)."""
