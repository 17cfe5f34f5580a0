"""Planners of several stores side by side on the initializations they share.

A row is named ``<configuration>/<planner>``. Only the (scene, angle) pairs that every named
row has are read, so a store of 8 scenes set beside one of 24 compares on the 8. The table:
Table III (scene success or partial, nominal replays; robust scene success) per row, and each
row's P(success) per initialization minus a reference row's, with the report's seeded bootstrap
interval and its better / same / worse counts by Sec. VI-A's grade. ``drake-clutter stores
compare A.db B.db --against NAME`` prints it.
"""

from __future__ import annotations

from collections import defaultdict
from collections.abc import Sequence

import numpy as np

from drake_clutter.common.config import ReportConfig
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.experiments.paired import bootstrap_interval, row_grade, row_p_success, verdict
from drake_clutter.experiments.report import table_iii
from drake_clutter.experiments.store import Store

Named = dict[str, dict[tuple[str, int], dict]]  # row name -> (scene, angle) -> stored row


def load_stores(paths: Sequence[str]) -> Named:
    """<configuration>/<planner> -> (scene, angle) -> row, from every store; a name found in
    two stores raises InputError naming the second."""
    named: Named = defaultdict(dict)
    owner: dict[str, str] = {}
    for path in paths:
        with Store(path, read_only=True) as store:
            for row in store.rows():
                name = f"{row['config_name']}/{row['planner']}"
                if owner.setdefault(name, path) != path:
                    raise InputError(path, "rows", f"{name} is also in {owner[name]}")
                named[name][(row["scene"], row["angle"])] = row
    return dict(named)


def shared(named: Named) -> Named:
    """The rows of the initializations every name has, in (scene, angle) order."""
    keys = set.intersection(*(set(rows) for rows in named.values())) if named else set()
    return {name: {k: rows[k] for k in sorted(keys)} for name, rows in named.items()}


def compare_table(named: Named, against: str, settings: ReportConfig | None = None) -> str:
    """The Markdown comparison of the shared rows (module docstring) against the row
    ``against``; an unknown ``against`` raises InputError naming ``--against``."""
    if against not in named:
        raise InputError("<command line>", "--against",
                         f"no row {against} (have: {', '.join(named) or 'none'})")
    settings = settings or ReportConfig()
    reference = named[against]
    if not reference:
        raise InputError("<command line>", "stores", "no initialization is shared by "
                         f"every row ({', '.join(named)})")
    lines = [f"{len(reference)} initializations, {len({s for s, _ in reference})} scenes "
             f"shared by {', '.join(named)}", "",
             "| row | Table III success or partial | robust scene success | P(success) mean | "
             f"minus {against} [95 % CI] | better / same / worse |",
             "|---|---:|---:|---:|---:|---:|"]
    for name, rows in named.items():
        lines.append(_row_line(name, rows, reference, name == against, settings))
    return "\n".join(lines) + "\n"


def _row_line(name: str, rows: dict, reference: dict, is_reference: bool,
              settings: ReportConfig) -> str:
    """One row of `compare_table`."""
    t3 = next(t for t in table_iii(list(rows.values())) if t["environment"] == "aggregate")
    p = np.array([row_p_success(r) for r in rows.values()])
    cells = ["", ""]
    if not is_reference:
        d = p - np.array([row_p_success(reference[k]) for k in rows])
        low, high = bootstrap_interval(d, settings)
        votes = [verdict(row_grade(rows[k]), row_grade(reference[k])) for k in rows]
        cells = [f"{d.mean():+.3f} [{low:+.3f}, {high:+.3f}]",
                 f"{votes.count('better')} / {votes.count('same')} / {votes.count('worse')}"]
    return (f"| {name} | {t3['success_or_partial_pct']:.1f} % | "
            f"{t3['robust_success_pct']:.1f} % | {p.mean():.3f} | {cells[0]} | {cells[1]} |")
