"""Push actions as joint paths and the beam search over them, on a box crowding the grasp:
the paths start and end at the reach's first knot inside the judge's limits and clear the
shelf; the search's goals leave the region clear, the same on every run, and a spent budget
finds nothing."""

from __future__ import annotations

import numpy as np
import pytest

from drake_clutter.common.config import Config, load_config
from drake_clutter.planners.budget import Deadline
from drake_clutter.planners.clearance import dense_check
from drake_clutter.planners.rearrange import search
from drake_clutter.planners.rearrange.actions import (
    CLOSED,
    Move,
    action_path,
    contact_points,
    push_tip_ratio,
)
from drake_clutter.planners.rearrange.board import (
    Board,
    crowding,
    entered,
    reach_region,
    world_poses,
)
from drake_clutter.planners.rearrange.search import RoomSearch, State, directions, search_room
from drake_clutter.planners.tool_path import approach_frame
from drake_clutter.scene.mechanics import tip_ratio
from drake_clutter.scene.shelf import SHELF_FRICTION
from drake_clutter.trajectory import Trajectory, plan_limit_violation


@pytest.fixture(scope="module")
def setting(context, reach_q):
    geometry = context.arm()
    frame = approach_frame(geometry, reach_q)
    rotation = geometry.tool_jacobian(reach_q[-1])[0].rotation().matrix()
    return geometry, frame, rotation, reach_region(reach_q, 1)


@pytest.fixture(scope="module")
def found(context, reach_q, setting):
    geometry, frame, rotation, region = setting
    return search_room(geometry, context.clearance, frame, region, reach_q[0], rotation,
                       Config(), Deadline(60.0))


def test_directions_never_point_back_at_the_robot(setting):
    frame = setting[1]
    us = directions(frame, 16, 0.1)
    assert 9 <= len(us) < 16
    assert all(u @ frame.d[:2] >= -0.1 - 1e-12 for u in us)
    assert np.allclose([np.linalg.norm(u) for u in us], 1.0)


def test_the_search_finds_pushes_that_clear_the_grasp(found, setting):
    geometry, _, _, region = setting
    assert found.goals, found.reasons
    for goal in found.goals:
        assert 1 <= len(goal.moves) <= Config().rearrange.max_moves
        assert len(goal.paths) == len(goal.moves)
        assert crowding(geometry, region, goal.offsets, Config().rearrange.deep) == {}
        assert goal.moves[0].box == "side"


def test_each_push_path_goes_from_the_first_knot_back_to_it(found, context, reach_q, setting):
    geometry, frame, _, _ = setting
    config = Config()
    for goal in found.goals:
        for path, move in zip(goal.paths, goal.moves, strict=True):
            np.testing.assert_allclose(path[0, :7], reach_q[0, :7])
            np.testing.assert_allclose(path[-1, :7], reach_q[0, :7])
            assert np.all(path[:, 7] == CLOSED)
            times = np.arange(len(path)) * config.baseline.knot_time
            assert plan_limit_violation(Trajectory(times, path), config.evaluation) == ""
            assert dense_check(context.clearance, path[:, :7], config.baseline).passed
            # G travels along the push direction at least the box's travel
            u = np.r_[move.u, 0.0]
            along = [geometry.tool_jacobian(q)[0].translation() @ u for q in path]
            assert max(along) - along[0] > move.travel


def test_the_search_repeats_itself(found, context, reach_q, setting):
    geometry, frame, rotation, region = setting
    again = search_room(geometry, context.clearance, frame, region, reach_q[0], rotation,
                        Config(), Deadline(60.0))
    assert [[m.to_data() for m in g.moves] for g in again.goals] == [
        [m.to_data() for m in g.moves] for g in found.goals]
    for a, b in zip(again.goals, found.goals, strict=True):
        for p, q in zip(a.paths, b.paths, strict=True):
            np.testing.assert_array_equal(p, q)


def test_a_spent_budget_finds_nothing_and_says_so(context, reach_q, setting):
    geometry, frame, rotation, region = setting
    deadline = Deadline(1e-9)
    result = search_room(geometry, context.clearance, frame, region, reach_q[0], rotation,
                         Config(), deadline)
    assert result.goals == [] and deadline.cut == ["search"]


def test_a_push_that_must_cross_the_target_is_refused_naming_it(context, reach_q, setting,
                                                                 crowded):
    geometry, frame, rotation, _ = setting
    board = Board(crowded, 3)
    u = frame.side[:2]  # the side box away from the target: the gripper would stand in it
    after = board.push({}, "side", 0.06 * u)
    blocked: list = []
    path, why = action_path(geometry, context.clearance, frame, reach_q[0], rotation, {},
                            after, Move("side", tuple(u), 0.06, ("side",)), Config(), blocked)
    assert path is None and "target" in why
    assert all(b.box != "target" for b in blocked)  # the target is never pushed out of the way


def test_a_push_is_tried_low_on_the_box_first_then_at_the_grasp_height(setting, crowded):
    geometry = setting[0]
    poses = world_poses(geometry, {})
    move = Move("side", (0.0, 1.0), 0.05, ("side",))
    side = next(b for b in crowded.boxes if b.name == "side")
    bottom = poses["side"].translation()[2] - side.size[2] / 2
    low = bottom + Config().rearrange.push_height * side.size[2]
    low_first = load_config(None, ["rearrange.push_low=true"])
    first, second = contact_points(geometry, poses, move, bottom + 0.1, low_first)
    assert first[2] == pytest.approx(low) and second[2] == pytest.approx(bottom + 0.1)
    np.testing.assert_allclose(first[:2], second[:2])
    # without push_low (the default) only the higher; never above the top less 1 cm
    (only,) = contact_points(geometry, poses, move, bottom + 0.1, Config())
    assert only[2] == pytest.approx(bottom + 0.1)
    (capped,) = contact_points(geometry, poses, move, bottom + 0.5, Config())
    assert capped[2] == pytest.approx(bottom + side.size[2] - 0.01)
    # a grasp height at or below the low point: one height
    assert len(contact_points(geometry, poses, move, low - 0.02, low_first)) == 1


def test_the_settings_are_checked_at_load():
    from drake_clutter.common.config import ConfigError

    with pytest.raises(ConfigError, match="rearrange.max_moves"):
        load_config(None, ["rearrange.max_moves=0"])
    with pytest.raises(ConfigError, match="rearrange.max_travel"):
        load_config(None, ["rearrange.step=0.05", "rearrange.max_travel=0.02"])


def test_a_state_ranks_fewer_crowding_boxes_first():
    a = State({}, travel=0.5, crowd={})
    b = State({}, travel=0.1, crowd={"x": 0.01})
    assert sorted([b, a], key=State.key) == [a, b]
    assert RoomSearch().to_data()["goals"] == []


def test_a_push_tips_by_mechanics_where_it_is_high_on_the_box(setting, crowded):
    """`push_tip_ratio` is the lone box's quasi-static rule at the first contact height (the
    box's length along the push, the judge's pair coefficients): low on the 6 cm box it
    slides, at its top it tips; a box shoved ahead, pressing back below the push, tips it
    sooner."""
    geometry = setting[0]
    poses = world_poses(geometry, {})
    side = next(b for b in crowded.boxes if b.name == "side")
    bottom = poses["side"].translation()[2] - side.size[2] / 2
    move = Move("side", (0.0, 1.0), 0.05, ("side",))
    mu = side.friction * SHELF_FRICTION
    ratios = []
    for grasp_z in (bottom + 0.02, bottom + 0.5):
        (p,) = contact_points(geometry, poses, move, grasp_z, Config())
        ratios.append(push_tip_ratio(geometry, poses, move, grasp_z, Config()))
        assert ratios[-1] == pytest.approx(tip_ratio(0.06, p[2] - bottom, mu, mu))
    assert ratios[0] < 1.0 < ratios[1]
    chain = Move("side", move.u, 0.05, ("side", crowded.target))
    assert push_tip_ratio(geometry, poses, chain, bottom + 0.5, Config()) > ratios[1]


def test_tipping_pushes_rank_after_the_rest_or_are_left_out(context, reach_q, setting,
                                                            monkeypatch):
    geometry, frame, rotation, region = setting

    def run(mode: str) -> RoomSearch:
        return search_room(geometry, context.clearance, frame, region, reach_q[0], rotation,
                           load_config(None, [f"rearrange.tipping={mode}"]), Deadline(60.0))

    kept = run("ignore")
    assert kept.goals and kept.tipping == 0
    assert all(m.tip_ratio > 0.0 for g in kept.goals for m in g.moves)  # each carries it
    monkeypatch.setattr(search, "push_tip_ratio", lambda *a: 2.0)  # every push tips
    def pushes(found: RoomSearch) -> list:
        return [[(m.box, m.u, m.travel, m.moved) for m in g.moves] for g in found.goals]

    assert pushes(run("ignore")) == pushes(kept)  # "ignore" reads the ratio, acts on none
    refused = run("refuse")
    assert refused.goals == [] and refused.tipping == refused.pushes > 0
    assert refused.to_data()["tipping"] == refused.tipping
    a = State({}, travel=0.1, crowd={}, tips=1)
    b = State({}, travel=0.5, crowd={}, tips=0)
    assert sorted([a, b], key=State.key) == [a, b]
    assert sorted([a, b], key=State.tip_key) == [b, a]


@pytest.fixture(scope="module")
def blocked_scene(crowded):
    """The crowded scene with a 6 cm box in front of the side box: it crowds no grasp, but
    the gripper pushing the side box deeper would stand in it."""
    from dataclasses import replace

    from drake_clutter.scene.scenes import validate_scene
    from drake_clutter.testing.handmade import make_box

    target = crowded.target_box
    front = make_box("front", (0.06, 0.06, 0.12), (target.pose[0] - 0.12, target.pose[1] + 0.09))
    return validate_scene(replace(crowded, name="blocked", boxes=(*crowded.boxes, front)))


@pytest.fixture(scope="module")
def blocked_setting(blocked_scene):
    """The baseline's reach at angle 7 (as the shared fixtures') into the blocked scene."""
    from drake_clutter.planners.context import PlanningContext
    from drake_clutter.planners.registry import run_planners

    (reach,) = run_planners(blocked_scene, Config(), ["baseline"], angles=[7])["baseline"]
    assert reach.ok, reach.reason
    q = np.asarray(reach.trajectory.q, float)
    context = PlanningContext(blocked_scene, Config())
    geometry = context.arm()
    return (context, geometry, approach_frame(geometry, q),
            geometry.tool_jacobian(q[-1])[0].rotation().matrix(), reach_region(q, 1), q)


def test_a_push_refused_by_another_box_names_it_with_the_knots_that_entered_it(
        blocked_setting):
    context, geometry, frame, rotation, region, q = blocked_setting
    assert set(crowding(geometry, region, {}, Config().rearrange.deep)) == {"side"}
    u = frame.d[:2] / np.linalg.norm(frame.d[:2])  # the side box pushed deeper
    after = Board(context.scene, 3).push({}, "side", 0.07 * u)
    blocked: list = []
    path, why = action_path(geometry, context.clearance, frame, q[0], rotation, {}, after,
                            Move("side", tuple(u), 0.07, ("side",)), Config(), blocked)
    assert path is None and "front" in why
    fronts = [b for b in blocked if b.box == "front"]
    assert fronts and all(b.knots.ndim == 2 and b.knots.shape[1] == 8 for b in fronts)
    poses = world_poses(geometry, {})
    deepest = max(entered(geometry, k, poses).get("front", 0.0) for k in fronts[0].knots)
    assert deepest > Config().rearrange.entry_tolerance


def test_clear_ways_pushes_the_blocking_box_out_of_the_way_first(blocked_setting):
    context, geometry, frame, rotation, region, q = blocked_setting
    args = (geometry, context.clearance, frame, region, q[0], rotation)
    plain = search_room(*args, Config(), Deadline(60.0))
    assert plain.goals == [] and plain.detours == 0  # every push of the side box is refused
    ways = load_config(None, ["rearrange.clear_ways=true"])
    found = search_room(*args, ways, Deadline(60.0))
    assert found.goals and found.detours > 0
    for goal in found.goals:
        assert [m.box for m in goal.moves] == ["front", "side"]
        assert crowding(geometry, region, goal.offsets, ways.rearrange.deep) == {}
        assert len(goal.paths) == 2 and all(p is not None for p in goal.paths)
    again = search_room(*args, ways, Deadline(60.0))
    assert [[m.to_data() for m in g.moves] for g in again.goals] == [
        [m.to_data() for m in g.moves] for g in found.goals]
