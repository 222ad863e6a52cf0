"""Measure a second robot's gain: exploration task time of 1 vs 2 robots on one world.

The Python face of ``mrexplore task-time`` (docs/guide/worlds.md): the single-robot and the
two-robot episode start robot_0 at the same place; each gives an *observed* time (the team's
sensors saw the target share) and a *held* time (some robot holds it at the true place, so a
wrong merge costs time), and the wrong-merge columns say whether a team held a wrong merge.
Give your own map as ``world="my.yaml"`` (check it first: ``mrexplore world check my.yaml``).

    python examples/measure_team_gain.py
"""

import tempfile

from mrexplore.experiments.task_time import run_task_time

with tempfile.TemporaryDirectory() as out:
    doc = run_task_time(
        world="small_office",  # 10 x 8 m, two identical rooms
        seeds=1,
        first_seed=1000,
        tasks=["explore"],
        env_options={"max_time_s": 300.0},
        out=out,  # task_time.json, .csv and .png land here
        progress=False,
    )

explore = doc["tasks"]["explore"]
for team in ("single", "multi"):
    t = explore[team]
    print(
        f"{team:6s} robots={t['n_robots']} observed={t['task_times_s']} s "
        f"held={t['held_task_times_s']} s merged={t['merged_episodes']} "
        f"wrong_merge={t['wrong_merge']} merged_wrongly_s={t['merged_wrongly_s']}"
    )
print(f"reduction: observed {explore['reduction']}, held {explore['held_reduction']}")
