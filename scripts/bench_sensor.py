"""Lidar cast, own-map update and simulator step timings.

Same as ``mrexplore bench sensor``; see :mod:`mrexplore.experiments.sensor_bench`.
"""

from mrexplore.experiments.sensor_bench import main

if __name__ == "__main__":
    raise SystemExit(main())
