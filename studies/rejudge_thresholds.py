#!/usr/bin/env python3
"""How much of the distance to the paper's rows the judge's settings carry: Tables III and IV
of two planners' stores re-judged at each setting, side by side.

    python studies/rejudge_thresholds.py --setting LABEL BASELINE.db COMPARED.db
        [--setting LABEL BASELINE.db COMPARED.db ...] [--out FILE.md]

Each ``--setting`` names one judge setting and the two stores judged under it
(`drake-clutter experiment rejudge STORE --db NEW --set evaluation.FIELD=VALUE`): the
baseline's and the compared planner's, the same initializations; a store that holds both (a
tier run) may be named twice. Printed per setting, for each
planner: Table III (scenes with success or partial, nominal replays; aggregate, bookshelf,
refrigerator), Table IV (the trajectories' classes, nominal replays), the robust P(success)
mean; and the paired compared - baseline P(success) per initialization with its seeded
bootstrap 95 % interval, overall and per environment, with better / same / worse counts by
Sec. VI-A's grade; then the same difference per environment and clutter level. The paper's
rows are printed beside them.

Its dated results: docs/log/evaluation.md.
"""

from __future__ import annotations

import argparse

import numpy as np

from drake_clutter.common.config import ReportConfig
from drake_clutter.experiments.paired import bootstrap_interval, row_grade, row_p_success, verdict
from drake_clutter.experiments.report import table_iii, table_iv
from drake_clutter.experiments.store import Store
from drake_clutter.planners.registry import BASELINE

CLASSES = ("success", "partial_success", "failure_to_grasp", "objects_falling",
           "kinematic_failure")
PAPER = {"baseline": ("70.0 %", "36.9 / 1.1 / 32.9 / 1.4 / 27.7"),
         "physics-aware": ("84.7 %", "48.7 / 2.2 / 27.2 / 1.3 / 20.6")}


def rows_of(path: str, baseline: bool) -> dict[tuple[str, int], dict]:
    """(scene, angle) -> row of the baseline's plans in a store (``baseline``), or of the one
    other planner's; either under one configuration."""
    with Store(path, read_only=True) as store:
        rows = [r for r in store.rows() if (r["planner"] == BASELINE) == baseline]
    names = {(r["config_name"], r["planner"]) for r in rows}
    if len(names) != 1:
        wanted = "the baseline" if baseline else "one compared planner"
        raise SystemExit(f"rejudge_thresholds: {path}: holds {sorted(names)}, {wanted} "
                         "under one configuration wanted")
    return {(r["scene"], int(r["angle"])): r for r in rows}


def tables(rows: list[dict]) -> tuple[str, str, str, str]:
    """Table III aggregate / bookshelf / refrigerator (%) and Table IV's five classes (%)."""
    t3 = {t["environment"]: t["success_or_partial_pct"] for t in table_iii(rows)}
    t4 = {t["outcome"]: t["pct"] for t in table_iv(rows)}
    return (f"{t3.get('aggregate', np.nan):.1f} %", f"{t3.get('bookshelf', np.nan):.1f}",
            f"{t3.get('fridge', np.nan):.1f}",
            " / ".join(f"{t4.get(k, 0.0):.1f}" for k in CLASSES))


def difference(pairs: list[tuple[dict, dict]], settings: ReportConfig) -> str:
    """Mean compared - baseline P(success) [95 %] (better / same / worse) over ``pairs``."""
    if not pairs:
        return "-"
    d = np.array([row_p_success(c) - row_p_success(b) for b, c in pairs])
    low, high = bootstrap_interval(d, settings)
    votes = [verdict(row_grade(c), row_grade(b)) for b, c in pairs]
    return (f"{d.mean():+.3f} [{low:+.3f}, {high:+.3f}] ({votes.count('better')}/"
            f"{votes.count('same')}/{votes.count('worse')})")


def report(settings_stores: list[tuple[str, str, str]]) -> str:
    """The markdown tables (module docstring)."""
    settings = ReportConfig()
    head = ["| setting | planner | Table III (aggregate) | bookshelf | refrigerator | Table IV: "
            "S / PS / FG / OF / KF % | P(success) | compared - baseline [95 %] (b/s/w) | "
            "bookshelf | refrigerator |", "|---|---|---:|---:|---:|---:|---:|---:|---:|---:|"]
    levels = ["", "| setting | " + " | ".join(f"{e} {n}" for e, n in _levels()) + " |",
              "|---|" + "---:|" * len(_levels())]
    for label, base_path, compared_path in settings_stores:
        base, compared = rows_of(base_path, True), rows_of(compared_path, False)
        keys = sorted(set(base) & set(compared))
        pairs = [(base[k], compared[k]) for k in keys]
        for name, chosen in (("baseline", [b for b, _ in pairs]),
                             (next(iter(compared.values()))["planner"], [c for _, c in pairs])):
            a, bs, fr, t4 = tables(chosen)
            p = np.mean([row_p_success(r) for r in chosen])
            cells = ["", "", ""]
            if name != "baseline":
                cells = [difference(pairs, settings)] + [
                    difference([x for x in pairs if x[0]["env"] == env], settings)
                    for env in ("bookshelf", "fridge")]
            head.append(f"| {label} | {name} | {a} | {bs} | {fr} | {t4} | {p:.3f} | "
                        + " | ".join(cells) + " |")
        means = []
        for env, n in _levels():
            d = [row_p_success(c) - row_p_success(b) for b, c in pairs
                 if b["env"] == env and int(b["num_objects"]) == n]
            means.append(f"{np.mean(d):+.3f}" if d else "-")
        levels.append(f"| {label} | " + " | ".join(means) + " |")
    paper = [f"| the paper | {k} | {v[0]} | | | {v[1]} | | | | |" for k, v in PAPER.items()]
    return "\n".join(head + paper + levels)


def _levels() -> list[tuple[str, int]]:
    return [("bookshelf", n) for n in (5, 10, 15, 20)] + [("fridge", n) for n in (4, 8, 12, 16)]


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--setting", nargs=3, action="append", required=True,
                        metavar=("LABEL", "BASELINE_DB", "COMPARED_DB"))
    parser.add_argument("--out", default="")
    args = parser.parse_args(argv)
    text = report([tuple(s) for s in args.setting])
    print(text)
    if args.out:
        with open(args.out, "w") as f:
            f.write(text + "\n")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
