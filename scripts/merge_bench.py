"""Merge benchmark (mrexplore/experiments/merge_bench.py): python scripts/merge_bench.py --help"""

from __future__ import annotations

import sys

from mrexplore.experiments.merge_bench import main

if __name__ == "__main__":
    sys.exit(main())
