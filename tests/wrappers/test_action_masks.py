"""VecActionMasks: per-slot masks for MaskablePPO from the goal-level env's observations."""

from __future__ import annotations

import numpy as np
import pytest

from mrexplore.errors import ConfigError
from mrexplore.wrappers.action_masks import VecActionMasks
from mrexplore.wrappers.sb3_vec import make_vec_env

OPTS = {"world": "small_office", "n_robots": 2, "max_time_s": 20.0, "action_mode": "goal"}


def test_masks_per_slot_follow_the_observations() -> None:
    from sb3_contrib.common.maskable.utils import get_action_masks, is_masking_supported

    venv = VecActionMasks(make_vec_env(n_copies=2, seed=0, **OPTS))
    obs = venv.reset()
    assert is_masking_supported(venv)
    masks = get_action_masks(venv)
    assert masks.shape == (4, 8) and masks.dtype == bool
    assert np.array_equal(masks, obs["action_mask"].astype(bool))
    assert [m.tolist() for m in venv.env_method("action_masks", indices=[3])] == [masks[3].tolist()]
    for _ in range(3):
        acts = np.array([int(np.flatnonzero(m)[0]) for m in masks])
        obs, _, _, _ = venv.step(acts)
        masks = get_action_masks(venv)
        assert np.array_equal(masks, obs["action_mask"].astype(bool))
    venv.close()


def test_needs_dict_observations_with_masks() -> None:
    venv = make_vec_env(n_copies=1, seed=0, world="small_office", n_robots=2, max_cycles=3)
    with pytest.raises(ConfigError, match="action_mask"):
        VecActionMasks(venv)
    venv.close()
