#!/usr/bin/env python3
"""Planners of several stores side by side on the initializations they share: Table III
(scene success or partial, nominal replays; robust scene success) per configuration/planner,
and each one's P(success) per initialization minus a reference's, with the report's seeded
bootstrap interval and its better / same / worse counts by Sec. VI-A's grade.

    python benchmarks/stores_beside.py paper_protocol.db sec5_paper_protocol.db \
        --against defaults/baseline

A row is named <configuration>/<planner>. Only the (scene, angle) pairs that every named row
has are read, so a store of 8 scenes set beside one of 24 compares on the 8. Two rows with the
same name in two stores (the same planner and configuration name) are an error.
"""

from __future__ import annotations

import argparse
import sys
from collections import defaultdict

import numpy as np

from drake_clutter.common.config import ReportConfig
from drake_clutter.experiments.paired import bootstrap_interval, row_grade, row_p_success, verdict
from drake_clutter.experiments.report import table_iii
from drake_clutter.experiments.store import Store


def load(paths: list[str]) -> dict[str, dict[tuple[str, int], dict]]:
    """<configuration>/<planner> -> (scene, angle) -> row, from every store."""
    named: dict[str, dict[tuple[str, int], dict]] = defaultdict(dict)
    owner: dict[str, str] = {}
    for path in paths:
        with Store(path, read_only=True) as store:
            for row in store.rows():
                name = f"{row['config_name']}/{row['planner']}"
                if owner.setdefault(name, path) != path:
                    sys.exit(f"stores_beside: {path}: {name} is also in {owner[name]}")
                named[name][(row["scene"], row["angle"])] = row
    return dict(named)


def shared(named: dict[str, dict]) -> dict[str, dict]:
    """The rows of the initializations every name has."""
    keys = set.intersection(*(set(rows) for rows in named.values()))
    return {name: {k: rows[k] for k in sorted(keys)} for name, rows in named.items()}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("stores", nargs="+")
    parser.add_argument("--against", required=True, help="<configuration>/<planner>")
    args = parser.parse_args(argv)
    named = shared(load(args.stores))
    if args.against not in named:
        sys.exit(f"stores_beside: --against: no {args.against} (have: {', '.join(named)})")
    settings = ReportConfig()
    reference = named[args.against]
    print(f"{len(reference)} initializations, "
          f"{len({s for s, _ in reference})} scenes shared by {', '.join(named)}\n")
    print("| row | Table III success or partial | robust scene success | "
          f"P(success) mean | minus {args.against} [95 % CI] | better / same / worse |")
    print("|---|---:|---:|---:|---:|---:|")
    for name, rows in named.items():
        aggregate = [t for t in table_iii(list(rows.values())) if t["environment"] == "aggregate"]
        t3 = aggregate[0]
        p = np.array([row_p_success(r) for r in rows.values()])
        cells = ["", ""]
        if name != args.against:
            d = p - np.array([row_p_success(reference[k]) for k in rows])
            low, high = bootstrap_interval(d, settings)
            votes = [verdict(row_grade(rows[k]), row_grade(reference[k])) for k in rows]
            cells = [f"{d.mean():+.3f} [{low:+.3f}, {high:+.3f}]",
                     f"{votes.count('better')} / {votes.count('same')} / {votes.count('worse')}"]
        print(f"| {name} | {t3['success_or_partial_pct']:.1f} % | "
              f"{t3['robust_success_pct']:.1f} % | {p.mean():.3f} | {cells[0]} | {cells[1]} |")
    return 0


if __name__ == "__main__":
    sys.exit(main())
