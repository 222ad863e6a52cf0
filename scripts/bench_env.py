"""Environment steps per second (2 robots, merging on, random actions), with a breakdown.

Same as ``mrexplore bench env``; see :mod:`mrexplore.experiments.env_bench`.
"""

from mrexplore.experiments.env_bench import main

if __name__ == "__main__":
    raise SystemExit(main())
