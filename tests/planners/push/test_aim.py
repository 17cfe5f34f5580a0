"""Aimed push members: the boxes a straight path enters are found with their place in the
approach frame; an aimed move's via-points sit beside the box it aims at, in time order, and
its members are seeded and mostly feasible on a real scene."""

from __future__ import annotations

import numpy as np
import pytest

from drake_clutter.common.config import Config
from drake_clutter.planners.approach import static_planning_world
from drake_clutter.planners.baseline import plan_baseline
from drake_clutter.planners.clearance import ShelfClearance, dense_check
from drake_clutter.planners.geometry import ArmGeometry
from drake_clutter.planners.push.aim import (
    Obstruction,
    aimed_member,
    draw,
    obstructions,
)
from drake_clutter.planners.push.family import member_path
from drake_clutter.planners.tool_path import approach_frame
from drake_clutter.scene import scenes
from drake_clutter.trajectory import Trajectory, plan_limit_violation


@pytest.fixture(scope="module")
def setting():
    scene = scenes.load_shipped_scene("fig6_push_sideways")
    (candidate,) = plan_baseline(scene, Config().baseline, alphas=[0.0])
    assert candidate.ok, candidate.reason
    geometry = ArmGeometry(scene, "capsules")
    q = candidate.trajectory.q
    frame = approach_frame(geometry, q)
    return scene, geometry, candidate.trajectory, frame, obstructions(geometry, q, frame,
                                                                      scene.target)


def test_the_frame_runs_along_the_approach(setting):
    _, _, trajectory, frame, _ = setting
    np.testing.assert_allclose(np.linalg.norm(frame.d), 1.0)
    assert abs(frame.d[2]) == 0.0 and abs(frame.side @ frame.d) < 1e-12
    assert frame.along[-1] == 0.0 and frame.along[0] < -0.1
    assert frame.progress_at(frame.along[0]) == 0.0 and frame.progress_at(0.0) == 1.0
    half = frame.along[len(frame.along) // 2]
    assert abs(frame.progress_at(half) - 0.5) < 0.1


def test_the_met_box_is_found_in_front_of_the_target(setting):
    scene, geometry, trajectory, frame, found = setting
    assert found, "fig6's straight path meets a box"
    assert all(o.box != scene.target and o.depth > 0.0 for o in found)
    assert [o.depth for o in found] == sorted((o.depth for o in found), reverse=True)
    # The deepest: a geometric query of the arm at every knot agrees on its depth.
    o = found[0]
    deepest = max(-c.distance for q in trajectory.q
                  for c in geometry.contacts(q, max_distance=0.0, obstacles="boxes")
                  if c.obstacle == o.box)
    assert deepest == pytest.approx(o.depth)
    size = np.asarray(next(b.size for b in scene.boxes if b.name == o.box)) / 2
    assert min(size) - 1e-9 <= o.half_side <= np.linalg.norm(size) + 1e-9
    assert o.along < 0.0  # before the pre-grasp


def test_an_aside_move_starts_beside_the_box_and_sweeps_across(setting):
    _, _, _, frame, _ = setting
    box = Obstruction("b", 0.02, along=-0.15, lateral=0.03, half_along=0.04, half_side=0.05)
    ranges = Config().push_search
    for seed in range(20):
        rng = np.random.default_rng(seed)
        member = aimed_member(rng, frame, [box], ranges)
        times = [v.knot for v in member.vias]
        assert times == sorted(times) and 0.0 < times[0] and times[-1] < 1.0
        first = member.vias[0]
        # the first via-point clears the box on one side, by its half width and the gripper's
        clear = abs(first.lateral - box.lateral)
        assert ranges.gripper_half_width + box.half_side - 1e-9 <= clear <= (
            ranges.gripper_half_width + box.half_side + ranges.aim_slack + 1e-9)
        if len(member.vias) == 3:  # aside: in at the box's depth, then across the line
            assert member.vias[1].lateral == first.lateral
            assert member.vias[2].progress == member.vias[1].progress
            assert np.sign(member.vias[2].lateral) == -np.sign(first.lateral - box.lateral) or (
                member.vias[2].lateral == 0.0)
        else:  # around: the offset held past the box's far face
            assert len(member.vias) == 2 and member.vias[1].lateral == first.lateral
            assert member.vias[1].progress >= first.progress
    assert aimed_member(np.random.default_rng(0), frame, [], ranges) is None


def test_draws_are_seeded_and_mostly_feasible(setting):
    scene, geometry, trajectory, frame, found = setting
    config = Config()
    clearance = ShelfClearance(static_planning_world(scene))

    def members(seed):
        rng = np.random.default_rng(seed)
        return [draw(rng, frame, found, config.push_search) for _ in range(8)]

    assert members(3) == members(3) and members(3) != members(4)
    feasible = 0
    for member in members(3):
        path, error = member_path(geometry, trajectory.q, member)
        feasible += (error < 1e-3 and not plan_limit_violation(
            Trajectory(trajectory.times, path), config.evaluation)
            and dense_check(clearance, path[:, :7], config.baseline).passed)
    assert feasible >= 5
