"""The radio: where robots hear their merged teammates, bit for bit as ``apply_transform``."""

from __future__ import annotations

import numpy as np

from mrexplore.environment.radio import Radio
from mrexplore.grid import apply_transform, make_transform


def test_heard_positions_are_the_transformed_pose_cells_bit_for_bit() -> None:
    rng = np.random.default_rng(3)
    agents = ["robot_0", "robot_1", "robot_2"]
    radio = Radio(agents, comm_range_m=None)
    for _ in range(200):
        poses = {k: (*rng.uniform(-500.0, 1500.0, 2), 0.0) for k in range(3)}
        T = make_transform(float(rng.uniform(-np.pi, np.pi)), *rng.uniform(-300.0, 300.0, 2))
        radio.hear({"robot_0": {"robot_2": T}}, poses.__getitem__)
        got = radio.heard("robot_0", ["robot_2"])["robot_2"]
        want = apply_transform(T, np.array([poses[2][:2]]))[0]
        assert got == (float(want[0]), float(want[1]))
        assert all(type(v) is float for v in got)
