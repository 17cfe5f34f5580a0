#!/usr/bin/env python3
"""Benchmark: does a planner's time budget hold? Each planner plans one initialization (one
baseline candidate) under each budget, and the script prints the wall time of the planner's
call against the budget, and how far beyond it the planner ran.

    python benchmarks/bench_budgets.py                                  # the defaults below
    python benchmarks/bench_budgets.py --budgets 2 10 --planners push \
        --scenes fridge:16:16015:6

The target: a planner stops within its budget + 10 % + one indivisible step (a start planned at
another grasp height, which no solver can cut; phi's knots are cut one by one). 'longest step'
is the longest such step the planner timed in the same call, and 'holds' says whether the wall
time is within 1.1 x budget + that step. The reference in the same run is the free call (no
budget): 'free s' and 'cut' (what the budget left out). The baseline's own planning of the
angle is not part of the budget (it is the baseline's); the planning worlds are.

Scenes are the probe tier's densest (bookshelf 20 boxes, refrigerator 16), given as
kind:level:seed:angle. The physics planner runs with Sec. V's phi stages (``--physics-set``,
default 30 iterations, 10 on the sphere gripper), which is where its time goes.
"""

from __future__ import annotations

import argparse
import math
import time
from dataclasses import replace

from drake_clutter.common.config import load_config
from drake_clutter.planners.registry import get_planner
from drake_clutter.scene.generators import generate_scene

BUDGET_FIELD = {"push": "push_search.time_budget", "physics": "physics.time_budget"}


def plan_once(planner: str, scene, config, start, budget: float | None) -> dict:
    """One call of ``planner`` on the baseline candidate ``start`` under ``budget`` (s; None:
    free): its wall time (s), what its budget record says was cut and its longest step."""
    section, name = BUDGET_FIELD[planner].split(".")
    config = replace(config, **{section: replace(getattr(config, section), **{name: budget})})
    tic = time.monotonic()
    (candidate,) = get_planner(planner).plan(scene, config, start=[start])
    wall = time.monotonic() - tic
    record = candidate.details.get("budget") or candidate.details.get("time_budget") or {}
    cut = record.get("cut", [*record.get("stopped", []), *record.get("skipped", [])])
    return {"wall": wall, "cut": cut, "longest": float(record.get("longest_step", 0.0)),
            "chosen": candidate.details.get("chosen", record.get("returned", ""))}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--budgets", type=float, nargs="+", default=[2.0, 10.0, 30.0, 120.0])
    parser.add_argument("--planners", nargs="+", default=["push", "physics"],
                        choices=sorted(BUDGET_FIELD))
    parser.add_argument("--scenes", nargs="+",
                        default=["bookshelf:20:6015:6", "fridge:16:16015:6"])
    parser.add_argument("--set", action="append", default=[], help="section.field=value")
    parser.add_argument("--physics-set", action="append",
                        default=["physics.iterations=30", "physics.sphere_iterations=10"])
    parser.add_argument("--no-free", action="store_true", help="skip the free reference call")
    args = parser.parse_args()
    print(f"{'scene':>20} {'planner':>8} {'budget s':>8} {'wall s':>8} {'over s':>7} "
          f"{'wall/budget':>11} {'longest step':>12} {'holds':>5}  cut")
    worst = {}
    for item in args.scenes:
        kind, level, seed, angle = item.split(":")
        base = load_config(None, args.set)
        scene = generate_scene(kind, int(level), int(seed), base.generator)
        (start,) = get_planner("baseline").plan(scene, base, angles=[int(angle)])
        if not start.ok:
            print(f"{item:>20} the baseline found no path ({start.reason}); skipped")
            continue
        for planner in args.planners:
            config = load_config(None, [*args.set, *(args.physics_set if planner == "physics"
                                                     else [])])
            runs = [] if args.no_free else [None]
            for budget in [*runs, *args.budgets]:
                r = plan_once(planner, scene, config, start, budget)
                if budget is None:
                    print(f"{item:>20} {planner:>8} {'free':>8} {r['wall']:8.1f} {'':>7} "
                          f"{'':>11} {r['longest']:12.2f} {'':>5}  chosen {r['chosen']}")
                    continue
                over = r["wall"] - budget
                holds = r["wall"] <= 1.1 * budget + r["longest"]
                worst[planner] = max(worst.get(planner, -math.inf), over - 0.1 * budget
                                     - r["longest"])
                print(f"{item:>20} {planner:>8} {budget:8.1f} {r['wall']:8.1f} {over:+7.1f} "
                      f"{r['wall'] / budget:11.2f} {r['longest']:12.2f} "
                      f"{'yes' if holds else 'NO':>5}  {', '.join(r['cut']) or '-'}")
    for planner, excess in worst.items():
        print(f"{planner}: largest excess over budget + 10 % + longest step: {excess:+.2f} s")


if __name__ == "__main__":
    main()
