"""Does the merger answer the same on every CPU? Loop-study merge attempts replayed with the
wide SIMD paths of OpenCV, numpy and OpenBLAS switched off.

    python studies/cpu_independence.py [--worlds depot tb3_office] [--seeds 20] [--first-seed 1000]

Runs the loop study's semantic episodes (:func:`mrexplore.studies.loop_study.run_loop_episode`,
two robots, random headings, noise on) and keeps every merge attempt's two maps; then replays
all of them in two child processes, one as the machine is and one with SSE-level code
(:data:`NARROW_CPU`), and prints per world how many attempts answered differently: in outcome
(matched or not, and the reason with its figures) and in any bit of the transform or score.
The replay, not the episodes, is compared: an episode diverges after its first differing
attempt, which would hide every later one. Nothing is written but a temporary file.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import pickle
import subprocess
import sys
import tempfile
from collections import Counter
from pathlib import Path
from typing import Any

#: SSE-level code in OpenCV, numpy and OpenBLAS (names as each library spells them).
NARROW_CPU = {
    "OPENCV_CPU_DISABLE": "AVX512-SKX,AVX2,FMA3,AVX,FP16",
    "NPY_DISABLE_CPU_FEATURES": "AVX512_ICL AVX512_SPR X86_V4 X86_V3",
    "OPENBLAS_CORETYPE": "Nehalem",
}

# Run in the child: replay every attempt, print (outcome, bits) fingerprints as JSON.
REPLAY = """
import hashlib, json, pickle, sys
import cv2
cv2.setNumThreads(1)
from mrexplore.merge import merge_maps
out = []
for world, a, b, opts in pickle.load(open(sys.argv[1], "rb")):
    r = merge_maps(a, b, method="semantic", **opts)
    t = None if r.transform is None else r.transform.tobytes().hex()
    bits = hashlib.sha1(repr((t, r.score)).encode()).hexdigest()
    out.append([world, repr((r.matched, r.reason)), bits])
print(json.dumps(out))
"""


def capture(worlds: list[str], seeds: list[int]) -> list[tuple[str, Any, Any, dict[str, Any]]]:
    """Every merge attempt ``(world, a, b, options)`` of the episodes, in order."""
    from mrexplore.merge import tracker
    from mrexplore.studies.loop_study import run_loop_episode

    attempts: list[tuple[str, Any, Any, dict[str, Any]]] = []
    merge = tracker.NamedMerger.__call__
    world = ""

    def recording(self: tracker.NamedMerger, a: Any, b: Any) -> Any:
        attempts.append((world, a.copy(), b.copy(), dict(self.options)))
        return merge(self, a, b)

    tracker.NamedMerger.__call__ = recording  # type: ignore[method-assign]
    try:
        for world in worlds:
            for seed in seeds:
                run_loop_episode(world, "semantic", seed, 600.0)
    finally:
        tracker.NamedMerger.__call__ = merge  # type: ignore[method-assign]
    return attempts


def replay(path: str, extra_env: dict[str, str]) -> list[list[str]]:
    """The fingerprints of the attempts in ``path``, replayed in a child process."""
    res = subprocess.run(
        [sys.executable, "-c", REPLAY, path],
        env={**os.environ, **extra_env},
        capture_output=True,
        text=True,
        check=False,
    )
    if res.returncode != 0:
        raise SystemExit(f"replay failed:\n{res.stderr[-2000:]}")
    return list(json.loads(res.stdout.strip().splitlines()[-1]))


def main(argv: list[str] | None = None) -> int:
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument(
        "--worlds", nargs="+", default=["symmetric_office", "twin_wings", "tb3_office", "depot"]
    )
    p.add_argument("--seeds", type=int, default=20)
    p.add_argument("--first-seed", type=int, default=1000)
    args = p.parse_args(argv)
    from mrexplore.errors import MrexploreError
    from mrexplore.studies.loop_study import validate

    try:  # every option checked before any work, with the loop study's own rules
        validate(list(args.worlds), args.seeds, args.first_seed, ["semantic"], 600.0, 1)
    except MrexploreError as exc:
        p.error(str(exc))
    seeds = list(range(args.first_seed, args.first_seed + args.seeds))
    attempts = capture(list(args.worlds), seeds)
    with tempfile.TemporaryDirectory() as tmp:
        path = str(Path(tmp) / "attempts.pkl")
        with open(path, "wb") as f:
            pickle.dump(attempts, f)
        wide, narrow = replay(path, {}), replay(path, NARROW_CPU)
    total: Counter[str] = Counter()
    outcome: Counter[str] = Counter()
    bits: Counter[str] = Counter()
    for (world, o1, b1), (_, o2, b2) in zip(wide, narrow, strict=True):
        total[world] += 1
        outcome[world] += o1 != o2
        bits[world] += o1 != o2 or b1 != b2
    print(f"{len(seeds)} seeds per world; narrow = {NARROW_CPU}")
    print(f"{'world':<18} {'attempts':>9} {'differ in outcome':>18} {'differ in any bit':>18}")
    for world in args.worlds:
        print(f"{world:<18} {total[world]:>9} {outcome[world]:>18} {bits[world]:>18}")
    digest = hashlib.sha1(json.dumps(wide).encode()).hexdigest()[:12]
    print(
        f"all {sum(total.values())} attempts: {sum(outcome.values())} differ in outcome, "
        f"{sum(bits.values())} in any bit (answers digest {digest})"
    )
    return 0


if __name__ == "__main__":
    sys.exit(main())
