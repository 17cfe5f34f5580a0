#!/usr/bin/env python3
"""Benchmark of the judge in phi (beyond the paper): seconds to judge one search's paths,
against the reference measured in the same run.

    python benchmarks/bench_phi_judge.py                                  # 2 probe inits
    python benchmarks/bench_phi_judge.py --inits bookshelf:20:6016:4 --members 4

Per initialization (kind:level:seed:angle of the probe tier's generator): the baseline's
straight paths at the push planner's grasp heights and the search's first-round draws
(`aim.draw`, seeded like the search), judged in the same K members of phi
(``push_search.engine``) two ways:

* **complete** (the reference): one phi per member, one rollout per path through its knots and
  the hold, its jam measured on its own steps (`phi_judge.judged_rollouts`);
* **short**: ``judge_paths(..., complete=False)``, the search's: no rollout for a plan its
  checks fail, a rollout stops once its jam reads a kinematic failure.

Printed per initialization and in total: seconds of each, the reference's over the short
judge's, and the member readings that differ between them (0 expected: the same classes).
"""

from __future__ import annotations

import argparse
import time
from dataclasses import replace

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.phi_judge import (
    PhiVerdict,
    judge_paths,
)
from drake_clutter.planners.push.aim import draw
from drake_clutter.planners.push.search import Search
from drake_clutter.planners.registry import get_planner
from drake_clutter.planners.starts import height_candidates, start_key
from drake_clutter.scene.generators import generate_scene

DEFAULT_INITS = ("fridge:12:14015:4", "bookshelf:10:4015:4")


def search_paths(item: str, config):
    """(scene, {name: knots (T + 1, 8)}, times (s)) of one initialization: the straight
    starts and the search's first-round draws that are feasible."""
    kind, level, seed, angle = item.split(":")
    scene = generate_scene(kind, int(level), int(seed), config.generator)
    (candidate,) = get_planner("baseline").plan(scene, config, [int(angle)])
    context = PlanningContext(scene, config)
    found = height_candidates(context, candidate)
    starts = {start_key(*key): c.trajectory.q for key, c in found.items()}
    search = Search(scene, starts, candidate.trajectory.times, config, context.arm(),
                    context.clearance)
    rng = np.random.default_rng([config.push_search.seed, int(angle), 0])
    names = list(starts)
    for i in range(config.push_search.samples):
        start = names[i % len(starts)]
        frame, met = search.frame(start)
        search.add(f"{start}/r0m{i}", start, draw(rng, frame, met, config.push))
    return scene, {n: s.q for n, s in search.samples.items()}, candidate.trajectory.times


def differing(a: dict[str, PhiVerdict], b: dict[str, PhiVerdict]) -> int:
    """Member readings whose class differs between two sets of verdicts."""
    return sum(x.kind != y.kind for n in a for x, y in zip(a[n].readings, b[n].readings,
                                                           strict=True))


def main(argv=None) -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--inits", nargs="+", default=list(DEFAULT_INITS),
                        help="kind:level:seed:angle (default: %(default)s)")
    parser.add_argument("--members", type=int, default=4, help="K (default: %(default)s)")
    parser.add_argument("--set", nargs="*", default=[], metavar="FIELD=VALUE")
    args = parser.parse_args(argv)
    config = load_config(None, ["dynamics.workers=0", *args.set])
    judged = replace(config, dynamics=replace(config.dynamics,
                                              engine=config.push_search.engine),
                     ensemble=replace(config.ensemble, members=args.members))
    totals = np.zeros(2)
    print(f"{'initialization':>22} {'paths':>5} {'complete s':>10} {'short s':>8} {'ratio':>6} "
          f"{'differ':>6}")
    for item in args.inits:
        scene, paths, times = search_paths(item, config)
        geometry = PlanningContext(scene, judged).arm()
        seconds, verdicts = [], []
        for complete in (True, False):
            tic = time.perf_counter()
            verdicts.append(judge_paths(scene, paths, times, judged, geometry,
                                        complete=complete))
            seconds.append(time.perf_counter() - tic)
        totals += seconds
        print(f"{item:>22} {len(paths):5d} {seconds[0]:10.1f} {seconds[1]:8.1f} "
              f"{seconds[0] / seconds[1]:6.2f} {differing(verdicts[0], verdicts[1]):6d}")
    print(f"{'total':>22} {'':>5} {totals[0]:10.1f} {totals[1]:8.1f} "
          f"{totals[0] / totals[1]:6.2f}")

if __name__ == "__main__":
    main()
