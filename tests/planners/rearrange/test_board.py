"""The board model: rigid pushes with chains, refused where the target, the board's edge or a
long chain stands in the way; the region to clear and the boxes that crowd it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from drake_clutter.common.config import Config
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.rearrange.board import (
    Board,
    crowding,
    moved_boxes,
    reach_region,
    world_poses,
)
from drake_clutter.scene.scenes import validate_scene
from drake_clutter.testing.handmade import make_box


def _row(crowded, count: int):
    """The crowded scene with ``count`` 4 cm boxes in a row along -x, 6 cm apart, 15 cm
    beside the target."""
    t = crowded.target_box
    boxes = [make_box(f"b{i}", (0.04, 0.04, 0.08), (t.pose[0] - 0.06 * i, t.pose[1] - 0.15))
             for i in range(count)]
    return validate_scene(replace(crowded, boxes=(t, *boxes)))


def test_a_push_moves_its_box_alone_where_nothing_is_in_the_way(crowded):
    board = Board(_row(crowded, 3), chain=3)
    after = board.push({}, "b0", np.array([0.0, -0.05]))
    assert moved_boxes({}, after) == ["b0"]
    np.testing.assert_allclose(after["b0"], [0.0, -0.05])


def test_a_push_shoves_the_boxes_it_meets_ahead_as_a_chain(crowded):
    board = Board(_row(crowded, 3), chain=3)
    after = board.push({}, "b0", np.array([-0.05, 0.0]))  # b0 into b1 (2 cm apart), b1 into b2
    assert set(moved_boxes({}, after)) == {"b0", "b1", "b2"}
    assert after["b1"][0] < -0.029 and after["b2"][0] < -0.009  # 3 cm and 1 cm shoved
    for a, b in (("b0", "b1"), ("b1", "b2")):
        gap = (board.moved(a, after[a]).pose[0] - board.moved(b, after[b]).pose[0])
        assert gap >= 0.04 - 1e-3  # parted, not overlapping


def test_a_push_is_refused_past_its_chain_the_target_or_the_board(crowded):
    row = _row(crowded, 3)
    assert Board(row, chain=2).push({}, "b0", np.array([-0.05, 0.0])) is None
    assert Board(row, chain=3).push({}, "b0", np.array([0.0, 0.14])) is None  # onto the target
    assert Board(row, chain=3).push({}, "b0", np.array([0.0, -2.0])) is None  # off the board


def test_the_region_is_the_reach_with_the_gripper_open_at_its_last_knots(reach_q):
    region = reach_region(reach_q, 3)
    assert region.shape == (3, 8)
    np.testing.assert_array_equal(region[:, :7], reach_q[-3:, :7])
    assert np.all(region[:, 7] == reach_q[-1, 7])
    assert len(reach_region(reach_q)) == len(reach_q)


def test_the_side_box_crowds_the_grasp_until_it_is_moved_away(crowded, reach_q):
    geometry = PlanningContext(crowded, Config()).arm()
    region = reach_region(reach_q, 1)
    crowd = crowding(geometry, region, {}, 0.005)
    assert set(crowd) == {"side"} and crowd["side"] > 0.02
    away = {"side": np.array([0.0, 0.15])}
    assert crowding(geometry, region, away, 0.005) == {}
    moved = world_poses(geometry, away)["side"].translation()
    rest = geometry.rest_pose("side").translation()
    np.testing.assert_allclose(moved - rest, [0.0, 0.15, 0.0], atol=1e-12)
