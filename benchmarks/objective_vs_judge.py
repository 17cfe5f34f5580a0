#!/usr/bin/env python3
"""Does phi's objective (one rollout, or an ensemble of K) grade plans as the judge does?

    python benchmarks/objective_vs_judge.py --db RUN.db [--db RUN2.db ...]
        [--configurations NAME ...] [--scenes NAME ...] [--set FIELD=VALUE ...] [--robust]
        [--members 1 4 8] [--margin 0.5] [--jobs 2] [--cache FILE.jsonl] [--rejudge]

The physics planner can only beat the baseline in Bullet if a lower objective in phi means a
better grade there. This takes every stored plan of the experiment stores (both planners,
every configuration, shipped and generated scenes; a plan stored twice, such as the same
baseline in two stores, is priced once), rolls it out in phi with every box dynamic (no
pruning, so all plans of a scene meet the same boxes) and prices it with the full stage's
objective (Table I with the Table II weights, the capsule arm and the held knots after Delta:
what the planner minimises last), with ``--set`` overrides on the defaults.

With ``--members`` the plan is priced in the first max(K) members of phi's ensemble
(`planners.physics.ensemble`: member 0 the scene, the others perturbed boxes with seeds
``[ensemble.seed, k]``, member 1 with Bullet's friction pairing), and the agreement is printed
for each K listed and each risk measure (mean, mean + std, CVaR of the worst half); the terms
are the members' means. Every plan of a scene meets the same members.

The judge's grade is the stored one (`judge.behaviour_grade`: Sec. VI-A's class, then boxes
tipped or fallen); with ``--robust`` the stored robust judge's (its K replays' mean class,
then mean boxes tipped or fallen; rows without robust replays are left out); with
``--rejudge`` that of a fresh nominal Bullet replay under ``evaluation``.

Besides the terms, each plan is graded in phi itself ('phi_class', `settled_class`): Sec. III's
classes read on phi's boxes after the hold tail (a box tipped or off the board, the target in
the last knot's pre-grasp zone), averaged over the members as the robust judge averages its
replays - the surrogate of the judge's classes; 'phi_class_kf' also reads a kinematic failure
where c_force holds at least one knot's worth of a contact at the judge's shelf-force limit,
'phi_class_jam' where phi's jam measure ('jam', `phi.jam`: the arm's commanded approach into a
box a rigid world would not let move, largest knot, m) reaches ``dynamics.jam_depth``.

Printed: one line per scene, start and member; then, over every two plans of the same
initialization (scene and angle) whose grades differ (with ``--margin`` also over the pairs
whose class or P(success) differs by at least that much), how often each term and the total
order them as the judge does (agree / disagree; ties in the term are left out) with a 95 %
Wilson interval of the agreement (pairs share plans, so the interval is optimistic) - about
half and half is a coin; with ``--robust`` also over the pairs whose P(success)
differs; and per store and configuration, the physics plans whose objective is below their
baseline's, split by the verdict (better / same / worse); and whether other weights would do:
a linear score of the members' log terms fitted on every scene's pairs but one and tested on
that scene's (leave one scene out). ``--cache`` keeps each priced plan
(one JSON line), so a stopped run resumes where it stopped.
"""

from __future__ import annotations

import argparse
import itertools
import json
import sys
from collections import Counter, defaultdict
from concurrent.futures import ProcessPoolExecutor
from dataclasses import replace
from pathlib import Path

import numpy as np
from scipy.optimize import minimize
from scipy.stats import binomtest

from drake_clutter.common.config import load_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.evaluation.judge import evaluate
from drake_clutter.evaluation.outcome import outcome_grade
from drake_clutter.experiments.paired import row_grade, verdict, wilson_interval
from drake_clutter.experiments.specs import stored_scene
from drake_clutter.experiments.store import stored_plans
from drake_clutter.planners.physics.ensemble import member_rollouts, risk_score
from drake_clutter.planners.physics.geometry import ArmGeometry
from drake_clutter.planners.physics.grasp_height import settled_class

EVERY_BOX = 100.0  # m, a prune margin that keeps every box of a shelf dynamic in phi
RISKS = ("mean", "mean_std", "cvar")


def _robust_grade(row: dict) -> tuple[float, float] | None:
    """(mean class, mean boxes tipped or fallen) over a row's robust replays, or None."""
    robust = (row.get("outcome") or {}).get("robust")
    if not row.get("robust_replays") or not robust:
        return None
    grades = np.asarray(robust["grades"], float)
    return float(grades[:, 0].mean()), float(grades[:, 1].mean())


def distinct_plans(dbs: list[str], configurations: list[str], robust: bool) -> list[dict]:
    """One dict per distinct stored plan: scene, angle, trajectory, grade, p_success (robust
    rows) and the rows it came from ([(store, configuration, planner)])."""
    plans = {}
    for db, r, trajectory, digest in stored_plans(dbs, configurations):
        grade = _robust_grade(r) if robust else row_grade(r)
        if grade is None:
            continue
        key = (r["scene"], r["angle"], digest)
        plan = plans.setdefault(key, {"scene": r["scene"], "angle": r["angle"],
                                      "key": "|".join(map(str, key)),
                                      "trajectory": trajectory, "grade": grade,
                                      "p_success": r.get("p_success"), "rows": []})
        plan["rows"].append((db, r["config_name"], r["planner"]))
    return list(plans.values())


def price(job: tuple) -> dict[str, dict]:
    """Every knot path of one scene (one start) in one member, every box dynamic: per plan
    key, its terms (None where phi fails) and the boxes' states after the hold tail."""
    scene_name, paths, config, member = job
    scene = stored_scene(scene_name, config)
    rollouts = member_rollouts(scene, paths, config, member, jam=True)
    return {key: {"terms": r.terms, "jam": r.jam,
                  "final": (None if r.final_boxes is None else
                            {n: b.tolist() for n, b in r.final_boxes.items()})}
            for key, r in rollouts.items()}


def _terms(plan: dict, members: int) -> list[dict | None]:
    """The plan's terms in its first ``members`` members (None where phi failed)."""
    return [m["terms"] if m else None for m in plan["members"][:members]]


def add_phi_class(plans: list[dict], config) -> None:
    """Adds 'phi_class' (`grasp_height.settled_class`), 'phi_class_kf' and 'phi_class_jam' to
    every priced member's entry: 'phi_class_kf' reads a kinematic failure (class 3) where
    c_force is at least one knot's worth of a contact at the judge's shelf-force limit
    (w_force / 2 x max_static_force^2), 'phi_class_jam' where the jam measure reaches
    ``dynamics.jam_depth``."""
    scene, geometry = None, None
    for p in sorted(plans, key=lambda p: p["scene"]):
        if scene is None or p["scene"] != scene.name:  # one scene's world at a time
            scene = stored_scene(p["scene"], config)
            geometry = ArmGeometry(scene, "capsules")
        q_last = np.asarray(p["trajectory"].q[-1], float)
        for m in p["members"]:
            if m is not None:
                m["phi_class"] = settled_class(scene, geometry, q_last, m["final"],
                                               config.evaluation)
                m["phi_class_kf"] = _with_jams(m["phi_class"], m["terms"], config)
                m["phi_class_jam"] = _with_jam_measure(m["phi_class"], m.get("jam"), config)


def _with_jams(value: float | None, terms: dict | None, config) -> float | None:
    if value is None or terms is None:
        return None
    jam = 0.5 * config.physics.w_force * config.evaluation.max_static_force ** 2
    return 3.0 + (value % 1.0) if terms.get("force", 0.0) >= jam else value


def _with_jam_measure(value: float | None, jam: float | None, config) -> float | None:
    """The phi class read as a kinematic failure (3) where the jam measure reaches
    ``dynamics.jam_depth``."""
    if value is None or jam is None:
        return None
    return 3.0 + (value % 1.0) if jam >= config.dynamics.jam_depth else value


def _total(terms: dict) -> float:
    return float(sum(terms.values()))


def score(plan: dict, term: str, members: int, risk: str, config) -> float | None:
    """The plan's ensemble score of ``term`` ('total' or a Table I term; terms by their
    members' mean) over its first ``members`` members; None where phi failed."""
    if term in ("phi_class", "phi_class_kf", "phi_class_jam", "jam"):
        values = [m.get(term) if m else None for m in plan["members"][:members]]
        return None if None in values else float(np.mean(values))
    per = _terms(plan, members)
    if any(t is None for t in per):
        return None
    if term != "total":
        return float(np.mean([t[term] for t in per]))
    return risk_score([_total(t) for t in per], replace(config.ensemble, risk=risk))


def order_agreement(plans: list[dict], label: str, terms: list[str], members: int, risk: str,
                    config, margin: float = 0.0) -> dict[str, Counter]:
    """Per term (and 'total'): Counter(agree=, disagree=) over the pairs of plans of one
    initialization whose ``label`` ('grade' or 'p_success'; a higher P(success) is better)
    differs; with ``margin`` > 0, only pairs whose class (or P(success)) differs by at least
    that much."""
    groups, out = defaultdict(list), defaultdict(Counter)
    for p in plans:
        if all(t is not None for t in _terms(p, members)):
            groups[(p["scene"], p["angle"])].append(p)
    for group in groups.values():
        for a, b in itertools.combinations(group, 2):
            la, lb = _label(a, label), _label(b, label)
            if la == lb or (margin > 0 and abs(la[0] - lb[0]) < margin):
                continue
            for term in terms:
                va, vb = (score(a, term, members, risk, config),
                          score(b, term, members, risk, config))
                if va is not None and vb is not None and va != vb:
                    out[term]["agree" if (va < vb) == (la < lb) else "disagree"] += 1
    return out


def against_one(plans: list[dict], label: str, members: int, risk: str, config) -> tuple:
    """Over the pairs of one initialization whose ``label`` differs and that both K =
    ``members`` and K = 1 order (no tie): (pairs only K orders as the judge, pairs only K = 1
    does, the two-sided sign test's p) - the paired view of an ensemble's gain."""
    groups = defaultdict(list)
    for p in plans:
        if all(t is not None for t in _terms(p, members)):
            groups[(p["scene"], p["angle"])].append(p)
    gain = loss = 0
    for group in groups.values():
        for a, b in itertools.combinations(group, 2):
            la, lb = _label(a, label), _label(b, label)
            if la == lb:
                continue
            ka, kb = (score(a, "total", members, risk, config),
                      score(b, "total", members, risk, config))
            oa, ob = score(a, "total", 1, "mean", config), score(b, "total", 1, "mean", config)
            if ka == kb or oa == ob:
                continue
            k_right, one_right = (ka < kb) == (la < lb), (oa < ob) == (la < lb)
            gain += k_right and not one_right
            loss += one_right and not k_right
    p_value = binomtest(gain, gain + loss).pvalue if gain + loss else 1.0
    return gain, loss, p_value


FIT_TERMS = ("acc", "force", "grasp", "grp_horiz", "grp_open", "motion", "static", "upright")


def _features(plan: dict, members: int) -> np.ndarray | None:
    """log(1 + term) of each Table I term, and phi_class_kf, averaged over the members."""
    ms = plan["members"][:members]
    if len(ms) < members or any(m is None or m["terms"] is None for m in ms):
        return None
    logs = [np.mean([np.log1p(m["terms"].get(t, 0.0)) for m in ms]) for t in FIT_TERMS]
    return np.array([*logs, np.mean([m["phi_class_kf"] for m in ms])])


def refit_agreement(plans: list[dict], members: int, l2: float = 1.0) -> tuple[int, int]:
    """Could other weights make phi agree? Over the pairs of one initialization with different
    grades, a linear score of `_features` is fitted (L2-regularised logistic loss on the
    pairs' order) on every scene but one and tested on that scene's pairs: (right, pairs)
    summed over the held-out scenes."""
    rows = []
    groups = defaultdict(list)
    for p in plans:
        f = _features(p, members)
        if f is not None:
            groups[(p["scene"], p["angle"])].append((p, f))
    for (scene, _), group in groups.items():
        for (a, fa), (b, fb) in itertools.combinations(group, 2):
            if _label(a, "grade") != _label(b, "grade"):
                rows.append((scene, fa - fb, _label(a, "grade") < _label(b, "grade")))
    if not rows:
        return 0, 0
    X = np.array([r[1] for r in rows])
    X = X / (X.std(axis=0) + 1e-9)
    y = np.array([r[2] for r in rows], float)
    scenes = np.array([r[0] for r in rows])

    def fit(Xt, yt):  # a lower score is better: P(a better) = sigmoid(-w (f_a - f_b))
        def loss(w):
            z = Xt @ w
            return np.sum(yt * np.logaddexp(0, z) + (1 - yt) * np.logaddexp(0, -z)) + l2 * w @ w
        return minimize(loss, np.zeros(X.shape[1])).x

    right = 0
    for scene in sorted(set(scenes)):
        held = scenes == scene
        w = fit(X[~held], y[~held])
        right += int(np.sum(((X[held] @ w) < 0) == (y[held] == 1)))
    return right, len(rows)


def _label(plan: dict, label: str) -> tuple:
    """The judge's verdict on a plan as a tuple that sorts better first."""
    return (-plan["p_success"],) if label == "p_success" else tuple(plan["grade"])


def physics_below_baseline(plans: list[dict], members: int, config) -> dict:
    """Per (store, configuration): Counter of (score below the baseline's?, verdict) over
    the physics plans with a baseline plan of the same initialization."""
    by_row = {}
    for p in plans:
        for db, config_name, planner in p["rows"]:
            by_row[(db, config_name, planner, p["scene"], p["angle"])] = p
    out = defaultdict(Counter)
    for (db, config_name, planner, scene, angle), p in by_row.items():
        base = by_row.get((db, config_name, "baseline", scene, angle))
        if planner != "physics" or base is None:
            continue
        sp, sb = (score(p, "total", members, "mean", config),
                  score(base, "total", members, "mean", config))
        if sp is None or sb is None:
            continue
        out[(db, config_name)][(sp < sb, verdict(tuple(p["grade"]), tuple(base["grade"])))] += 1
    return out


def _load_cache(path: Path | None) -> dict[str, list]:
    """Per plan key, its priced members in order (the leading run of members 0, 1, ...)."""
    if path is None or not path.exists():
        return {}
    found = defaultdict(dict)
    for line in path.read_text().splitlines():
        if line.strip():
            entry = json.loads(line)
            found[entry["key"]][entry["member"]] = {"terms": entry["terms"],
                                                   "jam": entry.get("jam"),
                                                   "final": entry["final"]}
    out = {}
    for key, members in found.items():
        run = []
        while len(run) in members:
            run.append(members[len(run)])
        out[key] = run
    return out


def price_all(plans: list[dict], config, members: int, jobs: int, cache: Path | None) -> None:
    """Fills each plan's 'members' (per member: its terms and final box states), reusing and
    extending the cache file; the plans of one scene and start are rolled out in one phi per
    member (one settle, the same boxes)."""
    done = _load_cache(cache)
    groups = defaultdict(dict)
    for p in plans:
        p["members"] = list(done.get(p["key"], []))[:members]
        for k in range(len(p["members"]), members):
            q = np.asarray(p["trajectory"].q, float)
            groups[(p["scene"], q[0].tobytes(), k)][p["key"]] = q
    by_key = {p["key"]: p for p in plans}
    work = sorted(groups.items(), key=lambda item: (item[0][2], item[0][0]))
    jobs_args = [(scene, paths, config, k) for (scene, _, k), paths in work]
    with ProcessPoolExecutor(max_workers=jobs) as pool:
        for ((scene, _, k), paths), result in zip(work, pool.map(price, jobs_args),
                                                         strict=True):
            for key, entry in result.items():
                plan = by_key[key]
                while len(plan["members"]) < k:  # filled in member order: see the sort
                    plan["members"].append(None)
                plan["members"].append(entry)
                if cache is not None:
                    with cache.open("a") as f:
                        f.write(json.dumps({"key": key, "member": k, **entry}) + "\n")
            totals = ["failed" if e["terms"] is None else f"{_total(e['terms']):.4g}"
                      for e in result.values()]
            print(f"{scene} member {k}: {len(paths)} plans, objectives {' '.join(totals)}",
                  flush=True)


def _print_agreement(plans, label, ks, config, margin: float = 0.0) -> None:
    terms = sorted({k for p in plans for t in _terms(p, max(ks)) if t for k in t})
    for k in ks:
        for risk in (RISKS if k > 1 else ("mean",)):
            extra = ["total", "phi_class", "phi_class_kf", "jam", "phi_class_jam"]
            counts = order_agreement(plans, label, [*terms, *extra], k, risk, config, margin)
            print(f"  K = {k}, {risk}:")
            for term in ([*terms, *extra] if risk == "mean" else ["total"]):
                c = counts[term]
                n = c["agree"] + c["disagree"]
                lo, hi = wilson_interval(c["agree"], n)
                print(f"    {term:14} agree {c['agree']:4} of {n:4} "
                      f"({c['agree'] / max(n, 1):.0%}, 95 % [{lo:.0%}, {hi:.0%}])")
            if k > 1:
                gain, loss, p_value = against_one(plans, label, k, risk, config)
                print(f"    total against K = 1 on the same pairs: right only at K = {k} in "
                      f"{gain}, only at K = 1 in {loss} (sign test p = {p_value:.3f})")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--db", action="append", required=True,
                        help="an experiment store whose plans to price (repeatable)")
    parser.add_argument("--configurations", nargs="+", default=[],
                        help="only these configurations' rows (default: all)")
    parser.add_argument("--scenes", nargs="+", default=[], help="only these scenes' plans")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    parser.add_argument("--robust", action="store_true",
                        help="grade by the stored robust judge's replays")
    parser.add_argument("--members", type=int, nargs="+", default=[1],
                        help="ensemble sizes K to compare (default: 1, phi alone)")
    parser.add_argument("--jobs", type=int, default=2, help="processes pricing plans")
    parser.add_argument("--cache", type=Path, help="JSON-lines file of priced plans (resume)")
    parser.add_argument("--margin", type=float, default=0.0,
                        help="also count only the pairs whose (robust) class or P(success) "
                             "differs by at least this much")
    parser.add_argument("--rejudge", action="store_true",
                        help="grade each plan by a fresh Bullet replay, not the stored grade")
    args = parser.parse_args(argv)
    if min(args.members) < 1 or args.jobs < 1:
        print("error: <command line>: --members and --jobs must be at least 1", file=sys.stderr)
        return 2
    try:
        config = load_config(None, args.set)
        plans = [p for p in distinct_plans(args.db, args.configurations, args.robust)
                 if not args.scenes or p["scene"] in args.scenes]
    except InputError as exc:
        print(f"error: {exc}", file=sys.stderr)
        return 2
    if not plans:
        print(f"error: {', '.join(args.db)}: no stored plan"
              + (" with robust replays" if args.robust else "")
              + (f" in configurations {', '.join(args.configurations)}"
                 if args.configurations else ""), file=sys.stderr)
        return 2
    config = replace(config, dynamics=replace(config.dynamics, prune_margin=EVERY_BOX))
    if args.rejudge:
        for p in plans:
            p["grade"] = outcome_grade(evaluate(stored_scene(p["scene"], config),
                                                p["trajectory"], config.evaluation))
    price_all(plans, config, max(args.members), args.jobs, args.cache)
    add_phi_class(plans, config)
    ks = sorted(set(args.members))
    print(f"\n{len(plans)} plans; pairs of one initialization with different grades, "
          "ordered by phi as by the judge:")
    _print_agreement(plans, "grade", ks, config)
    if args.margin > 0:
        print(f"\npairs whose class differs by at least {args.margin}:")
        _print_agreement(plans, "grade", ks, config, args.margin)
    if args.robust:
        print("\npairs of one initialization with different robust P(success):")
        _print_agreement([p for p in plans if p["p_success"] is not None], "p_success", ks,
                         config)
    right, n = refit_agreement(plans, max(ks))
    lo, hi = wilson_interval(right, n)
    print(f"\nweights refitted on the other scenes' pairs (K = {max(ks)}, log terms and "
          f"phi_class_kf), leave one scene out: {right} of {n} ({right / max(n, 1):.0%}, "
          f"95 % [{lo:.0%}, {hi:.0%}])")
    print("\nphysics plans with phi's mean objective below their baseline's, by verdict:")
    for (db, config_name), counts in physics_below_baseline(plans, max(ks), config).items():
        cells = [f"{'below' if below else 'above'}: "
                 + " / ".join(str(counts[(below, v)]) for v in ("better", "same", "worse"))
                 for below in (True, False)]
        print(f"  {db} ({config_name}): {'; '.join(cells)} (better / same / worse)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
