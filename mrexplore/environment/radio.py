"""The radio: who can exchange maps and positions now, and where teammates were last heard.

Links are physics (the true distance against ``comm_range_m``), not knowledge given to the
robots: a robot learns only what it hears. Once two robots' maps are merged, each hears the
other's own pose estimate, mapped through its *estimated* transform; out of range it keeps
where the teammate was when last heard.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

import numpy as np
from numpy.typing import NDArray


class Radio:
    """Links between ``agents`` (robot i = ``agents[i]``) and the positions heard over them.

    Args:
        agents: agent names in robot order.
        comm_range_m: link range in metres; None: every pair is always linked.
    """

    def __init__(self, agents: Sequence[str], comm_range_m: float | None = None) -> None:
        self.agents = list(agents)
        self.comm_range_m = comm_range_m
        self.index = {a: i for i, a in enumerate(self.agents)}
        #: (N, N) bool of this step, or None when everyone is linked.
        self.links: NDArray[np.bool_] | None = None
        self._heard: dict[tuple[str, str], tuple[float, float]] = {}

    def reset(self) -> None:
        """A new episode: nobody has heard anybody."""
        self.links = None
        self._heard = {}

    def update_links(self, true_xy: NDArray[np.float64]) -> NDArray[np.bool_] | None:
        """This step's links from the robots' true positions ``(N, 2)`` metres (None: all)."""
        if self.comm_range_m is None:
            self.links = None
        else:
            d = np.linalg.norm(true_xy[:, None, :] - true_xy[None, :, :], axis=-1)
            self.links = np.asarray(d <= self.comm_range_m)
        return self.links

    def linked(self, i: int, j: int) -> bool:
        """Whether robots i and j hear each other this step."""
        return self.links is None or bool(self.links[i, j] and self.links[j, i])

    def hear(
        self,
        transforms: Mapping[str, Mapping[str, NDArray[np.float64]]],
        pose_cell: Callable[[int], tuple[float, float, float]],
    ) -> None:
        """For every merged and linked pair, record where each robot hears the other: the
        teammate's own pose estimate ``pose_cell(j)`` (its map cells; asked only for heard
        teammates) through the estimated transform ``transforms[a][other]`` (the teammate's
        cells -> a's cells)."""
        for a, mates in transforms.items():
            i = self.index[a]
            for other, T in mates.items():
                j = self.index[other]
                if not self.linked(i, j):
                    continue
                c, r = (float(v) for v in pose_cell(j)[:2])
                (a0, a1, a2), (b0, b1, b2) = np.asarray(T, dtype=np.float64)[:2].tolist()
                # apply_transform's elementwise operations in its order, on Python floats
                # (numpy's per-call overhead on one point was most of the step's radio)
                self._heard[(a, other)] = (c * a0 + r * a1 + a2, c * b0 + r * b1 + b2)

    def heard(self, agent: str, others: Sequence[str]) -> dict[str, tuple[float, float]]:
        """Where ``agent`` last heard each of ``others`` (its own map cells); unheard ones are
        left out."""
        out = {}
        for other in others:
            pos = self._heard.get((agent, other))
            if pos is not None:
                out[other] = pos
        return out

    def in_range(self, agent: str) -> frozenset[str]:
        """The teammates ``agent`` can talk to now."""
        i = self.index[agent]
        return frozenset(o for j, o in enumerate(self.agents) if j != i and self.linked(i, j))
