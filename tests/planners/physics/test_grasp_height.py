"""Sec. V's start: the choice among the baseline's straight paths at several grasp heights and
yaws (the first clear of box tops and sides), and the planner's record of it."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from drake_clutter.common.config import Config, ConfigError, check_config, load_config
from drake_clutter.planners import geometry as arm_geometry
from drake_clutter.planners import starts
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.geometry import ArmGeometry
from drake_clutter.planners.physics import grasp_height, pipeline


def test_the_planner_starts_from_the_chosen_height(scene, fig5_heights):
    candidate, config = fig5_heights
    record = candidate.details["grasp_height"]
    assert set(record["candidates"]) == {"0.5", "0.9"} and record["rule"] == "clear"
    entries = record["candidates"]
    flags = {k: (e["press"] > config.starts.press_tolerance,
                 e["side"] > config.starts.side_tolerance) for k, e in entries.items()}
    assert flags[record["chosen"]] == min(flags.values())
    # No stage changes the path: the plan is the chosen height's baseline path.
    tool_z = ArmGeometry(scene, "capsules").tool(candidate.trajectory.q[-1])[0][2]
    height = entries[record["chosen"]]["height"]
    assert tool_z - scene.shelf.top_height == pytest.approx(height, abs=2e-3)
    assert candidate.timings["height"] > 0
    # Without phi stages the plan is ranked by its start's kinematic cost.
    score = candidate.details["start_score"]
    assert np.isfinite(score) and score > 0.0  # c_vel of a path that moves is positive


@pytest.fixture(scope="module")
def fig5_heights(scene):
    from drake_clutter.planners.baseline import plan_baseline

    config = load_config(None, ["starts.grasp_heights=[0.9]", "physics.iterations=0",
                                "physics.sphere_iterations=0", "physics.pre_iterations=0",
                                "physics.post_iterations=0", "dynamics.workers=0"])
    (start,) = plan_baseline(scene, config.baseline, alphas=[0.3])
    return pipeline.optimise_candidate(PlanningContext(scene, config), start), config


def test_the_clear_choice_prefers_a_path_off_every_box_then_one_that_does_not_press(
        scene, monkeypatch):
    from drake_clutter.planners.baseline import plan_baseline

    config = load_config(None, ["starts.grasp_heights=[0.7, 0.9]"])
    (start,) = plan_baseline(scene, config.baseline, alphas=[0.3])
    base = start.details["height"]
    excluded = []

    def stub(depths):  # (press, side) (m) by the path's grasp height above the start's
        def path_depths(geometry, q, substeps, normal_z, side_exclude=()):
            excluded.append(side_exclude)
            h = geometry.tool(q[-1])[0][2] - scene.shelf.top_height
            return depths(h - base)
        monkeypatch.setattr(arm_geometry, "path_depths", path_depths)

    def chosen(depths):
        stub(depths)
        return grasp_height.choose_height(PlanningContext(scene, config), start)

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
    # Nothing is clear: the first that does not press (the start and 0.7 press, 0.9 touches
    # a side).
    found, record = chosen(lambda dh: (0.0, 0.01) if dh > top else (0.004, 0.0))
    assert record["chosen"] == "0.9" and found.details["height"] > base
    assert chosen(lambda dh: (0.004, 0.0))[0] is start  # every path presses: the start


def test_approach_offsets_turn_the_line_and_come_after_every_height(scene, monkeypatch):
    from drake_clutter.planners.baseline import plan_baseline

    config = load_config(None, ["starts.grasp_heights=[0.9]", "starts.approach_offsets=[0.06]"])
    (start,) = plan_baseline(scene, config.baseline, alphas=[0.3])
    context = PlanningContext(scene, config)
    found = starts.height_candidates(context, start)
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

    monkeypatch.setattr(arm_geometry, "path_depths", path_depths)
    chosen, record = grasp_height.choose_height(context, start)
    assert record["chosen"] == "0.5 yaw +0.06" and chosen.alpha == pytest.approx(0.36)
    assert record["candidates"]["0.5 yaw +0.06"]["yaw_offset"] == 0.06
    assert record["candidates"]["0.9"]["side"] == 0.01


@pytest.mark.parametrize("fractions", [[0.0], [1.2], [0.6, -0.1]])
def test_grasp_heights_must_be_fractions_of_the_target(fractions):
    config = Config()
    config = replace(config, starts=replace(config.starts, grasp_heights=tuple(fractions)))
    with pytest.raises(ConfigError, match="starts.grasp_heights"):
        check_config(config)


@pytest.mark.parametrize("field, value", [("press_tolerance", -0.001), ("press_substeps", 0),
                                          ("side_tolerance", -0.001),
                                          ("approach_offsets", (0.1, -0.7))])
def test_the_press_checks_settings_are_checked(field, value):
    config = Config()
    config = replace(config, starts=replace(config.starts, **{field: value}))
    with pytest.raises(ConfigError, match=f"starts.{field}"):
        check_config(config)
