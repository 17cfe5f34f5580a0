"""Choosing among a planner's configurations: the candidates' selection ceiling.

A store that runs one planner under several configurations on the same initializations (grasp
heights, approach-line offsets, any overrides) holds, per initialization, a set of candidate
plans. How much could a planner gain by choosing among them? Per initialization the best
candidate's P(success) minus the reference configuration's, on all the robust judge's replays
(biased up: the max of noisy estimates) and held out (`paired.held_out_choice_gain`: picked on
the even replays, read on the odd ones, and the reverse). This is the bound on any rule that
picks one of these candidates, the judge-free ones a robot could run included.
"""

from __future__ import annotations

import numpy as np

from drake_clutter.common.config import ReportConfig
from drake_clutter.experiments.paired import (
    bootstrap_interval,
    held_out_cell,
    held_out_choice_gain,
    held_out_summary,
    row_kinds,
    row_p_success,
)


def candidate_rows(rows: list[dict], reference: str | None = None) -> list[dict]:
    """Per planner with two or more configurations and per initialization (scene, angle) that
    has the reference configuration's plan: the reference's P(success), the best candidate's
    configuration and P(success), the gain on all replays and the held-out gain (None without
    equal K >= 2 replays). The reference is ``reference`` where the planner has it, else the
    planner's first configuration in the store."""
    out = []
    for planner in dict.fromkeys(r["planner"] for r in rows):
        mine = [r for r in rows if r["planner"] == planner]
        configs = list(dict.fromkeys(r["config_name"] for r in mine))
        if len(configs) < 2:
            continue
        ref = reference if reference in configs else configs[0]
        by_init: dict[tuple, dict[str, dict]] = {}
        for r in mine:
            by_init.setdefault((r["scene"], r["angle"]), {})[r["config_name"]] = r
        for (scene, angle), plans in by_init.items():
            if ref in plans:
                out.append(_initialization(planner, scene, angle, ref, plans, configs))
    return out


def _initialization(planner, scene, angle, ref, plans, configs) -> dict:
    order = [ref] + [c for c in configs if c != ref and c in plans]
    p = [row_p_success(plans[c]) for c in order]
    best = int(np.argmax(p))
    return {"planner": planner, "scene": scene, "angle": angle, "reference": ref,
            "candidates": len(order), "reference_p_success": p[0],
            "best_configuration": order[best], "best_p_success": p[best],
            "gain": p[best] - p[0],
            "held_out_gain": held_out_choice_gain([row_kinds(plans[c]) for c in order])}


def candidate_ceiling(per_init: list[dict], settings: ReportConfig | None = None) -> list[dict]:
    """Per planner of `candidate_rows`' ``per_init``: its configurations, the initializations
    with the reference's plan, the reference's mean P(success), and the mean gain of the best
    candidate on all replays and held out (`paired.held_out_summary`), each with its bootstrap
    interval (``settings``)."""
    settings = settings or ReportConfig()
    out = []
    for planner in dict.fromkeys(r["planner"] for r in per_init):
        mine = [r for r in per_init if r["planner"] == planner]
        gains = [r["gain"] for r in mine]
        low, high = bootstrap_interval(gains, settings)
        out.append({"planner": planner, "reference": mine[0]["reference"],
                    "configurations": max(r["candidates"] for r in mine),
                    "initializations": len(mine),
                    "reference_p_success": float(np.mean([r["reference_p_success"]
                                                          for r in mine])),
                    "ceiling": float(np.mean(gains)), "ceiling_ci_low": low,
                    "ceiling_ci_high": high,
                    **held_out_summary([r["held_out_gain"] for r in mine], settings)})
    return out


def markdown_candidates(table: list[dict], config: ReportConfig | None = None) -> str:
    """`candidate_ceiling` as a Markdown table."""
    level = f"{100 * (config or ReportConfig()).confidence:g} %"
    lines = ["| planner | reference | configurations | initializations | reference P(success) "
             f"| best candidate's gain on all replays [{level} CI] | picked and read on "
             f"different replays [{level} CI] |",
             "|---|---|---:|---:|---:|---:|---:|"]
    for r in table:
        lines.append(f"| {r['planner']} | {r['reference']} | {r['configurations']} | "
                     f"{r['initializations']} | {r['reference_p_success']:.3f} | "
                     f"{r['ceiling']:+.3f} [{r['ceiling_ci_low']:+.3f}, "
                     f"{r['ceiling_ci_high']:+.3f}] | {held_out_cell(r)} |")
    return "\n".join(lines)
