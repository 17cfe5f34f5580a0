#!/usr/bin/env python3
"""The gate of the judge in phi: does it order stored plans as the robust judge does?

    python studies/phi_judge_gate.py --db RUN.db [--db RUN2.db ...]
        [--configurations NAME ...] [--planners baseline] [--set FIELD=VALUE ...]
        [--members 8] [--jobs 2] [--cache FILE.jsonl] [--examples 5] [--read K ...]
        [--cached-only]

Every distinct stored plan with robust replays (default: the baseline's plans, which no planner
optimised against the score; the ``candidates`` tier holds 15 per initialization) is judged in
phi (`planners.phi_judge.judge_paths`): the plans of one initialization (scene and
angle) meet the same ``--members`` members, the planner's own seeds, never the judge's.

Printed:
* the pairs of one initialization whose robust P(success) differs: how often phi's P(success)
  orders them as the judge does (ties in phi left out, and counted), and how often phi's
  verdict order (P(success), then expected grade, then boxes disturbed) does; 95 % Wilson
  intervals (pairs share plans, so they are optimistic);
* the confusion matrix of each plan's class in phi's nominal member against the judge's
  nominal class, and against the robust judge's most frequent class;
* the misread plans with the most weight (``--examples`` per confusion cell): their reasons
  on both sides, to trace where the score goes wrong.

``--cache`` keeps each initialization's verdicts (one JSON line), so a stopped run resumes;
``--cached-only`` reads the cached initializations alone and judges nothing; ``--read`` also
prints the pair agreement over the first K members of each verdict (K <= ``--members``).

Its dated results: docs/log/push_planner.md.
"""

from __future__ import annotations

import argparse
import json
import sys
from collections import Counter, defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.experiments.paired import wilson_interval
from drake_clutter.experiments.specs import stored_scene
from drake_clutter.experiments.store import stored_plans
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.phi_judge import PhiVerdict, judge_paths
from drake_clutter.scene.grading import GRADE_CLASSES, OUTCOME_KINDS

KINDS = OUTCOME_KINDS[:5]  # the five classes of Sec. III (no planner failures here)


def load_plans(dbs, configurations, planners) -> dict[tuple[str, int], list[dict]]:
    """The distinct stored plans with robust replays, by initialization (scene, angle)."""
    found: dict[tuple[str, int], dict[str, dict]] = defaultdict(dict)
    for _, row, trajectory, digest in stored_plans(dbs, configurations):
        robust = (row.get("outcome") or {}).get("robust")
        if not robust or (planners and row["planner"] not in planners):
            continue
        found[(row["scene"], row["angle"])].setdefault(digest, {
            "digest": digest, "times": trajectory.times.tolist(), "q": trajectory.q.tolist(),
            "p_success": float(robust["p_success"]), "kinds": list(robust["kinds"]),
            "nominal": row["kind"], "reason": row["outcome"].get("reason", ""),
            "config": row["config_name"]})
    return {k: list(v.values()) for k, v in found.items()}


def judge_one(job) -> dict:
    """The verdicts of one initialization's plans (a worker's job)."""
    (scene_name, angle), plans, config = job
    scene = stored_scene(scene_name, config)
    times = np.asarray(plans[0]["times"])
    paths = {p["digest"]: np.asarray(p["q"]) for p in plans}
    geometry = PlanningContext(scene, config).arm()
    same = all(len(p["times"]) == len(times) for p in plans)
    verdicts = {}
    if same:
        found = judge_paths(scene, paths, times, config, geometry)
        verdicts = {k: v.to_data() for k, v in found.items()}
    else:  # knots differ: one call per plan
        for p in plans:
            one = judge_paths(scene, {p["digest"]: np.asarray(p["q"])},
                              np.asarray(p["times"]), config, geometry)
            verdicts.update({k: v.to_data() for k, v in one.items()})
    return {"scene": scene_name, "angle": angle, "verdicts": verdicts}


def _load_cache(path: Path | None) -> dict[tuple[str, int], dict]:
    if path is None or not path.exists():
        return {}
    out = {}
    for line in path.read_text().splitlines():
        entry = json.loads(line)
        out[(entry["scene"], entry["angle"])] = entry["verdicts"]
    return out


def judge_all(plans, config, jobs: int, cache: Path | None) -> dict:
    """Verdicts by initialization and digest, resumed from ``cache``."""
    done = _load_cache(cache)
    todo = [(key, ps, config) for key, ps in plans.items() if key not in done]
    print(f"{len(plans)} initializations, {sum(map(len, plans.values()))} plans; "
          f"{len(todo)} to judge", flush=True)
    with ProcessPoolExecutor(max(1, jobs)) as pool:
        for i, result in enumerate(pool.map(judge_one, todo), 1):
            done[(result["scene"], result["angle"])] = result["verdicts"]
            if cache is not None:
                with cache.open("a") as f:
                    f.write(json.dumps(result) + "\n")
            print(f"  {i}/{len(todo)} {result['scene']} angle {result['angle']}", flush=True)
    return done


def _first_members(v: dict, k: int) -> dict:
    """A cached verdict over its first k members only."""
    kinds = v["kinds"][:k]
    return {"kinds": kinds, "reasons": v["reasons"][:k], "disturbed": v["disturbed"][:k],
            "p_success": sum(x == "success" for x in kinds) / len(kinds),
            "expected_grade": float(np.mean([GRADE_CLASSES[x] for x in kinds]))}


def _phi_key(v: dict) -> tuple:
    return (-v["p_success"], v["expected_grade"], float(np.mean(v["disturbed"])))


def _margin_key(v: dict) -> tuple:
    margin = v.get("margin")
    return (-v["p_success"], v["expected_grade"], np.inf if margin is None else margin,
            float(np.mean(v["disturbed"])))


def differing_pairs(plans, verdicts, key):
    """(judge's sign, phi's verdict of the first, of the second) for each pair of one
    initialization ``key`` whose robust P(success) differs."""
    ps = plans[key]
    for i, a in enumerate(ps):
        for b in ps[i + 1:]:
            if a["p_success"] != b["p_success"]:
                yield (np.sign(a["p_success"] - b["p_success"]), verdicts[key][a["digest"]],
                       verdicts[key][b["digest"]])


def pair_agreement(plans, verdicts) -> dict[str, tuple[int, int, int]]:
    """(agree, disagree, ties) over the pairs whose robust P(success) differs, by phi's
    P(success) alone, by phi's verdict order without the margin (P(success), expected grade,
    boxes disturbed) and with it (the margin after the expected grade)."""
    out = {"p_success": [0, 0, 0], "verdict": [0, 0, 0], "verdict with margin": [0, 0, 0]}
    for key in plans:
        for judge, va, vb in differing_pairs(plans, verdicts, key):
            for name, phi in (("p_success", np.sign(va["p_success"] - vb["p_success"])),
                              ("verdict", _order(_phi_key(vb), _phi_key(va))),
                              ("verdict with margin", _order(_margin_key(vb), _margin_key(va)))):
                slot = 2 if phi == 0 else 0 if phi == judge else 1
                out[name][slot] += 1
    return {k: tuple(v) for k, v in out.items()}


def margin_gain(plans, verdicts, resamples: int = 10000, seed: int = 0
                ) -> tuple[float, float, float, int]:
    """Over the pairs whose robust P(success) differs: the share that phi's verdict order with
    the margin orders as the judge does minus the share without it (a tie counts half), with
    a 95 % bootstrap interval over initializations (pairs of one initialization share plans,
    so they are resampled together); and the number of pairs."""
    per_init = []
    for key in plans:
        rows = []
        for judge, va, vb in differing_pairs(plans, verdicts, key):
            scores = [0.5 if o == 0 else float(o == judge)
                      for o in (_order(_margin_key(vb), _margin_key(va)),
                                _order(_phi_key(vb), _phi_key(va)))]
            rows.append(scores[0] - scores[1])
        if rows:
            per_init.append((sum(rows), len(rows)))
    if not per_init:
        return float("nan"), float("nan"), float("nan"), 0
    sums, counts = np.array(per_init, dtype=float).T
    rng = np.random.default_rng(seed)
    draws = rng.integers(0, len(sums), size=(resamples, len(sums)))
    boot = sums[draws].sum(axis=1) / counts[draws].sum(axis=1)
    low, high = np.percentile(boot, [2.5, 97.5])
    return float(sums.sum() / counts.sum()), float(low), float(high), int(counts.sum())


def _order(x: tuple, y: tuple) -> int:
    return (x > y) - (x < y)


def confusion(plans, verdicts, against: str) -> Counter:
    """(judge's class, phi's nominal class) counts: ``against`` "nominal" (the judge's nominal
    replay) or "mode" (the robust replays' most frequent class)."""
    table = Counter()
    for key, ps in plans.items():
        for p in ps:
            judge = (p["nominal"] if against == "nominal"
                     else Counter(p["kinds"]).most_common(1)[0][0])
            table[(judge, verdicts[key][p["digest"]]["kinds"][0])] += 1
    return table


def print_confusion(table: Counter, title: str) -> None:
    print(f"\n{title} (rows: the judge; columns: phi's nominal member)")
    short = [k[:12] for k in KINDS]
    print(f"{'':>18} " + " ".join(f"{s:>12}" for s in short) + f" {'recall':>7}")
    for j in KINDS:
        row = [table[(j, k)] for k in KINDS]
        total = sum(row)
        recall = table[(j, j)] / total if total else float("nan")
        print(f"{j:>18} " + " ".join(f"{v:>12}" for v in row) + f" {recall:>7.2f}")
    right = sum(table[(k, k)] for k in KINDS)
    n = sum(table.values())
    low, high = wilson_interval(right, n)
    print(f"accuracy {right}/{n} = {right / max(n, 1):.2f} [{low:.2f}, {high:.2f}]")


def print_examples(plans, verdicts, count: int) -> None:
    """The misread plans, ``count`` per (judge, phi) cell, with both sides' reasons."""
    cells = defaultdict(list)
    for key, ps in plans.items():
        for p in ps:
            v = verdicts[key][p["digest"]]
            if v["kinds"][0] != p["nominal"]:
                cells[(p["nominal"], v["kinds"][0])].append((key, p, v))
    print("\nmisread plans (nominal: judge -> phi)")
    for (judge, phi), items in sorted(cells.items(), key=lambda c: -len(c[1])):
        print(f"  {judge} -> {phi}: {len(items)}")
        for (scene, angle), p, v in items[:count]:
            print(f"    {scene} angle {angle} {p['config']}: judge '{p['reason'][:70]}' | "
                  f"phi '{v['reasons'][0][:70]}' | P(s) judge {p['p_success']:.2f} phi "
                  f"{v['p_success']:.2f}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", action="append", required=True)
    parser.add_argument("--configurations", nargs="*", default=[])
    parser.add_argument("--planners", nargs="*", default=["baseline"])
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    parser.add_argument("--config")
    parser.add_argument("--members", type=int, default=8)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--cache", type=Path)
    parser.add_argument("--examples", type=int, default=3)
    parser.add_argument("--read", type=int, nargs="*", default=[])
    parser.add_argument("--cached-only", action="store_true")
    args = parser.parse_args(argv)
    try:
        config = load_config(args.config, [*args.overrides, f"phi_judge.members={args.members}",
                                           "dynamics.workers=0"])
        for db in args.db:
            if not Path(db).exists():
                raise InputError("<command line>", "--db", f"no such store {db}")
    except InputError as exc:
        print(exc, file=sys.stderr)
        return 2
    plans = load_plans(args.db, args.configurations, args.planners)
    if args.cached_only:
        verdicts = _load_cache(args.cache)
        plans = {k: v for k, v in plans.items() if k in verdicts}
    else:
        verdicts = judge_all(plans, config, args.jobs, args.cache)
    read = {key: {d: PhiVerdict.from_findings(v["findings"], config).to_data()
                  for d, v in vs.items()} for key, vs in verdicts.items()}
    report(plans, read, config, args)
    return 0


def report(plans, verdicts, config, args) -> None:
    """The pair agreement, the confusion matrices and the misread plans of one reading."""
    print(f"\n=== phi {config.phi_judge.engine}, {args.members} members, "
          f"hold {config.phi_judge.hold_knots} knots")
    for name, (agree, disagree, ties) in pair_agreement(plans, verdicts).items():
        n = agree + disagree
        low, high = wilson_interval(agree, n)
        half = (agree + ties / 2) / max(n + ties, 1)
        print(f"pairs differing in robust P(success), ordered by phi's {name}: {agree}/{n} = "
              f"{agree / max(n, 1):.2f} [{low:.2f}, {high:.2f}]; {ties} ties "
              f"(of all {n + ties}: {agree / max(n + ties, 1):.2f} strictly, "
              f"{half:.2f} with ties as half)")
    gain, low, high, pairs = margin_gain(plans, verdicts)
    print(f"the margin's gain in ordered pairs (ties as half) over the verdict order without it: "
          f"{gain:+.3f} [{low:+.3f}, {high:+.3f}] over {pairs} pairs (bootstrap over "
          f"initializations)")
    for k in args.read:
        first = {key: {d: _first_members(v, k) for d, v in vs.items()}
                 for key, vs in verdicts.items()}
        agree, disagree, ties = pair_agreement(plans, first)["p_success"]
        low, high = wilson_interval(agree, agree + disagree)
        print(f"  first {k} members, by P(success): {agree}/{agree + disagree} = "
              f"{agree / max(agree + disagree, 1):.2f} [{low:.2f}, {high:.2f}]; {ties} ties")
    print_confusion(confusion(plans, verdicts, "nominal"), "classes: the judge's nominal replay")
    print_confusion(confusion(plans, verdicts, "mode"), "classes: the robust judge's most "
                                                        "frequent class")
    print_examples(plans, verdicts, args.examples)
    return 0


if __name__ == "__main__":
    sys.exit(main())
