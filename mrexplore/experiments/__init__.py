"""The commands users run: ``mrexplore demo | merge | task-time | train | evaluate | imitate``
(:mod:`~mrexplore.experiments.demo`, :mod:`~mrexplore.experiments.merge_files`,
:mod:`~mrexplore.experiments.task_time`, :mod:`~mrexplore.experiments.train`,
:mod:`~mrexplore.experiments.evaluate`, :mod:`~mrexplore.experiments.imitate`) and the episode
runner they share (:mod:`~mrexplore.experiments.episode`). The studies and benchmarks
(``mrexplore bench ...``) are :mod:`mrexplore.studies`.
"""
