#!/usr/bin/env python3
"""Has the Bullet judge (Sec. III) converged? Its verdicts and time per plan against its step and
solver iterations, and against its kinematic-failure thresholds.

    python studies/judge_convergence.py --db RUN.db [--db RUN2.db ...] [--rates 240 480 960]
        [--iterations 10 50 150] [--thresholds RATE ITERATIONS | --no-thresholds] [--workers 2]
        [--out results.json] [--set FIELD=VALUE ...]
    python studies/judge_convergence.py --from results.json   # print again, no replays

Every distinct stored plan of the stores (both planners, every configuration; a plan stored
twice is replayed once; generated scenes are rebuilt from their names) is replayed at every
``evaluation.sim_dt`` = 1 / rate and ``evaluation.solver_iterations`` of the grid. The motor
updates and checks keep their period (``monitor_interval`` scaled with the rate: 4 steps at
240 Hz, 16 at 960 Hz), so only the physics gets finer. Printed per setting: the mean seconds per
plan, how many plans get the class the finest setting gives (with a Wilson 95 % interval), and
the kinematic failures. Then, at the ``--thresholds`` setting (default: the finest), every plan
again with each kinematic-failure threshold (``max_static_force``: the arm's and a box's force
into the shelf; ``max_tracking_error``; ``static_penetration``) at half and at one and a half
times its value: how many classes move. ``--out`` keeps every verdict (class, reason, seconds)
as JSON; ``--from`` prints such a file again.

Its dated results: docs/log/decisions.md, docs/log/evaluation.md.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
from collections import Counter
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace

from drake_clutter.common.config import load_config
from drake_clutter.common.typed_yaml import EXIT_USAGE, InputError
from drake_clutter.evaluation.judge import evaluate
from drake_clutter.experiments.paired import wilson_interval
from drake_clutter.experiments.specs import stored_scene
from drake_clutter.experiments.store import Store
from drake_clutter.trajectory import Trajectory

BASE_RATE = 240  # Hz at which monitor_interval is the configuration's own
THRESHOLDS = ("max_static_force", "max_tracking_error", "static_penetration")
FACTORS = (0.5, 1.5)


def stored_plans(paths: list[str]) -> list[dict]:
    """[{scene, planner, configuration, angle, trajectory (data)}], one per distinct plan."""
    seen, out = set(), []
    for path in paths:
        with Store(path, read_only=True) as store:
            rows = store.rows()
        for r in rows:
            traj = (r.get("plan") or {}).get("trajectory")
            if not traj:
                continue
            key = hashlib.sha1(json.dumps([r["scene"], traj], sort_keys=True).encode()).hexdigest()
            if key in seen:
                continue
            seen.add(key)
            out.append({"scene": r["scene"], "planner": r["planner"],
                        "configuration": r["config_name"], "angle": r["angle"],
                        "trajectory": traj})
    return out


def settings(args) -> list[dict]:
    """The grid's evaluation overrides, cheapest first; the finest is the last."""
    grid = [{"label": f"{rate} Hz, {it} it", "rate": rate, "iterations": it}
            for rate in sorted(args.rates) for it in sorted(args.iterations)]
    if args.no_thresholds:
        return grid
    if args.thresholds:
        rate, it = args.thresholds
    else:
        rate, it = max(args.rates), max(args.iterations)
    for name in THRESHOLDS:
        for factor in FACTORS:
            grid.append({"label": f"{name} x{factor:g} at {rate} Hz, {it} it", "rate": rate,
                         "iterations": it, "threshold": name, "factor": factor})
    return grid


def _evaluation(config, setting: dict):
    """The evaluation section of one grid setting."""
    interval = max(1, round(config.monitor_interval * setting["rate"] / BASE_RATE))
    changes = {"sim_dt": 1.0 / setting["rate"], "solver_iterations": setting["iterations"],
               "monitor_interval": interval}
    if "threshold" in setting:
        name = setting["threshold"]
        changes[name] = getattr(config, name) * setting["factor"]
    return replace(config, **changes)


def judge_plan(task) -> list[dict]:
    """Every grid setting's verdict on one plan: [{kind, reason, seconds}]."""
    plan, grid, overrides = task
    config = load_config(None, overrides)
    scene = stored_scene(plan["scene"], config)
    trajectory = Trajectory.from_data(plan["trajectory"])
    out = []
    for setting in grid:
        outcome = evaluate(scene, trajectory, _evaluation(config.evaluation, setting))
        out.append({"kind": str(outcome.kind), "reason": outcome.reason,
                    "seconds": outcome.wall_time})
    return out


def report(results: dict) -> None:
    """Prints the grid table, the moves against the finest setting and the thresholds."""
    grid, plans, verdicts = results["grid"], results["plans"], results["verdicts"]
    sweep = [i for i, s in enumerate(grid) if "threshold" not in s]
    finest = sweep[-1]
    n = len(plans)
    print(f"{n} plans ({Counter(p['planner'] for p in plans)}); reference: "
          f"{grid[finest]['label']}")
    print(f"{'setting':34} {'s/plan':>7} {'classes as finest':>18} {'95% CI':>13} "
          f"{'kin. fail.':>10} {'same reason':>11}")
    for i in sweep:
        same = sum(v[i]["kind"] == v[finest]["kind"] for v in verdicts)
        reason = sum(v[i]["reason"] == v[finest]["reason"] for v in verdicts)
        lo, hi = wilson_interval(same, n)
        seconds = sum(v[i]["seconds"] for v in verdicts) / max(n, 1)
        kin = sum(v[i]["kind"] == "kinematic_failure" for v in verdicts)
        print(f"{grid[i]['label']:34} {seconds:7.3f} {same:>8} of {n:<4} ({100 * same / n:5.1f} %)"
              f" {100 * lo:5.1f}-{100 * hi:5.1f} % {kin:>10} {reason:>11}")
    first = sweep[0]
    moves = Counter((v[first]["kind"], v[finest]["kind"]) for v in verdicts
                    if v[first]["kind"] != v[finest]["kind"])
    print(f"\nclass moves from {grid[first]['label']} to {grid[finest]['label']}:")
    for (a, b), count in moves.most_common():
        print(f"  {a} -> {b}: {count}")
    if len(sweep) == len(grid):
        return
    base = next((i for i in sweep if grid[i]["rate"] == grid[-1]["rate"]
                 and grid[i]["iterations"] == grid[-1]["iterations"]), finest)
    print(f"\nthresholds, each at half and one and a half times, at {grid[base]['label']}:")
    for i, s in enumerate(grid):
        if "threshold" not in s:
            continue
        changed = Counter((v[base]["kind"], v[i]["kind"]) for v in verdicts
                          if v[i]["kind"] != v[base]["kind"])
        kin = sum(v[i]["kind"] == "kinematic_failure" for v in verdicts)
        text = ", ".join(f"{a} -> {b} {c}" for (a, b), c in changed.most_common()) or "none"
        print(f"  {s['threshold']:20} x{s['factor']:<4g} classes moved {sum(changed.values()):3}"
              f" (kinematic failures {kin}): {text}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--db", action="append", default=[], help="an experiment store")
    parser.add_argument("--from", dest="source", help="print a --out file again")
    parser.add_argument("--rates", nargs="+", type=int, default=[240, 480, 960],
                        help="Bullet step rates, Hz (sim_dt = 1 / rate)")
    parser.add_argument("--iterations", nargs="+", type=int, default=[10, 50, 150])
    parser.add_argument("--thresholds", nargs=2, type=int, metavar=("RATE", "ITERATIONS"),
                        help="the setting the thresholds are varied at (default: the finest)")
    parser.add_argument("--no-thresholds", action="store_true",
                        help="only the grid of rates and iterations")
    parser.add_argument("--workers", type=int, default=2)
    parser.add_argument("--limit", type=int, help="only the first N plans")
    parser.add_argument("--out", help="write every verdict to this JSON file")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    args = parser.parse_args(argv)
    try:
        if args.source:
            with open(args.source, encoding="utf-8") as handle:
                report(json.load(handle))
            return 0
        if not args.db:
            raise InputError("<command line>", "--db", "name at least one store (or --from)")
        if min(args.rates) < 1 or min(args.iterations) < 1 or args.workers < 1:
            raise InputError("<command line>", "--rates/--iterations/--workers",
                             "must be at least 1")
        load_config(None, args.set)
        plans = stored_plans(args.db)[:args.limit]
        if not plans:
            raise InputError(args.db[0], "results", "no stored plan with a trajectory")
    except (InputError, OSError) as exc:
        print(f"judge_convergence.py: {exc}", file=sys.stderr)
        return EXIT_USAGE
    grid = settings(args)
    tasks = [(p, grid, args.set) for p in plans]
    verdicts = []
    with ProcessPoolExecutor(args.workers) as pool:
        for k, result in enumerate(pool.map(judge_plan, tasks), 1):
            verdicts.append(result)
            print(f"[{k}/{len(plans)}] {plans[k - 1]['scene']} {plans[k - 1]['planner']} "
                  f"angle {plans[k - 1]['angle']}: "
                  + " ".join(v["kind"][:4] for v in result), flush=True)
    results = {"grid": grid, "plans": [{k: v for k, v in p.items() if k != "trajectory"}
                                       for p in plans], "verdicts": verdicts}
    if args.out:
        with open(args.out, "w", encoding="utf-8") as handle:
            json.dump(results, handle, indent=1)
    report(results)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
