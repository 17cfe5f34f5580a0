"""Does a pushed box tip? phi and Bullet on one controlled push.

    python benchmarks/bench_push.py [--set FIELD=VALUE ...]

fig5_large_small's target alone on the board with one obstacle box in front of it, in the
baseline's path at alpha = 0: the arm pushes the obstacle into the target. The obstacle's
width w (square footprint), height h and lateral offset y sweep a grid; for each the
baseline's plan is replayed in Bullet (`judge.evaluate`) and rolled out in phi with both
boxes dynamic (`bench_fidelity.phi_final`), and both boxes are classed as in Sec. III
(standing / tipped / fallen). Printed per case: each engine's class, displacement (cm) and
tilt (deg) of the obstacle and of the target; then how many boxes agree.
``--set`` overrides apply to both engines' configuration (e.g. ``evaluation.*`` for the
judge, ``world.*`` / ``dynamics.*`` for phi).
"""

from __future__ import annotations

import argparse
import dataclasses

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.evaluation.judge import evaluate
from drake_clutter.planners.baseline import plan_baseline
from drake_clutter.scene import scenes
from drake_clutter.testing.fidelity import classes, phi_final

WIDTHS = (0.04, 0.06, 0.08, 0.10)  # m, the obstacle's square footprint
HEIGHTS = (0.10, 0.16, 0.22)  # m
OFFSETS = (0.0, 0.03)  # m across the approach (W y)
OBSTACLE_X = 0.66  # m (W x): between the arm's start and the target (0.79)


def push_case(base, w: float, h: float, y: float, config):
    """(Bullet's and phi's classes, displacements (cm) and tilts (deg) per box, outcome kind)
    of the baseline's plan through an obstacle w x w x h at (OBSTACLE_X, y); None if no plan."""
    target = next(b for b in base.boxes if b.name == base.target)
    obstacle = dataclasses.replace(target, name="obstacle", size=(w, w, h),
                                   pose=(OBSTACLE_X, y, 0.0), friction=0.6)
    scene = dataclasses.replace(base, boxes=(target, obstacle))
    (candidate,) = plan_baseline(scene, config.baseline, alphas=[0.0])
    if not candidate.ok:
        return None
    outcome = evaluate(scene, candidate.trajectory, config.evaluation)
    p_phi, tilt_phi, *_ = phi_final(scene, candidate.trajectory, config, 2.0)
    start = np.array([[b.pose[0], b.pose[1], scene.box_center_z(b)] for b in scene.boxes])
    p_bullet = np.array([b.final_position for b in outcome.boxes])
    tilt_bullet = np.array([b.tilt for b in outcome.boxes])
    max_tilt = config.evaluation.max_tilt
    return {"bullet": (classes(scene, p_bullet, tilt_bullet, max_tilt),
                       np.linalg.norm(p_bullet - start, axis=1) * 100, np.degrees(tilt_bullet)),
            "phi": (classes(scene, p_phi, tilt_phi, max_tilt),
                    np.linalg.norm(p_phi - start, axis=1) * 100, np.degrees(tilt_phi)),
            "kind": outcome.kind}


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    args = parser.parse_args(argv)
    config = load_config(None, args.set)
    base = scenes.load_shipped_scene("fig5_large_small")
    agree = {"obstacle": 0, "target": 0}
    cases = 0
    for w in WIDTHS:
        for h in HEIGHTS:
            for y in OFFSETS:
                case = push_case(base, w, h, y, config)
                label = f"w {w:.2f} h {h:.2f} y {y:+.2f}"
                if case is None:
                    print(f"{label}: no baseline plan")
                    continue
                cases += 1
                (cb, mb, tb), (cp, mp, tp) = case["bullet"], case["phi"]
                agree["target"] += cb[0] == cp[0]
                agree["obstacle"] += cb[1] == cp[1]
                print(f"{label}: obstacle Bullet {cb[1]:8} {mb[1]:5.1f} cm {tb[1]:3.0f} deg | "
                      f"phi {cp[1]:8} {min(mp[1], 999.9):5.1f} cm {tp[1]:3.0f} deg | target "
                      f"Bullet {cb[0]} {mb[0]:5.1f} cm {tb[0]:3.0f} deg, phi {cp[0]} "
                      f"{min(mp[0], 999.9):5.1f} cm {tp[0]:3.0f} deg ({case['kind']})",
                      flush=True)
    print(f"\n{cases} pushes: obstacle classes agree {agree['obstacle']}/{cases}, target "
          f"{agree['target']}/{cases}")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
