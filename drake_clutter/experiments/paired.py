"""Paired statistics of an experiment store's rows: each compared planner's plan (any planner
but the baseline) against the baseline plan of its initialization (Sec. VI-A's grade over many
initializations), and a compared planner's configurations against one another on the same
initializations. Nothing here reads a plan's record but through its planner (`bent`).

* Per row: P(success) and expected grade class (the robust judge's over its replays, else the
  one outcome's), its behaviour grade (class, then boxes tipped or fallen).
* Per configuration: better / same / worse by the grade, the kinematic failures of each side,
  a two-sided sign test on better against worse (ties left out), and the mean per-
  initialization difference in P(success) and in expected grade with a seeded percentile
  bootstrap interval and a Wilcoxon signed-rank p-value. One plan per scene is a draw on
  toppling clutter; this is the fair reading.
"""

from __future__ import annotations

import numpy as np
from scipy.stats import binomtest, wilcoxon

from drake_clutter.common.config import ReportConfig
from drake_clutter.evaluation.outcome import GRADE_CLASSES, behaviour_grade
from drake_clutter.planners.registry import BASELINE, get_planner

SHARE_ROUNDING = 1e-12  # a scene's summed P(success) differences this small are zero (sums of k/K)


def _robust(row: dict) -> dict | None:
    """The robust judge's summary data of a stored row (`robust.RobustSummary.to_data`), or
    None for a row judged once."""
    return (row.get("outcome") or {}).get("robust")


def row_p_success(row: dict, partial: bool = False) -> float:
    """A stored row's P(success) (or P(success or partial success)): the robust judge's over
    its K replays, else 1 or 0 by its one (nominal) outcome."""
    robust = _robust(row)
    if robust:
        return float(robust["p_success_or_partial" if partial else "p_success"])
    return float(row["kind"] in (("success", "partial_success") if partial else ("success",)))


def row_expected_grade(row: dict) -> float:
    """A stored row's expected grade class (0 success .. 4 no plan): the robust judge's mean
    over its K replays, else its one outcome's class."""
    robust = _robust(row)
    if robust:
        return float(robust["expected_grade"])
    return float(GRADE_CLASSES[row["kind"]])


def row_kinds(row: dict) -> list[str]:
    """The classes of a stored row's replays: the robust judge's K, else its one kind."""
    robust = _robust(row)
    return list(robust["kinds"]) if robust else [row["kind"]]


def held_out_gain(compared_kinds: list[str], baseline_kinds: list[str]) -> float | None:
    """What choosing between two plans by half of their common replays gains on the other
    half: the plan with the higher success rate on the even replays (ties to the baseline)
    read on the odd ones, minus the baseline there, averaged with the reverse. Unlike the
    better plan's P(success) on all replays, this is not biased up by picking on the same
    noise it reads. None unless both plans have the same K >= 2 replays (a missing plan fails
    in every replay)."""
    return held_out_choice_gain([baseline_kinds, compared_kinds])


def held_out_choice_gain(candidates_kinds: list[list[str]]) -> float | None:
    """`held_out_gain` over any number of plans of one initialization, the first the
    reference: the plan with the highest success rate on the even replays (ties to the earlier
    plan) read on the odd ones minus the reference there, averaged with the reverse. A
    candidate without a plan (its one kind ``planner_failure``) fails in every replay. None
    unless every other plan has the same K >= 2 replays."""
    k = max(len(kinds) for kinds in candidates_kinds)
    candidates_kinds = [kinds * k if kinds == ["planner_failure"] else kinds
                        for kinds in candidates_kinds]
    if k < 2 or any(len(kinds) != k for kinds in candidates_kinds):
        return None
    success = np.asarray([[kind == "success" for kind in kinds] for kinds in candidates_kinds],
                         dtype=float)
    gains = []
    for pick, read in ((slice(0, None, 2), slice(1, None, 2)),
                       (slice(1, None, 2), slice(0, None, 2))):
        chosen = int(np.argmax(success[:, pick].mean(axis=1)))  # first of the ties
        gains.append(success[chosen, read].mean() - success[0, read].mean())
    return float(np.mean(gains))


def row_grade(row: dict) -> tuple[int, int]:
    """`behaviour_grade` of a stored row (its kind and the boxes of its outcome)."""
    boxes = (row.get("outcome") or {}).get("boxes", [])
    return behaviour_grade(row["kind"], sum(bool(b.get("tipped") or b.get("fallen"))
                                            for b in boxes))


def verdict(compared: tuple[int, int], baseline: tuple[int, int]) -> str:
    """'better', 'same' or 'worse': the compared plan's grade against the baseline's."""
    return "better" if compared < baseline else "same" if compared == baseline else "worse"


def paired_rows(rows: list[dict]) -> list[dict]:
    """One row per unit of a planner other than the baseline (the compared planner) that has a
    baseline unit of the same scene, angle and configuration: both kinds, both grades and the
    verdict (better / same / worse); the comparison is named "<configuration>/<planner>"."""
    base = {(r["config_name"], r["scene"], r["angle"]): r for r in rows
            if r["planner"] == BASELINE}
    return [_pair(comparison_name(r), r, base[(r["config_name"], r["scene"], r["angle"])])
            for r in rows if r["planner"] != BASELINE
            and (r["config_name"], r["scene"], r["angle"]) in base]


def bent(row: dict) -> bool:
    """Whether a stored row's plan is a bent member of its planner's path family (the
    planner's own record says; False for a row without a plan)."""
    plan = row.get("plan") or {}
    return bool(plan) and get_planner(row["planner"]).record(plan.get("details") or {}).bent


def widest_wins(rows: list[dict], planner: str) -> dict[str, tuple[dict, dict]]:
    """{scene: (baseline row, ``planner`` row)}: per scene, the initialization (angle and
    configuration) where the planner's robust P(success) exceeds the baseline's the most (ties:
    the planner's higher P(success), then a bent path over a straight one, then the lower
    angle); scenes without a pair judged robustly are left out."""
    index = {(r["scene"], r["angle"], r["config_hash"], r["planner"]): r for r in rows}
    pairs: dict[str, list[tuple[dict, dict]]] = {}
    for row in rows:
        base = index.get((row["scene"], row["angle"], row["config_hash"], BASELINE))
        if row["planner"] != planner or base is None or not row["plan"]:
            continue
        if row["p_success"] is None or base["p_success"] is None:
            continue
        pairs.setdefault(row["scene"], []).append((base, row))

    def key(pair: tuple[dict, dict]) -> tuple:
        base, row = pair
        return (row["p_success"] - base["p_success"], row["p_success"], bent(row),
                -row["angle"])

    return {scene: max(found, key=key) for scene, found in pairs.items()}


def comparison_name(row: dict) -> str:
    """The name a stored row is compared under: "<configuration>/<planner>"."""
    return f"{row['config_name']}/{row['planner']}"


def _pair(configuration: str, r: dict, b: dict) -> dict:
    """Row r ("compared" fields) against row b ("baseline" fields) of the same
    initialization."""
    gp, gb = row_grade(r), row_grade(b)
    return {"configuration": configuration, "scene": r["scene"], "angle": r["angle"],
            "baseline": b["kind"], "baseline_grade": gb, "compared": r["kind"],
            "compared_grade": gp, "verdict": verdict(gp, gb),
            "baseline_p_success": row_p_success(b), "compared_p_success": row_p_success(r),
            "baseline_expected_grade": row_expected_grade(b),
            "compared_expected_grade": row_expected_grade(r),
            "held_out_gain": held_out_gain(row_kinds(r), row_kinds(b))}


def wilson_interval(k: int, n: int, z: float = 1.96) -> tuple[float, float]:
    """The Wilson score interval (95 % at z = 1.96) of a proportion k / n; (0, 1) for n = 0."""
    if n == 0:
        return 0.0, 1.0
    p = k / n
    centre = (p + z * z / (2 * n)) / (1 + z * z / n)
    half = z * np.sqrt(p * (1 - p) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return float(max(0.0, centre - half)), float(min(1.0, centre + half))


def bootstrap_interval(values, config: ReportConfig) -> tuple[float, float]:
    """The percentile bootstrap interval (``config.confidence``) of the mean of ``values``,
    ``config.bootstrap_resamples`` resamples seeded with ``config.bootstrap_seed``."""
    values = np.asarray(values, dtype=float)
    if len(values) == 0:
        return (float("nan"), float("nan"))
    rng = np.random.default_rng(config.bootstrap_seed)
    means = values[rng.integers(0, len(values), (config.bootstrap_resamples, len(values)))]
    tail = 50.0 * (1.0 - config.confidence)
    low, high = np.percentile(means.mean(axis=1), [tail, 100.0 - tail])
    return float(low), float(high)


def signed_rank_p(differences) -> float | None:
    """Two-sided Wilcoxon signed-rank p-value of paired differences (zeros dropped); None
    when every difference is zero."""
    nonzero = [d for d in differences if d != 0]
    if not nonzero:
        return None
    return float(wilcoxon(nonzero).pvalue)


def _mean_difference(pairs: list[dict], key: str, config: ReportConfig) -> dict:
    """Mean of the compared planner minus the baseline in ``key`` over the pairs, its
    interval and p-value."""
    diffs = [p[f"compared_{key}"] - p[f"baseline_{key}"] for p in pairs]
    low, high = bootstrap_interval(diffs, config)
    return {f"{key}_diff": float(np.mean(diffs)), f"{key}_ci_low": low,
            f"{key}_ci_high": high, f"{key}_wilcoxon_p": signed_rank_p(diffs)}


def _selection_ceiling(pairs: list[dict], config: ReportConfig) -> dict:
    """What a perfect choice between the two plans of each initialization would gain: the mean
    of max(compared, baseline) minus baseline P(success), with its bootstrap interval. The
    bound on any selector that executes one of the two plans (a judge-free one included);
    biased up, as the max of two estimates is. Beside it the held-out ceiling
    (`held_out_gain`, mean and interval over the pairs that have one; None where none does)."""
    gains = [max(p["compared_p_success"], p["baseline_p_success"]) - p["baseline_p_success"]
             for p in pairs]
    low, high = bootstrap_interval(gains, config)
    return {"p_success_ceiling": float(np.mean(gains)), "p_success_ceiling_ci_low": low,
            "p_success_ceiling_ci_high": high,
            **held_out_summary([p.get("held_out_gain") for p in pairs], config)}


def held_out_summary(gains: list[float | None], config: ReportConfig) -> dict:
    """The held-out ceiling: the mean of the held-out gains that are not None and its
    bootstrap interval (``held_out_ceiling``, ``_ci_low``, ``_ci_high``); all None when none is."""
    held = [g for g in gains if g is not None]
    if not held:
        return {"held_out_ceiling": None, "held_out_ceiling_ci_low": None,
                "held_out_ceiling_ci_high": None}
    low, high = bootstrap_interval(held, config)
    return {"held_out_ceiling": float(np.mean(held)), "held_out_ceiling_ci_low": low,
            "held_out_ceiling_ci_high": high}


def paired_comparison(rows: list[dict], settings: ReportConfig | None = None) -> list[dict]:
    """Per configuration: pairs, better / same / worse, kinematic failures of each planner,
    the two-sided sign test's p-value on better against worse (None when all tie), and the
    mean difference compared planner minus baseline per initialization in P(success) and in expected
    grade class, each with its bootstrap interval (``settings``) and Wilcoxon signed-rank
    p-value; and the selection ceiling (`_selection_ceiling`)."""
    return _summaries(paired_rows(rows), settings or ReportConfig())


def _summaries(pairs_in: list[dict], settings: ReportConfig) -> list[dict]:
    by_config: dict[str, list[dict]] = {}
    for p in pairs_in:
        by_config.setdefault(p["configuration"], []).append(p)
    out = []
    for config, pairs in by_config.items():
        verdicts = [p["verdict"] for p in pairs]
        better, worse = verdicts.count("better"), verdicts.count("worse")
        out.append({"configuration": config, "pairs": len(pairs), "better": better,
                    "same": verdicts.count("same"), "worse": worse,
                    "compared_kinematic_failures": sum(p["compared"] == "kinematic_failure"
                                                       for p in pairs),
                    "baseline_kinematic_failures": sum(p["baseline"] == "kinematic_failure"
                                                       for p in pairs),
                    "sign_test_p": (binomtest(better, better + worse).pvalue
                                    if better + worse else None),
                    **_mean_difference(pairs, "p_success", settings),
                    **_mean_difference(pairs, "expected_grade", settings),
                    **_selection_ceiling(pairs, settings)})
    return out


def configuration_rows(rows: list[dict], reference: str) -> list[dict]:
    """One row per unit of a compared planner (not the baseline) under another configuration
    that has a unit of the same planner under the ``reference`` configuration at the same scene
    and angle, shaped as `paired_rows` (the other configuration in the "compared" fields, the
    reference in the "baseline" ones), named "<configuration>/<planner> vs <reference>"."""
    ref = {(r["planner"], r["scene"], r["angle"]): r for r in rows
           if r["planner"] != BASELINE and r["config_name"] == reference}
    return [_pair(f"{comparison_name(r)} vs {reference}", r,
                  ref[(r["planner"], r["scene"], r["angle"])])
            for r in rows if r["planner"] != BASELINE and r["config_name"] != reference
            and (r["planner"], r["scene"], r["angle"]) in ref]


def configuration_comparison(rows: list[dict], reference: str,
                             settings: ReportConfig | None = None) -> list[dict]:
    """`paired_comparison`'s figures for every other configuration of a compared planner
    against the same planner's ``reference`` configuration on the same initializations (other
    minus reference; "baseline" fields hold the reference's)."""
    return _summaries(configuration_rows(rows, reference), settings or ReportConfig())


def _p(value: float | None) -> str:
    return "-" if value is None else f"{value:.3f}"


def markdown_paired(table: list[dict], config: ReportConfig | None = None) -> str:
    """The paired comparison as Markdown: better / same / worse with the sign test, and the
    mean differences (the compared planner minus the baseline) with their intervals and
    Wilcoxon p-values."""
    level = f"{100 * (config or ReportConfig()).confidence:g} %"
    lines = ["| configuration | pairs | planner better | same | worse | kinematic failures "
             f"planner / baseline | sign test p | P(success) difference [{level} CI] | "
             f"Wilcoxon p | expected grade difference [{level} CI] | Wilcoxon p | "
             f"P(success) gain of the better plan of each pair [{level} CI] | "
             f"the same, picked and read on different replays [{level} CI] |",
             "|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|"]
    for r in table:
        lines.append(f"| {r['configuration']} | {r['pairs']} | {r['better']} | {r['same']} | "
                     f"{r['worse']} | {r['compared_kinematic_failures']} / "
                     f"{r['baseline_kinematic_failures']} | {_p(r['sign_test_p'])} | "
                     f"{r['p_success_diff']:+.3f} [{r['p_success_ci_low']:+.3f}, "
                     f"{r['p_success_ci_high']:+.3f}] | {_p(r['p_success_wilcoxon_p'])} | "
                     f"{r['expected_grade_diff']:+.3f} [{r['expected_grade_ci_low']:+.3f}, "
                     f"{r['expected_grade_ci_high']:+.3f}] | "
                     f"{_p(r['expected_grade_wilcoxon_p'])} | "
                     f"{r['p_success_ceiling']:+.3f} [{r['p_success_ceiling_ci_low']:+.3f}, "
                     f"{r['p_success_ceiling_ci_high']:+.3f}] | {held_out_cell(r)} |")
    return "\n".join(lines)


def held_out_cell(r: dict) -> str:
    """The held-out ceiling's cell: mean [interval], or "-" where no pair had replays."""
    if r["held_out_ceiling"] is None:
        return "-"
    return (f"{r['held_out_ceiling']:+.3f} [{r['held_out_ceiling_ci_low']:+.3f}, "
            f"{r['held_out_ceiling_ci_high']:+.3f}]")


def scene_contributions(pairs: list[dict], top: int) -> list[dict]:
    """Where a mean P(success) difference lies: per configuration of ``pairs`` (`paired_rows`
    or `configuration_rows`), each scene's share of the configuration's mean difference
    (compared minus baseline: the scene's summed per-initialization differences over all the
    configuration's pairs, so a configuration's shares sum to its mean), with the kinds of
    the pairs that differ. Only scenes whose share is non-zero; the ``top`` largest in
    magnitude per configuration, largest first."""
    by_config: dict[str, dict[str, list[dict]]] = {}
    for p in pairs:
        by_config.setdefault(p["configuration"], {}).setdefault(p["scene"], []).append(p)
    out = []
    for config, scenes in by_config.items():
        total = sum(len(ps) for ps in scenes.values())
        rows = [_contribution(config, scene, ps, total) for scene, ps in scenes.items()]
        rows = [r for r in rows if abs(r["p_success_share"]) > SHARE_ROUNDING]
        out.extend(sorted(rows, key=lambda r: -abs(r["p_success_share"]))[:top])
    return out


def _contribution(config: str, scene: str, pairs: list[dict], total: int) -> dict:
    """One scene's row of `scene_contributions` (``total``: the configuration's pairs)."""
    differing = [p for p in pairs if p["compared_p_success"] != p["baseline_p_success"]]
    share = sum(p["compared_p_success"] - p["baseline_p_success"] for p in pairs) / total
    return {"configuration": config, "scene": scene, "pairs": len(pairs),
            "differing": len(differing), "p_success_share": float(share),
            "changes": "; ".join(f"angle {p['angle']}: {p['baseline']} "
                                 f"{p['baseline_p_success']:.2f} -> {p['compared']} "
                                 f"{p['compared_p_success']:.2f}" for p in differing)}


def markdown_contributions(table: list[dict]) -> str:
    """`scene_contributions` as Markdown: configuration, scene, its share of the mean
    P(success) difference, and the differing pairs as baseline -> planner (kind, P)."""
    lines = ["| configuration | scene | pairs (differing) | share of the P(success) difference "
             "| baseline -> planner, where P(success) differs |",
             "|---|---|---:|---:|---|"]
    lines += [f"| {r['configuration']} | {r['scene']} | {r['pairs']} ({r['differing']}) | "
              f"{r['p_success_share']:+.3f} | {r['changes']} |" for r in table]
    return "\n".join(lines)
