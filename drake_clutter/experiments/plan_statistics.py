"""What the stored plans look like beside their grades: the plans' smoothness; shared row
helpers of the report. (A planner's own statistics, such as the physics planner's phi stages,
are its own: `registry.Planner.report_section`.)"""

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
