"""Moved to :mod:`mrexplore.merge.fusion`; this alias keeps old imports working."""

from mrexplore.merge.fusion import FusionStage

__all__ = ["FusionStage"]
