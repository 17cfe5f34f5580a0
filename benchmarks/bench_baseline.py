#!/usr/bin/env python3
"""Benchmark of the baseline planner (Sec. IV): time per approach angle, IK and optimisation
separately, on generated bookshelf and refrigerator scenes at several clutter levels, and how
many angles were IK-feasible and ended "ok".

    python benchmarks/bench_baseline.py                 # 2 scenes per level, 14 angles each
    python benchmarks/bench_baseline.py --seeds 1 --angles 7

Target: a median of at most 1 s per angle (IK + optimisation + check) on the
project's 2-core machine. The reference measured in the same run is one arm-vs-shelf
signed-distance query; one evaluation of the optimiser's cost queries (num_knots - 1) x
opt_substeps configurations, and the optimisation time is also printed in such evaluations
('opt/ref'), a machine-independent measure of the optimiser's work. Scenes are the first ones
of each level of the 'paper' set. The baseline ignores the boxes, so clutter changes only
where the generator put the target.
"""

from __future__ import annotations

import argparse
import dataclasses
import statistics
import time

import numpy as np

from drake_clutter.common.config import BaselineConfig, Config, WorldConfig, load_config
from drake_clutter.planners.approach import static_planning_world
from drake_clutter.planners.baseline import plan_baseline
from drake_clutter.planners.clearance import ShelfClearance
from drake_clutter.scene.generators import generate_scene, scene_set

LEVELS = {"bookshelf": (1, 10, 25), "fridge": (1, 8, 16)}


def reference_query_us(repeats: int = 2000) -> float:
    """us for one arm-vs-shelf signed-distance query (d_safe range) at the parked arm."""
    world = static_planning_world(generate_scene("bookshelf", 1, seed=0))
    clearance = ShelfClearance(world)
    q = np.asarray(WorldConfig().park_configuration)
    tic = time.perf_counter()
    for _ in range(repeats):
        clearance.contacts(q, BaselineConfig().d_safe)
    return (time.perf_counter() - tic) / repeats * 1e6


def run_level(kind: str, level: int, seeds: int, config: Config) -> list:
    """Candidates of the first ``seeds`` scenes of one clutter level of the 'paper' set."""
    specs = [s for s in scene_set("paper", config.generator)
             if s.kind == kind and s.num_objects == level]
    candidates = []
    for spec in specs[:seeds]:
        scene = generate_scene(kind, level, spec.seed, config.generator)
        candidates += plan_baseline(scene, config.baseline)
    return candidates


def _median(values) -> float:
    return statistics.median(values) if values else float("nan")


def summary_row(label: str, candidates, per_evaluation_s: float) -> str:
    """One table row: counts and median / 90th-percentile seconds per angle."""
    ik = [c.timings.get("ik", 0.0) for c in candidates]
    opt = [c.timings["optimisation"] for c in candidates if "optimisation" in c.timings]
    total = [sum(c.timings.values()) for c in candidates]
    feasible = sum(c.status != "ik_failed" for c in candidates)
    ok = sum(c.ok for c in candidates)
    p90 = float(np.percentile(total, 90)) if total else float("nan")
    return (f"{label:16} {len(candidates):6d} {feasible:8d} {ok:4d} {_median(ik):8.3f} "
            f"{_median(opt):8.3f} {_median(opt) / per_evaluation_s:7.0f} "
            f"{_median(total):8.3f} {p90:7.3f}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--seeds", type=int, default=2, help="scenes per clutter level")
    parser.add_argument("--angles", type=int, default=None, help="angles per scene")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE", help="configuration override, as drake-clutter's")
    args = parser.parse_args(argv)
    full = load_config(None, args.overrides)
    config = full.baseline
    if args.angles is not None:
        config = dataclasses.replace(config, num_angles=args.angles)
        full = dataclasses.replace(full, baseline=config)
    query_us = reference_query_us()
    samples = (config.num_knots - 1) * config.opt_substeps
    per_evaluation = query_us * 1e-6 * samples
    print(f"reference: one arm-vs-shelf distance query {query_us:.0f} us; a cost evaluation "
          f"queries {samples} configurations = {per_evaluation * 1000:.1f} ms ('opt/ref' is the "
          "optimisation time in such evaluations)")
    print(f"{'scenes':16} {'angles':>6} {'IK-feas.':>8} {'ok':>4} {'ik s':>8} {'opt s':>8} "
          f"{'opt/ref':>7} {'total s':>8} {'p90 s':>7}   (medians per angle)")
    everything = []
    tic = time.perf_counter()
    for kind, levels in LEVELS.items():
        for level in levels:
            candidates = run_level(kind, level, args.seeds, full)
            everything += candidates
            print(summary_row(f"{kind} n={level}", candidates, per_evaluation), flush=True)
    print(summary_row("all", everything, per_evaluation))
    median = _median([sum(c.timings.values()) for c in everything])
    verdict = "meets" if median <= 1.0 else "MISSES"
    print(f"median per angle {median:.3f} s: {verdict} the 1 s target "
          f"({time.perf_counter() - tic:.0f} s for {len(everything)} angles)")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
