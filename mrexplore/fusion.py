"""Moved to :mod:`mrexplore.merge.fusion`; this alias keeps old imports working."""

from mrexplore.merge.fusion import IN_LOOP_MIN_COMMON_M2, FusionStage

__all__ = ["IN_LOOP_MIN_COMMON_M2", "FusionStage"]
