#!/usr/bin/env python3
"""The plans a code version makes, as digests: one JSON line per planner and initialization,
to hold two versions' plans against each other (a refactor must not change them).

    PYTHONPATH=OLD_CHECKOUT python benchmarks/plan_digests.py smoke behaviours bench > old.jsonl
    PYTHONPATH=NEW_CHECKOUT python benchmarks/plan_digests.py smoke behaviours bench > new.jsonl
    python benchmarks/plan_digests.py --compare old.jsonl new.jsonl

A tier name (``smoke``, ``behaviours``, ...) plans every initialization of the tier (its
scenes, angles and configurations) with the baseline and the push planner; ``bench`` plans
bookshelf scenes of 10 and 25 boxes (seeds 0, 1; angles 3, 10) with the baseline, the push and
the physics planner. Each line: the SHA-1 (12 digits) of the knots and of the candidate's record
with its wall times removed (`specs.split_wall_times`), and the planning seconds. ``--compare``
prints the rows whose plans or records differ and the seconds per tier and planner, new over
old.
"""

from __future__ import annotations

import argparse
import hashlib
import json
import sys
import time
from collections import defaultdict

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.experiments.specs import _build_scene, expand, load_spec, split_wall_times
from drake_clutter.planners.registry import get_planner


def digest(candidate) -> tuple[str, str]:
    """SHA-1 (12 digits) of the candidate's knots and of its record without wall times."""
    q = (np.zeros(0) if candidate.trajectory is None
         else np.ascontiguousarray(candidate.trajectory.q))
    data = candidate.to_data()
    data.pop("timings", None)
    split_wall_times(data["details"])
    record = json.dumps(data, sort_keys=True, default=str).encode()
    return hashlib.sha1(q.tobytes()).hexdigest()[:12], hashlib.sha1(record).hexdigest()[:12]


def initializations(which: str):
    """(tier, scene source, angle index, overrides, planners) of a tier or of ``bench``."""
    if which == "bench":
        for n in (10, 25):
            for seed in (0, 1):
                for angle in (3, 10):
                    yield (which, ("generated", "bookshelf", n, seed), angle,
                           ["dynamics.workers=0"], ("baseline", "push", "physics"))
        return
    seen = set()
    for unit in expand(load_spec(which)[0]):
        key = (str(unit.source), unit.angle, unit.overrides)
        if key not in seen:
            seen.add(key)
            yield which, unit.source, unit.angle, list(unit.overrides), ("baseline", "push")


def plan_all(tiers) -> None:
    """Prints one JSON line per planner and initialization of ``tiers``."""
    for which in tiers:
        for tier, source, angle, overrides, planners in initializations(which):
            config = load_config(None, overrides)
            scene = _build_scene(source, config)
            start = None
            for name in planners:
                tic = time.perf_counter()
                (candidate,) = get_planner(name).plan(scene, config, [angle], start)
                seconds = time.perf_counter() - tic
                if name == "baseline":
                    start = [candidate]
                q, record = digest(candidate)
                print(json.dumps({"tier": tier, "scene": scene.name, "angle": angle,
                                  "planner": name, "q": q, "details": record,
                                  "seconds": round(seconds, 3)}), flush=True)


def compare(old_path: str, new_path: str) -> int:
    """Prints the differing rows and the seconds new over old; 1 when any plan differs."""
    old = [json.loads(line) for line in open(old_path, encoding="utf-8")]
    new = [json.loads(line) for line in open(new_path, encoding="utf-8")]
    keys = [(r["tier"], r["scene"], r["angle"], r["planner"]) for r in old]
    if keys != [(r["tier"], r["scene"], r["angle"], r["planner"]) for r in new]:
        print("the two files hold different initializations", file=sys.stderr)
        return 2
    differ = [k for k, a, b in zip(keys, old, new, strict=True)
              if (a["q"], a["details"]) != (b["q"], b["details"])]
    print(f"{len(keys)} candidates, {len(differ)} with another plan or record")
    for k in differ:
        print("  differs:", *k)
    seconds = defaultdict(lambda: [0.0, 0.0])
    for k, a, b in zip(keys, old, new, strict=True):
        seconds[(k[0], k[3])][0] += a["seconds"]
        seconds[(k[0], k[3])][1] += b["seconds"]
    for (tier, planner), (a, b) in sorted(seconds.items()):
        print(f"{tier:>12} {planner:>9}: old {a:8.1f} s, new {b:8.1f} s, x{b / max(a, 1e-9):.3f}")
    return 1 if differ else 0


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("tiers", nargs="*", help="tier names and/or 'bench'")
    parser.add_argument("--compare", nargs=2, metavar=("OLD", "NEW"))
    args = parser.parse_args(argv)
    if args.compare:
        return compare(*args.compare)
    try:
        plan_all(args.tiers or ["smoke"])
    except InputError as exc:
        print(exc, file=sys.stderr)
        return 2
    return 0


if __name__ == "__main__":
    sys.exit(main())
