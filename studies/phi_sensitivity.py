#!/usr/bin/env python3
"""How smooth is a phi stage's objective? Why its line searches fail.

    python studies/phi_sensitivity.py [SCENE] [--generated KIND N SEED] [--variant V]
        [--directions D] [--seed S] [--set FIELD=VALUE ...]

On the pre-processed baseline path of one scene (a shipped scene at its provenance angle, by
default fig7_cascade, or the first usable of 3 angles of a generated one), builds the phi
stage's problem (`stage.stage_problem`; ``--variant`` capsules = the full stage) and prints:

1. Sensitivity: the objective's change dJ, and the largest change of any box state (rad, m,
   rad/s, m/s), when every arm control (rad; the gripper left alone) moves by eps along a
   seeded random direction of max-norm 1, for eps 1e-9 .. 1e-3. A smooth objective changes
   in proportion to eps; a chaotic rollout (boxes near tipping, contact onsets) gives box-state
   gains of 1e4-1e6 and dJ far above eps x the gradient the model sees. Also the knot where the
   boxes' states start to differ at eps 1e-7, and how fast the difference grows after it.
2. The model against the objective: one backward pass (mu = the solver's first) at the start,
   then the predicted decrease -(alpha d1 + alpha^2 d2) against the actual one at step sizes
   2^0 .. 2^-14, closed loop (K) and open loop, with the trust region as the stage uses it.
   Where the actual changes are much larger than predicted and of either sign, the line search
   can only win (or lose) by chance.

Its dated results: docs/log/decisions.md, docs/log/phi.md, docs/log/physics_planner.md.
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.phi.workers import WorkerPool
from drake_clutter.planners.baseline import plan_baseline
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.physics.kinematic import preprocess
from drake_clutter.planners.physics.limits import solver_settings
from drake_clutter.planners.physics.stage import stage_problem
from drake_clutter.scene import scenes
from drake_clutter.scene.generators import generate_scene
from drake_clutter.solvers import ilqr

EPSILONS = (1e-9, 1e-7, 1e-5, 1e-3)


def start_path(args, config) -> tuple[object, np.ndarray]:
    """The scene and its pre-processed baseline knot path (T + 1, 8)."""
    if args.generated:
        kind, n, seed = args.generated
        scene = generate_scene(kind, int(n), int(seed), config.generator)
        baseline = dataclasses.replace(config.baseline, num_angles=3)
        candidate = next(c for c in plan_baseline(scene, baseline) if c.ok)
    else:
        scene = scenes.load_shipped_scene(args.scene)
        alpha = float(scene.provenance.parameters["alpha"])
        (candidate,) = plan_baseline(scene, config.baseline, alphas=[alpha])
    q, _ = preprocess(PlanningContext(scene, config), candidate.trajectory.q)
    return scene, q


def objective(problem, us: np.ndarray) -> tuple[float, np.ndarray]:
    zs = ilqr.rollout(problem.augmented, problem.z0, us)
    return float(sum(problem.objective.terms(zs, us).values())), zs


def sensitivity(problem, us: np.ndarray, directions: int, seed: int) -> None:
    total, zs = objective(problem, us)
    nx = problem.augmented.nx
    print(f"objective {total:.4f}")
    rng = np.random.default_rng(seed)
    for trial in range(directions):
        d = rng.uniform(-1.0, 1.0, us.shape)
        d[:, 7] = 0.0  # the gripper opening (m) left alone
        for eps in EPSILONS:
            value, zs_eps = objective(problem, us + eps * d)
            boxes = np.abs(zs_eps[:, 8:nx] - zs[:, 8:nx])
            print(f"direction {trial} eps {eps:7.0e}: dJ {value - total:11.4g}  max |d box "
                  f"state| {np.nanmax(boxes):9.2e}  gain {np.nanmax(boxes) / eps:9.2e}")
        _, zs_eps = objective(problem, us + 1e-7 * d)
        per_knot = np.nanmax(np.abs(zs_eps[:, 8:nx] - zs[:, 8:nx]), axis=1)
        print("  max |d box state| per knot at eps 1e-7: "
              + " ".join(f"{v:.0e}" for v in per_knot))


def model_check(problem, us: np.ndarray, config, knot_time: float) -> None:
    settings = solver_settings(config, 1, knot_time)
    lo, hi = np.array(settings.u_min), np.array(settings.u_max)
    limit = np.asarray(settings.step_limit)
    augmented, cost = problem.augmented, problem.objective
    total, zs = objective(problem, us)
    A, B = augmented.linearize(zs, us)
    exp = cost.quadratize(zs, us)
    ilqr.zero_nonfinite(A, B, *vars(exp).values())
    bp = ilqr.backward_pass(A, B, exp, settings.reg_init, us, lo, hi)
    if bp is None:
        print(f"Q_uu not positive definite at mu {settings.reg_init:g}")
        return
    k, K, (d1, d2) = bp
    print(f"\nmodel at mu {settings.reg_init:g}: d1 {d1:.4g}, d2 {d2:.4g}, max |k| "
          f"{np.abs(k).max():.3g} rad")
    print(f"{'alpha':>8} {'predicted':>10} {'closed loop':>12} {'open loop':>12}")
    for i in range(0, 15, 2):
        alpha = 0.5 ** i
        actual = []
        for gain in (K, np.zeros_like(K)):
            new_zs, new_us = ilqr.forward_pass(augmented, zs, us, k, gain, alpha, lo, hi,
                                               augmented.difference, limit)
            finite = np.all(np.isfinite(new_zs))
            actual.append(total - sum(cost.terms(new_zs, new_us).values()) if finite
                          else float("nan"))
        print(f"  2^-{i:<3d} {-(alpha * d1 + alpha ** 2 * d2):10.4g} {actual[0]:12.4g} "
              f"{actual[1]:12.4g}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("scene", nargs="?", default="fig7_cascade")
    parser.add_argument("--generated", nargs=3, metavar=("KIND", "N", "SEED"))
    parser.add_argument("--variant", default="capsules", choices=("capsules", "sphere_gripper"))
    parser.add_argument("--directions", type=int, default=2)
    parser.add_argument("--seed", type=int, default=0, help="of the random directions")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE")
    args = parser.parse_args()
    config = load_config(None, args.overrides)
    scene, q = start_path(args, config)
    knot_time = config.baseline.knot_time
    pool = WorkerPool(config.dynamics.workers) if config.dynamics.workers > 0 else None
    try:
        with stage_problem(PlanningContext(scene, config), q, args.variant, pool,
                           knot_time) as problem:
            print(f"{scene.name}: {problem.augmented.layout.num_boxes} boxes in phi, "
                  f"{args.variant} arm, {len(q) - 1} knots")
            sensitivity(problem, q[1:], args.directions, args.seed)
            model_check(problem, q[1:], config, knot_time)
    finally:
        if pool is not None:
            pool.close()


if __name__ == "__main__":
    main()
