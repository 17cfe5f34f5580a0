"""An approach angle whose baseline path fails is not given up: the push planner plans its other
heights, then the line turned toward the shelf's axis, and searches from what plans; with
nothing planned the baseline's failure comes back unchanged."""

from __future__ import annotations

import pytest

from drake_clutter.common.config import ConfigError, load_config
from drake_clutter.experiments.specs import stored_scene
from drake_clutter.planners import baseline
from drake_clutter.planners.approach import approach_angles
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.push.planner import plan_push
from drake_clutter.planners.starts import height_candidates, turned_starts
from drake_clutter.trajectory import CandidateStatus

SMALL = ["dynamics.workers=0", "push_search.samples=3", "push_search.rounds=1",
         "phi_judge.members=2", "phi_judge.veto_members=2"]


def _failed(name: str, index: int, sets=()):
    """The scene ``name``, its context and the baseline's candidate at angle ``index``."""
    config = load_config(None, [*SMALL, *sets])
    scene = stored_scene(name, config)
    context = PlanningContext(scene, config)
    alpha = float(approach_angles(config.baseline)[index])
    candidate = baseline.plan_angle(
        context.baseline_at(config.baseline.grasp_height_fraction), alpha, index)
    return scene, config, context, candidate


@pytest.fixture(scope="module")
def steep_fridge():
    """A refrigerator's steepest angle (alpha -0.93 rad): the start pose on line l never
    clears the side wall, at any grasp height."""
    return _failed("fridge_n08_s12017", 0)


def test_a_steep_angle_that_fails_is_planned_turned_toward_the_shelf_axis(steep_fridge):
    _, config, context, candidate = steep_fridge
    assert candidate.status is CandidateStatus.IK_FAILED and "start pose" in candidate.reason
    assert height_candidates(context, candidate) == {}
    found = turned_starts(context, candidate)
    turn = config.starts.recovery_turns[0]
    assert found and {offset for _, offset in found} == {turn}  # toward alpha = 0: positive
    for (fraction, _), start in found.items():
        assert start.ok and start.alpha == pytest.approx(candidate.alpha + turn)
        assert fraction in (config.baseline.grasp_height_fraction,
                            *config.starts.grasp_heights)


def test_the_push_planner_searches_from_the_turned_starts(steep_fridge):
    scene, config, _, candidate = steep_fridge
    (planned,) = plan_push(scene, config, [candidate])
    assert planned.ok and planned.planner == "push" and planned.alpha == candidate.alpha
    assert planned.details["recovered"] == {"status": "ik_failed", "reason": candidate.reason}
    assert "yaw +0.1" in planned.details["chosen"]  # a turned start or a member drawn from one
    assert planned.trajectory.q.shape == (config.baseline.num_knots, 8)


def test_with_nothing_planned_the_failure_comes_back_as_it_was():
    scene, config, _, candidate = _failed("fridge_n04_s10015", 12, ["starts.recovery_turns=[]"])
    assert not candidate.ok
    (planned,) = plan_push(scene, config, [candidate])
    assert (planned.status, planned.reason, planned.planner) == (candidate.status,
                                                                 candidate.reason, "push")
    assert planned.timings["heights"] > 0 and "recovered" not in planned.details


@pytest.mark.parametrize("turns", ["[0.0]", "[0.6]", "[-0.1]"])
def test_recovery_turns_are_checked(turns):
    with pytest.raises(ConfigError, match="recovery_turns"):
        load_config(None, [f"starts.recovery_turns={turns}"])
