#!/usr/bin/env python3
"""Does phi's objective grade plans as the Bullet judge does?

    python benchmarks/objective_vs_judge.py --db RUN.db [--db RUN2.db ...]
        [--configurations NAME ...] [--set FIELD=VALUE ...] [--rejudge]

The physics planner can only beat the baseline in Bullet if a lower objective in phi means a
better grade there. This takes every stored plan of a shipped scene in the experiment stores
(both planners, every configuration; a plan stored twice, such as the same baseline in two
stores, is rolled out once), rolls it out in phi with every box dynamic (no pruning, so all
plans of a scene meet the same boxes) and prices it with the full stage's objective (Table I
with the Table II weights, the capsule arm and the held knots after Delta: what the planner
minimises last), with ``--set`` overrides on the defaults. The grade is the stored one
(`judge.behaviour_grade`: Sec. VI-A's class, then boxes tipped or fallen), or with
``--rejudge`` that of a fresh Bullet replay under the configuration's ``evaluation`` section
(e.g. ``--set evaluation.solver_iterations=50 --rejudge``: is a judge that resolves friction
better closer to phi?).

Printed: one line per plan (its grade and objective); then, over every two plans of the same
initialization (scene and angle) whose grades differ, how often each term and the total order
them as the judge does (agree / disagree; ties in the term are left out) - about half and half
is a coin; and per store and configuration, the physics plans whose objective is below their
baseline's, split by the stored verdict (better / same / worse).
"""

from __future__ import annotations

import argparse
import itertools
import sys
from collections import Counter, defaultdict
from dataclasses import replace

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.evaluation.judge import evaluate
from drake_clutter.evaluation.outcome import outcome_grade
from drake_clutter.experiments.report import row_grade, verdict
from drake_clutter.experiments.store import Store
from drake_clutter.planners.physics.pipeline import path_terms
from drake_clutter.planners.physics.stage import stage_problem
from drake_clutter.scene import scenes
from drake_clutter.trajectory import Trajectory

EVERY_BOX = 100.0  # m, a prune margin that keeps every box of a shelf dynamic in phi


def stored_plans(dbs: list[str], configurations: list[str]) -> list[dict]:
    """One dict per distinct stored plan of a shipped scene: scene, angle, trajectory, grade
    and the rows it came from ([(store, configuration, planner)])."""
    shipped, plans = set(scenes.shipped_scene_names()), {}
    for db in dbs:
        with Store(db, create=False) as store:
            rows = store.rows()
        for r in rows:
            if (r["scene"] not in shipped or not (r["plan"] or {}).get("trajectory")
                    or (configurations and r["config_name"] not in configurations)):
                continue
            trajectory = Trajectory.from_data(r["plan"]["trajectory"])
            key = (r["scene"], r["angle"], trajectory.q.tobytes())
            plan = plans.setdefault(key, {"scene": r["scene"], "angle": r["angle"],
                                          "trajectory": trajectory, "grade": row_grade(r),
                                          "rows": []})
            plan["rows"].append((db, r["config_name"], r["planner"]))
    return list(plans.values())


def objective_terms(scene, q: np.ndarray, config) -> dict[str, float] | None:
    """The full stage's objective of the knot path ``q`` per Table I term, every box dynamic
    in phi; None where phi cannot roll it out (a non-finite state or a Drake error: such a
    plan is reported and left out of the counts)."""
    try:
        with stage_problem(scene, q, config, "capsules") as problem:
            return path_terms(problem.augmented, problem.objective, problem.z0, q)
    except (RuntimeError, ValueError):  # Drake's solver errors
        return None


def order_agreement(plans: list[dict]) -> dict[str, Counter]:
    """Per term (and 'total'): Counter(agree=, disagree=) over the pairs of plans of one
    initialization whose grades differ."""
    groups, out = defaultdict(list), defaultdict(Counter)
    for p in plans:
        if p["terms"] is not None:
            groups[(p["scene"], p["angle"])].append(p)
    for group in groups.values():
        for a, b in itertools.combinations(group, 2):
            if a["grade"] == b["grade"]:
                continue
            for term in [*a["terms"], "total"]:
                va, vb = _value(a, term), _value(b, term)
                if va != vb:
                    out[term]["agree" if (va < vb) == (a["grade"] < b["grade"]) else
                              "disagree"] += 1
    return out


def _value(plan: dict, term: str) -> float:
    return sum(plan["terms"].values()) if term == "total" else plan["terms"][term]


def physics_below_baseline(plans: list[dict]) -> dict[tuple[str, str], Counter]:
    """Per (store, configuration): Counter of (objective below the baseline's?, verdict) over
    the physics plans with a baseline plan of the same initialization."""
    by_row = {}
    for p in plans:
        for db, config_name, planner in p["rows"]:
            by_row[(db, config_name, planner, p["scene"], p["angle"])] = p
    out = defaultdict(Counter)
    for (db, config_name, planner, scene, angle), p in by_row.items():
        base = by_row.get((db, config_name, "baseline", scene, angle))
        if planner != "physics" or base is None or None in (p["terms"], base["terms"]):
            continue
        below = _value(p, "total") < _value(base, "total")
        out[(db, config_name)][(below, verdict(p["grade"], base["grade"]))] += 1
    return out


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--db", action="append", required=True,
                        help="an experiment store whose plans to price (repeatable)")
    parser.add_argument("--configurations", nargs="+", default=[],
                        help="only these configurations' rows (default: all)")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    parser.add_argument("--rejudge", action="store_true",
                        help="grade each plan by a fresh Bullet replay, not the stored grade")
    args = parser.parse_args(argv)
    try:
        config = load_config(None, args.set)
        plans = stored_plans(args.db, args.configurations)
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if not plans:
        print(f"error: {', '.join(args.db)}: no stored plan of a shipped scene"
              + (f" in configurations {', '.join(args.configurations)}"
                 if args.configurations else ""), file=sys.stderr)
        return 2
    config = replace(config, dynamics=replace(config.dynamics, prune_margin=EVERY_BOX))
    cache = {}
    for p in plans:
        scene = cache.setdefault(p["scene"], scenes.load_shipped_scene(p["scene"]))
        p["terms"] = objective_terms(scene, np.asarray(p["trajectory"].q, float), config)
        if args.rejudge:
            p["grade"] = outcome_grade(evaluate(scene, p["trajectory"], config.evaluation))
        total = "phi failed" if p["terms"] is None else f"{_value(p, 'total'):.4g}"
        print(f"{p['scene']} angle {p['angle']} grade {p['grade']} objective {total} "
              f"({', '.join(f'{c}:{pl}' for _, c, pl in p['rows'])})", flush=True)
    print(f"\n{len(plans)} plans; pairs of one initialization with different grades, "
          "ordered by phi as by the judge:")
    for term, counts in order_agreement(plans).items():
        print(f"  {term:10} agree {counts['agree']:4}  disagree {counts['disagree']:4}")
    print("\nphysics plans with phi's objective below their baseline's, by verdict in Bullet:")
    for (db, config_name), counts in physics_below_baseline(plans).items():
        cells = [f"{'below' if below else 'above'}: "
                 + " / ".join(str(counts[(below, v)]) for v in ("better", "same", "worse"))
                 for below in (True, False)]
        print(f"  {db} ({config_name}): {'; '.join(cells)} (better / same / worse)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
