#!/usr/bin/env python3
"""The ceiling of the push path family: the best of N sampled paths per initialization, picked
by the robust judge and read on fresh seeds, against the straight lines' own ceiling.

    python studies/push_ceiling.py --db CANDIDATES.db [--samples 3] [--seed 0]
        [--fresh-seed 1] [--replays 8] [--jobs 2] [--cache FILE.jsonl] [--set FIELD=VALUE]
        [--angles 4 7] [--phi-members K [--phi-set FIELD=VALUE]]

The store holds the baseline's straight paths of each initialization (scene, angle) at several
grasp heights, judged by the robust judge (`docs/specs/candidates_probe_half.yaml`: 5 heights).
Around each straight path ``--samples`` members of the push family are drawn
(`planners.push.aim.draw`: aimed at the boxes the straight path meets with
``push_search.aimed_chance``, else blind; seeded by ``[seed, initialization, height]``); the
feasible ones are judged by the robust judge as the store's were (``--replays`` replays, its
seed). Per initialization three plans are picked by that judgement (P(success), then
expected grade):

* ``default``: the straight path at the baseline's default height (no choice);
* ``straight``: the best straight path (the straight lines' ceiling);
* ``family``: the best of the straight paths and the sampled members (the family's ceiling);

and each is read again on ``--replays`` fresh perturbed worlds (seed ``--fresh-seed``, the
nominal replay left out: it is the same world at any seed, and the pick saw it). Printed: the
mean fresh P(success) of each, and the paired differences family - default, straight - default
and family - straight with seeded bootstrap intervals, overall and per environment; how often
the family's pick is a bent path, and what its via-points were. With ``--phi-members K`` every
plan is also judged in phi (`phi_judge.judge_paths`, K members, ``--phi-set`` on top of
``--set``) and two more picks are read fresh: the judge in phi's best straight path
(``phi_straight``) and its best of all (``phi_family``), what a search scored by the judge in
phi over the same samples would return. ``--cache`` keeps one JSON line
per initialization, so a stopped run resumes; ``--angles`` keeps those angles' initializations.

Its dated results: docs/log/push_planner.md.
"""

from __future__ import annotations

import argparse
import json
import sys
import zlib
from collections import defaultdict
from concurrent.futures import ProcessPoolExecutor
from pathlib import Path

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.evaluation.judge import evaluate
from drake_clutter.experiments.paired import bootstrap_interval
from drake_clutter.experiments.specs import stored_scene
from drake_clutter.experiments.store import stored_plans
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.phi_judge import judge_paths
from drake_clutter.planners.push.aim import draw, obstructions
from drake_clutter.planners.push.family import feasible, member_path
from drake_clutter.planners.tool_path import approach_frame
from drake_clutter.trajectory import Trajectory

DEFAULT_HEIGHT = "h0.5"


def load_straights(dbs) -> dict[tuple[str, int], dict[str, dict]]:
    """The stored straight paths with robust replays, by initialization and configuration."""
    found: dict[tuple[str, int], dict[str, dict]] = defaultdict(dict)
    for _, row, trajectory, _ in stored_plans(dbs):
        robust = (row.get("outcome") or {}).get("robust")
        if robust:
            found[(row["scene"], row["angle"])][row["config_name"]] = {
                "times": trajectory.times.tolist(), "q": trajectory.q.tolist(),
                "p_success": float(robust["p_success"]),
                "expected_grade": float(robust["expected_grade"])}
    return found


def _judged(scene, times, q, config, replays: int, seed: int, fresh: bool) -> dict:
    """The robust judge's P(success) and expected grade of one path (fresh: replay 0, the
    nominal world, left out)."""
    outcome = evaluate(scene, Trajectory(np.asarray(times), np.asarray(q)), config.evaluation,
                       robust=replays + (1 if fresh else 0), seed=seed)
    kinds = list(outcome.robust.kinds)[1 if fresh else 0:]
    grades = [g[0] for g in outcome.robust.grades][1 if fresh else 0:]
    return {"p_success": sum(k == "success" for k in kinds) / len(kinds),
            "expected_grade": float(np.mean(grades)), "nominal": outcome.kind.value}


def ceiling_one(job) -> dict:
    """One initialization: the members drawn and judged, the three picks read fresh."""
    (scene_name, angle), straights, config, args = job
    scene = stored_scene(scene_name, config)
    context = PlanningContext(scene, config)
    geometry, clearance = context.arm(), context.clearance
    ranges = config.push_search
    plans = {name: {**s, "member": None} for name, s in straights.items()}
    drawn = kept = 0
    for name, s in sorted(straights.items()):
        rng = np.random.default_rng([args.seed, zlib.crc32(f"{scene_name}|{angle}".encode()),
                                     zlib.crc32(name.encode())])
        q = np.asarray(s["q"])
        frame = approach_frame(geometry, q)
        found = obstructions(geometry, q, frame, scene.target)
        for i in range(args.samples):
            member = draw(rng, frame, found, ranges)
            path, error = member_path(geometry, q, member)
            drawn += 1
            times = np.asarray(s["times"])
            if not feasible(path, error, times, clearance, config):
                continue
            kept += 1
            judged = _judged(scene, times, path, config, args.replays, 0, fresh=False)
            plans[f"{name}/m{i}"] = {"times": s["times"], "q": path.tolist(), **judged,
                                     "member": member.to_data()}

    def best(names):
        return min(names, key=lambda n: (-plans[n]["p_success"], plans[n]["expected_grade"], n))

    picks = {"default": DEFAULT_HEIGHT, "straight": best(list(straights)),
             "family": best(list(plans))}
    if args.phi_members > 0:
        picks.update(_phi_picks(scene, geometry, plans, straights, args))
    fresh = {}
    for name in picks.values():
        if name not in fresh:
            p = plans[name]
            fresh[name] = _judged(scene, p["times"], p["q"], config, args.replays,
                                  args.fresh_seed, fresh=True)
    return {"scene": scene_name, "angle": angle, "drawn": drawn, "kept": kept,
            "picks": {label: {"name": name, "picked": {k: plans[name][k] for k in
                                                       ("p_success", "expected_grade")},
                              "fresh": fresh[name], "member": plans[name]["member"],
                              "phi": plans[name].get("phi")}
                      for label, name in picks.items()}}


def _phi_picks(scene, geometry, plans: dict, straights: dict, args) -> dict[str, str]:
    """The plans the judge in phi would pick (``--phi-members`` members, ``--phi-set``):
    among the straight paths (``phi_straight``) and among all (``phi_family``); every plan's
    phi verdict is kept in ``plans``."""
    config = load_config(None, [*args.overrides, *args.phi_overrides,
                                f"phi_judge.members={args.phi_members}"])
    times = np.asarray(next(iter(plans.values()))["times"])
    verdicts = judge_paths(scene, {n: np.asarray(p["q"]) for n, p in plans.items()}, times,
                           config, geometry)
    for name, verdict in verdicts.items():
        plans[name]["phi"] = {"p_success": verdict.p_success,
                              "expected_grade": verdict.expected_grade}

    def best(names):
        return min(names, key=lambda n: (*verdicts[n].key(), n))

    return {"phi_straight": best(list(straights)), "phi_family": best(list(plans))}


def _cache(path: Path | None) -> dict:
    if path is None or not path.exists():
        return {}
    return {(e["scene"], e["angle"]): e for e in map(json.loads, path.read_text().splitlines())}


def summary(results: list[dict], config) -> None:
    """The fresh P(success) of each pick and the paired differences with intervals."""
    groups = {"all": results,
              "bookshelf": [r for r in results if r["scene"].startswith("bookshelf")],
              "fridge": [r for r in results if r["scene"].startswith("fridge")]}
    for group, rows in groups.items():
        if not rows:
            continue
        labels = [k for k in ("default", "straight", "family", "phi_straight", "phi_family")
                  if all(k in r["picks"] for r in rows)]
        fresh = {k: np.array([r["picks"][k]["fresh"]["p_success"] for r in rows])
                 for k in labels}
        print(f"\n{group}: {len(rows)} initializations; fresh P(success) default "
              f"{fresh['default'].mean():.3f}, best straight {fresh['straight'].mean():.3f}, "
              f"best of the family {fresh['family'].mean():.3f}")
        if "phi_family" in fresh:
            print(f"  picked by the judge in phi: among the straight paths "
                  f"{fresh['phi_straight'].mean():.3f}, among all {fresh['phi_family'].mean():.3f}")
        for a, b in (("family", "default"), ("straight", "default"), ("family", "straight"),
                     ("phi_straight", "default"), ("phi_family", "default"),
                     ("phi_family", "phi_straight")):
            if a not in fresh or b not in fresh:
                continue
            d = fresh[a] - fresh[b]
            low, high = bootstrap_interval(d, config.report)
            print(f"  {a} - {b}: {d.mean():+.3f} [{low:+.3f}, {high:+.3f}] "
                  f"({int((d > 0).sum())} better, {int((d == 0).sum())} same, "
                  f"{int((d < 0).sum())} worse)")
    bent = [r for r in results if r["picks"]["family"]["member"] is not None]
    print(f"\nthe family's pick is a bent path in {len(bent)} of {len(results)}; members kept "
          f"{sum(r['kept'] for r in results)} of {sum(r['drawn'] for r in results)} drawn")
    for r in bent[:12]:
        f = r["picks"]["family"]
        print(f"  {r['scene']} angle {r['angle']}: {f['name']} {json.dumps(f['member'])} "
              f"picked {f['picked']['p_success']:.2f}, fresh {f['fresh']['p_success']:.2f}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", action="append", required=True)
    parser.add_argument("--samples", type=int, default=3)
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--fresh-seed", type=int, default=1)
    parser.add_argument("--replays", type=int, default=8)
    parser.add_argument("--jobs", type=int, default=2)
    parser.add_argument("--cache", type=Path)
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    parser.add_argument("--angles", type=int, nargs="*", default=[])
    parser.add_argument("--phi-members", type=int, default=0)
    parser.add_argument("--phi-set", action="append", default=[], dest="phi_overrides")
    args = parser.parse_args(argv)
    try:
        config = load_config(None, args.overrides)
        load_config(None, [*args.overrides, *args.phi_overrides,
                           f"phi_judge.members={max(args.phi_members, 1)}"])
        for db in args.db:
            if not Path(db).exists():
                raise InputError("<command line>", "--db", f"no such store {db}")
        if args.samples < 1 or args.replays < 1 or args.fresh_seed == 0:
            raise InputError("<command line>", "--samples/--replays/--fresh-seed",
                             "must be >= 1, and --fresh-seed not the judge's seed 0")
    except InputError as exc:
        print(exc, file=sys.stderr)
        return 2
    straights = load_straights(args.db)
    done = _cache(args.cache)
    todo = [(key, s, config, args) for key, s in sorted(straights.items())
            if key not in done and DEFAULT_HEIGHT in s
            and (not args.angles or key[1] in args.angles)]
    print(f"{len(straights)} initializations, {len(todo)} to run", flush=True)
    with ProcessPoolExecutor(max(1, args.jobs)) as pool:
        for i, result in enumerate(pool.map(ceiling_one, todo), 1):
            done[(result["scene"], result["angle"])] = result
            if args.cache is not None:
                with args.cache.open("a") as f:
                    f.write(json.dumps(result) + "\n")
            print(f"  {i}/{len(todo)} {result['scene']} angle {result['angle']}: kept "
                  f"{result['kept']}/{result['drawn']}, family pick "
                  f"{result['picks']['family']['name']}", flush=True)
    summary([r for r in done.values() if not args.angles or r["angle"] in args.angles], config)
    return 0


if __name__ == "__main__":
    sys.exit(main())
