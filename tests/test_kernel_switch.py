"""The kernel switch: the package runs with the compiled kernels off, and without numba."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest

# A short merging rollout; prints what must not depend on the path taken.
ROLLOUT = """
import json, sys
if sys.argv[1] == "blocked":
    sys.modules["numba"] = None  # import numba now fails, as on a machine without it
import numpy as np
import mrexplore
from mrexplore import kernels
penv = mrexplore.parallel_env(world="small_office", merge_every=5, merge_latency_steps=0)
obs, infos = penv.reset(seed=3)
rng = np.random.default_rng(3)
for _ in range(40):
    obs, _, _, _, infos = penv.step({a: int(rng.integers(4)) for a in penv.agents})
print(json.dumps({"enabled": kernels.enabled(), "have": kernels.HAVE_NUMBA,
                  "coverage": infos["robot_0"]["coverage"],
                  "shape": list(obs["robot_0"].shape)}))
"""


def _run(mode: str, env: dict[str, str]) -> dict[str, object]:
    out = subprocess.run(
        [sys.executable, "-c", ROLLOUT, mode],
        env={**os.environ, **env},
        capture_output=True,
        text=True,
        check=True,
        timeout=600,
    )
    return dict(json.loads(out.stdout.strip().splitlines()[-1]))


@pytest.mark.expensive
def test_the_env_runs_with_the_kernels_off_and_without_numba() -> None:
    on = _run("normal", {"MREXPLORE_NUMBA": "1"})
    off = _run("normal", {"MREXPLORE_NUMBA": "0"})
    blocked = _run("blocked", {})
    assert on["enabled"] and not off["enabled"] and off["have"]
    assert not blocked["enabled"] and not blocked["have"]
    for other in (off, blocked):
        assert other["shape"] == on["shape"]
        # The numpy paths compute the same figures up to float32 rounding of beam positions
        # near grid lines, so the robots' rollouts agree closely, not bit for bit.
        assert abs(float(other["coverage"]) - float(on["coverage"])) < 0.02
