"""Reports: Tables III and IV and the Fig. 9 PNGs from a small store (synthetic rows, real code)."""

from __future__ import annotations

import csv
import struct

import numpy as np
import pytest

from drake_clutter.cli import main
from drake_clutter.common.config import ReportConfig
from drake_clutter.experiments.candidates import (
    candidate_ceiling,
    candidate_rows,
    markdown_candidates,
)
from drake_clutter.experiments.paired import (
    bootstrap_interval,
    configuration_comparison,
    held_out_choice_gain,
    held_out_gain,
    markdown_paired,
    paired_comparison,
    paired_rows,
    scene_contributions,
)
from drake_clutter.experiments.plan_statistics import largest_kink, smoothness
from drake_clutter.experiments.report import (
    PAPER_TABLE_III,
    selected_plan_success,
    selected_rows,
    selection_score,
    table_iii,
    table_iv,
    table_levels,
    write_report,
)
from drake_clutter.experiments.store import Store
from drake_clutter.planners.physics.record import markdown_stages, stage_statistics
from drake_clutter.planners.registry import get_planner

# (env, objects, seed) -> per planner, the outcome kinds of its angles.
SCENES = {
    ("bookshelf", 1, 0): {"baseline": ["success", "failure_to_grasp"],
                          "physics": ["success", "success"]},
    ("bookshelf", 10, 0): {"baseline": ["partial_success", "planner_failure"],
                           "physics": ["success", "planner_failure"]},
    ("fridge", 2, 0): {"baseline": ["kinematic_failure", "objects_falling"],
                       "physics": ["partial_success", "kinematic_failure"]},
    ("fridge", 2, 1): {"baseline": ["failure_to_grasp", "failure_to_grasp"],
                       "physics": ["failure_to_grasp", "success"]},
    ("fridge", 8, 0): {"baseline": ["planner_failure", "planner_failure"],
                       "physics": ["planner_failure", "planner_failure"]},
}


def _fill(db):
    with Store(db) as store:
        for (env, n, seed), planners in SCENES.items():
            for planner, kinds in planners.items():
                for angle, kind in enumerate(kinds):
                    unit = {"scene": f"{env}_n{n:02d}_s{seed}", "planner": planner,
                            "angle": angle, "config_hash": "abc", "config_name": "default",
                            "kind": env, "num_objects": n}
                    stages = {"pre": 1.0, "sphere": 2.0 * n, "full": 3.0, "post": 0.5}
                    timings = {"plan": 0.3 + n, "eval": 0.4,
                               "planner": stages if planner == "physics" else {"ik": 0.1}}
                    if kind == "planner_failure":
                        timings["planner"] = {}
                    store.put(unit, {"alpha": 0.1 * angle, "outcome": {"kind": kind},
                                     "plan": {"status": "ok"}, "timings": timings, "error": ""})
        return store.rows()


def _by(table, **match):
    return [r for r in table if all(r[k] == v for k, v in match.items())]


def test_table_iii_scene_scores(tmp_path):
    rows = _fill(tmp_path / "r.db")
    t3 = table_iii(rows)
    base_shelf = _by(t3, planner="baseline", environment="bookshelf")[0]
    # Bookshelf baseline: one scene success, one partial -> 100% (50%), success 50%.
    assert base_shelf["scenes"] == 2 and base_shelf["success_pct"] == 50.0
    assert base_shelf["partial_pct"] == 50.0 and base_shelf["success_or_partial_pct"] == 100.0
    base_fridge = _by(t3, planner="baseline", environment="fridge")[0]
    assert base_fridge["scenes"] == 3 and base_fridge["success_or_partial_pct"] == 0.0
    phys_all = _by(t3, planner="physics", environment="aggregate")[0]
    # Physics: bookshelf 2 successes, fridge s0 partial, s1 success, n8 failure.
    assert phys_all["scenes"] == 5 and phys_all["success_pct"] == pytest.approx(60.0)
    assert phys_all["partial_pct"] == pytest.approx(20.0)
    paper = PAPER_TABLE_III["paper: physics-aware"]["aggregate"][0]
    assert phys_all["paper_success_or_partial_pct"] == paper


def test_table_iv_counts_trajectories_only(tmp_path):
    t4 = table_iv(_fill(tmp_path / "r.db"))
    base = {r["outcome"]: r for r in _by(t4, planner="baseline")}
    # Baseline: 10 angles, 3 without a trajectory, 7 trajectories.
    assert base["planner_failure"]["count"] == 3 and base["planner_failure"]["pct"] is None
    assert base["failure_to_grasp"]["count"] == 3
    assert base["failure_to_grasp"]["pct"] == pytest.approx(300 / 7)
    assert sum(r["pct"] for k, r in base.items() if k != "planner_failure") == pytest.approx(100)
    assert base["success"]["paper_pct"] == 36.9


def test_levels_table_splits_tables_iii_and_iv_by_clutter_level(tmp_path):
    levels = table_levels(_fill(tmp_path / "r.db"))
    fridge2 = _by(levels, planner="physics", environment="fridge", num_objects=2)[0]
    # Physics at fridge 2: s0 partial (partial, kinematic), s1 success (failure, success).
    assert fridge2["scenes"] == 2 and fridge2["success_pct"] == 50.0
    assert fridge2["partial_pct"] == 50.0 and fridge2["failure_pct"] == 0.0
    assert fridge2["trajectories"] == 4 and fridge2["trajectory_success_pct"] == 25.0
    assert fridge2["trajectory_partial_success_pct"] == 25.0
    assert fridge2["trajectory_failure_to_grasp_pct"] == 25.0
    fridge8 = _by(levels, planner="baseline", environment="fridge", num_objects=8)[0]
    assert fridge8["failure_pct"] == 100.0 and fridge8["trajectories"] == 0
    # Every level of the store, once per planner; the shares of each level sum to 100.
    assert len(levels) == 2 * 4
    for r in levels:
        assert r["success_pct"] + r["partial_pct"] + r["failure_pct"] == pytest.approx(100)


def _png_size(path) -> tuple[int, int]:
    data = path.read_bytes()
    assert data[:8] == b"\x89PNG\r\n\x1a\n" and data[12:16] == b"IHDR"
    return struct.unpack(">II", data[16:24])


def test_report_has_both_tables_and_four_figures(tmp_path, capsys):
    _fill(tmp_path / "r.db")
    out = tmp_path / "report"
    assert main(["report", str(tmp_path / "r.db"), "--out", str(out)]) == 0
    assert "20 rows" in capsys.readouterr().out
    text = (out / "report.md").read_text()
    assert "Table III" in text and "Table IV" in text and "76.7% (8.3%)" in text
    assert "48.7%" in text  # the paper's Table IV beside ours
    assert "phi stages (Sec. V)" in text  # physics plans: their stages' table
    rows = [r for r in _fill(tmp_path / "b.db") if r["planner"] == "baseline"]
    write_report(rows, tmp_path / "baseline_only")
    assert "phi stages" not in (tmp_path / "baseline_only" / "report.md").read_text()
    with (out / "table3.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 2 * 3
    with (out / "table4.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 2 * 6
    # The four figures: Fig. 9a, 9b, 9c and the three panels together; their points in CSV.
    with (out / "fig9.csv").open() as f:
        points = list(csv.DictReader(f))
    assert {(p["planner"], p["environment"], p["num_objects"]) for p in points} == {
        (pl, env, str(n)) for pl in ("baseline", "physics") for env, n, _ in SCENES}
    from matplotlib.image import imread

    for name in ("fig9a.png", "fig9b.png", "fig9c.png", "fig9.png"):
        width, height = _png_size(out / name)
        assert width >= 400 and height >= 300
        pixels = imread(out / name)[..., :3]
        colours = np.unique(pixels.reshape(-1, 3).round(2), axis=0)
        assert len(colours) > 20  # lines, markers, text: not a blank canvas
        assert (pixels < 0.9).any(axis=-1).mean() > 0.01  # some ink on the page


def test_paired_comparison_matches_physics_with_the_baseline_of_its_initialization(tmp_path):
    rows = _fill(tmp_path / "r.db")
    pairs = paired_rows(rows)
    assert len(pairs) == 10  # every physics angle has its baseline angle
    verdicts = {(p["scene"], p["angle"]): p["verdict"] for p in pairs}
    assert verdicts[("bookshelf_n01_s0", 1)] == "better"  # success against failure to grasp
    assert verdicts[("fridge_n02_s0", 1)] == "worse"  # kinematic failure against falling
    assert verdicts[("fridge_n08_s0", 0)] == "same"  # neither planned
    (summary,) = paired_comparison(rows)
    assert (summary["pairs"], summary["better"], summary["same"], summary["worse"]) == (10, 4, 5, 1)
    assert summary["compared_kinematic_failures"] == 1 == summary["baseline_kinematic_failures"]
    assert summary["sign_test_p"] == pytest.approx(0.375)  # 4 of 5 untied pairs, two-sided
    out = tmp_path / "report"
    write_report(rows, out)
    assert "| default/physics | 10 | 4 | 5 | 1 | 1 / 1 | 0.375 |" in (out / "report.md").read_text()
    with (out / "paired.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 10


def test_paired_grade_counts_disturbed_boxes_within_a_class():
    def row(planner, kind, tipped, config="c"):
        boxes = [{"tipped": i < tipped, "fallen": False} for i in range(4)]
        return {"config_name": config, "scene": "s", "angle": 0, "planner": planner,
                "kind": kind, "outcome": {"kind": kind, "boxes": boxes}}

    def verdict(base, phys):
        return paired_rows([row("baseline", *base), row("physics", *phys)])[0]["verdict"]

    assert verdict(("objects_falling", 3), ("failure_to_grasp", 1)) == "better"
    assert verdict(("failure_to_grasp", 1), ("failure_to_grasp", 1)) == "same"
    assert verdict(("failure_to_grasp", 0), ("kinematic_failure", 0)) == "worse"
    # A baseline of another configuration is not this physics row's initialization.
    assert paired_rows([row("baseline", "success", 0, "a"), row("physics", "success", 0)]) == []
    (summary,) = paired_comparison([row("baseline", "success", 0), row("physics", "success", 0)])
    assert summary["same"] == 1 and summary["sign_test_p"] is None
    # Every planner is paired with the baseline under its own name.
    pairs = paired_rows([row("baseline", "failure_to_grasp", 0), row("physics", "success", 0),
                         row("push", "success", 0)])
    assert [(p["configuration"], p["verdict"]) for p in pairs] == [("c/physics", "better"),
                                                                   ("c/push", "better")]


def test_paired_differences_have_a_seeded_interval_and_a_signed_rank_p(tmp_path):
    rows = _fill(tmp_path / "r.db")
    (summary,) = paired_comparison(rows)
    # Nominal rows: P(success) is 1 or 0; physics gains a success on 3 of the 10 pairs.
    assert summary["p_success_diff"] == pytest.approx(0.3)
    assert summary["p_success_ci_low"] <= 0.3 <= summary["p_success_ci_high"]
    assert 0.0 <= summary["p_success_ci_low"] and summary["p_success_ci_high"] <= 0.6 + 1e-12
    assert summary["p_success_wilcoxon_p"] == pytest.approx(0.25)  # 3 of 3 untied pairs up
    assert paired_comparison(rows) == [summary]  # the same seed, the same interval
    wider = paired_comparison(rows, ReportConfig(confidence=0.99))[0]
    assert wider["p_success_ci_low"] <= summary["p_success_ci_low"]
    assert bootstrap_interval([0.25] * 7, ReportConfig()) == (0.25, 0.25)
    narrow = bootstrap_interval(np.tile([0.0, 1.0], 200), ReportConfig())
    broad = bootstrap_interval([0.0, 1.0] * 5, ReportConfig())
    assert broad[0] < narrow[0] < 0.5 < narrow[1] < broad[1]


def test_scene_contributions_split_the_mean_difference_among_the_scenes(tmp_path, capsys):
    rows = _fill(tmp_path / "r.db")
    pairs = paired_rows(rows)
    shares = scene_contributions(pairs, top=10)
    (summary,) = paired_comparison(rows)
    # Three scenes gain one success each; the others' P(success) does not move: left out.
    assert sum(r["p_success_share"] for r in shares) == pytest.approx(summary["p_success_diff"])
    assert {r["scene"] for r in shares} == {"bookshelf_n01_s0", "bookshelf_n10_s0",
                                            "fridge_n02_s1"}
    assert all(r["p_success_share"] == pytest.approx(1 / len(pairs)) for r in shares)
    fridge = _by(shares, scene="fridge_n02_s1")[0]
    assert (fridge["pairs"], fridge["differing"]) == (2, 1)
    assert fridge["changes"] == "angle 1: failure_to_grasp 0.00 -> success 1.00"
    assert len(scene_contributions(pairs, top=2)) == 2
    out = tmp_path / "report"
    assert main(["report", str(tmp_path / "r.db"), "--out", str(out)]) == 0
    assert "## Where the P(success) difference lies" in (out / "report.md").read_text()
    with (out / "contributions.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 3
    assert main(["report", str(tmp_path / "r.db"), "--out", str(tmp_path / "never"),
                 "--set", "report.contribution_scenes=0"]) == 2
    assert "report.contribution_scenes" in capsys.readouterr().err


def test_scene_contributions_rank_by_magnitude_and_keep_losses():
    def pair(scene, angle, base, phys):
        return {"configuration": "c", "scene": scene, "angle": angle, "baseline": "b",
                "compared": "p", "baseline_p_success": base, "compared_p_success": phys}
    pairs = [pair("a", 0, 1.0, 0.0), pair("a", 1, 0.25, 0.0), pair("b", 0, 0.0, 0.5),
             pair("c", 0, 0.5, 0.5), pair("d", 0, 0.0, 0.1), pair("d", 1, 0.0, 0.2),
             pair("d", 2, 0.3, 0.0)]  # d: 0.1 + 0.2 - 0.3, not 0.0 in floating point
    shares = scene_contributions(pairs, top=5)
    assert [r["scene"] for r in shares] == ["a", "b"]  # |-1.25 / 7| before |+0.5 / 7|; d nets 0
    assert [r["p_success_share"] for r in shares] == pytest.approx([-1.25 / 7, 0.5 / 7])


def _robust_row(planner, scene, angle, kinds):
    grades = [[{"success": 0, "partial_success": 1}.get(k, 2), 0] for k in kinds]
    robust = {"seed": 0, "kinds": kinds, "grades": grades,
              "p_success": kinds.count("success") / len(kinds),
              "p_success_or_partial": sum(k in ("success", "partial_success") for k in kinds)
              / len(kinds), "expected_grade": sum(g[0] for g in grades) / len(kinds)}
    return {"config_name": "c", "scene": scene, "angle": angle, "planner": planner,
            "env": "bookshelf", "num_objects": 5, "kind": kinds[0],
            "outcome": {"kind": kinds[0], "robust": robust}, "timings": {}}


def test_robust_columns_take_each_scenes_best_angle_and_every_replay():
    rows = [_robust_row("baseline", "a", 0, ["success", "failure_to_grasp", "success", "success"]),
            _robust_row("baseline", "a", 1, ["failure_to_grasp"] * 3 + ["success"]),
            _robust_row("baseline", "b", 0, ["partial_success"] * 2 + ["failure_to_grasp"] * 2),
            _robust_row("physics", "a", 0, ["success"] * 4),
            _robust_row("physics", "a", 1, ["success"] * 2 + ["failure_to_grasp"] * 2),
            _robust_row("physics", "b", 0, ["success", "partial_success"] * 2)]
    base = _by(table_iii(rows), planner="baseline", environment="bookshelf")[0]
    assert base["robust_success_pct"] == pytest.approx(100 * (0.75 + 0.0) / 2)
    assert base["robust_success_or_partial_pct"] == pytest.approx(100 * (0.75 + 0.5) / 2)
    t4 = {r["outcome"]: r for r in _by(table_iv(rows), planner="baseline")}
    assert t4["success"]["robust_pct"] == pytest.approx(100 * 4 / 12)
    assert t4["partial_success"]["robust_pct"] == pytest.approx(100 * 2 / 12)
    (summary,) = paired_comparison(rows)
    assert summary["p_success_diff"] == pytest.approx(((1 - .75) + (.5 - .25) + (.5 - 0)) / 3)
    # expected grades, physics - baseline: a0 0 - 0.5, a1 1.0 - 1.5, b0 0.5 - 1.5
    assert summary["expected_grade_diff"] == pytest.approx((-0.5 - 0.5 - 1.0) / 3)


def test_the_selection_ceiling_takes_the_better_plan_of_each_pair():
    rows = [_robust_row("baseline", "a", 0, ["success"] * 3 + ["failure_to_grasp"]),
            _robust_row("physics", "a", 0, ["success"] + ["failure_to_grasp"] * 3),
            _robust_row("baseline", "b", 0, ["failure_to_grasp"] * 4),
            _robust_row("physics", "b", 0, ["success"] * 2 + ["failure_to_grasp"] * 2)]
    (summary,) = paired_comparison(rows)
    # Scene a: the baseline is better (no gain); scene b: physics gains 0.5.
    assert summary["p_success_diff"] == pytest.approx(((.25 - .75) + (.5 - 0)) / 2)
    assert summary["p_success_ceiling"] == pytest.approx((0 + .5) / 2)
    assert summary["p_success_ceiling_ci_low"] == pytest.approx(0.0)
    assert summary["p_success_ceiling_ci_high"] == pytest.approx(0.5)
    assert "+0.250 [+0.000, +0.500]" in markdown_paired([summary])


def test_the_held_out_ceiling_picks_on_half_the_replays_and_reads_the_other_half():
    # Physics succeeds in replays 0 and 2 (both even), the baseline in 1 and 3 (both odd):
    # each half picks the plan that wins there and reads the other half, where it loses.
    physics = ["success", "failure_to_grasp"] * 2
    baseline = ["failure_to_grasp", "success"] * 2
    assert held_out_gain(physics, baseline) == pytest.approx(-0.5)
    # A plan better in every replay keeps its whole gain; a tie is read as the baseline.
    assert held_out_gain(["success"] * 4, ["failure_to_grasp"] * 4) == pytest.approx(1.0)
    assert held_out_gain(["success"] * 4, ["success"] * 4) == 0.0
    # One replay, or replay counts that differ: no halves.
    assert held_out_gain(["success"], ["failure_to_grasp"]) is None
    assert held_out_gain(["success"] * 4, ["success"] * 2) is None
    rows = [_robust_row("baseline", "a", 0, baseline), _robust_row("physics", "a", 0, physics),
            _robust_row("baseline", "b", 0, ["failure_to_grasp"] * 4),
            _robust_row("physics", "b", 0, ["success"] * 4)]
    (summary,) = paired_comparison(rows)
    assert summary["p_success_ceiling"] == pytest.approx((0.0 + 1.0) / 2)
    assert summary["held_out_ceiling"] == pytest.approx((-0.5 + 1.0) / 2)
    assert "+0.250 [-0.500, +1.000]" in markdown_paired([summary])


def test_the_held_out_ceiling_is_blank_for_plans_judged_once():
    rows = [{"config_name": "c", "scene": "a", "angle": 0, "planner": planner, "kind": kind,
             "outcome": {"kind": kind}}
            for planner, kind in (("baseline", "failure_to_grasp"), ("physics", "success"))]
    (summary,) = paired_comparison(rows)
    assert summary["held_out_ceiling"] is None
    assert markdown_paired([summary]).splitlines()[-1].endswith("| - |")


def test_a_report_setting_that_makes_no_sense_names_its_field(tmp_path, capsys):
    _fill(tmp_path / "r.db")
    out = tmp_path / "never"
    assert main(["report", str(tmp_path / "r.db"), "--out", str(out),
                 "--set", "report.confidence=1.5"]) == 2
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and "report.confidence" in err and not out.exists()


def _stage(iterations, entries):
    log = [{"alpha": a, "actual": act, "predicted": pred} for a, act, pred in entries]
    return {"iterations": iterations, "log": log}


def test_stage_statistics_count_accepting_stages_ratios_and_choices():
    """Three physics plans: the sphere stage accepted steps in two (ratios 0.5, 1, 2 and 4),
    the full stage in one (ratio 1; a failed search logs alpha 0 and is not a step); the plan
    was the post-processed path twice and the baseline's once. Rows without details count as
    stages not run."""
    plans = [{"sphere": _stage(2, [(1.0, 1.0, 2.0), (0.5, 2.0, 2.0)]),
              "full": _stage(0, [(0.0, 0.0, 0.0)]), "chosen": "post"},
             {"sphere": _stage(2, [(1.0, 4.0, 2.0), (1.0, 4.0, 1.0)]),
              "full": _stage(1, [(0.25, 3.0, 3.0), (0.0, 0.0, 0.0)]), "chosen": "baseline"},
             {"sphere": _stage(0, []), "full": _stage(0, []), "chosen": "post"}]
    details = [{"stages": {"sphere": p["sphere"], "full": p["full"]},
                "select": {"chosen": p["chosen"]}} for p in plans] + [{}]
    sphere, full = stage_statistics({"defaults": details})
    assert (sphere["stage"], sphere["stages"], sphere["accepting"]) == ("sphere", 3, 2)
    assert sphere["accepted_steps"] == 4 and sphere["ratio_median"] == pytest.approx(1.5)
    assert (full["stages"], full["accepting"], full["accepted_steps"]) == (3, 1, 1)
    assert full["ratio_median"] == 1.0 and full["accepting_pct"] == pytest.approx(100 / 3)
    assert (sphere["chosen_post"], sphere["chosen_pre"], sphere["chosen_baseline"]) == (2, 0, 1)
    text = markdown_stages([sphere, full])
    section = get_planner("physics").report_section({"defaults": details})
    assert section.csv_name == "stages.csv" and section.table == [sphere, full]
    assert text in "\n".join(section.lines)
    assert get_planner("push").report_section({"defaults": details}) is None
    assert "| defaults | sphere | 3 | 2 (66.7%) | 4 | 1.50 [0.88, 2.50] | 2 / 0 / 1 / 0 |" in text


def _scored(row, score):
    """A robust row with the record its planner ranks it by (see `selection_score`)."""
    if row["planner"] == "baseline":
        details = {"c_static_hull": [1.0, score[0]], "c_vel": [1.0, score[1]]}
    else:
        details = {"select": {"chosen": "post", "objectives": {"post": score, "pre": 0.0}}}
    return {**row, "plan": {"trajectory": {"q": []}, "details": details}}


def test_selected_plan_success_takes_each_planners_own_first_choice():
    """Scene a: the baseline ranks angle 1 first (kinematic cost 80 x 0 + 0.2 against 80 x
    0.01 + 0.1), the physics planner angle 0 (objective 5 < 7); scene b: one angle each, the
    physics row without a plan is never selected."""
    rows = [_scored(_robust_row("baseline", "a", 0, ["success"] * 4), (0.01, 0.1)),
            _scored(_robust_row("baseline", "a", 1, ["failure_to_grasp"] * 3 + ["success"]),
                    (0.0, 0.2)),
            _scored(_robust_row("baseline", "b", 0, ["success", "failure_to_grasp"] * 2),
                    (0.0, 1.0)),
            _scored(_robust_row("physics", "a", 0, ["success"] * 2 + ["partial_success"] * 2),
                    5.0),
            _scored(_robust_row("physics", "a", 1, ["success"] * 4), 7.0),
            _robust_row("physics", "b", 0, ["success"] * 4)]
    assert selection_score(rows[0]) == pytest.approx(80 * 0.01 + 0.1)
    assert selection_score(rows[3]) == 5.0 and selection_score(rows[5]) is None
    chosen = selected_rows(rows)
    assert chosen[("c", "baseline", "a")]["angle"] == 1
    assert chosen[("c", "physics", "a")]["angle"] == 0
    assert chosen[("c", "physics", "b")] is None
    (summary,) = selected_plan_success(rows)
    assert summary["baseline_selected"] == pytest.approx((0.25 + 0.5) / 2)
    assert summary["compared_selected"] == pytest.approx((0.5 + 0.0) / 2)
    assert summary["compared_best_angle"] == pytest.approx((1.0 + 1.0) / 2)
    assert summary["selected_diff"] == pytest.approx(0.25 / 2 - 0.5 / 2)
    # two scenes, differences +0.25 and -0.5: the resampled means are -0.5, -0.125 and +0.25,
    # and each end has a quarter of the resamples, so the 95 % interval spans them all
    assert (summary["selected_ci_low"], summary["selected_ci_high"]) == pytest.approx(
        (-0.5, 0.25))


def test_selected_plan_success_pairs_the_push_planner_with_the_baseline():
    """The push planner ranks its candidates by minus P(success) in phi (a clear start -1):
    scene a's clear angle 1 is chosen; the row is named "<configuration>/push"."""
    def push(angle, kinds, details):
        row = _robust_row("push", "a", angle, kinds)
        return {**row, "plan": {"trajectory": {"q": []}, "details": details}}

    rows = [_scored(_robust_row("baseline", "a", 0, ["failure_to_grasp"] * 4), (0.0, 0.1)),
            _scored(_robust_row("baseline", "a", 1, ["success"] * 4), (0.0, 0.2)),
            push(0, ["failure_to_grasp"] * 4,
                 {"chosen": "0.5/r0m1", "search": {"verdicts": {"0.5/r0m1": {
                     "p_success": 0.75, "expected_grade": 0.5}}}}),
            push(1, ["success"] * 3 + ["partial_success"], {"chosen": "0.6", "clear": ["0.6"]})]
    chosen = selected_rows(rows)
    assert chosen[("c", "push", "a")]["angle"] == 1
    assert chosen[("c", "baseline", "a")]["angle"] == 0
    (summary,) = selected_plan_success(rows)
    assert summary["configuration"] == "c/push"
    assert summary["compared_selected"] == pytest.approx(0.75)
    assert summary["baseline_selected"] == 0.0 and summary["selected_diff"] == pytest.approx(0.75)


def _fill_two_configurations(db) -> list[dict]:
    """The physics planner in two configurations over the same initializations: 'plain'
    (failure to grasp, success, kinematic failure) and 'search' (success, success, failure to
    grasp), the baseline once per configuration."""
    kinds = {"plain": ["failure_to_grasp", "success", "kinematic_failure"],
             "search": ["success", "success", "failure_to_grasp"]}
    with Store(db) as store:
        for config, physics in kinds.items():
            for angle, kind in enumerate(physics):
                for planner, k in (("physics", kind), ("baseline", "failure_to_grasp")):
                    unit = {"scene": "fig5", "planner": planner, "angle": angle,
                            "config_hash": config, "config_name": config, "kind": "bookshelf",
                            "num_objects": 3}
                    store.put(unit, {"alpha": 0.1 * angle, "outcome": {"kind": k},
                                     "plan": {"status": "ok"}, "timings": {}, "error": ""})
        return store.rows()


@pytest.mark.filterwarnings("ignore:No artists with labels")  # no fridge scene: empty Fig. 9b
def test_configurations_are_compared_on_the_same_initializations(tmp_path, capsys):
    rows = _fill_two_configurations(tmp_path / "c.db")
    (summary,) = configuration_comparison(rows, "plain")
    assert summary["configuration"] == "search/physics vs plain"
    assert (summary["pairs"], summary["better"], summary["same"], summary["worse"]) == (3, 2, 1, 0)
    assert summary["p_success_diff"] == pytest.approx(1 / 3)  # search minus plain
    assert summary["compared_kinematic_failures"] == 0
    assert summary["baseline_kinematic_failures"] == 1  # plain's
    assert configuration_comparison(rows, "search")[0]["p_success_diff"] == pytest.approx(-1 / 3)
    out = tmp_path / "report"
    assert main(["report", str(tmp_path / "c.db"), "--out", str(out)]) == 0
    text = (out / "report.md").read_text()
    assert "against each other" in text and "search/physics vs plain" in text  # first: reference
    with (out / "configurations.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 3
    assert main(["report", str(tmp_path / "c.db"), "--out", str(out), "--against", "search"]) == 0
    assert "plain/physics vs search" in (out / "report.md").read_text()
    assert main(["report", str(tmp_path / "c.db"), "--out", str(out), "--against", "nope"]) == 2
    err = capsys.readouterr().err.strip().splitlines()
    assert len(err) == 1 and "--against" in err[0] and "plain, search" in err[0]


def test_a_store_with_one_physics_configuration_has_no_configuration_table(tmp_path):
    _fill(tmp_path / "r.db")
    out = tmp_path / "report"
    assert main(["report", str(tmp_path / "r.db"), "--out", str(out)]) == 0
    assert "against each other" not in (out / "report.md").read_text()
    assert not (out / "configurations.csv").exists()


def test_smoothness_reads_each_plans_largest_kink_per_configuration_and_planner():
    t = np.linspace(0.0, 1.0, 30)[:, None]
    line = np.hstack([np.tile(t, (1, 7)), np.full((30, 1), 0.09)])  # straight in joint space
    kinked = line.copy()
    kinked[10, 3] += 0.2  # one knot 0.2 rad off: second differences 0.2, -0.4, 0.2
    kinked[20, 7] += 0.05  # the gripper does not count
    assert largest_kink(line) == pytest.approx(0.0, abs=1e-12)
    assert largest_kink(kinked) == pytest.approx(0.4)
    assert largest_kink(line[:2]) == 0.0

    def row(planner, q):
        return {"config_name": "default", "planner": planner,
                "plan": {"trajectory": {"q": q.tolist()}}}

    rows = [row("baseline", line), row("physics", line), row("physics", kinked),
            {"config_name": "default", "planner": "physics", "plan": None}]
    table = {r["planner"]: r for r in smoothness(rows)}
    assert table["baseline"]["plans"] == 1 and table["baseline"]["kink_max"] < 1e-12
    assert table["physics"]["plans"] == 2
    assert table["physics"]["kink_median"] == pytest.approx(0.2)
    assert table["physics"]["kink_max"] == pytest.approx(0.4)


def _candidate(config, scene, angle, kinds):
    return {**_robust_row("baseline", scene, angle, kinds), "config_name": config}


def test_the_candidates_ceiling_picks_among_all_configurations_of_a_planner():
    fail, ok = "failure_to_grasp", "success"
    rows = [  # initialization a: h2 wins on the even replays, h3 on the odd ones
        _candidate("h1", "a", 0, [fail] * 4), _candidate("h2", "a", 0, [ok, fail, ok, fail]),
        _candidate("h3", "a", 0, [fail, ok, fail, ok]),
        # b: h3 better in every replay; h2 missing there
        _candidate("h1", "b", 0, [fail] * 4), _candidate("h3", "b", 0, [ok] * 4),
        # c: no reference plan, left out
        _candidate("h2", "c", 0, [ok] * 4)]
    per_init = {r["scene"]: r for r in candidate_rows(rows)}
    assert set(per_init) == {"a", "b"}
    assert per_init["a"]["gain"] == pytest.approx(0.5)  # in-sample: the best on all replays
    assert per_init["a"]["held_out_gain"] == pytest.approx(0.0)  # each pick loses its half
    assert per_init["b"]["best_configuration"] == "h3" and per_init["b"]["candidates"] == 2
    assert per_init["b"]["held_out_gain"] == pytest.approx(1.0)
    (summary,) = candidate_ceiling(candidate_rows(rows))
    assert (summary["reference"], summary["configurations"], summary["initializations"]) == (
        "h1", 3, 2)
    assert summary["ceiling"] == pytest.approx(0.75)
    assert summary["held_out_ceiling"] == pytest.approx(0.5)
    assert "| baseline | h1 | 3 | 2 | 0.000 | +0.750 [" in markdown_candidates([summary])
    # Another reference: the gains are read against it.
    assert candidate_rows(rows, "h3")[0]["reference"] == "h3"
    # A tie on the picking half goes to the earlier candidate (the reference first).
    assert held_out_choice_gain([[ok, ok], [ok, ok]]) == 0.0
    assert held_out_choice_gain([[ok, ok], [ok]]) is None
    # A candidate without a plan fails in every replay: never picked, never a lost half.
    assert held_out_choice_gain([["planner_failure"], [ok, ok]]) == pytest.approx(1.0)
    assert held_out_choice_gain([[ok, fail], ["planner_failure"]]) == pytest.approx(0.0)


@pytest.mark.filterwarnings("ignore:No artists with labels")  # no fridge scene: empty Fig. 9b
def test_the_report_shows_the_candidates_ceiling_only_for_several_configurations(tmp_path):
    rows = _fill_two_configurations(tmp_path / "c.db")
    table = {r["planner"]: r for r in candidate_ceiling(candidate_rows(rows))}
    assert table["physics"]["ceiling"] == pytest.approx(1 / 3)  # search wins at angle 0
    assert table["baseline"]["ceiling"] == 0.0  # the same failure under both
    out = tmp_path / "report"
    assert main(["report", str(tmp_path / "c.db"), "--out", str(out)]) == 0
    assert "Choosing among a planner's configurations" in (out / "report.md").read_text()
    with (out / "candidates.csv").open() as f:
        assert len(list(csv.DictReader(f))) == 6  # 3 initializations x 2 planners
    _fill(tmp_path / "r.db")
    assert main(["report", str(tmp_path / "r.db"), "--out", str(tmp_path / "one")]) == 0
    assert "Choosing among" not in (tmp_path / "one" / "report.md").read_text()
    assert not (tmp_path / "one" / "candidates.csv").exists()


@pytest.mark.filterwarnings("ignore:No artists with labels")  # no fridge scene: empty Fig. 9b
def test_against_may_name_a_configuration_of_the_baseline_alone(tmp_path):
    fail, ok = "failure_to_grasp", "success"
    with Store(tmp_path / "b.db") as store:
        for config, kinds in (("h1", [fail] * 4), ("h2", [ok] * 4)):
            row = _candidate(config, "fig5", 0, kinds)
            unit = {"scene": "fig5", "planner": "baseline", "angle": 0, "config_hash": config,
                    "config_name": config, "kind": "bookshelf", "num_objects": 3}
            store.put(unit, {"alpha": 0.0, "outcome": row["outcome"], "plan": {"status": "ok"},
                             "timings": {}, "error": ""})
    out = tmp_path / "report"
    assert main(["report", str(tmp_path / "b.db"), "--out", str(out), "--against", "h2"]) == 0
    text = (out / "report.md").read_text()
    assert "| baseline | h2 | 2 | 1 | 1.000 | +0.000 [" in text
    assert "against each other" not in text  # no physics plans to compare
