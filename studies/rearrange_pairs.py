#!/usr/bin/env python3
"""The rearrange planner against the planner it starts from, per initialization, on a store.

    python studies/rearrange_pairs.py --db STORE.db [--against push]

For every initialization (scene, angle, configuration) with both a ``rearrange`` row and an
``--against`` row: the robust judge's P(success) difference, rearrange minus the other, its
mean with the report's seeded bootstrap interval, how many are better, the same and worse; why
the push answer stood where it did (``details["why"]``) and, where it rearranged, both
P(success), the pushes and the planning seconds (the rearrange unit's, which includes the push
planner, and its excess over the push unit's); objects falling per planner.

Its dated results: docs/log/rearrange.md.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter

import numpy as np

from drake_clutter.common.config import Config
from drake_clutter.experiments.paired import bootstrap_interval
from drake_clutter.experiments.store import Store


def pairs(rows: list[dict], against: str) -> list[tuple[dict, dict]]:
    """(rearrange row, ``against`` row) per initialization that has both."""
    by_key: dict = {}
    for r in rows:
        by_key.setdefault((r["scene"], r["angle"], r["config_name"]), {})[r["planner"]] = r
    return [(v["rearrange"], v[against]) for _, v in sorted(by_key.items())
            if "rearrange" in v and against in v]


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", required=True)
    parser.add_argument("--against", default="push")
    args = parser.parse_args(argv)
    try:
        with Store(args.db, read_only=True) as store:
            rows = store.rows()
    except Exception as err:  # an unreadable store is one line, not a traceback
        print(f"rearrange_pairs: --db: {err}", file=sys.stderr)
        return 2
    found = pairs(rows, args.against)
    if not found:
        print(f"rearrange_pairs: --db: no initialization has both rearrange and "
              f"{args.against} rows", file=sys.stderr)
        return 2
    diff = np.array([(a["p_success"] or 0.0) - (b["p_success"] or 0.0) for a, b in found])
    lo, hi = bootstrap_interval(diff, Config().report)
    print(f"rearrange - {args.against}, P(success): {diff.mean():+.3f} [{lo:+.3f}, {hi:+.3f}] "
          f"over {len(diff)}: better {int(np.sum(diff > 0))}, same {int(np.sum(diff == 0))}, "
          f"worse {int(np.sum(diff < 0))}")
    details = [((a["plan"] or {}).get("details") or {}) for a, _ in found]
    print("push answer kept:", dict(Counter(d.get("why") for d in details
                                            if d.get("chosen", "push") == "push")))
    done = [(a, b, d) for (a, b), d in zip(found, details, strict=True)
            if d.get("chosen", "push") != "push"]
    for a, b, d in done:
        print(f"  {a['scene']} angle {a['angle']}: {b['p_success']:.2f} -> {a['p_success']:.2f}"
              f", {len(d.get('moves', []))} pushes, {a['timings']['plan']:.1f} s")
    if done:
        total = np.array([a["timings"]["plan"] for a, _, _ in done])
        extra = total - np.array([b["timings"]["plan"] for _, b, _ in done])
        print(f"rearranged {len(done)}: planning s mean {total.mean():.1f}, median "
              f"{np.median(total):.1f}, p90 {np.percentile(total, 90):.1f}; after the "
              f"{args.against} planner mean {extra.mean():.1f}")
    for planner in sorted({r["planner"] for r in rows}):
        kinds = [r["kind"] for r in rows if r["planner"] == planner]
        print(f"{planner}: objects falling {kinds.count('objects_falling') / len(kinds):.1%} "
              f"of {len(kinds)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
