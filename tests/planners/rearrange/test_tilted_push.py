"""Pushes with the closed gripper's axis tipped down (`rearrange.push_pitch`): the rotation
tips G's x-axis down by the pitch about a horizontal axis, the turn to it is slerped at the
configured speed in front of the shelf, and the search's push paths still start and end at the
reach's first knot inside the judge's limits, clear the shelf, and push tipped."""

from __future__ import annotations

import numpy as np
import pytest

from drake_clutter.common.config import ConfigError, load_config
from drake_clutter.planners.budget import Deadline
from drake_clutter.planners.clearance import dense_check
from drake_clutter.planners.rearrange import actions
from drake_clutter.planners.rearrange.actions import push_rotation, turning
from drake_clutter.planners.rearrange.board import crowding, reach_region
from drake_clutter.planners.rearrange.search import search_room
from drake_clutter.planners.tool_path import approach_frame
from drake_clutter.trajectory import Trajectory, plan_limit_violation

TILTED = ["rearrange.push_pitch=0.3", "rearrange.push_low=true"]


def _yawed(yaw: float) -> np.ndarray:
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def test_the_push_rotation_tips_the_gripper_axis_down_by_the_pitch():
    R = _yawed(0.3)
    np.testing.assert_array_equal(push_rotation(R, 0.0), R)
    P = push_rotation(R, 0.5)
    np.testing.assert_allclose(P.T @ P, np.eye(3), atol=1e-12)
    assert P[2, 0] == pytest.approx(-np.sin(0.5))  # x points down by 0.5 rad
    np.testing.assert_allclose(P[:2, 0] / np.linalg.norm(P[:2, 0]), R[:2, 0])  # same heading
    assert P[2, 1] == pytest.approx(0.0, abs=1e-12)  # about the horizontal axis across x


def test_the_turn_is_slerped_no_faster_than_the_turn_speed():
    R = _yawed(-0.2)
    P = push_rotation(R, 0.8)
    turns = turning(R, P, 1.0, 0.1)
    assert len(turns) == 8
    np.testing.assert_allclose(turns[-1], P, atol=1e-12)
    previous = R
    for T in turns:
        step = np.arccos(np.clip((np.trace(previous.T @ T) - 1.0) / 2.0, -1.0, 1.0))
        assert step <= 0.1 + 1e-9
        previous = T
    assert turning(R, R, 1.0, 0.1).shape == (0, 3, 3)


def test_the_pitch_is_checked_at_load():
    with pytest.raises(ConfigError, match="rearrange.push_pitch"):
        load_config(None, ["rearrange.push_pitch=2.0"])
    with pytest.raises(ConfigError, match="rearrange.turn_speed"):
        load_config(None, ["rearrange.turn_speed=0"])


def _search(context, reach_q, overrides: list[str]):
    config = load_config(None, overrides)
    geometry = context.arm()
    frame = approach_frame(geometry, reach_q)
    rotation = geometry.tool_jacobian(reach_q[-1])[0].rotation().matrix()
    region = reach_region(reach_q, 1)
    found = search_room(geometry, context.clearance, frame, region, reach_q[0], rotation,
                        config, Deadline(60.0))
    return config, geometry, frame, rotation, region, found


def test_a_tilt_the_arm_cannot_turn_to_is_refused_and_the_push_tried_untilted(
        context, reach_q):
    # at 0.5 rad the wrist must rise past the shoulder's lift limit at the reach's first knot
    *_, tilted = _search(context, reach_q, ["rearrange.push_pitch=0.5"])
    *_, untilted = _search(context, reach_q, [])
    assert tilted.goals and len(tilted.goals) == len(untilted.goals)
    for a, b in zip(tilted.goals, untilted.goals, strict=True):
        assert [m.to_data() for m in a.moves] == [m.to_data() for m in b.moves]
        for p, q in zip(a.paths, b.paths, strict=True):
            np.testing.assert_array_equal(p, q)


def test_a_path_outside_the_judges_limits_says_which_joint(reach_q):
    config = load_config(None, [])
    assert actions._outside_limits(reach_q, config) == ""
    assert actions._outside_limits(None, config) == ""
    raised = reach_q.copy()
    raised[2:, 1] = -0.6  # the shoulder lifted past its -0.524 rad limit
    assert "r_shoulder_lift_joint at -0.600 rad" in actions._outside_limits(raised, config)


def test_tilted_pushes_clear_the_grasp_within_the_limits(context, reach_q):
    config, geometry, frame, rotation, region, found = _search(context, reach_q, TILTED)
    assert found.goals, found.reasons
    tipped = push_rotation(rotation, 0.3)[:, 0]
    for goal in found.goals:
        assert crowding(geometry, region, goal.offsets, config.rearrange.deep) == {}
        for path in goal.paths:
            np.testing.assert_allclose(path[0, :7], reach_q[0, :7])
            np.testing.assert_allclose(path[-1, :7], reach_q[0, :7])
            times = np.arange(len(path)) * config.baseline.knot_time
            assert plan_limit_violation(Trajectory(times, path), config.evaluation) == ""
            assert dense_check(context.clearance, path[:, :7], config.baseline).passed
            # the knot deepest into the shelf (the push) points G's axis tipped down
            depths = [geometry.tool_jacobian(q)[0].translation() @ frame.d for q in path]
            deepest = geometry.tool_jacobian(path[int(np.argmax(depths))])[0]
            np.testing.assert_allclose(deepest.rotation().matrix()[:, 0], tipped, atol=2e-3)
