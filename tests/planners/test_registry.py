"""The planner registry: one interface, each planner (and its start) run once, single angles
planned as experiment units plan them; the str enums serialise as the strings they replace."""

from __future__ import annotations

import json
from typing import get_args

import numpy as np
import pytest

from drake_clutter.common.config import Config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.evaluation.outcome import OUTCOME_KINDS, Outcome, OutcomeKind
from drake_clutter.planners import baseline
from drake_clutter.planners.approach import approach_angles
from drake_clutter.planners.registry import (
    REGISTRY,
    PlannerName,
    check_planners,
    get_planner,
    planner_names,
    run_planners,
)
from drake_clutter.scene.scenes import load_shipped_scene
from drake_clutter.solvers.ilqr import StopReason
from drake_clutter.trajectory import (
    CANDIDATE_STATUSES,
    Candidate,
    CandidateStatus,
    PlanFileError,
    load_plan,
)


def test_the_registry_lists_the_planners_typed_yaml_accepts():
    assert planner_names() == ("baseline", "physics", "push", "rearrange")
    assert set(get_args(PlannerName)) == set(planner_names())
    for name in planner_names():
        assert get_planner(name).name == name
    assert {name: get_planner(name).starts_from for name in planner_names()} == {
        "baseline": None, "physics": "baseline", "push": "baseline", "rearrange": "push"}


def test_an_unknown_planner_names_the_file_and_field():
    with pytest.raises(InputError) as err:
        get_planner("rrt", "spec.yaml", "planners[1]")
    assert err.value.file == "spec.yaml" and err.value.field == "planners[1]"
    assert "baseline" in err.value.reason


class _Fake:
    """A planner that records its calls; its candidates carry its name."""

    def __init__(self, name, starts_from, calls):
        self.name, self.starts_from, self.calls = name, starts_from, calls

    def check(self, config, file="<configuration>"):
        self.calls.append(("check", self.name))

    def plan(self, scene, config, angles=None, start=None):
        self.calls.append(("plan", self.name, None if start is None else len(start)))
        count = len(angles) if angles is not None else config.baseline.num_angles
        return [Candidate(0.1 * i, "ok", planner=self.name) for i in range(count)]

    def table(self, candidates):
        return self.name


def test_each_planner_and_its_start_run_once_in_the_order_asked(monkeypatch):
    calls = []
    monkeypatch.setitem(REGISTRY, "baseline", _Fake("baseline", None, calls))
    monkeypatch.setitem(REGISTRY, "physics", _Fake("physics", "baseline", calls))
    plans = run_planners(None, Config(), ["physics", "baseline"], num_angles=3)
    assert list(plans) == ["physics", "baseline"]
    assert calls == [("plan", "baseline", None), ("plan", "physics", 3)]
    assert [c.planner for c in plans["physics"]] == ["physics"] * 3
    calls.clear()
    assert list(run_planners(None, Config(), ["physics"], angles=[5])) == ["physics"]
    assert calls == [("plan", "baseline", None), ("plan", "physics", 1)]
    calls.clear()
    check_planners(Config(), ["physics"])
    assert calls == [("check", "physics"), ("check", "baseline")]


def test_a_single_angle_is_planned_alone_as_an_experiment_unit_plans_it():
    scene = load_shipped_scene("fig5_large_small")
    config = Config()
    index = 7
    alpha = float(approach_angles(config.baseline)[index])
    alone = baseline.plan_angle(baseline.prepare(scene, config.baseline), alpha, index)
    (got,) = run_planners(scene, config, ["baseline"], angles=[index])["baseline"]
    assert got.alpha == alpha and got.status == alone.status
    assert got.trajectory is not None and alone.trajectory is not None
    np.testing.assert_array_equal(got.trajectory.q, alone.trajectory.q)


def test_str_enums_serialise_as_the_strings_they_replace(tmp_path):
    assert CANDIDATE_STATUSES == tuple(s.value for s in CandidateStatus)
    assert OUTCOME_KINDS[0] == "success" and OUTCOME_KINDS[-1] == "planner_failure"
    candidate = Candidate(0.25, "ik_failed", "no IK")
    assert candidate.status is CandidateStatus.IK_FAILED and not candidate.ok
    data = candidate.to_data()
    assert type(data["status"]) is str and json.dumps(data["status"]) == '"ik_failed"'
    assert Candidate.from_data(data) == candidate
    outcome = Outcome("success", "grasped")
    assert outcome.kind is OutcomeKind.SUCCESS and outcome.kind == "success"
    assert type(outcome.to_data()["kind"]) is str
    assert Outcome.from_data(outcome.to_data()) == outcome
    assert f"{StopReason.SMALL_STEP:12}|" == "small_step  |"
    assert json.dumps({"stop": StopReason.CONVERGED}) == '{"stop": "converged"}'
    with pytest.raises(ValueError):
        Candidate(0.0, "lost")
    with pytest.raises(ValueError):
        Outcome("won", "")
    bad = tmp_path / "plan.json"
    bad.write_text(json.dumps({"format": "drake_clutter.plan/1", "candidates": [
        {"alpha": 0.0, "status": "lost"}]}))
    with pytest.raises(PlanFileError, match="candidates\\[0\\]"):
        load_plan(bad)


# ------------------------------------------------------------- each planner reads its own record


def test_each_planner_reads_its_own_record_and_ranks_by_it():

    push = get_planner("push")
    bent = {"chosen": "0.6/r1m2", "search": {"verdicts": {
        "0.6/r1m2": {"p_success": 0.75, "expected_grade": 0.5, "kinds": ["success"]}}}}
    record = push.record(bent)
    assert record.bent and record.label == "path 0.6/r1m2" and not record.fallback
    assert push.score(bent) == pytest.approx(-0.75 + 0.005)
    assert not push.record({"chosen": "0.6", "clear": ["0.6"]}).bent
    assert push.record({"chosen": "baseline"}).fallback
    assert push.score({}) is None  # nothing judged, nothing to rank by

    physics = get_planner("physics")
    staged = {"stages": {"full": {"cost_history": [5.0, 4.0], "term_history": {"c_vel": [1, 2]}},
                         "pre": {"cost_history": [9.0]}},
              "select": {"chosen": "pre", "objectives": {"pre": 3.0, "post": 2.0}}}
    record = physics.record(staged)
    assert record.chosen == "pre" and not record.bent and physics.score(staged) == 3.0
    assert record.histories()["full"]["term_history"] == {"c_vel": [1, 2]}

    baseline = get_planner("baseline")
    config = Config()
    details = {"c_static_hull": [1.0, 0.01], "c_vel": [2.0, 0.3], "max_penetration": 0.0}
    assert baseline.score(details, config) == pytest.approx(
        config.baseline.w_static_hull * 0.01 + config.baseline.w_vel * 0.3)
    assert baseline.record(details).max_penetration == 0.0 and baseline.score({}) is None


def test_each_planner_reads_its_own_planning_seconds():
    assert get_planner("push").plan_seconds({"plan": 12.5, "planner": {"search": 9.0}}) == 12.5
    assert get_planner("baseline").plan_seconds({}) is None
    stages = {"pre": 1.0, "sphere": 2.0, "full": 3.0, "post": 0.5, "worker_start": 40.0}
    assert get_planner("physics").plan_seconds({"plan": 99.0, "planner": stages}) == 6.5
    assert get_planner("physics").plan_seconds({"plan": 99.0}) is None
    assert get_planner("baseline").paper_row == "paper: baseline"
    assert get_planner("physics").paper_row == "paper: physics-aware"
    assert get_planner("push").paper_row is None


def test_the_push_planners_record_is_what_it_stores():
    from drake_clutter.planners.push.record import PushRecord

    searched = {"initialization": "baseline", "chosen": "0.6/r1m2", "budget": {"spent": False},
                "search": {"verdicts": {"0.6/r1m2": {"p_success": 0.5}}, "best_start": "0.6"},
                "recovered": {"status": "ik_failed", "reason": "start pose"}}
    clear = {"initialization": "baseline", "clear": ["0.7", "0.8"], "chosen": "0.7",
             "budget": {"spent": False}}
    # no start planned: the baseline's failed record kept beside what the budget cut
    failed = PushRecord.failed({"height": 0.07, "start_xyz": [0.5, 0.0, 0.8]},
                               {"spent": True}).to_details()
    assert failed == {"height": 0.07, "start_xyz": [0.5, 0.0, 0.8], "budget": {"spent": True}}
    assert PushRecord.from_details(failed).start == {"height": 0.07, "start_xyz": [0.5, 0.0, 0.8]}
    for details in (searched, clear, failed):
        assert PushRecord.from_details(details).to_details() == details


def test_both_stands_for_the_compared_planners_each_once_in_order():
    from drake_clutter.planners.registry import ALL_PLANNERS, COMPARED, named_planners

    assert named_planners([ALL_PLANNERS]) == COMPARED
    assert named_planners(["rearrange", ALL_PLANNERS, "baseline"]) == ("rearrange", *COMPARED)
    assert named_planners(["push"]) == ("push",)
