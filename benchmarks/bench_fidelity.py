"""How well phi predicts the judge: phi and Bullet on the same plans (issues 5 and 6).

    python benchmarks/bench_fidelity.py [--scenes fig5_large_small ...] [--set dynamics.substeps=5]

The physics planner can only be as good as phi's prediction of what Bullet will do. For each
behaviour scene (Sec. VI-A) the baseline plans its provenance angle; that plan is replayed in
Bullet (`evaluation.evaluate`: hard contacts, until the boxes rest) and rolled out in phi with
every box dynamic (no pruning), then ``--settle`` seconds with the arm held. Each box is
classed as in Sec. III on both final states: fallen (off the board), tipped (tilt over
``evaluation.max_tilt``) or standing. A kinematic failure in Bullet stops its replay early, so
its boxes are left out of the comparison.

Printed per scene: each box's class, displacement (cm) and tilt (deg) in Bullet | phi; then
the boxes whose class agrees, and the mean |displacement difference| over the boxes that moved
more than 1 cm in either. The seconds are phi's rollout.
"""

from __future__ import annotations

import argparse
import time

import numpy as np
from scipy.spatial.transform import Rotation

from drake_clutter import scenes
from drake_clutter.baseline import plan_baseline
from drake_clutter.config import load_config
from drake_clutter.dynamics import Phi, initial_state, make_spec, scene_box_states
from drake_clutter.evaluation import evaluate, off_the_board, tilt_angle

SCENES = ("fig5_large_small", "fig6_push_sideways", "fig7_cascade", "fig8_snaking")


def classes(scene, p_WB: np.ndarray, tilts: np.ndarray, max_tilt: float) -> list[str]:
    """Sec. III's class per box from final positions (W, m) and tilts (rad)."""
    fallen = off_the_board(scene, p_WB)
    return ["fallen" if f else "tipped" if t > max_tilt else "standing"
            for f, t in zip(fallen, tilts, strict=True)]


def phi_final(scene, trajectory, config, settle: float) -> tuple[np.ndarray, np.ndarray, float]:
    """Box positions (n, 3) and tilts (n,) after phi rolls the plan out with every box dynamic
    and holds the arm ``settle`` s; and the rollout's seconds."""
    names = [b.name for b in scene.boxes]
    knot_time = float(np.diff(trajectory.times[:2])[0])
    spec = make_spec(scene, names, None, knot_time, config.dynamics, config.world, "capsules")
    phi = Phi(spec)
    tic = time.perf_counter()
    x = phi.settle(initial_state(spec.layout, trajectory.q[0], scene_box_states(scene)))
    x = phi.rollout(x, trajectory.q[1:])[-1]
    x = phi.settle(x, settle)
    seconds = time.perf_counter() - tic
    boxes = spec.layout.boxes(x)
    R = Rotation.from_quat(np.nan_to_num(boxes[:, [1, 2, 3, 0]], nan=1.0)).as_matrix()
    return boxes[:, 4:7], tilt_angle(R), seconds


def compare(name: str, config, settle: float) -> tuple[int, int]:
    """Prints one scene's comparison; returns (boxes whose class agrees, boxes compared)."""
    scene = scenes.load_shipped_scene(name)
    alpha = float(scene.provenance.parameters["alpha"])
    (candidate,) = plan_baseline(scene, config.baseline, alphas=[alpha])
    if not candidate.ok:
        print(f"{name}: the baseline found no plan ({candidate.reason})")
        return 0, 0
    outcome = evaluate(scene, candidate.trajectory, config.evaluation)
    p_phi, tilt_phi, seconds = phi_final(scene, candidate.trajectory, config, settle)
    start = np.array([[b.pose[0], b.pose[1], scene.box_center_z(b)] for b in scene.boxes])
    p_bullet = np.array([b.final_position for b in outcome.boxes])
    tilt_bullet = np.array([b.tilt for b in outcome.boxes])
    max_tilt = config.evaluation.max_tilt
    c_bullet = classes(scene, p_bullet, tilt_bullet, max_tilt)
    c_phi = classes(scene, p_phi, tilt_phi, max_tilt)
    moved_b = np.linalg.norm(p_bullet - start, axis=1) * 100
    moved_p = np.linalg.norm(p_phi - start, axis=1) * 100
    print(f"\n{name} (alpha {alpha:+.2f}): Bullet {outcome.kind}; phi rollout {seconds:.1f} s")
    print(f"  {'box':16} {'Bullet':>8} {'cm':>6} {'deg':>4} | {'phi':>8} {'cm':>6} {'deg':>4}")
    for i, box in enumerate(scene.boxes):
        print(f"  {box.name:16} {c_bullet[i]:>8} {moved_b[i]:6.1f} "
              f"{np.degrees(tilt_bullet[i]):4.0f} | {c_phi[i]:>8} "
              f"{min(moved_p[i], 999.9):6.1f} {np.degrees(tilt_phi[i]):4.0f}")
    if outcome.kind == "kinematic_failure":
        print("  (kinematic failure in Bullet: its replay stopped early, not compared)")
        return 0, 0
    agree = sum(a == b for a, b in zip(c_bullet, c_phi, strict=True))
    moving = (moved_b > 1.0) | (moved_p > 1.0)
    error = np.minimum(np.abs(moved_b - moved_p), 100.0)[moving]  # fallen: capped at 1 m
    print(f"  classes agree: {agree}/{len(c_phi)}; mean |displacement difference| of moved "
          f"boxes: {error.mean() if len(error) else 0.0:.1f} cm (capped at 100)")
    return agree, len(c_phi)


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenes", nargs="+", default=list(SCENES))
    parser.add_argument("--settle", type=float, default=2.0, help="s the arm holds after the plan")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE")
    args = parser.parse_args(argv)
    config = load_config(None, args.set)
    print(f"phi: {config.dynamics.substeps} sub-steps a {config.baseline.knot_time} s knot, "
          f"modulus {config.world.hydroelastic_modulus:g} Pa")
    agree = total = 0
    for name in args.scenes:
        a, n = compare(name, config, args.settle)
        agree, total = agree + a, total + n
    print(f"\nall scenes: classes agree for {agree}/{total} boxes")
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
