"""The push path family: a member with no via-points is its straight path; a member's knots
put the tool frame on its targets (the via-points' offsets, sideways and up); the gripper's
schedule; draws are seeded and feasible on a real scene."""

from __future__ import annotations

import numpy as np
import pytest

from drake_clutter.common.config import Config
from drake_clutter.planners.approach import static_planning_world
from drake_clutter.planners.baseline import plan_baseline
from drake_clutter.planners.clearance import ShelfClearance, dense_check
from drake_clutter.planners.geometry import ArmGeometry
from drake_clutter.planners.push.family import (
    PushPath,
    ViaPoint,
    draw_member,
    member_path,
    profiles,
)
from drake_clutter.scene import scenes
from drake_clutter.trajectory import Trajectory, plan_limit_violation


@pytest.fixture(scope="module")
def setting():
    scene = scenes.load_shipped_scene("fig6_push_sideways")
    (candidate,) = plan_baseline(scene, Config().baseline, alphas=[0.0])
    assert candidate.ok, candidate.reason
    return scene, ArmGeometry(scene, "capsules"), candidate.trajectory


def test_profiles_pass_through_the_via_points():
    member = PushPath((ViaPoint(0.25, 0.5, 0.08, 0.02), ViaPoint(0.75, 0.5, -0.04, 0.0)))
    progress, lateral, vertical = profiles(member, 5)  # knots at 0, 0.25, 0.5, 0.75, 1
    np.testing.assert_allclose(progress, [0.0, 0.5, 0.5, 0.5, 1.0])
    np.testing.assert_allclose(lateral, [0.0, 0.08, 0.02, -0.04, 0.0])
    np.testing.assert_allclose(vertical, [0.0, 0.02, 0.01, 0.0, 0.0])
    with pytest.raises(ValueError, match="time order"):
        profiles(PushPath((ViaPoint(0.6, 0.5), ViaPoint(0.4, 0.6))), 5)


def test_no_via_points_is_the_straight_path(setting):
    _, geometry, trajectory = setting
    path, error = member_path(geometry, trajectory.q, PushPath())
    np.testing.assert_allclose(path, trajectory.q, atol=1e-12)
    assert error == 0.0


def test_a_sweep_puts_the_tool_frame_on_its_offsets(setting):
    _, geometry, trajectory = setting
    q = trajectory.q
    n = len(q)
    mid = (n - 1) // 2
    at = mid / (n - 1)  # the via-point on a knot, at that knot's own progress
    member = PushPath((ViaPoint(at, at, 0.06, 0.03),))
    path, error = member_path(geometry, q, member)
    assert error < 1e-3
    np.testing.assert_array_equal(path[0], q[0])
    np.testing.assert_array_equal(path[-1], q[-1])
    d = geometry.tool_axis(q[-1], 0)[0]
    side = np.cross([0, 0, 1.0], d)
    side /= np.linalg.norm(side)
    moved = geometry.tool(path[mid])[0] - geometry.tool(q[mid])[0]
    assert moved @ side == pytest.approx(0.06, abs=2e-3)
    assert moved[2] == pytest.approx(0.03, abs=2e-3)


def test_the_gripper_opens_when_asked(setting):
    _, geometry, trajectory = setting
    q = trajectory.q
    path, _ = member_path(geometry, q, PushPath((), open_at=0.5), closed_opening=0.01,
                          opening_knots=3)
    first = int(round(0.5 * (len(q) - 1)))
    np.testing.assert_allclose(path[:first + 1, 7], 0.01)
    np.testing.assert_allclose(path[first + 3:, 7], q[first + 3:, 7])
    assert 0.01 < path[first + 1, 7] < q[first + 1, 7]


def test_draws_are_seeded_and_mostly_feasible(setting):
    scene, geometry, trajectory = setting
    ranges = Config().push_search
    a = [draw_member(np.random.default_rng(4), ranges) for _ in range(2)]
    b = [draw_member(np.random.default_rng(4), ranges) for _ in range(2)]
    assert a == b
    rng = np.random.default_rng(0)
    clearance = ShelfClearance(static_planning_world(scene))
    feasible = 0
    for _ in range(10):
        member = draw_member(rng, ranges)
        assert all(abs(v.lateral) <= ranges.lateral for v in member.vias)
        path, error = member_path(geometry, trajectory.q, member)
        feasible += (error < 1e-3
                     and not plan_limit_violation(Trajectory(trajectory.times, path),
                                                  Config().evaluation)
                     and dense_check(clearance, path[:, :7], Config().baseline).passed)
    assert feasible >= 7
