#!/usr/bin/env python3
"""Benchmark of the physics planner's sampling search (beyond the paper): seconds per search
with each member's phi built once for the whole search and the shared knots' steps taken once
(``physics.search_shared_phi``, the default), against the reference measured in the same run:
the same search with phis built and exactly pruned for every round's samples.

    python benchmarks/bench_search.py                                   # fig5 and fig7, K = 4
    python benchmarks/bench_search.py --scenes fig5_large_small --angles 7 --members 8
    python benchmarks/bench_search.py --generated bookshelf:25 --set physics.search_rounds=2

Per scene and angle: the baseline's candidate, pre-processed as the planner does, is the
search's start (the baseline's path its alternative). Printed: seconds of both searches and
their ratio, phi rollouts scored per second, the first knot the offsets move (``begin``),
rounds that rebuilt the shared phis for boxes the samples reached, samples not scored
because they still reached a frozen box, and fidelity: the shared search's best
path and its start rescored in exactly pruned members (`ensemble.ensemble_scores`) - their
scores there, and whether the best still beats the start. The two searches draw the same
offsets but apply them from different knots (the reference from knot 0), so their found
paths differ; the ratio compares the cost of the same number of scored samples.
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.planners.physics import pipeline
from drake_clutter.planners.physics.ensemble import ensemble_scores
from drake_clutter.planners.physics.objective import max_steps
from drake_clutter.planners.physics.sampling import sampling_search
from drake_clutter.planners.registry import get_planner
from drake_clutter.scene.generators import generate_scene, scene_set
from drake_clutter.scene.scenes import resolve_scene


def scenes(args, config):
    """(label, scene) of the shipped names and the generated kind:level (the paper set's first
    scene of that level)."""
    out = [(name, resolve_scene(name)) for name in args.scenes]
    for item in args.generated:
        kind, level = item.split(":")
        spec = next(s for s in scene_set("paper", config.generator)
                    if s.kind == kind and s.num_objects == int(level))
        out.append((item, generate_scene(kind, int(level), spec.seed, config.generator)))
    return out


def timed_search(scene, start, baseline_q, config, knot_time, shared: bool):
    """(seconds, SearchResult) of one search with ``search_shared_phi`` = shared."""
    cfg = replace(config, physics=replace(config.physics, search_shared_phi=shared))
    lo, hi = (np.array(b) for b in pipeline.control_bounds())
    steps = max_steps(cfg.physics, knot_time)
    tic = time.perf_counter()
    found = sampling_search(scene, start, cfg, lo, hi, steps, None, knot_time, (baseline_q,))
    return time.perf_counter() - tic, found


def rollouts(found, members: int) -> int:
    """phi rollouts the search scored: the two starts and every kept sample, in every member."""
    return members * (2 + sum(r["kept"] for r in found.rounds))


def bench(label: str, scene, angle: int, config) -> str:
    (candidate,) = get_planner("baseline").plan(scene, config, angles=[angle])
    if not candidate.ok:
        return f"{label:18} {angle:5d}  no usable baseline candidate ({candidate.status})"
    q = np.array(candidate.trajectory.q)
    knot_time = float(np.diff(candidate.trajectory.times[:2])[0])
    start, _ = pipeline.preprocess(scene, q, config)
    members = config.ensemble.members
    new_s, new = timed_search(scene, start, q, config, knot_time, shared=True)
    ref_s, ref = timed_search(scene, start, q, config, knot_time, shared=False)
    frozen = sum(r["reached_frozen"] for r in new.rounds)
    rebuilt = sum(bool(r.get("rebuilt")) for r in new.rounds)
    exact, _ = ensemble_scores(scene, {"best": new.q, "start": new.centre}, config, None,
                               knot_time)
    holds = "yes" if exact["best"] <= exact["start"] else "no"
    return (f"{label:18} {angle:5d} {new_s:7.1f} {ref_s:7.1f} {ref_s / new_s:6.2f} "
            f"{rollouts(new, members) / new_s:6.2f} {rollouts(ref, members) / ref_s:6.2f} "
            f"{new.begin:5d} {rebuilt:7d} {frozen:6d} {new.start_score:9.2f} {new.score:9.2f} "
            f"{exact['start']:9.2f} {exact['best']:9.2f} {holds:>5}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="*", default=["fig5_large_small", "fig7_cascade"])
    parser.add_argument("--generated", nargs="*", default=[], metavar="KIND:LEVEL")
    parser.add_argument("--angles", type=int, nargs="+", default=[7],
                        help="baseline angle indices (default 7)")
    parser.add_argument("--members", type=int, default=4, help="ensemble members (default 4)")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE")
    args = parser.parse_args()
    config = load_config(None, ["dynamics.workers=0", f"ensemble.members={args.members}",
                                *args.overrides])
    cfg = config.physics
    print(f"members {args.members}, rounds {cfg.search_rounds} x {cfg.search_samples} samples, "
          f"lead {cfg.search_lead_knots} knots, extra prune margin {cfg.search_prune_margin} m, "
          f"rebuilds {cfg.search_rebuilds}")
    print(f"{'scene':18} {'angle':>5} {'new s':>7} {'ref s':>7} {'ratio':>6} {'r/s':>6} "
          f"{'ref r/s':>6} {'begin':>5} {'rebuilt':>7} {'frozen':>6} {'start':>9} {'best':>9} "
          f"{'x start':>9} {'x best':>9} {'holds':>5}")
    for label, scene in scenes(args, config):
        for angle in args.angles:
            print(bench(label, scene, angle, config), flush=True)


if __name__ == "__main__":
    np.set_printoptions(precision=3, suppress=True)
    main()
