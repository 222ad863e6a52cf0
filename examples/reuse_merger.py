"""Reuse the map merger: on two maps of your own, and as a wrapper on a PettingZoo env.

``merge_maps`` fuses two int8 occupancy grids (-1 unknown, 0 free, 100 occupied) in unrelated
frames, or says why it refuses (look-alike places are refused, never guessed);
``MapMergeWrapper`` does it every step on any ParallelEnv with the map protocol
(docs/guide/merger.md).

    python examples/reuse_merger.py
"""

from pathlib import Path

import numpy as np

import mrexplore
from mrexplore.merge import merge_maps
from mrexplore.policies import make_team_policy
from mrexplore.world import read_map_yaml
from mrexplore.wrappers import MapMergeWrapper

# 1. Two overlapping crops of a real office map, the second turned by 90 degrees.
office = read_map_yaml(Path(__file__).resolve().parents[1] / "envs" / "tb3_office.yaml")
a = np.ascontiguousarray(office.grid[60:280, 60:300])
b = np.ascontiguousarray(np.rot90(office.grid[100:300, 120:330]))
res = merge_maps(a, b, resolution_m=office.resolution_m)
T = res.transform  # b's cells -> a's cells (3x3), None when refused (res.reason says why)
print("crops: merged", res.matched, T.round().astype(int).tolist() if T is not None else res.reason)

# 2. The wrapper on a PettingZoo env (ours, its own merging off), driven by a frontier team.
env = MapMergeWrapper(mrexplore.parallel_env(world="small_office", merger=None), merger="semantic")
obs, infos = env.reset(seed=5)
team = make_team_policy("coordinated-frontier", env.possible_agents)
team.reset(np.random.default_rng(0))
while env.agents and not infos["robot_0"]["merged"]:
    views = {a: env.unwrapped.robot_view(a) for a in env.agents}
    obs, rewards, terms, truncs, infos = env.step(team.act(views))
t_01 = np.round(infos["robot_0"]["transform"]["robot_1"], 1) + 0.0  # robot_1 -> robot_0 cells
print("wrapper: merged", infos["robot_0"]["merged"], t_01.tolist())
print("fused map of robot_0:", env.fused_map("robot_0").shape, "obs:", obs["robot_0"].shape)
