#!/usr/bin/env python3
"""How many of the baseline's failed approach angles have another straight start: the gate
before the push planner plans from them.

    python studies/recover_failures.py [--tier paper_protocol] [--jobs 2] [--out FILE.jsonl]
        [--judge]

For every scene of the tier and every approach angle (all 14, as paper_protocol plans them),
the baseline's path is planned as a tier unit plans it (alone, no neighbour's IK solution).
Where it fails (IK, the optimiser, or the dense shelf check), the push planner's other straight
starts are planned as it plans them (`starts.planned_starts`: the grasp heights of
``starts.grasp_heights`` and yaws of ``starts.approach_offsets``, then the line turned by
``starts.recovery_turns``). Printed: per environment and clutter level, the failed angles, by
status, how many have at least one start and of those how many only turned; the tier's own
angles (the probe's 4, 6, 7, 9) apart.

With ``--judge``, every failed angle is then run as the tier runs a push unit
(`specs.run_unit`: the push planner, then the robust judge, K = 8): printed per angle, what the
push planner returned (the start it took, or the failure) and its robust P(success); the
baseline's P(success) there is 0 (no plan).

Its dated results: docs/log/push_planner.md.
"""

from __future__ import annotations

import argparse
import json
from collections import Counter, defaultdict
from concurrent.futures import ProcessPoolExecutor

from drake_clutter.common.config import load_config
from drake_clutter.experiments.specs import expand, load_spec, run_unit
from drake_clutter.planners import baseline
from drake_clutter.planners.approach import approach_angles
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.registry import get_planner
from drake_clutter.planners.starts import planned_starts, start_key
from drake_clutter.scene.generators import SceneSpec, generate_scene

FIXED = ["dynamics.workers=0", "evaluation.robust_replays=8"]
PROBE_ANGLES = (4, 6, 7, 9)


def one(source: tuple) -> list[dict]:
    """Every angle of one generated scene ``source``: the baseline's status, and for a failure
    the other starts that planned."""
    config = load_config(None, FIXED)
    _, kind, n, seed = source
    scene = generate_scene(kind, int(n), int(seed), config.generator)
    context = PlanningContext(scene, config)
    rows = []
    for index, alpha in enumerate(approach_angles(config.baseline)):
        candidate = baseline.plan_angle(context.baseline_at(
            config.baseline.grasp_height_fraction), float(alpha), index)
        row = {"scene": scene.name, "kind": kind, "level": int(n), "angle": index,
               "status": candidate.status.value, "reason": candidate.reason}
        if not candidate.ok:  # the starts the push planner plans from, as it plans them
            found = planned_starts(context, candidate)
            row["starts"] = [start_key(*key) for key in found]
            row["turned"] = any(offset != 0.0 for _, offset in found)
        rows.append(row)
    return rows


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--tier", default="paper_protocol")
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--out", default="")
    parser.add_argument("--judge", action="store_true")
    args = parser.parse_args(argv)
    spec, _ = load_spec(args.tier)
    sources = list(dict.fromkeys(u.source for u in expand(spec) if u.source[0] == "generated"))
    rows = []
    with ProcessPoolExecutor(args.jobs) as pool:
        for found in pool.map(one, sources):
            rows.extend(found)
            print(f"{found[0]['scene']}: {sum(r['status'] != 'ok' for r in found)} failed, "
                  f"{sum(bool(r.get('starts')) for r in found)} with a start", flush=True)
    if args.out:
        with open(args.out, "w") as f:
            f.writelines(json.dumps(r) + "\n" for r in rows)
    summarise(rows)
    if args.judge:
        judge_failures(rows, args.jobs, args.out)
    return 0


def judged(row: dict) -> dict:
    """The push unit of a failed angle ``row``, planned and judged as the tier does."""
    spec = SceneSpec.from_name(row["scene"])
    unit = {"source": ("generated", spec.kind, spec.num_objects, spec.seed),
            "overrides": FIXED, "planner": "push", "angle": row["angle"]}
    result = run_unit(unit)
    plan = result["plan"] or {}
    robust = result["outcome"].get("robust") or {}
    return row | {"push_status": plan.get("status"),
                  "chosen": get_planner("push").record(plan.get("details") or {}).chosen,
                  "kind_nominal": result["outcome"]["kind"],
                  "p_success": robust.get("p_success", 0.0),
                  "seconds": result["timings"].get("plan")}


def judge_failures(rows: list[dict], jobs: int, out: str) -> None:
    """Runs and prints the push unit of every failed angle (module docstring)."""
    failed = [r for r in rows if r["status"] != "ok"]
    print(f"\nthe push planner on the {len(failed)} failed angles (robust judge):")
    results = []
    with ProcessPoolExecutor(jobs) as pool:
        for r in pool.map(judged, failed):
            results.append(r)
            print(f"  {r['scene']} {r['angle']:>2} {r['status']:>22} -> {r['push_status']:>14} "
                  f"{str(r['chosen']):>14} {r['kind_nominal']:>16} P {r['p_success']:.3f} "
                  f"{r['seconds'] or 0:6.1f} s", flush=True)
    if out:
        with open(out.replace(".jsonl", "_judged.jsonl"), "w") as f:
            f.writelines(json.dumps(r) + "\n" for r in results)
    for label, keep in (("all 14 angles", lambda r: True),
                        ("probe angles", lambda r: r["angle"] in PROBE_ANGLES)):
        group = [r for r in results if keep(r)]
        planned = sum(r["push_status"] == "ok" for r in group)
        p = [r["p_success"] for r in group]
        print(f"{label}: {len(group)} failed, {planned} planned, mean robust P(success) "
              f"{sum(p) / max(len(p), 1):.3f}, with P >= 0.5: {sum(x >= 0.5 for x in p)}")


def summarise(rows: list[dict]) -> None:
    """Prints the failed angles per environment and level, by status, and those with a start."""
    for label, keep in (("all 14 angles", lambda r: True),
                        ("probe angles", lambda r: r["angle"] in PROBE_ANGLES)):
        print(f"\n{label}: env level  units  failed  with a start (turned)  by status")
        groups = defaultdict(list)
        for r in rows:
            if keep(r):
                groups[(r["kind"], r["level"])].append(r)
        total = Counter()
        for key in sorted(groups):
            g = groups[key]
            failed = [r for r in g if r["status"] != "ok"]
            recovered = [r for r in failed if r.get("starts")]
            turned = sum(bool(r.get("turned")) for r in failed)
            status = Counter(r["status"] for r in failed)
            total.update(units=len(g), failed=len(failed), recovered=len(recovered), turned=turned)
            print(f"  {key[0]:>9} {key[1]:>3} {len(g):>6} {len(failed):>7} {len(recovered):>13}"
                  f" ({turned})  {dict(status)}")
        print(f"  {'total':>13} {total['units']:>6} {total['failed']:>7} "
              f"{total['recovered']:>13} ({total['turned']})")


if __name__ == "__main__":
    raise SystemExit(main())
