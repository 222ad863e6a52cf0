#!/usr/bin/env bash
# Regenerate the two tables of the README that correspond to the seed paper's results:
#   1. the merge table (method x detector, symmetric worlds and real maps; the paper's Table 1/2)
#   2. the single- vs multi-robot task-time table (the paper's 105 s -> 65 s and 125 s -> 85 s)
# Outputs go to results/. Takes about 15-30 minutes on 2 cores.
set -euo pipefail
cd "$(dirname "$0")/.."
mkdir -p results
mrexplore bench merge --out results/merge_table --force  # regenerates: replaces the old files
mrexplore task-time --world symmetric_office --seeds 20 --policy coordinated-frontier --out results/ --force
