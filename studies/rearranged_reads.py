#!/usr/bin/env python3
"""phi's reading of the plans the rearrange planner returned rearranged, against the judge.

    python studies/rearranged_reads.py STORE.db [STORE.db ...] [--members 8] [--part 0/1]
        [--out reads.json] [--read reads.json ...]

For every rearrange unit whose returned plan is a sequence of pushes and the reach (the
record's ``chosen`` names a sequence) and that the robust judge replayed, the plan is rolled out
again in the judge in phi (`phi_judge.judge_paths`, ``complete=True`` so every member's box
fates are read) in members 0 .. ``--members`` - 1 (the planner judged on the first
``phi_judge.members`` and vetoed on the next ``veto_members``). Printed per plan: phi's
P(success), its members' margins (`phi_judge.member_margin`: the largest of the jam, the
tilt, the edge, the zone and the intrusion over their limits; above 1 decides a failure) and
the judge's robust P(success) and kinematic failures. Then, for thresholds on the largest
member margin, the plans a sequence acceptance would keep and refuse, with the judge's mean
P(success) of each: does any margin in phi tell the plans the judge fails from those it
passes? ``--part i/n`` reads every n-th plan from the i-th (two processes on two cores);
``--out`` saves the reads, ``--read`` prints the table of saved ones.

Its dated results: docs/log/rearrange.md.
"""

from __future__ import annotations

import argparse
import json
import math
import sys

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.experiments.paired import wilson_interval
from drake_clutter.experiments.specs import stored_scene
from drake_clutter.experiments.store import Store
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.phi_judge import judge_paths
from drake_clutter.trajectory import Trajectory

THRESHOLDS = (0.25, 0.5, 0.75, 1.0)


def rearranged(dbs: list[str]) -> list[dict]:
    """The rearranged units of the stores the robust judge replayed, in store order."""
    out = []
    for db in dbs:
        with Store(db, read_only=True) as store:
            rows = store.rows()
        for row in rows:
            details = ((row.get("plan") or {}).get("details") or {})
            robust = (row.get("outcome") or {}).get("robust")
            if (row["planner"] == "rearrange" and str(details.get("chosen", "")).startswith(
                    "room") and robust and (row.get("plan") or {}).get("trajectory")):
                out.append({"db": db, "scene": row["scene"], "angle": row["angle"],
                            "config": row["config_name"],
                            "phi_planner": details["verdicts"][details["chosen"]]["p_success"],
                            "judge_p": float(robust["p_success"]),
                            "judge_kf": robust["kinds"].count("kinematic_failure")
                            / len(robust["kinds"]),
                            "trajectory": row["plan"]["trajectory"]})
    return out


def read(unit: dict, members: int) -> dict:
    """``unit`` with phi's rollout of its plan in ``members`` members: P(success), the
    classes, each member's margin (None: infinite)."""
    config = load_config()
    scene = stored_scene(unit["scene"], config)
    path = Trajectory.from_data(unit["trajectory"])
    verdict = judge_paths(scene, {"plan": path.q}, path.times, config,
                          PlanningContext(scene, config).arm(), members=range(members))["plan"]
    margins = [r.margin if math.isfinite(r.margin) else None for r in verdict.readings]
    return {k: v for k, v in unit.items() if k != "trajectory"} | {
        "phi_p": verdict.p_success, "kinds": [r.kind for r in verdict.readings],
        "margins": margins}


def worst(margins: list) -> float:
    """The largest member margin (inf for an unreadable member)."""
    return max(math.inf if m is None else m for m in margins)


def table(reads: list[dict]) -> None:
    """Per plan, then per threshold on the largest member margin."""
    print(f"{'scene':>22} {'angle':>5} {'phi (planner)':>13} {'phi':>5} {'worst margin':>12} "
          f"{'judge':>6} {'judge KF':>8}")
    for r in sorted(reads, key=lambda r: worst(r["margins"])):
        print(f"{r['scene']:>22} {r['angle']:>5} {r['phi_planner']:>13.2f} {r['phi_p']:>5.2f} "
              f"{worst(r['margins']):>12.2f} {r['judge_p']:>6.2f} {r['judge_kf']:>8.2f}")
    n = len(reads)
    print(f"\n{n} plans; phi {np.mean([r['phi_p'] for r in reads]):.3f}, judge "
          f"{np.mean([r['judge_p'] for r in reads]):.3f}")
    print("| largest member margin at most | kept | judge P(success) kept | refused | judge "
          "P(success) refused | judge KF share refused |\n|---:|---:|---:|---:|---:|---:|")
    for t in THRESHOLDS:
        kept = [r for r in reads if worst(r["margins"]) <= t]
        out = [r for r in reads if worst(r["margins"]) > t]
        print(f"| {t:g} | {len(kept)} | {_mean(kept, 'judge_p')} | {len(out)} | "
              f"{_mean(out, 'judge_p')} | {_mean(out, 'judge_kf')} |")
    good = sum(r["judge_p"] >= 0.5 for r in reads)
    low, high = wilson_interval(good, n)
    print(f"judge P(success) >= 0.5: {good}/{n} = {good / max(n, 1):.2f} [{low:.2f}, {high:.2f}]")


def _mean(reads: list[dict], key: str) -> str:
    """The mean of ``key`` over ``reads`` as text ('-' for none)."""
    return f"{np.mean([r[key] for r in reads]):.3f}" if reads else "-"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("dbs", nargs="*")
    parser.add_argument("--members", type=int, default=8)
    parser.add_argument("--part", default="0/1", help="i/n: every n-th plan from the i-th")
    parser.add_argument("--out", help="save the reads (JSON)")
    parser.add_argument("--read", nargs="+", default=[], help="saved reads to print")
    args = parser.parse_args(argv)
    try:
        index, count = (int(x) for x in args.part.split("/"))
        if not 0 <= index < count:
            raise ValueError(args.part)
    except ValueError:
        print(f"rearranged_reads: --part: expected i/n with 0 <= i < n, got {args.part}",
              file=sys.stderr)
        return 2
    reads = [r for f in args.read for r in json.load(open(f))]
    units = rearranged(args.dbs)[index::count]
    for k, unit in enumerate(units):
        reads.append(read(unit, args.members))
        print(f"{k + 1}/{len(units)} {unit['scene']} {unit['angle']}: phi "
              f"{reads[-1]['phi_p']:.2f}, judge {unit['judge_p']:.2f}", flush=True)
    if args.out:
        json.dump(reads, open(args.out, "w"))
    table(reads)
    return 0


if __name__ == "__main__":
    sys.exit(main())
