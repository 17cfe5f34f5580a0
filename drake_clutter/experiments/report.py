"""Reports of an experiment store: Tables III and IV and Fig. 9 of Sec. VI-B, beside the paper's.

Definitions (Sec. VI-B), per (configuration, planner):

* Scene score: success if any approach angle's trajectory succeeded, partial success if the
  best was a partial success, else failure (`judge.scene_score` over the scene's rows,
  every stored angle of the scene counted).
* Table III: per environment (bookshelf, refrigerator) and in aggregate, the percentage of
  scenes whose score is success or partial success, and in parentheses the percentage whose
  score is partial success - the paper's "76.7% (8.3%)" is 46 of 60 and 5 of 60 scenes.
* Table IV: the outcome distribution over the trajectories the planner returned (the paper's
  918: angles with an IK solution). Rows of kind ``planner_failure`` (no trajectory: IK or
  optimisation failed, or the unit raised) are outside the distribution and counted apart.
* Fig. 9a/9b: per environment, the percentage of scenes with score success (solid) and with
  success or partial success (dashed) against the number of objects, both planners.
* Paired comparison (Sec. VI-A's grade, over many initializations): per configuration, each
  compared planner's row (any planner but the baseline) against the baseline row of the same
  scene, angle and configuration, by `scene.grading.behaviour_grade` (class, then boxes
  tipped or fallen): better / same / worse, the kinematic failures of each, and a two-sided
  sign test on better against worse (ties left out). One plan per scene is a draw on
  toppling clutter; this is the fair reading.
* Where the difference lies: per comparison, the scenes carrying the mean P(success)
  difference (`paired.scene_contributions`), with the pairs that differ.
* Selected-plan success (beyond the paper): per scene, the robust P(success) of the candidate
  each planner ranks first without the judge (`selection_score`), beside the best angle's.
* Fig. 9c: mean planning time per initialization (s) against the number of objects, as each
  planner reads its own (`Planner.plan_seconds`: the physics planner's stages on units whose
  baseline candidate gave it an initialization; the others' whole planning time per angle).

The paper's published numbers sit beside ours (Tables III and IV), beside the planner that
reproduces each of its rows (`Planner.paper_row`). The paper gives Fig. 9's
curves only as plots; its text says the baseline was near 100% at 5 objects or fewer, which
`PAPER_FIG9_NOTE` repeats in the Markdown.
"""

from __future__ import annotations

import csv
from collections import defaultdict
from pathlib import Path

import numpy as np

from drake_clutter.common.config import Config, ReportConfig
from drake_clutter.evaluation.outcome import OUTCOME_KINDS, scene_score
from drake_clutter.experiments.candidates import (
    candidate_ceiling,
    candidate_rows,
    markdown_candidates,
)
from drake_clutter.experiments.figures import (
    ENV_LABELS,
    ENVIRONMENTS,
    plot_combined,
    plot_success,
    plot_time,
)
from drake_clutter.experiments.paired import (
    bootstrap_interval,
    configuration_comparison,
    configuration_rows,
    markdown_contributions,
    markdown_paired,
    paired_comparison,
    paired_rows,
    row_kinds,
    row_p_success,
    scene_contributions,
)
from drake_clutter.experiments.plan_statistics import (
    format_percent,
    groups,
    markdown_smoothness,
    percent,
    smoothness,
)
from drake_clutter.planners.registry import BASELINE, get_planner
from drake_clutter.planners.selection import selection_score as planner_selection_score

TRAJECTORY_KINDS = tuple(k for k in OUTCOME_KINDS if k != "planner_failure")

# Table III (Sec. VI-B): % of scenes with success or partial success, (% partial success).
PAPER_TABLE_III = {
    "paper: baseline": {"bookshelf": (76.7, 8.3), "fridge": (65.6, 5.6),
                        "aggregate": (70.0, 6.7)},
    "paper: physics-aware": {"bookshelf": (86.7, 10.0), "fridge": (83.3, 13.3),
                             "aggregate": (84.7, 12.0)},
}
# Table IV (Sec. VI-B): % of the 918 trajectories of each algorithm per outcome.
PAPER_TABLE_IV = {
    "paper: baseline": {"success": 36.9, "partial_success": 1.1, "failure_to_grasp": 32.9,
                        "objects_falling": 1.4, "kinematic_failure": 27.7},
    "paper: physics-aware": {"success": 48.7, "partial_success": 2.2,
                             "failure_to_grasp": 27.2, "objects_falling": 1.3,
                             "kinematic_failure": 20.6},
}
PAPER_TRAJECTORIES = 918
PAPER_FIG9_NOTE = ("The paper gives Fig. 9's curves as plots only; its text: at 5 objects or "
                   "fewer the baseline succeeded in near 100% of scenes, and the rates fall "
                   "from about 6 objects on; Fig. 9c's time per initialization grows with the "
                   "number of objects (C++, 24-core workstation).")




def scene_scores(rows: list[dict]) -> dict[str, tuple[str, int, str]]:
    """scene -> (environment, number of objects, scene score) over the rows of one group."""
    kinds: dict[str, list[str]] = defaultdict(list)
    meta = {}
    for row in rows:
        kinds[row["scene"]].append(row["kind"])
        meta[row["scene"]] = (row["env"], row["num_objects"])
    return {s: (*meta[s], scene_score(k)) for s, k in kinds.items()}


def robust_scene_success(rows: list[dict], partial: bool = False) -> dict[str, float]:
    """scene -> its robust success over the rows of one group: the best angle's P(success)
    (or P(success or partial success); `row_p_success`)."""
    best: dict[str, float] = {}
    for row in rows:
        best[row["scene"]] = max(best.get(row["scene"], 0.0), row_p_success(row, partial))
    return best


def paper_row(planner: str) -> str | None:
    """The key of the paper's rows (`PAPER_TABLE_III`, `PAPER_TABLE_IV`) that ``planner``
    reproduces (`Planner.paper_row`); None for a planner beyond the paper."""
    return get_planner(planner).paper_row


def table_iii(rows: list[dict]) -> list[dict]:
    """Table III rows: per group and environment (and aggregate), scenes and percentages."""
    out = []
    for (config, planner), group in groups(rows).items():
        scores = scene_scores(group)
        robust = robust_scene_success(group)
        robust_or_partial = robust_scene_success(group, partial=True)
        for env in (*ENVIRONMENTS, "aggregate"):
            names = [s for s, (e, _, _) in scores.items() if env in ("aggregate", e)]
            chosen = [scores[s][2] for s in names]
            n = len(chosen)
            success, partial = chosen.count("success"), chosen.count("partial_success")
            paper = PAPER_TABLE_III.get(paper_row(planner), {}).get(env, (None, None))
            out.append({"configuration": config, "planner": planner, "environment": env,
                        "scenes": n, "success_pct": percent(success, n),
                        "partial_pct": percent(partial, n),
                        "success_or_partial_pct": percent(success + partial, n),
                        "robust_success_pct": percent(sum(robust[s] for s in names), n),
                        "robust_success_or_partial_pct": percent(
                            sum(robust_or_partial[s] for s in names), n),
                        "paper_success_or_partial_pct": paper[0], "paper_partial_pct": paper[1]})
    return out


def table_iv(rows: list[dict]) -> list[dict]:
    """Table IV rows: per group and outcome kind, trajectories and percentage of them; plus
    one row per group counting the units without a trajectory (planner_failure)."""
    out = []
    for (config, planner), group in groups(rows).items():
        kinds = [r["kind"] for r in group]
        trajectories = sum(k != "planner_failure" for k in kinds)
        replays = [k for r in group if r["kind"] != "planner_failure" for k in row_kinds(r)]
        for kind in TRAJECTORY_KINDS:
            out.append({"configuration": config, "planner": planner, "outcome": kind,
                        "count": kinds.count(kind), "pct": percent(kinds.count(kind), trajectories),
                        "robust_pct": percent(replays.count(kind), len(replays)),
                        "paper_pct": PAPER_TABLE_IV.get(paper_row(planner), {}).get(kind)})
        out.append({"configuration": config, "planner": planner, "outcome": "planner_failure",
                    "count": kinds.count("planner_failure"), "pct": None, "robust_pct": None,
                    "paper_pct": None})
    return out


def table_levels(rows: list[dict]) -> list[dict]:
    """Tables III and IV per clutter level: per group, environment and number of objects, the
    scenes and their % of success, partial success and failure (a scene scored by its best
    angle, as Table III), the robust judge's scene success (the best angle's P(success)), and
    the trajectories (units with a plan) with each outcome class's % of them (as Table IV)."""
    out = []
    for (config, planner), group in groups(rows).items():
        scores = scene_scores(group)
        robust = robust_scene_success(group)
        for env in ENVIRONMENTS:
            for n in sorted({m for e, m, _ in scores.values() if e == env}):
                names = [s for s, (e, m, _) in scores.items() if e == env and m == n]
                chosen = [scores[s][2] for s in names]
                success, partial = chosen.count("success"), chosen.count("partial_success")
                kinds = [r["kind"] for r in group if r["env"] == env and r["num_objects"] == n
                         and r["kind"] != "planner_failure"]
                out.append({"configuration": config, "planner": planner, "environment": env,
                            "num_objects": n, "scenes": len(names),
                            "success_pct": percent(success, len(names)),
                            "partial_pct": percent(partial, len(names)),
                            "failure_pct": percent(len(names) - success - partial, len(names)),
                            "robust_success_pct": percent(sum(robust[s] for s in names),
                                                       len(names)),
                            "trajectories": len(kinds),
                            **{f"trajectory_{k}_pct": percent(kinds.count(k), len(kinds))
                               for k in TRAJECTORY_KINDS}})
    return out


def _init_seconds(row: dict) -> float | None:
    """Planning seconds of one initialization (see the module docstring), None if none."""
    timings = row.get("timings") or {}
    return get_planner(row["planner"]).plan_seconds(timings)


def fig9_data(rows: list[dict]) -> list[dict]:
    """Per group, environment and number of objects: scenes, % success, % success or partial,
    initializations and their mean planning time (s)."""
    out = []
    for (config, planner), group in groups(rows).items():
        scores = scene_scores(group)
        robust = robust_scene_success(group)
        for env in ENVIRONMENTS:
            levels = sorted({n for e, n, _ in scores.values() if e == env})
            for n in levels:
                names = [s for s, (e, m, _) in scores.items() if e == env and m == n]
                chosen = [scores[s][2] for s in names]
                times = [t for r in group if r["env"] == env and r["num_objects"] == n
                         for t in [_init_seconds(r)] if t is not None]
                success, partial = chosen.count("success"), chosen.count("partial_success")
                out.append({"configuration": config, "planner": planner, "environment": env,
                            "num_objects": n, "scenes": len(chosen),
                            "success_pct": percent(success, len(chosen)),
                            "success_or_partial_pct": percent(success + partial, len(chosen)),
                            "robust_success_pct": percent(sum(robust[s] for s in names),
                                                       len(chosen)),
                            "initializations": len(times),
                            "mean_seconds_per_init": sum(times) / len(times) if times
                            else None})
    return out


def markdown_table_iii(table: list[dict]) -> str:
    """Table III as Markdown: ours "cumulative (partial)" beside the paper's."""
    lines = ["| configuration | planner | environment | scenes | ours: success or partial "
             "(partial) | ours: success | robust: success or partial | robust: success | "
             "paper: success or partial (partial) |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|"]
    for r in table:
        paper = ("-" if r["paper_success_or_partial_pct"] is None else
                 f"{r['paper_success_or_partial_pct']:.1f}% ({r['paper_partial_pct']:.1f}%)")
        lines.append(f"| {r['configuration']} | {r['planner']} | {ENV_LABELS[r['environment']]}"
                     f" | {r['scenes']} | {format_percent(r['success_or_partial_pct'])} "
                     f"({format_percent(r['partial_pct'])}) | {format_percent(r['success_pct'])} | "
                     f"{format_percent(r['robust_success_or_partial_pct'])} | "
                     f"{format_percent(r['robust_success_pct'])} | {paper} |")
    return "\n".join(lines)


def markdown_table_iv(table: list[dict]) -> str:
    """Table IV as Markdown: ours (count and % of trajectories) beside the paper's %."""
    lines = ["| configuration | planner | outcome | ours: trajectories | ours: % | robust: % of "
             "replays | paper: % |", "|---|---|---|---:|---:|---:|---:|"]
    for r in table:
        paper = "-" if r["paper_pct"] is None else f"{r['paper_pct']:.1f}%"
        outcome = ("no trajectory (planner_failure, not in the %)"
                   if r["outcome"] == "planner_failure" else r["outcome"])
        lines.append(f"| {r['configuration']} | {r['planner']} | {outcome} | {r['count']} | "
                     f"{format_percent(r['pct'])} | {format_percent(r['robust_pct'])} | {paper} |")
    return "\n".join(lines)


def markdown_table_levels(table: list[dict]) -> str:
    """`table_levels` as Markdown: scene shares (Table III) and trajectory classes (Table IV)."""
    classes = " | ".join(TRAJECTORY_KINDS)
    lines = [f"| configuration | planner | environment | objects | scenes | success | partial | "
             f"failure | robust success | trajectories | {classes} |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|---:|" + "---:|" * len(TRAJECTORY_KINDS)]
    for r in table:
        scenes = " | ".join(format_percent(r[k]) for k in
                            ("success_pct", "partial_pct", "failure_pct", "robust_success_pct"))
        shares = " | ".join(format_percent(r[f"trajectory_{k}_pct"]) for k in TRAJECTORY_KINDS)
        lines.append(f"| {r['configuration']} | {r['planner']} | {ENV_LABELS[r['environment']]}"
                     f" | {r['num_objects']} | {r['scenes']} | {scenes} | {r['trajectories']} | "
                     f"{shares} |")
    return "\n".join(lines)


def markdown_fig9(data: list[dict]) -> str:
    """Fig. 9's points as a Markdown table."""
    lines = ["| configuration | planner | environment | objects | scenes | success | "
             "success or partial | robust success | initializations | s per initialization |",
             "|---|---|---|---:|---:|---:|---:|---:|---:|---:|"]
    for p in data:
        secs = "-" if p["mean_seconds_per_init"] is None else f"{p['mean_seconds_per_init']:.2f}"
        shares = " | ".join(format_percent(p[k]) for k in
                            ("success_pct", "success_or_partial_pct", "robust_success_pct"))
        lines.append(f"| {p['configuration']} | {p['planner']} | {ENV_LABELS[p['environment']]}"
                     f" | {p['num_objects']} | {p['scenes']} | {shares} | "
                     f"{p['initializations']} | {secs} |")
    return "\n".join(lines)


def selection_score(row: dict, config: Config | None = None) -> float | None:
    """The score the row's planner ranks its candidates by without the judge
    (`planners.selection.selection_score`, lower is better); None for a row without a plan."""
    plan = row.get("plan") or {}
    if not plan.get("trajectory"):
        return None
    return planner_selection_score(row["planner"], plan.get("details") or {}, config)


def selected_rows(rows: list[dict]) -> dict[tuple[str, str, str], dict | None]:
    """(configuration, planner, scene) -> the row of the candidate the planner would execute:
    the lowest `selection_score` among the scene's angles (ties to the lower angle); None
    when no angle has a scored plan."""
    out: dict[tuple[str, str, str], dict | None] = {}
    for row in sorted(rows, key=lambda r: r["angle"]):
        key = (row["config_name"], row["planner"], row["scene"])
        score = selection_score(row)
        best = out.get(key)
        if score is not None and (best is None or score < selection_score(best)):
            out[key] = row
        else:
            out.setdefault(key, None)
    return out


def selected_plan_success(rows: list[dict], settings: ReportConfig | None = None
                          ) -> list[dict]:
    """Per configuration and planner compared with that configuration's baseline: over the
    scenes, the mean robust P(success) (`row_p_success`; 0 where nothing was selected) of the
    candidate each planner would execute (`selected_rows`) beside the best angle's (the
    paper's scene success, which needs the judge to pick), and the per-scene difference
    planner minus baseline with its bootstrap interval. The "compared" fields hold the
    planner's; the comparison is named "<configuration>/<planner>" (as in the paired table)."""
    settings = settings or ReportConfig()
    chosen = selected_rows(rows)
    best = {(c, p): robust_scene_success(g) for (c, p), g in groups(rows).items()}
    out = []
    for config, planner in best:
        if planner == BASELINE or (config, BASELINE) not in best:
            continue
        scenes = sorted(set(best[(config, planner)]) & set(best[(config, BASELINE)]))
        p = {name: [0.0 if chosen.get((config, name, s)) is None else
                    row_p_success(chosen[(config, name, s)]) for s in scenes]
             for name in (planner, BASELINE)}
        diffs = np.subtract(p[planner], p[BASELINE])
        low, high = bootstrap_interval(diffs, settings)
        out.append({"configuration": f"{config}/{planner}", "scenes": len(scenes),
                    "compared_selected": float(np.mean(p[planner])),
                    "baseline_selected": float(np.mean(p[BASELINE])),
                    "compared_best_angle": float(np.mean([best[(config, planner)][s]
                                                         for s in scenes])),
                    "baseline_best_angle": float(np.mean([best[(config, BASELINE)][s]
                                                          for s in scenes])),
                    "selected_diff": float(np.mean(diffs)), "selected_ci_low": low,
                    "selected_ci_high": high})
    return out


def markdown_selected(table: list[dict], config: ReportConfig | None = None) -> str:
    """`selected_plan_success` as Markdown."""
    level = f"{100 * (config or ReportConfig()).confidence:g} %"
    lines = ["| configuration | scenes | selected-plan P(success): planner / baseline | "
             f"difference [{level} CI] | best angle's P(success): planner / baseline |",
             "|---|---:|---:|---:|---:|"]
    for r in table:
        lines.append(f"| {r['configuration']} | {r['scenes']} | {r['compared_selected']:.3f} / "
                     f"{r['baseline_selected']:.3f} | {r['selected_diff']:+.3f} "
                     f"[{r['selected_ci_low']:+.3f}, {r['selected_ci_high']:+.3f}] | "
                     f"{r['compared_best_angle']:.3f} / {r['baseline_best_angle']:.3f} |")
    return "\n".join(lines)


def _write_csv(path: Path, table: list[dict]) -> None:
    with path.open("w", newline="", encoding="utf-8") as f:
        writer = csv.DictWriter(f, fieldnames=list(table[0]) if table else ["empty"])
        writer.writeheader()
        writer.writerows(table)


def compared_configurations(rows: list[dict]) -> list[str]:
    """The configurations with rows of a compared planner (any but the baseline), in the
    store's order."""
    return list(dict.fromkeys(r["config_name"] for r in rows if r["planner"] != BASELINE))


def write_report(rows: list[dict], out_dir: str | Path, source: str = "",
                 config: ReportConfig | None = None,
                 reference: str | None = None) -> dict[str, Path]:
    """Writes report.md, table3.{md,csv}, table4.{md,csv}, levels.csv (`table_levels`),
    fig9.csv, fig9a/b/c.png, fig9.png
    (the three panels together), paired.csv (each compared planner against the baseline per
    initialization), configurations.csv (every other configuration of a compared planner
    against the ``reference`` one per initialization; default the store's first, when it has
    two or more), candidates.csv (each planner's configurations as candidates per
    initialization, when it has two or more), contributions.csv (`scene_contributions`), each
    planner's own section's CSV (`Planner.report_section`, e.g. the physics planner's
    stages.csv) and smoothness.csv (`smoothness`) into ``out_dir`` (created); returns the paths
    by name. ``config``: the paired comparison's bootstrap settings; ``reference``: the
    configuration the others are read against (the configurations' comparison takes it only if
    a compared planner has plans under it, else the store's first such configuration)."""
    config = config or ReportConfig()
    compared_configs = compared_configurations(rows)
    compared_reference = reference if reference in compared_configs else None
    if compared_reference is None and len(compared_configs) > 1:
        compared_reference = compared_configs[0]
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    t3, t4, f9 = table_iii(rows), table_iv(rows), fig9_data(rows)
    paths = {"table3.md": out / "table3.md", "table4.md": out / "table4.md",
             "table3.csv": out / "table3.csv", "table4.csv": out / "table4.csv",
             "fig9.csv": out / "fig9.csv", "levels.csv": out / "levels.csv",
             "paired.csv": out / "paired.csv",
             "selected.csv": out / "selected.csv",
             "smoothness.csv": out / "smoothness.csv",
             "report.md": out / "report.md"}
    md3, md4 = markdown_table_iii(t3), markdown_table_iv(t4)
    paths["table3.md"].write_text(md3 + "\n", encoding="utf-8")
    paths["table4.md"].write_text(md4 + "\n", encoding="utf-8")
    _write_csv(paths["table3.csv"], t3)
    _write_csv(paths["table4.csv"], t4)
    _write_csv(paths["fig9.csv"], f9)
    levels = table_levels(rows)
    _write_csv(paths["levels.csv"], levels)
    pairs = paired_rows(rows)
    _write_csv(paths["paired.csv"], pairs)
    against, reference_pairs = [], []
    if compared_reference is not None:
        paths["configurations.csv"] = out / "configurations.csv"
        reference_pairs = configuration_rows(rows, compared_reference)
        _write_csv(paths["configurations.csv"], reference_pairs)
        against = ["## A planner's configurations against each other", "",
                   "Each other configuration's plan of a compared planner against the same "
                   f"planner's under `{compared_reference}` at the same scene and angle (the "
                   "same initialization): the columns read as above, \"planner\" the other "
                   f"configuration and \"baseline\" `{compared_reference}`. Per pair: "
                   "configurations.csv.", "",
                   markdown_paired(configuration_comparison(rows, compared_reference, config),
                                   config),
                   ""]
    candidates = _candidates_section(rows, reference, config, out, paths)
    contributions = scene_contributions(pairs + reference_pairs, config.contribution_scenes)
    paths["contributions.csv"] = out / "contributions.csv"
    _write_csv(paths["contributions.csv"], contributions)
    own_sections = _planner_sections(rows, out, paths)
    selected = selected_plan_success(rows, config)
    _write_csv(paths["selected.csv"], selected)
    smooth = smoothness(rows)
    _write_csv(paths["smoothness.csv"], smooth)
    paths["fig9a.png"] = plot_success(f9, "bookshelf", out / "fig9a.png")
    paths["fig9b.png"] = plot_success(f9, "fridge", out / "fig9b.png")
    paths["fig9c.png"] = plot_time(f9, out / "fig9c.png")
    paths["fig9.png"] = plot_combined(f9, out / "fig9.png")
    text = [f"# Experiment report{f' ({source})' if source else ''}", "",
            f"{len(rows)} stored units, {len(scene_keys(rows))} scenes.", "",
            "## Table III: scene-level success (Sec. VI-B)", "",
            "A scene succeeds if any of its angles succeeded; partial if the best angle was a "
            "partial success. Paper: 150 scenes, 14 angles each.", "", md3, "",
            "## Table IV: trajectory outcomes (Sec. VI-B)", "",
            f"Percentages of the trajectories each planner returned (paper: "
            f"{PAPER_TRAJECTORIES} per algorithm).", "", md4, "",
            "## Tables III and IV per clutter level", "",
            "Per level: the scenes' shares as Table III (best angle; failure: neither success "
            "nor partial) and the robust judge's scene success, then the trajectories' outcome "
            "classes as Table IV. The paper gives these per level only as Fig. 9's curves. "
            "Per level: levels.csv.", "", markdown_table_levels(levels), "",
            "## Fig. 9: success and time per initialization against clutter", "",
            "![Fig. 9](fig9.png)", "",
            markdown_fig9(f9), "", PAPER_FIG9_NOTE, "",
            "## Each planner against the baseline from the same initialization (Sec. VI-A's grade)",
            "", "Each plan of a planner other than the baseline (the comparison's name: "
            "<configuration>/<planner>) against "
            "the baseline plan of the same scene, angle and "
            "configuration: the outcome class first (success, partial, failure to grasp or "
            "objects falling, kinematic failure), then the boxes tipped or fallen. Per pair: "
            "paired.csv. The differences are per initialization, planner minus baseline: "
            "P(success) (the robust judge's over its replays, else 1 or 0) and the expected "
            "grade class (lower is better), with a seeded percentile bootstrap interval. The "
            "last two columns are the most any choice between the pair's two plans could gain "
            "over the baseline (the better plan's P(success) minus the baseline's): the "
            "ceiling of plan selection, judge-free or not. Picking the better of two noisy "
            "estimates and reading the same estimates biases it up, so the last column picks "
            "on the even replays and reads the odd ones (and the reverse).", "",
            markdown_paired(paired_comparison(rows, config), config), "", *against,
            *candidates,
            "## Where the P(success) difference lies", "",
            "Per comparison above, the scenes whose initializations carry its mean P(success) "
            "difference: each scene's share (its summed differences over the comparison's "
            "pairs; the shares of a comparison sum to its mean), the "
            f"{config.contribution_scenes} largest, and the pairs that differ as baseline -> "
            "planner (kind, P(success)). Per scene: contributions.csv.", "",
            markdown_contributions(contributions), "",
            "## The plan each planner would execute", "",
            "The paper scores a scene by its best angle, which only the judge can pick. Here "
            "each planner picks its own candidate without the judge - the baseline by its "
            "kinematic cost (Sec. IV's path objective), the physics planner by its objective "
            "in phi (or ensemble score), the push planner by its P(success) in phi - and the "
            "robust judge grades that one: selected-plan "
            "P(success), per scene, beside the best angle's. Per configuration: selected.csv.",
            "", markdown_selected(selected, config), "",
            *own_sections,
            "## Smoothness of the plans", "",
            "Per plan the largest change of an arm joint's step from one knot to the next "
            "(second difference, rad): the baseline's plans are B-splines, the physics "
            "planner's knots move one by one unless `physics.controls` is `spline`. Per "
            "configuration: smoothness.csv.", "", markdown_smoothness(smooth), ""]
    paths["report.md"].write_text("\n".join(text), encoding="utf-8")
    return paths


def _planner_sections(rows: list[dict], out: Path, paths: dict) -> list[str]:
    """Each planner's own section (`Planner.report_section`) on its stored plans, in the
    store's order, its CSV written into ``out``."""
    lines = []
    for planner in dict.fromkeys(r["planner"] for r in rows):
        plans: dict[str, list[dict]] = {}
        for r in rows:
            if r["planner"] == planner and r.get("plan"):
                plans.setdefault(r["config_name"], []).append(r["plan"].get("details") or {})
        section = get_planner(planner).report_section(plans)
        if section is not None:
            paths[section.csv_name] = out / section.csv_name
            _write_csv(paths[section.csv_name], section.table)
            lines += section.lines
    return lines


def _candidates_section(rows, reference, config, out, paths) -> list[str]:
    """The candidates' selection ceiling (`candidates`) as report lines, and candidates.csv;
    nothing for a store with one configuration per planner."""
    per_init = candidate_rows(rows, reference)
    if not per_init:
        return []
    paths["candidates.csv"] = out / "candidates.csv"
    _write_csv(paths["candidates.csv"], per_init)
    return ["## Choosing among a planner's configurations", "",
            "Each planner's plans of one initialization under the store's configurations, "
            "taken as candidates: the most a choice among them could gain over the reference "
            "configuration's plan (the best candidate's P(success) minus the reference's), on "
            "all replays and, unbiased by the choice, picked on the even replays and read on "
            "the odd ones (and the reverse). The bound on any rule that picks one of these "
            "candidates, judge-free or not. Per initialization: candidates.csv.", "",
            markdown_candidates(candidate_ceiling(per_init, config), config), ""]


def scene_keys(rows: list[dict]) -> set[str]:
    """The distinct scene names of the rows."""
    return {r["scene"] for r in rows}
