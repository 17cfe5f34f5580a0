"""The rearrange planner: the push answer unchanged where its reach is clear; on a box crowding
the grasp, pushes then the reach, judged in phi beside the push answer, the same plan on every
run, a plan the Bullet judge replays whole; its registry entry and record."""

from __future__ import annotations

import numpy as np
import pytest

from drake_clutter.common.config import load_config
from drake_clutter.evaluation.judge import evaluate
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.rearrange.planner import (
    held_to,
    rearrange_candidate,
    sequence_path,
)
from drake_clutter.planners.rearrange.record import PUSH, RearrangeRecord
from drake_clutter.planners.rearrange.search import State
from drake_clutter.planners.registry import REGISTRY, run_planners
from drake_clutter.trajectory import plan_limit_violation

ANGLE = 7  # as the shared fixtures' reach
FAST = ["phi_judge.members=2", "phi_judge.veto_members=2"]


@pytest.fixture(scope="module")
def config():
    return load_config(None, FAST)


@pytest.fixture(scope="module")
def planned(crowded, reach, config):
    """The planner on the crowded scene from the baseline's reach (as a push answer)."""
    return rearrange_candidate(PlanningContext(crowded, config), reach, ANGLE)


def test_a_clear_reach_returns_the_push_answer_unchanged(alone, config):
    (start,) = run_planners(alone, config, ["baseline"], angles=[ANGLE])["baseline"]
    out = rearrange_candidate(PlanningContext(alone, config), start, ANGLE)
    record = RearrangeRecord.from_details(out.details)
    assert out.planner == "rearrange" and out.trajectory == start.trajectory
    assert (record.chosen, record.why, record.crowd) == (PUSH, "clear", {})


def test_a_crowded_reach_is_judged_with_its_pushes_beside_the_push_answer(planned, reach,
                                                                          config):
    record = RearrangeRecord.from_details(planned.details)
    assert set(record.crowd) == {"side"}
    assert PUSH in record.verdicts and any(k.startswith("room") for k in record.verdicts)
    assert all(len(v["kinds"]) == 2 for v in record.verdicts.values())
    if not record.rearranged:
        assert record.why in ("not accepted", "veto") and planned.trajectory == reach.trajectory
        return
    q = planned.trajectory.q
    np.testing.assert_array_equal(q[-len(reach.trajectory.q) + 1:], reach.trajectory.q[1:])
    np.testing.assert_allclose(q[0, :7], reach.trajectory.q[0, :7])
    assert plan_limit_violation(planned.trajectory, config.evaluation) == ""
    assert record.moves and record.moves[0]["box"] == "side"
    assert record.veto["wins"] and record.verdicts[record.chosen]["p_success"] >= 0.5


def test_the_same_scene_gives_the_same_plan(planned, crowded, reach, config):
    again = rearrange_candidate(PlanningContext(crowded, config), reach, ANGLE)
    assert again.trajectory == planned.trajectory
    mine, theirs = (RearrangeRecord.from_details(c.details) for c in (planned, again))
    assert mine.verdicts == theirs.verdicts and mine.chosen == theirs.chosen


def test_the_judge_replays_a_long_plan_whole(planned, crowded, config):
    outcome = evaluate(crowded, planned.trajectory, config.evaluation)
    assert outcome.trajectory_time == pytest.approx(planned.trajectory.duration)
    assert outcome.simulated_time >= planned.trajectory.duration
    assert outcome.kind in ("success", "partial_success", "failure_to_grasp",
                            "objects_falling", "kinematic_failure")


def test_a_sequence_is_its_pushes_then_the_reach():
    reach = np.tile(np.r_[np.zeros(7), 0.08], (4, 1))
    reach[:, 0] = np.linspace(0.0, 0.3, 4)
    push = np.tile(np.r_[np.zeros(7), 0.0], (3, 1))
    push[1, 1] = 0.1
    q = sequence_path(State({}, paths=(push, push)), reach)
    assert len(q) == 2 * 2 + 3 + 3
    np.testing.assert_array_equal(q[-3:], reach[1:])
    np.testing.assert_allclose(q[4:7, 7], [0.08 / 3, 0.16 / 3, 0.08])
    held = held_to({"a": q, "b": reach})
    assert len(held["b"]) == len(q) and np.all(held["b"][: len(q) - 4] == reach[0])


def test_its_registry_entry_starts_from_the_push_planner_and_scores_without_the_judge():
    planner = REGISTRY["rearrange"]
    assert planner.starts_from == "push" and planner.paper_row is None
    room = {"chosen": "room0", "verdicts": {"room0": {"p_success": 0.75, "expected_grade": 1.0,
                                                      "kinds": []}}}
    assert planner.score(room) == pytest.approx(-0.74)
    kept = {"chosen": PUSH, "why": "clear", "push": {"clear": ["h0.5"], "chosen": "h0.5"}}
    assert planner.score(kept) == REGISTRY["push"].score(kept["push"])
    assert RearrangeRecord.from_details(room).label == "0 pushes, then the reach"
