"""Settings for the whole test run."""

from __future__ import annotations

import os
from collections.abc import Iterator

import pytest


@pytest.fixture(autouse=True, scope="session")
def _sb3_logs_in_the_test_run(tmp_path_factory: pytest.TempPathFactory) -> Iterator[None]:
    """stable-baselines3 models made without a logger folder log into ``$SB3_LOGDIR`` (else a
    new ``SB3-<time>`` folder in the system's temp directory): keep them in this run's."""
    old = os.environ.get("SB3_LOGDIR")
    os.environ["SB3_LOGDIR"] = str(tmp_path_factory.mktemp("sb3_logs"))
    yield
    if old is None:
        os.environ.pop("SB3_LOGDIR", None)
    else:
        os.environ["SB3_LOGDIR"] = old
