#!/usr/bin/env python3
"""The main job: plan a scene with both planners, evaluate both in Bullet, show the plans.

    python apps/plan_scene.py                         # the default shipped scene, served live
    python apps/plan_scene.py --scene fig7_cascade    # a shipped scene by name, or a YAML file
    python apps/plan_scene.py --html out.html         # write a self-contained HTML file instead
    python apps/plan_scene.py --angles 14 --iterations 30   # the paper's budget (slow)

The baseline (Sec. IV) plans ``--angles`` approach angles; the physics planner (Sec. V) optimises
every baseline candidate that came out usable; both are replayed in Bullet (Sec. III). A table
prints, per angle, each planner's outcome and planning time; Meshcat then plays the best
physics plan (else the best baseline plan; else shows the scene). Prints the Meshcat URL and
serves until Ctrl-C unless --html or --no-browser is given. Bad input prints one line and
exits 2.
"""

from __future__ import annotations

import argparse
import dataclasses
import sys

import numpy as np

from drake_clutter.cli import EXIT_USAGE
from drake_clutter.config import load_config
from drake_clutter.robot_model import VARIANTS
from drake_clutter.scenes import DEFAULT_SCENE, resolve_scene
from drake_clutter.typed_yaml import InputError

# Best first: the order in which an outcome is preferred for the Meshcat replay.
_RANK = ("success", "partial_success", "failure_to_grasp", "objects_falling",
         "kinematic_failure", "planner_failure")


def with_iterations(config, iterations: int):
    """``config`` with ``iterations`` physics iterations, the sphere-proxy ones in the same
    proportion as in ``config`` (10 of 30 by default)."""
    physics = config.physics
    share = physics.sphere_iterations / max(physics.iterations, 1)
    physics = dataclasses.replace(physics, iterations=iterations,
                                  sphere_iterations=round(share * iterations))
    return dataclasses.replace(config, physics=physics)


def plan_and_evaluate(scene, config, angles: int):
    """(baseline candidates, physics candidates, their Bullet outcomes) for ``angles``
    approach angles."""
    from drake_clutter.baseline import plan_baseline
    from drake_clutter.evaluation import evaluate_candidates
    from drake_clutter.physics import plan_physics

    baseline_config = dataclasses.replace(config.baseline, num_angles=angles)
    baseline = plan_baseline(scene, baseline_config)
    physics = plan_physics(scene, config, baseline)
    return (baseline, physics, evaluate_candidates(scene, baseline, config.evaluation),
            evaluate_candidates(scene, physics, config.evaluation))


def side_by_side(baseline, physics, base_out, phys_out) -> str:
    """One row per angle: each planner's outcome kind and planning time (s)."""
    rows = [f"{'alpha':>7}  {'baseline':18} {'s':>6}  {'physics':18} {'s':>6}  stages (s)"]
    for b, p, bo, po in zip(baseline, physics, base_out, phys_out, strict=True):
        stages = " ".join(f"{k}={v:.1f}" for k, v in p.timings.items())
        rows.append(f"{b.alpha:+7.3f}  {bo.kind:18} {sum(b.timings.values()):6.1f}  "
                    f"{po.kind:18} {sum(p.timings.values()):6.1f}  {stages}")
    return "\n".join(rows)


def best(candidates, outcomes):
    """The candidate with the best outcome (ties: the first), or None if none is usable."""
    usable = [(c, o) for c, o in zip(candidates, outcomes, strict=True) if c.ok]
    if not usable:
        return None
    return min(usable, key=lambda co: _RANK.index(co[1].kind))[0]


def play(scene, config, candidate, variant: str, html: str | None, wait: bool) -> None:
    """Records the arm following ``candidate``'s knots (boxes where the scene puts them) in
    Meshcat, then writes ``html`` or serves (until Ctrl-C when ``wait``)."""
    from pydrake.geometry import Meshcat

    from drake_clutter.trajectory import robot_positions
    from drake_clutter.viz import look_at_shelf, write_static_html
    from drake_clutter.world import build_planning_world

    meshcat = Meshcat()
    world = build_planning_world(scene, variant, config.world, meshcat=meshcat)
    context = world.diagram.CreateDefaultContext()
    plant_context = world.plant.GetMyMutableContextFromRoot(context)
    look_at_shelf(meshcat, scene)
    recording = world.diagram  # the visualiser lives in the diagram
    meshcat.StartRecording(set_visualizations_while_recording=False)
    for t, q in zip(candidate.trajectory.times, candidate.trajectory.q, strict=True):
        context.SetTime(float(t))
        world.set_robot_positions(plant_context, robot_positions(q))
        recording.ForcedPublish(context)
    meshcat.StopRecording()
    meshcat.PublishRecording()
    if html:
        print(f"wrote {write_static_html(meshcat, html)}")
        return
    print(f"Meshcat: {meshcat.web_url()} ({candidate.planner} plan, alpha = "
          f"{candidate.alpha:+.3f})")
    if wait:
        import time
        print("serving; Ctrl-C to stop")
        try:
            while True:
                time.sleep(1.0)
        except KeyboardInterrupt:
            pass


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scene", default=DEFAULT_SCENE,
                        help=f"shipped scene name or YAML file (default: {DEFAULT_SCENE})")
    parser.add_argument("--html", help="write a self-contained HTML file instead of serving")
    parser.add_argument("--variant", choices=VARIANTS, default="capsules")
    parser.add_argument("--no-browser", action="store_true",
                        help="publish once and exit instead of serving until interrupted")
    parser.add_argument("--angles", type=int, default=2,
                        help="approach angles to plan (default 2; the paper uses 14)")
    parser.add_argument("--iterations", type=int, default=4,
                        help="physics iLQR iterations per candidate (default 4, a quick demo; "
                        "the paper's 30: --iterations 30); the sphere-proxy share scales along")
    parser.add_argument("--config", help="YAML configuration overrides")
    parser.add_argument("--set", dest="overrides", action="append", default=[],
                        metavar="KEY=VALUE")
    args = parser.parse_args(argv)
    try:
        if args.angles < 1:
            raise InputError("<command line>", "--angles", f"must be at least 1, got {args.angles}")
        if args.iterations < 0:
            raise InputError("<command line>", "--iterations",
                             f"must be at least 0, got {args.iterations}")
        config = with_iterations(load_config(args.config, args.overrides), args.iterations)
        scene = resolve_scene(args.scene)
        baseline, physics, base_out, phys_out = plan_and_evaluate(scene, config, args.angles)
        print(side_by_side(baseline, physics, base_out, phys_out))
        chosen = best(physics, phys_out) or best(baseline, base_out)
        wait = not args.html and not args.no_browser
        if chosen is None:
            from drake_clutter.viz import show_scene

            print("no usable plan: showing the scene")
            show_scene(scene, config, variant=args.variant, html=args.html, wait=wait)
        else:
            play(scene, config, chosen, args.variant, args.html, wait)
    except InputError as exc:
        print(f"plan_scene: error: {exc}", file=sys.stderr)
        return EXIT_USAGE
    return 0


if __name__ == "__main__":
    np.set_printoptions(precision=3, suppress=True)
    sys.exit(main())
