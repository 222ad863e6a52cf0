"""The commands users run: ``mrexplore demo | merge | task-time | train | evaluate | imitate``
(:mod:`~mrexplore.experiments.demo`, :mod:`~mrexplore.experiments.merge_files`,
:mod:`~mrexplore.experiments.task_time`, :mod:`~mrexplore.experiments.train`,
:mod:`~mrexplore.experiments.evaluate`, :mod:`~mrexplore.experiments.imitate`) and the episode
runner they share (:mod:`~mrexplore.experiments.episode`). The loop study
(``mrexplore bench loop``) and the env and sensor benches are here too for now; the machinery of
the other studies is :mod:`mrexplore.studies`.
"""
