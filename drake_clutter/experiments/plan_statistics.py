"""What the stored plans look like beside their grades: the physics planner's phi stages (did
they accept iterations, how good was the model, which path became the plan) and the plans'
smoothness; shared row helpers of the report."""

from __future__ import annotations

import numpy as np


def percent(part: int, whole: int) -> float | None:
    """100 part / whole, or None when whole is 0."""
    return None if whole == 0 else 100.0 * part / whole


def format_percent(value: float | None) -> str:
    """A percentage with one decimal ("-" for None)."""
    return "-" if value is None else f"{value:.1f}%"


def groups(rows: list[dict]) -> dict[tuple[str, str], list[dict]]:
    """Rows by (configuration name, planner), in first-seen order."""
    out: dict[tuple[str, str], list[dict]] = {}
    for row in rows:
        out.setdefault((row["config_name"], row["planner"]), []).append(row)
    return out


PHI_STAGES = ("sphere", "full")  # the physics plan's stages through phi (its details' names)
SELECTIONS = ("post", "pre", "baseline", "search")  # the paths the physics planner chooses among


def stage_statistics(rows: list[dict]) -> list[dict]:
    """Per configuration and phi stage of the physics rows' plans: the stages run, those that
    accepted at least one iLQR iteration (count and %), the accepted steps and the quartiles of
    their actual / predicted decrease (the model's at the accepted step size), and how often
    each path was the plan (`SELECTIONS`; stages without a choice are not counted)."""
    out = []
    for (config_name, planner), group in groups(rows).items():
        if planner != "physics":
            continue
        details = [r["plan"].get("details", {}) for r in group if r.get("plan")]
        chosen = [d.get("select", {}).get("chosen") for d in details]
        for stage in PHI_STAGES:
            records = [d["stages"][stage] for d in details if stage in d.get("stages", {})]
            ratios = [e["actual"] / e["predicted"] for rec in records for e in rec["log"]
                      if e.get("alpha", 0.0) > 0 and e.get("predicted", 0.0) > 0]
            accepting = sum(rec["iterations"] > 0 for rec in records)
            q = (np.percentile(ratios, [25, 50, 75]) if ratios else [None] * 3)
            out.append({"configuration": config_name, "stage": stage, "stages": len(records),
                        "accepting": accepting, "accepting_pct": percent(accepting, len(records)),
                        "accepted_steps": len(ratios), "ratio_q25": q[0], "ratio_median": q[1],
                        "ratio_q75": q[2],
                        **{f"chosen_{n}": chosen.count(n) for n in SELECTIONS}})
    return out


def markdown_stages(table: list[dict]) -> str:
    """`stage_statistics` as Markdown."""
    lines = ["| configuration | stage | stages | accepting >= 1 iteration | accepted steps | "
             "actual / predicted: median [quartiles] | plan chosen: post / pre / baseline / "
             "search |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for r in table:
        ratio = ("-" if r["ratio_median"] is None else f"{r['ratio_median']:.2f} "
                 f"[{r['ratio_q25']:.2f}, {r['ratio_q75']:.2f}]")
        accepting = format_percent(r["accepting_pct"])
        lines.append(f"| {r['configuration']} | {r['stage']} | {r['stages']} | "
                     f"{r['accepting']} ({accepting}) | {r['accepted_steps']} | "
                     f"{ratio} | {r['chosen_post']} / {r['chosen_pre']} / "
                     f"{r['chosen_baseline']} / {r['chosen_search']} |")
    return "\n".join(lines)


def largest_kink(q: np.ndarray) -> float:
    """The largest knot-to-knot second difference |q_{t+1} - 2 q_t + q_{t-1}| of an arm
    joint (the first 7 columns of the knot path ``q``, rad); 0 for fewer than 3 knots."""
    arm = np.asarray(q, float)[:, :7]
    if len(arm) < 3:
        return 0.0
    return float(np.abs(arm[2:] - 2.0 * arm[1:-1] + arm[:-2]).max())


def smoothness(rows: list[dict]) -> list[dict]:
    """Per configuration and planner: the plans' `largest_kink` (rad), median, 90th
    percentile and maximum over the plans stored."""
    out = []
    for (config_name, planner), group in groups(rows).items():
        kinks = [largest_kink(r["plan"]["trajectory"]["q"]) for r in group
                 if (r.get("plan") or {}).get("trajectory")]
        if not kinks:
            continue
        median, p90 = np.percentile(kinks, [50, 90])
        out.append({"configuration": config_name, "planner": planner, "plans": len(kinks),
                    "kink_median": float(median), "kink_p90": float(p90),
                    "kink_max": float(max(kinks))})
    return out


def markdown_smoothness(table: list[dict]) -> str:
    """`smoothness` as Markdown."""
    lines = ["| configuration | planner | plans | largest kink per plan (rad): median | 90th "
             "percentile | max |", "|---|---|---:|---:|---:|---:|"]
    lines += [f"| {r['configuration']} | {r['planner']} | {r['plans']} | "
              f"{r['kink_median']:.3f} | {r['kink_p90']:.3f} | {r['kink_max']:.3f} |"
              for r in table]
    return "\n".join(lines)
