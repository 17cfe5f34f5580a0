#!/usr/bin/env python3
"""Benchmark of the physics planner (Sec. V): seconds per initialization (one baseline
candidate optimised) against the number of boxes, with the seconds of each stage (pre, sphere,
full, post): the project's Fig. 9c.

    python benchmarks/bench_planner.py                          # every Sec. VI-B level
    python benchmarks/bench_planner.py --kind bookshelf --levels 1 25 \
        --set physics.iterations=6 --set physics.sphere_iterations=2

Target: at most 60 s per initialization at 25 boxes on the project's 2-core machine.
Scenes are the first of each level of the 'paper' set; per scene the baseline plans
``--angles`` angles and the first usable candidate is optimised. The reference measured in the
same run is one phi step of the scene's first rollout (the kept boxes, ``dynamics.substeps``
SAP steps): the 'init/step' column is the initialization's time in phi steps, a
machine-independent measure of the planner's work; 'its' the accepted iLQR iterations through
phi and 'cost x' the phi stages' final objective over their initial one (a fast stage that makes
no progress is no win); 'budget x' the initialization's time over ``physics.time_budget``
(target: at most 1.1) and the stages it cut. ``--set`` overrides any configuration field;
``--seeds`` plans other scenes of a level, e.g. dense refrigerators with Sec. V's phi stages
(off by default) under a short budget. ``--engines drake mujoco`` plans every scene with each
phi engine in turn (``dynamics.engine``), in the same run; 'x first' is the initialization's
time over the first engine's on the same scene:

    python benchmarks/bench_planner.py --kind fridge --levels 20 --seeds 1 2 3 \
        --set physics.iterations=30 --set physics.sphere_iterations=10 \
        --set physics.time_budget=60
"""

from __future__ import annotations

import argparse
import dataclasses
import time

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.phi.dynamics import initial_state
from drake_clutter.phi.engines import build_phi
from drake_clutter.phi.pruning import make_pruned_spec
from drake_clutter.phi.state import scene_box_states
from drake_clutter.phi.workers import WorkerPool
from drake_clutter.planners.baseline import plan_baseline
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.physics.pipeline import optimise_candidate
from drake_clutter.scene.generators import generate_scene, scene_set

nan = float("nan")


def phi_step_seconds(scene, candidate, config, repeats: int = 5) -> float:
    """Mean seconds of one phi step along the candidate's first knots (the reference)."""
    q = candidate.trajectory.q
    spec, _ = make_pruned_spec(scene, q, None, config.baseline.knot_time, config.dynamics,
                               config.world)
    phi = build_phi(spec)
    x = initial_state(spec.layout, q[0], scene_box_states(scene))
    tic = time.perf_counter()
    for u in q[1:1 + repeats]:
        x = phi.step(x, u)
    return (time.perf_counter() - tic) / repeats


def first_scene(kind: str, level: int, config, seed: int | None = None):
    """The scene of ``seed``, else the 'paper' set's first at this level (seed 0 beyond it)."""
    if seed is None:
        spec = next((s for s in scene_set("paper", config.generator)
                     if s.kind == kind and s.num_objects == level), None)
        seed = 0 if spec is None else spec.seed
    return generate_scene(kind, level, seed, config.generator)


def budget_column(plan, total: float, config) -> str:
    """The initialization's time over ``physics.time_budget`` (the target: at most 1.1) and
    the stages the budget cut short or left out."""
    budget = config.physics.time_budget
    if budget is None:
        return f"{'-':>8}"
    record = plan.details.get("time_budget", {})
    cut = "+".join(record.get("stopped", []) + record.get("skipped", []))
    return f"{total / budget:8.2f}" + (f" (cut: {cut})" if cut else "")


def bench(kind: str, level: int, config, angles: int, pool, seed: int | None = None,
          first: float | None = None) -> tuple[str, float]:
    """One row (its text, the initialization's seconds); ``first`` is another engine's
    seconds on the same scene (the 'x first' column)."""
    scene = first_scene(kind, level, config, seed)
    baseline = dataclasses.replace(config.baseline, num_angles=angles)
    usable = [c for c in plan_baseline(scene, baseline) if c.ok]
    if not usable:
        return f"{kind:9} {level:5d}  no usable baseline candidate in {angles} angles", nan
    candidate = usable[0]
    reference = phi_step_seconds(scene, candidate, config)
    tic = time.perf_counter()
    plan = optimise_candidate(PlanningContext(scene, config), candidate, pool=pool)
    total = time.perf_counter() - tic
    t = plan.timings
    stages = plan.details.get("stages", {})
    kept = stages.get("full", {}).get("kept_boxes", [])
    phi = [stages[n] for n in ("sphere", "full") if n in stages]
    iterations = sum(s["iterations"] for s in phi)
    # The phi stages' objective at the end over the start: a fast stage that stalls is no win.
    ratio = (phi[-1]["cost_history"][-1] / max(phi[0]["cost_history"][0], 1e-12) if phi
             else float("nan"))
    relative = total / first if first else 1.0
    return (f"{config.dynamics.engine:6} {kind:9} {level:5d} {len(kept):5d} {total:8.1f} "
            f"{relative:7.2f} {t.get('pre', 0):6.1f} "
            f"{t.get('sphere', 0):7.1f} {t.get('full', 0):7.1f} {t.get('post', 0):6.1f} "
            f"{reference * 1000:8.1f} {total / reference:9.0f} {iterations:4d} {ratio:7.3f} "
            f"{budget_column(plan, total, config)}  {plan.status} {plan.reason}"), total


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--kind", choices=("bookshelf", "fridge", "both"), default="both")
    parser.add_argument("--levels", type=int, nargs="*", help="box counts (default: all)")
    parser.add_argument("--angles", type=int, default=3,
                        help="baseline angles tried for a usable initialization (default 3)")
    parser.add_argument("--seeds", type=int, nargs="*",
                        help="scene seeds per level (default: the 'paper' set's first)")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE")
    parser.add_argument("--engines", nargs="*", choices=("drake", "mujoco"),
                        help="phi engines to plan each scene with (default: as configured)")
    args = parser.parse_args()
    config = load_config(None, args.overrides)
    configs = [load_config(None, [*args.overrides, f"dynamics.engine={e}"])
               for e in args.engines or [config.dynamics.engine]]
    kinds = ("bookshelf", "fridge") if args.kind == "both" else (args.kind,)
    print(f"iterations {config.physics.iterations} (sphere {config.physics.sphere_iterations}),"
          f" derivative_stride {config.dynamics.derivative_stride}, workers "
          f"{config.dynamics.workers}")
    print(f"{'engine':6} {'kind':9} {'boxes':>5} {'kept':>5} {'init s':>8} {'x first':>7} "
          f"{'pre s':>6} {'sphere s':>7} "
          f"{'full s':>7} {'post s':>6} {'step ms':>8} {'init/step':>9} {'its':>4} "
          f"{'cost x':>7} {'budget x':>8}  status")
    pool = WorkerPool(config.dynamics.workers) if config.dynamics.workers > 0 else None
    try:
        for kind in kinds:
            env = getattr(config.generator, kind)
            for level in args.levels or env.clutter_levels:
                for seed in args.seeds or [None]:
                    first = None
                    for engine_config in configs:
                        row, seconds = bench(kind, level, engine_config, args.angles, pool, seed,
                                             first)
                        first = seconds if first is None else first
                        print(row, flush=True)
    finally:
        if pool is not None:
            pool.close()


if __name__ == "__main__":
    np.set_printoptions(precision=3, suppress=True)
    main()
