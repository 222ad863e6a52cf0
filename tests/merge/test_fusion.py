"""FusionStage: fused_version changes exactly when a fused map may have changed; hypotheses."""

from __future__ import annotations

import numpy as np
import pytest
from conftest import look_alike_canvases

from mrexplore.errors import ConfigError
from mrexplore.grid import invert_transform
from mrexplore.merge import SemanticOptions
from mrexplore.merge.fusion import (
    FusionStage,
    in_loop_semantic_options,
    in_loop_tracker_options,
)


def _maps() -> dict[str, np.ndarray]:
    m = np.full((40, 40), -1, dtype=np.int8)
    m[10:20, 10:20] = 0
    return {"a": m.copy(), "b": m.copy()}


def test_version_follows_map_changes_with_a_merger() -> None:
    stage = FusionStage(["a", "b"], merger="semantic")
    maps = _maps()
    stage.update(maps, step=1)
    v = stage.fused_version("a")
    stage.update({k: m.copy() for k, m in maps.items()}, step=2)  # same content, new arrays
    assert stage.fused_version("a") == v
    maps["a"][25, 25] = 100
    stage.update(maps, step=3)
    assert stage.fused_version("a") != v
    seen = {stage.fused_version("a"), stage.fused_version("b")}
    stage.reset()
    stage.update(_maps(), step=0)
    assert not {stage.fused_version("a"), stage.fused_version("b")} & seen  # never repeats


def test_version_changes_at_every_update_without_a_merger() -> None:
    stage = FusionStage(["a", "b"], merger=None)
    stage.update(_maps(), step=0)
    v = stage.fused_version("a")
    stage.update(_maps(), step=1)
    assert stage.fused_version("a") != v


def test_the_loop_asks_for_other_places_not_areas_and_no_perfect_rival_test_unless_told() -> None:
    """In the loop the semantic merger runs the place test instead of the area floors, without
    the perfect-rival test (docs/merging.md); options the caller gives win."""
    stage = FusionStage(["robot_0", "robot_1"], merger="semantic", resolution_m=0.05)
    opts = stage.tracker._merge.options
    assert opts["place_test"] is True and opts["rival_perfect_cells"] == 0
    assert opts["min_common_m2"] == 0.0 and opts["room_match_m2"] == 0.0
    told = FusionStage(
        ["robot_0", "robot_1"], merger="semantic", merge_options={"rival_perfect_cells": 250}
    )
    assert told.tracker._merge.options["rival_perfect_cells"] == 250


def test_typed_options_at_the_loops_defaults_are_the_untyped_defaults() -> None:
    """``in_loop_semantic_options()`` and ``in_loop_tracker_options()`` are what the stage uses
    when given nothing: the same merger options and the same tracker options."""
    plain = FusionStage(["a", "b"], merger="semantic", merge_every=5, resolution_m=0.1)
    typed = FusionStage(
        ["a", "b"],
        merger="semantic",
        merge_every=5,
        resolution_m=0.1,
        semantic_options=in_loop_semantic_options(),
        tracker_options=in_loop_tracker_options(),
    )
    assert (
        typed.tracker._merge.options
        == SemanticOptions.from_kwargs(**plain.tracker._merge.options).to_dict()
    )
    assert typed.tracker.options == plain.tracker.options
    assert typed.tracker.options.merge_every == 5  # the stage's schedule
    assert typed.tracker._merge.options["resolution_m"] == 0.1  # and the maps' resolution


def test_a_typed_option_changes_one_setting_and_keeps_the_loops_others() -> None:
    stage = FusionStage(
        ["a", "b"],
        merger="semantic",
        semantic_options=in_loop_semantic_options(min_margin=0.2),
        tracker_options=in_loop_tracker_options(drop_below=0.9),
    )
    opts = stage.tracker._merge.options
    assert opts["min_margin"] == 0.2 and opts["place_test"] is True
    assert stage.tracker.options.drop_below == 0.9
    # in the loop the place test is the look-alike guard: no floor sized on our worlds
    assert stage.tracker.options.min_accept_cells == 0
    assert opts["min_common_m2"] == opts["room_match_m2"] == 0.0
    assert opts["min_wall_area_m2"] == opts["min_object_m2"] == 0.0


@pytest.mark.parametrize(
    ("kwargs", "says"),
    [
        ({"merger": "orb", "semantic_options": in_loop_semantic_options()}, "merger is 'orb'"),
        ({"semantic_options": {"min_margin": 0.1}}, "must be a SemanticOptions"),
        ({"tracker_options": {"drop_below": 0.9}}, "must be a TrackerOptions"),
        (
            {"merge_options": {"min_margin": 0.1}, "semantic_options": in_loop_semantic_options()},
            "semantic_options only",
        ),
        (
            {"merge_options": {"drop_below": 0.9}, "tracker_options": in_loop_tracker_options()},
            "tracker_options only",
        ),
        (
            {"merge_every": 4, "tracker_options": in_loop_tracker_options(merge_every=6)},
            "set merge_every on the env",
        ),
        (
            {"resolution_m": 0.1, "semantic_options": in_loop_semantic_options(resolution_m=0.2)},
            "set resolution_m on the env",
        ),
    ],
)
def test_typed_options_given_twice_or_for_another_merger_are_refused(
    kwargs: dict, says: str
) -> None:
    kwargs = {"merger": "semantic", **kwargs}
    with pytest.raises(ConfigError, match=says):
        FusionStage(["a", "b"], **kwargs)


def test_hypotheses_give_each_robot_the_candidates_and_the_teammates_map() -> None:
    """Two identical rooms, robot_1 knows the left one: refused as ambiguous, each robot gets
    the tracker's candidates for the other's map (in its own cells) and that map, read-only."""
    canvas_a, canvas_b, _ = look_alike_canvases()
    stage = FusionStage(["robot_0", "robot_1"], merger="semantic", resolution_m=0.05)
    assert stage.hypotheses("robot_0") == {}
    stage.update({"robot_0": canvas_a, "robot_1": canvas_b}, step=0)
    assert not stage.merged("robot_0")
    cands, mate = stage.hypotheses("robot_0")["robot_1"]
    assert len(cands) >= 2 and all(T.shape == (3, 3) for T in cands)
    np.testing.assert_array_equal(mate, canvas_b)
    assert not mate.flags.writeable
    back, mate0 = stage.hypotheses("robot_1")["robot_0"]
    np.testing.assert_array_equal(mate0, canvas_a)
    np.testing.assert_allclose(back[0], invert_transform(cands[0]), atol=1e-9)
    assert FusionStage(["robot_0", "robot_1"], merger=None).hypotheses("robot_0") == {}
