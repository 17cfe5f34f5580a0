"""The push planner's search: perturbations keep a member well formed; the pick and the veto
follow the judge in phi's verdicts (a scripted judge); a real search on a shipped scene
returns a judged path, seeded, and never fails the plan; the planner is registered."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from drake_clutter.common.config import Config, load_config
from drake_clutter.planners.baseline import plan_baseline
from drake_clutter.planners.budget import Deadline
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.phi_judge import PhiReading, PhiVerdict
from drake_clutter.planners.push import search as search_module
from drake_clutter.planners.push.family import PushPath, ViaPoint
from drake_clutter.planners.push.search import offsets, perturb, run_search
from drake_clutter.planners.registry import get_planner
from drake_clutter.scene import scenes

SMALL = ["push_search.samples=3", "push_search.rounds=2", "phi_judge.members=2",
         "phi_judge.veto_members=2", "push_search.elite=1", "push_search.perturbations=2"]


@pytest.fixture(scope="module")
def setting():
    scene = scenes.load_shipped_scene("fig6_push_sideways")
    (candidate,) = plan_baseline(scene, Config().baseline, alphas=[0.0])
    assert candidate.ok, candidate.reason
    return scene, candidate.trajectory, PlanningContext(scene, Config())


def _verdict(*kinds: str) -> PhiVerdict:
    return PhiVerdict(tuple(PhiReading(k, "") for k in kinds))


def test_a_perturbation_keeps_the_member_in_order_and_in_range():
    member = PushPath((ViaPoint(0.3, 0.4, 0.05, 0.0), ViaPoint(0.35, 0.5, -0.02, 0.01)), 0.6)
    search = replace(Config().push_search, jitter_progress=0.2, jitter_offset=0.02)
    rng = np.random.default_rng(0)
    moved = [perturb(rng, member, search) for _ in range(50)]
    for m in moved:
        knots = [v.knot for v in m.vias]
        assert knots == sorted(knots) and 0.02 <= knots[0] and knots[-1] <= 0.98
        assert all(0.02 <= v.progress <= 0.98 for v in m.vias) and 0.02 <= m.open_at <= 0.98
    assert len({m.vias[0].lateral for m in moved}) == 50
    again = perturb(np.random.default_rng(0), member, search)
    assert again == moved[0]
    assert perturb(rng, PushPath(member.vias), search).open_at == 0.0


def test_offsets_are_the_differences_from_the_parent():
    parent = PushPath((ViaPoint(0.3, 0.4, 0.05, 0.0), ViaPoint(0.35, 0.5, -0.02, 0.01)), 0.6)
    child = PushPath((ViaPoint(0.32, 0.37, 0.06, -0.01), ViaPoint(0.4, 0.5, -0.02, 0.03)), 0.5)
    progress, offset = offsets(child, parent)
    np.testing.assert_allclose(progress, [0.02, -0.03, 0.05, 0.0, -0.1], atol=1e-12)
    np.testing.assert_allclose(offset, [0.01, -0.01, 0.0, 0.02], atol=1e-12)
    assert offsets(PushPath(child.vias), PushPath(parent.vias))[0].size == 4  # no opening


def _nearness_judge(start_q, aim):
    """A scripted judge: every path fails to grasp, its margin how far its largest joint
    deviation from ``start_q`` is from ``aim`` (rad): a smooth score to climb."""
    def judge(scene, paths, times, config, pool=None, geometry=None, members=None,
              complete=True, deadline=None):
        return {n: PhiVerdict((PhiReading("failure_to_grasp", "", 0, abs(
            float(np.abs(q - start_q).max()) - aim)),)) for n, q in paths.items()}
    return judge


def test_the_cross_entropy_search_climbs_and_refits_its_spreads(setting, monkeypatch):
    scene, trajectory, context = setting
    monkeypatch.setattr(search_module, "judge_paths", _nearness_judge(trajectory.q, 0.15))
    config = load_config(None, [*SMALL, "push_search.method=cem", "push_search.samples=6",
                                "push_search.rounds=4", "push_search.elite=2",
                                "push_search.population=6", "phi_judge.veto_members=1",
                                "push_search.spread_floor_offset=0.004"])
    seen = []
    result = run_search(context.with_config(config), {"a": trajectory.q}, trajectory.times,
                        observe=lambda r, s, best: seen.append((r, s.elite())))
    record = result.record
    assert [r for r, _ in seen] == [0, 1, 2, 3]
    margins = {n: v["margin"] for n, v in record["verdicts"].items()}
    first = min(m for n, m in margins.items() if "/r0m" in n)
    assert margins[record["rounds"][-1]["best"]] < first  # later rounds came nearer
    spreads = [tuple(r["spread"]) for r in record["rounds"]]
    assert spreads[0] == (0.04, 0.015)  # round 1's elite are draws: no step to refit to
    assert len(set(spreads[1:])) > 1 and all(o >= 0.004 for _, o in spreads)
    assert sum(1 for n in margins if "/r1m" in n) == record["rounds"][1]["judged"] <= 6
    again = run_search(context.with_config(config), {"a": trajectory.q}, trajectory.times)
    assert again.record["verdicts"].keys() == record["verdicts"].keys()
    assert again.record["rounds"] == record["rounds"]


def test_the_veto_keeps_the_start_unless_the_pick_wins_on_unseen_members(setting, monkeypatch):
    scene, trajectory, context = setting
    config = load_config(None, SMALL)
    seen_members = []

    def scripted(wins_held_out):
        def judge(scene, paths, times, config, pool=None, geometry=None, members=None,
                  complete=True, deadline=None):
            seen_members.append(None if members is None else list(members))
            held_out = members is not None
            out = {}
            for name in paths:
                bent = "/" in name
                if not held_out:  # in the search's members every bent path reads success
                    out[name] = _verdict("success", "success") if bent else _verdict(
                        "failure_to_grasp", "kinematic_failure")
                else:
                    good = bent == wins_held_out
                    out[name] = _verdict("success", "failure_to_grasp") if good else _verdict(
                        "failure_to_grasp", "failure_to_grasp")
            return out
        return judge

    starts = {"a": trajectory.q, "b": trajectory.q.copy()}
    monkeypatch.setattr(search_module, "judge_paths", scripted(True))
    result = run_search(context.with_config(config), starts, trajectory.times)
    assert "/" in result.name and result.record["veto"]["wins"] is True
    assert result.record["pick"] == result.name and result.record["best_start"] == "a"
    assert seen_members[-1] == [2, 3]  # the held-out members follow the search's
    monkeypatch.setattr(search_module, "judge_paths", scripted(False))
    result = run_search(context.with_config(config), starts, trajectory.times)
    assert result.name == "a" and result.record["veto"]["wins"] is False
    assert "/" in result.record["pick"]
    np.testing.assert_array_equal(result.q, trajectory.q)


def test_a_start_that_reads_success_stops_the_search(setting, monkeypatch):
    scene, trajectory, context = setting
    monkeypatch.setattr(search_module, "judge_paths",
                        lambda scene, paths, *a, **k: {n: _verdict("success") for n in paths})
    result = run_search(context.with_config(load_config(None, SMALL)), {"a": trajectory.q},
                        trajectory.times)
    assert result.name == "a" and result.record["rounds"] == []
    assert result.record["counts"]["drawn"] == 0 and result.record["veto"] is None


def test_a_search_past_its_time_budget_starts_no_round(setting, monkeypatch):
    scene, trajectory, context = setting
    monkeypatch.setattr(search_module, "judge_paths", lambda scene, paths, *a, **k: {
        n: _verdict("failure_to_grasp") for n in paths})  # a judge that ignores the deadline
    config = load_config(None, SMALL)
    spent = Deadline(1.0e-9)
    result = run_search(context.with_config(config), {"a": trajectory.q}, trajectory.times,
                        deadline=spent)
    assert result.name == "a" and result.record["rounds"] == []
    assert result.record["stopped"] == "time_budget after 0 rounds"
    assert spent.record()["cut"] == ["search round 1"] and spent.record()["spent"]
    ample = Deadline(1.0e6)
    result = run_search(context.with_config(config), {"a": trajectory.q}, trajectory.times,
                        deadline=ample)
    assert len(result.record["rounds"]) == 2 and "stopped" not in result.record
    assert ample.record()["cut"] == [] and not ample.record()["spent"]


def test_paths_the_deadline_cut_are_left_out_and_with_no_start_the_first_returns(
        setting, monkeypatch):
    scene, trajectory, context = setting
    config = load_config(None, SMALL)
    starts = {"a": trajectory.q, "b": trajectory.q.copy()}
    monkeypatch.setattr(search_module, "judge_paths", lambda scene, paths, *a, **k: {
        n: _verdict("failure_to_grasp") for n in paths if n != "a"})  # "a" was cut
    result = run_search(context.with_config(config), starts, trajectory.times)
    assert result.record["best_start"] == "b" and "a" not in result.record["verdicts"]
    assert result.record["stopped"] == "time_budget while judging the starts"
    assert result.record["counts"]["unjudged"] == 1 and result.record["rounds"] == []
    monkeypatch.setattr(search_module, "judge_paths", lambda *a, **k: {})  # all cut
    result = run_search(context.with_config(config), starts, trajectory.times)
    assert result.name == "a" and result.record["best_start"] is None
    assert result.record["verdicts"] == {} and result.record["counts"]["unjudged"] == 2
    np.testing.assert_array_equal(result.q, trajectory.q)


def test_the_real_judge_steps_nothing_after_its_deadline(setting):
    import time

    from drake_clutter.planners.phi_judge import judge_paths

    scene, trajectory, context = setting
    geometry = context.arm()
    config = load_config(None, ["phi_judge.members=2", "dynamics.engine=mujoco"])
    paths = {"a": trajectory.q}
    tic = time.monotonic()
    assert judge_paths(scene, paths, trajectory.times, config, geometry,
                       deadline=time.monotonic()) == {}
    assert time.monotonic() - tic < 1.0  # no phi built, no knot stepped
    judged = judge_paths(scene, paths, trajectory.times, config, geometry,
                         deadline=time.monotonic() + 1.0e6)
    assert len(judged["a"].readings) == 2


def test_a_push_plan_past_its_budget_returns_the_baseline_path_and_says_so():
    planner = get_planner("push")
    scene = scenes.load_shipped_scene("fig6_push_sideways")
    config = load_config(None, [*SMALL, "push_search.time_budget=1.0e-6",
                                "push_search.clear_first=false"])
    (baseline,) = get_planner("baseline").plan(scene, config, angles=[3])
    (candidate,) = planner.plan(scene, config, angles=[3], start=[baseline])
    budget = candidate.details["budget"]
    assert budget["spent"] and budget["cut"][0] == "heights" and budget["budget"] == 1.0e-6
    assert candidate.details["chosen"] == "baseline" and candidate.ok
    assert candidate.details["search"]["stopped"] == "time_budget before a start was judged"
    np.testing.assert_array_equal(candidate.trajectory.q, baseline.trajectory.q)
    assert "P phi" in planner.table([candidate])


def test_a_real_search_returns_a_judged_path_and_is_seeded(setting):
    scene, trajectory, context = setting
    config = load_config(None, [*SMALL, "push_search.rounds=1", "push_search.samples=2"])
    first = run_search(context.with_config(config), {"0.5": trajectory.q}, trajectory.times)
    record = first.record
    assert record["counts"]["drawn"] == 2 and record["chosen"] == first.name
    assert set(record["verdicts"]) >= {"0.5", first.name}
    for verdict in record["verdicts"].values():
        assert len(verdict["kinds"]) == 2
        assert verdict["p_success"] == verdict["kinds"].count("success") / 2
    again = run_search(context.with_config(config), {"0.5": trajectory.q}, trajectory.times)
    assert again.name == first.name and again.record["verdicts"] == record["verdicts"]


def test_the_push_planner_is_registered_and_plans_every_angle():
    planner = get_planner("push")
    assert planner.starts_from == "baseline"
    scene = scenes.load_shipped_scene("fig6_push_sideways")
    config = load_config(None, [*SMALL, "push_search.rounds=1", "push_search.samples=1",
                                "starts.grasp_heights=[]", "starts.approach_offsets=[]"])
    (candidate,) = planner.plan(scene, config, angles=[3])
    assert candidate.planner == "push" and candidate.ok
    search = candidate.details["search"]
    assert search["chosen"] in search["verdicts"]
    grasped = any(k in ("success", "partial_success")
                  for k in search["verdicts"][search["chosen"]]["kinds"])
    assert candidate.details["chosen"] == (search["chosen"] if grasped else "baseline")
    if not grasped:  # the fallback: the baseline's own path
        baseline = get_planner("baseline").plan(scene, config, angles=[3])[0]
        np.testing.assert_array_equal(candidate.trajectory.q, baseline.trajectory.q)
    assert "search" in candidate.timings and "P phi" in planner.table([candidate])


def test_members_rolled_out_in_workers_read_the_same(setting):
    from drake_clutter.phi.workers import WorkerPool
    from drake_clutter.planners.phi_judge import judge_paths

    scene, trajectory, context = setting
    geometry = context.arm()
    config = load_config(None, ["phi_judge.members=2", "dynamics.engine=mujoco"])
    paths = {"a": trajectory.q}
    serial = judge_paths(scene, paths, trajectory.times, config, geometry=geometry)
    pool = WorkerPool(2)
    try:
        spread = judge_paths(scene, paths, trajectory.times, config, geometry, pool)
    finally:
        pool.close()
    assert spread["a"].to_data() == serial["a"].to_data()


def test_a_clear_straight_start_is_returned_without_a_search():
    planner = get_planner("push")
    scene = scenes.load_shipped_scene("default_bookshelf")
    config = load_config(None, [*SMALL, "starts.grasp_heights=[]"])
    (clear,) = planner.plan(scene, config, angles=[10])  # its straight path keeps off the boxes
    assert clear.details["clear"] == ["0.5"] and clear.details["chosen"] == "0.5"
    assert "search" not in clear.details and "search" not in clear.timings
    (blocked,) = planner.plan(scene, config, angles=[2])  # its straight path enters a box
    assert "clear" not in blocked.details and blocked.details["search"]["verdicts"]
    off = load_config(None, [*SMALL, "starts.grasp_heights=[]", "push_search.clear_first=false",
                             "push_search.rounds=1", "push_search.samples=1"])
    (searched,) = planner.plan(scene, off, angles=[10])
    assert "search" in searched.details


def test_the_plan_command_compares_the_push_planner_with_the_baseline(tmp_path, capsys):
    from drake_clutter.cli import main
    from drake_clutter.trajectory import load_plan

    out = tmp_path / "plan.json"
    small = [f"--set={s}" for s in (*SMALL, "push_search.rounds=1", "push_search.samples=1",
                                      "starts.grasp_heights=[]", "starts.approach_offsets=[]")]
    code = main(["plan", "fig6_push_sideways", "--planner", "both", "--angles", "1", "--out",
                 str(out), *small])
    assert code == 0
    _, candidates, doc = load_plan(out)
    assert [c.planner for c in candidates] == ["baseline", "push"]
    assert candidates[0].alpha == candidates[1].alpha and doc["planner"] == "both"
    assert "P phi" in capsys.readouterr().out


@pytest.mark.parametrize("kinds, fallback, returned", [
    (["failure_to_grasp", "objects_falling"], True, "baseline"),
    (["failure_to_grasp", "partial_success"], True, "0.5/r0m0"),
    (["failure_to_grasp", "objects_falling"], False, "0.5/r0m0")])
def test_a_pick_that_reads_no_grasp_falls_back_to_the_baseline_path(kinds, fallback, returned,
                                                                     setting, monkeypatch):
    from drake_clutter.planners.push import planner as planner_module
    from drake_clutter.planners.push.search import SearchResult

    scene, trajectory, _ = setting
    bent = trajectory.q + 0.01
    record = {"chosen": "0.5/r0m0", "verdicts": {"0.5/r0m0": {"kinds": kinds}}}
    monkeypatch.setattr(planner_module, "run_search",
                        lambda *args, **kw: SearchResult("0.5/r0m0", bent, record))
    config = load_config(None, ["starts.grasp_heights=[]", "starts.approach_offsets=[]",
                                "push_search.clear_first=false",
                                f"push_search.fallback={str(fallback).lower()}"])
    (baseline,) = plan_baseline(scene, config.baseline, alphas=[0.0])
    context = PlanningContext(scene, config)
    candidate = planner_module.push_candidate(context, baseline, 0)
    assert candidate.details["chosen"] == returned
    assert candidate.details["search"]["chosen"] == "0.5/r0m0"
    expected = baseline.trajectory.q if returned == "baseline" else bent
    np.testing.assert_array_equal(candidate.trajectory.q, expected)


def test_the_push_planner_ranks_its_candidates_by_p_success_in_phi():
    from drake_clutter.planners.selection import selection_score

    def details(chosen, p, grade):
        return {"chosen": chosen, "search": {"chosen": "0.5/r0m0", "verdicts": {
            "0.5/r0m0": {"p_success": p, "expected_grade": grade}}}}

    clear = selection_score("push", {"clear": ["0.5"], "chosen": "0.5"})
    searched = selection_score("push", details("0.5/r0m0", 0.75, 0.5))
    failing = selection_score("push", details("0.5/r0m0", 0.0, 2.0))
    fallback = selection_score("push", details("baseline", 0.0, 2.0))
    assert clear < searched < failing < fallback
