"""The studies and benchmarks: what ``mrexplore bench merge|loop|env|sensor|policies|wrappers``
and the scripts in ``studies/`` run on, apart from the commands users run
(:mod:`mrexplore.experiments`).

- :mod:`~mrexplore.studies.merge_cases`: seeded map pairs with the true transform known (symmetric
  worlds, real maps, noisy, lidar-made, large, aliased);
- :mod:`~mrexplore.studies.merge_bench`: the merge table (method x detector), its outcome classes
  and ablations (``mrexplore bench merge``);
- :mod:`~mrexplore.studies.case_cache`: merge cases saved on disk, read back by runs of the same
  code;
- :mod:`~mrexplore.studies.loop_study` and :mod:`~mrexplore.studies.loop_report`: merging in the
  exploration loop against an oracle merger, and its figures and tables (``mrexplore bench loop``);
- :mod:`~mrexplore.studies.oracle`: mergers that know the truth, references for the loop study;
- :mod:`~mrexplore.studies.provenance`: the digest of the code, worlds and maps behind a result;
- :mod:`~mrexplore.studies.policy_bench` and :mod:`~mrexplore.studies.wrapper_bench`: planner
  and policy cost per step, wrapper throughput (``mrexplore bench policies|wrappers``);
- :mod:`~mrexplore.studies.env_bench` and :mod:`~mrexplore.studies.sensor_bench`: env steps per
  second with a per-stage breakdown, and the lidar and simulator step
  (``mrexplore bench env|sensor``).

Nothing here is imported by the env, the merger, the policies or the wrappers.
"""
