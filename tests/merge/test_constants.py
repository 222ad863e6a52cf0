from __future__ import annotations

import pytest

from mrexplore.errors import ConfigError
from mrexplore.merge import semantic, tracker
from mrexplore.merge.constants import is_constant, rule_constants, split_constants


def test_options_and_constants_are_told_apart_by_case() -> None:
    proper, constants = split_constants(
        {"drop_below": 0.9, "OUTRANKED_DROP": False, "MIN_EVIDENCE_CELLS": 30}
    )
    assert proper == {"drop_below": 0.9}
    assert constants == {"OUTRANKED_DROP": False, "MIN_EVIDENCE_CELLS": 30}
    assert is_constant("FAR_CELLS") and is_constant("RELOCATE_TOL_CELLS")
    assert not is_constant("drop_below") and not is_constant("DEMOTED_OPTIONS")


@pytest.mark.parametrize(
    ("constants", "message"),
    [
        ({"NO_SUCH_RULE": 1}, "NO_SUCH_RULE"),
        ({"OUTRANKED_DROP": 1}, "switch"),
        ({"FAR_CELLS": "far"}, "number"),
        ({"FAR_CELLS": True}, "number"),
    ],
)
def test_a_bad_constant_is_named(constants: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        split_constants(constants)


def test_constants_are_set_for_the_block_and_restored_after_it_also_on_an_error() -> None:
    before = (tracker.OUTRANKED_DROP, semantic.FAR_CELLS)
    with rule_constants({"OUTRANKED_DROP": False, "FAR_CELLS": 7}):
        assert tracker.OUTRANKED_DROP is False and semantic.FAR_CELLS == 7.0
        assert isinstance(semantic.FAR_CELLS, float)  # the constant's own type
    assert before == (tracker.OUTRANKED_DROP, semantic.FAR_CELLS)
    with pytest.raises(RuntimeError), rule_constants({"FAR_CELLS": 9}):
        raise RuntimeError("boom")
    assert before[1] == semantic.FAR_CELLS
