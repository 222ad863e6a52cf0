"""What one robot knows at one step: :class:`~mrexplore.types.RobotView`, the documented
accessor for policies (it moved to the :mod:`mrexplore.types` leaf; this name is kept).

A view holds only what the robot can know: its own map (or the fused map once a merge has been
accepted), its own pose estimate and path in its own frame, and - only after a merge - its
teammates' positions and the *estimated* transforms to their frames. Never the ground truth.
Get one with ``env.unwrapped.robot_view(agent)`` after ``reset``/``step``.
"""

from mrexplore.types import RobotView

__all__ = ["RobotView"]
