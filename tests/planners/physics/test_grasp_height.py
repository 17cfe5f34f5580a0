"""Choosing the grasp height in phi's ensemble: the judge's classes read on a phi state, the
choice among the baseline's paths at several heights, and the planner's record of it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from drake_clutter.common.config import Config, ConfigError, check_config, load_config
from drake_clutter.planners.physics import grasp_height, pipeline
from drake_clutter.planners.physics.ensemble import MemberRollout
from drake_clutter.planners.physics.geometry import ArmGeometry


@pytest.fixture(scope="module")
def geometry(scene):
    return ArmGeometry(scene, "capsules")


def _state(quat_wxyz, p_W) -> np.ndarray:
    """A 13-number box state at rest: quaternion wxyz, position, zero velocities."""
    return np.concatenate([quat_wxyz, p_W, np.zeros(6)])


def _rest(geometry, name: str) -> np.ndarray:
    X_WB = geometry.rest_pose(name)
    return _state(X_WB.rotation().ToQuaternion().wxyz(), X_WB.translation())


def test_settled_class_reads_the_judges_classes_on_a_state(scene, geometry, baseline_path):
    q_last = baseline_path[-1]  # the pre-grasp pose: the target between the open fingers
    evaluation = Config().evaluation
    at_rest = {b.name: _rest(geometry, b.name) for b in scene.boxes}
    assert grasp_height.settled_class(scene, geometry, q_last, at_rest, evaluation) == 0.0
    # Boxes phi held frozen are where the scene put them.
    assert grasp_height.settled_class(scene, geometry, q_last, {}, evaluation) == 0.0
    pushed = dict(at_rest, target=at_rest["target"] + np.r_[0, 0, 0, 0, 0.10, 0, 0, [0] * 6])
    assert grasp_height.settled_class(scene, geometry, q_last, pushed, evaluation) == 2.0
    on_its_side = np.array([np.cos(np.pi / 4), np.sin(np.pi / 4), 0.0, 0.0])  # 90 deg about x
    tipped = dict(at_rest, small_tippy=_state(on_its_side, at_rest["small_tippy"][4:7]))
    assert grasp_height.settled_class(scene, geometry, q_last, tipped, evaluation) == 1.01
    fallen = dict(at_rest, box_far_left=_state([1, 0, 0, 0], [0.0, 0.0, 0.2]))
    assert grasp_height.settled_class(scene, geometry, q_last, fallen, evaluation) == 2.01
    closed = np.r_[q_last[:7], 0.0]  # the closed gripper cannot hold the target between pads
    assert grasp_height.settled_class(scene, geometry, closed, at_rest, evaluation) == 2.0
    assert grasp_height.settled_class(scene, geometry, q_last, None, evaluation) is None


def _stub_rollouts(classes_by_height, monkeypatch):
    """member_rollouts without phi, and settled_class by the path's grasp height (m)."""
    monkeypatch.setattr(grasp_height, "member_rollouts",
                        lambda scene, paths, *args: {n: MemberRollout({}, {}) for n in paths})

    def by_height(scene, geometry, q_last, final, evaluation):
        height = geometry.tool_jacobian(q_last)[0].translation()[2] - scene.shelf.top_height
        return classes_by_height(height)

    monkeypatch.setattr(grasp_height, "settled_class", by_height)


def test_the_phi_choice_takes_the_lowest_mean_class_and_ties_keep_the_start(scene,
                                                                             monkeypatch):
    from drake_clutter.planners.baseline import plan_baseline

    config = load_config(None, ["physics.grasp_heights=[0.7, 0.9]", "ensemble.members=2",
                                "physics.height_choice=phi"])
    (start,) = plan_baseline(scene, config.baseline, alphas=[0.3])
    _stub_rollouts(lambda h: 1.0, monkeypatch)  # every height alike: the start stays
    chosen, record = grasp_height.choose_height(scene, start, config)
    assert chosen is start and record["chosen"] == "0.5"
    heights = [record["candidates"][f]["height"] for f in ("0.5", "0.7", "0.9")]
    assert heights == sorted(heights) and heights[0] == start.details["height"]
    assert all(record["candidates"][f]["classes"] == [1.0, 1.0] for f in ("0.5", "0.7"))
    _stub_rollouts(lambda h: 0.0 if h > heights[1] - 0.005 else 2.0, monkeypatch)
    chosen, record = grasp_height.choose_height(scene, start, config)
    assert record["chosen"] == "0.7"  # 0.7 and 0.9 tie at 0: the earlier listed
    assert chosen.details["height"] == pytest.approx(heights[1])
    assert chosen.alpha == start.alpha and chosen.ok


def test_the_planner_starts_from_the_chosen_height_in_phi(scene, fig5_heights):
    candidate, config = fig5_heights
    record = candidate.details["grasp_height"]
    means = {f: np.mean(r["classes"]) for f, r in record["candidates"].items()}
    assert set(means) == {"0.5", "0.9"}
    assert means[record["chosen"]] == min(means.values())
    if means["0.5"] == means["0.9"]:
        assert record["chosen"] == "0.5"
    # No stage changes the path: the plan is the chosen height's baseline path.
    tool_z = ArmGeometry(scene, "capsules").tool(candidate.trajectory.q[-1])[0][2]
    height = record["candidates"][record["chosen"]]["height"]
    assert tool_z - scene.shelf.top_height == pytest.approx(height, abs=2e-3)
    assert candidate.timings["height"] > 0
    # Without phi stages or a choice in phi the plan is ranked by its start's kinematic cost.
    start = record["candidates"][record["chosen"]]
    assert candidate.details["start_score"] is not None and start["height"] is not None


@pytest.fixture(scope="module")
def fig5_heights(scene):
    from drake_clutter.planners.baseline import plan_baseline

    config = load_config(None, ["physics.grasp_heights=[0.9]", "physics.height_choice=phi",
                                "physics.iterations=0", "physics.sphere_iterations=0",
                                "physics.pre_iterations=0", "physics.post_iterations=0",
                                "dynamics.workers=0"])
    (start,) = plan_baseline(scene, config.baseline, alphas=[0.3])
    return pipeline.optimise_candidate(scene, start, config), config


def test_the_press_choice_keeps_the_start_unless_it_presses_and_another_does_not(
        scene, monkeypatch):
    from drake_clutter.planners.baseline import plan_baseline

    config = load_config(None, ["physics.grasp_heights=[0.7, 0.9]", "physics.height_choice=press"])
    (start,) = plan_baseline(scene, config.baseline, alphas=[0.3])
    base = start.details["height"]

    def stub(presses):  # (press, no side) (m) by the path's grasp height above the start's
        def path_depths(geometry, q, substeps, normal_z, side_exclude=()):
            h = geometry.tool(q[-1])[0][2] - scene.shelf.top_height
            return presses(h - base), 0.0
        monkeypatch.setattr(grasp_height, "path_depths", path_depths)

    stub(lambda dh: 0.004)  # every height presses: the start
    chosen, record = grasp_height.choose_height(scene, start, config)
    assert chosen is start and record["rule"] == "press"
    assert record["candidates"]["0.9"]["press"] == 0.004
    stub(lambda dh: 0.0004)  # within press_tolerance: the start
    assert grasp_height.choose_height(scene, start, config)[0] is start
    stub(lambda dh: 0.004 if dh < 0.001 else 0.0)  # only the start presses: the next listed
    chosen, record = grasp_height.choose_height(scene, start, config)
    assert record["chosen"] == "0.7" and chosen.details["height"] > base


def test_the_clear_choice_prefers_a_path_off_every_box_then_one_that_does_not_press(
        scene, monkeypatch):
    from drake_clutter.planners.baseline import plan_baseline

    config = load_config(None, ["physics.grasp_heights=[0.7, 0.9]",
                                "physics.height_choice=clear"])
    (start,) = plan_baseline(scene, config.baseline, alphas=[0.3])
    base = start.details["height"]
    excluded = []

    def stub(depths):  # (press, side) (m) by the path's grasp height above the start's
        def path_depths(geometry, q, substeps, normal_z, side_exclude=()):
            excluded.append(side_exclude)
            h = geometry.tool(q[-1])[0][2] - scene.shelf.top_height
            return depths(h - base)
        monkeypatch.setattr(grasp_height, "path_depths", path_depths)

    def chosen(depths):
        stub(depths)
        return grasp_height.choose_height(scene, start, config)

    found, record = chosen(lambda dh: (0.0, 0.01))  # every path touches a side: the start
    assert found is start and record["rule"] == "clear"
    assert (record["candidates"]["0.9"]["press"], record["candidates"]["0.9"]["side"]) == (
        0.0, 0.01)
    assert set(excluded) == {(scene.target,)}  # the target's sides are the grasp's
    top = 0.3 * scene.target_box.size[2]  # between 0.7's and 0.9's height above the start's
    # The start touches a side, 0.9 (listed last) is clear: 0.9.
    assert chosen(lambda dh: (0.0, 0.0 if dh > top else 0.01))[1]["chosen"] == "0.9"
    # The start's 4 mm is within side_tolerance (5 mm): the start counts as clear.
    assert chosen(lambda dh: (0.0, 0.0 if dh > top else 0.004))[0] is start
    # Nothing is clear: the press rule (the start presses, 0.7 too, 0.9 only touches a side).
    found, record = chosen(lambda dh: (0.0, 0.01) if dh > top else (0.004, 0.0))
    assert record["chosen"] == "0.9" and found.details["height"] > base
    assert chosen(lambda dh: (0.004, 0.0))[0] is start  # every path presses: the start


def test_approach_offsets_turn_the_line_and_come_after_every_height(scene, monkeypatch):
    from drake_clutter.planners.baseline import plan_baseline

    config = load_config(None, ["physics.grasp_heights=[0.9]", "physics.approach_offsets=[0.06]",
                                "physics.height_choice=clear"])
    (start,) = plan_baseline(scene, config.baseline, alphas=[0.3])
    found = grasp_height.height_candidates(scene, start, config)
    assert list(found) == [(0.5, 0.0), (0.9, 0.0), (0.5, 0.06), (0.9, 0.06)]
    assert found[(0.5, 0.0)] is start
    assert found[(0.9, 0.06)].alpha == pytest.approx(0.36)
    assert found[(0.9, 0.06)].details["height"] == pytest.approx(found[(0.9, 0.0)].details[
        "height"])
    geometry = ArmGeometry(scene, "capsules")

    def direction(q):  # the gripper's approach axis at the pre-grasp, horizontal, unit
        d = geometry.tool_axis(q[-1], 0)[0][:2]
        return d / np.linalg.norm(d)

    def turn(q):  # rad, from the start's approach
        return np.arccos(np.clip(direction(q) @ direction(start.trajectory.q), -1.0, 1.0))

    assert turn(found[(0.5, 0.06)].trajectory.q) == pytest.approx(0.06, abs=0.02)
    assert turn(found[(0.9, 0.0)].trajectory.q) < 0.02

    def path_depths(geometry, q, substeps, normal_z, side_exclude=()):
        return 0.0, (0.0 if turn(q) > 0.03 else 0.01)  # only the turned lines are clear

    monkeypatch.setattr(grasp_height, "path_depths", path_depths)
    chosen, record = grasp_height.choose_height(scene, start, config)
    assert record["chosen"] == "0.5 yaw +0.06" and chosen.alpha == pytest.approx(0.36)
    assert record["candidates"]["0.5 yaw +0.06"]["yaw_offset"] == 0.06
    assert record["candidates"]["0.9"]["side"] == 0.01


@pytest.mark.parametrize("fractions", [[0.0], [1.2], [0.6, -0.1]])
def test_grasp_heights_must_be_fractions_of_the_target(fractions):
    config = Config()
    config = replace(config, physics=replace(config.physics, grasp_heights=tuple(fractions)))
    with pytest.raises(ConfigError, match="physics.grasp_heights"):
        check_config(config)


@pytest.mark.parametrize("field, value", [("press_tolerance", -0.001), ("press_substeps", 0),
                                          ("side_tolerance", -0.001),
                                          ("approach_offsets", (0.1, -0.7))])
def test_the_press_checks_settings_are_checked(field, value):
    config = Config()
    config = replace(config, physics=replace(config.physics, **{field: value}))
    with pytest.raises(ConfigError, match=f"physics.{field}"):
        check_config(config)
