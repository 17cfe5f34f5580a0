#!/usr/bin/env python3
"""Does a plan that jams a box fail in the judge? Two jam predictors against the judge.

    python studies/press_vs_judge.py --db RUN.db [--db RUN2.db ...]
        [--configurations NAME ...] [--measure press|jam] [--set FIELD=VALUE ...]
        [--variant capsules|evaluation] [--normal-z 0.5] [--substeps 4] [--seed 0]

The judge's most common kinematic failure (Sec. III) is a box pushed into the board: in hard
contact a kinematic arm that comes down on a box's top meets a box that cannot make way, and
the board reads hundreds of newtons; the compliant phi reads a few. This takes every distinct
stored plan with robust replays (both planners, every configuration; a plan stored twice is
counted once) and measures its deepest press (`geometry.path_press`: the arm in geometry
``--variant``, the boxes at rest, ``--substeps`` configurations per knot interval, pairs whose
normal from the box to the arm has an up component above ``--normal-z``).

With ``--measure jam`` the score is phi's jam measure instead (`phi.jam`: the arm's commanded
approach into a box that a rigid world would not let move, whatever the contact's stiffness):
each plan rolled out in its own pruned phi (the planner's, under ``--set`` overrides) from
the settled scene, then ``physics.hold_knots`` knots holding its last configuration; its
score is the largest knot's jam over every box (m).

Printed, over all plans and per planner: the plans that press (deeper than each of
THRESHOLDS_MM) and those that do not, with their mean robust P(kinematic failure) and
P(success) and 95 % bootstrap intervals (``--seed``); and the area under the ROC curve of the
depth against the nominal replay's kinematic failure (0.5: a coin).

Its dated results: docs/log/decisions.md, docs/log/phi.md, docs/log/physics_planner.md.
"""

from __future__ import annotations

import argparse
import sys
from dataclasses import replace

import numpy as np

from drake_clutter.common.config import ReportConfig, load_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.experiments.paired import bootstrap_interval
from drake_clutter.experiments.specs import stored_scene
from drake_clutter.experiments.store import StoreError, stored_plans
from drake_clutter.phi.dynamics import initial_state
from drake_clutter.phi.engines import build_phi
from drake_clutter.phi.pruning import make_pruned_spec
from drake_clutter.phi.state import scene_box_states
from drake_clutter.planners.geometry import ArmGeometry, path_press
from drake_clutter.robot.pr2 import VARIANTS

THRESHOLDS_MM = (0.5, 5.0, 20.0)  # press depths reported, mm
KF = "kinematic_failure"


def plans_with_replays(dbs: list[str], configurations: list[str]) -> list[dict]:
    """One dict per distinct stored plan with robust replays: scene, planner, q (knots, 8),
    p_kf and p_success over its replays, nominal (its nominal replay's class)."""
    plans = {}
    for _, r, trajectory, digest in stored_plans(dbs, configurations):
        robust = (r.get("outcome") or {}).get("robust")
        if not robust:
            continue
        kinds = robust["kinds"]
        plans.setdefault((r["scene"], digest), {
            "scene": r["scene"], "planner": r["planner"], "q": trajectory.q,
            "p_kf": float(np.mean([k == KF for k in kinds])),
            "p_success": float(np.mean([k == "success" for k in kinds])),
            "nominal": r["kind"]})
    return list(plans.values())


def measure(plans: list[dict], variant: str, substeps: int, normal_z: float) -> None:
    """Adds each plan's deepest press (m) as ``press``, one planning world per scene."""
    config = load_config(None, [])
    scene, geometry = None, None
    for plan in sorted(plans, key=lambda p: p["scene"]):
        if plan["scene"] != scene:  # one scene's world at a time
            scene = plan["scene"]
            geometry = ArmGeometry(stored_scene(scene, config), variant)
        plan["press"] = path_press(geometry, plan["q"], substeps, normal_z)


def path_jam(scene, q: np.ndarray, config) -> float:
    """The largest knot's jam measure (m) over every box when the knot path ``q`` (T + 1, 8)
    is rolled out in its pruned phi and held ``physics.hold_knots`` knots; NaN where phi
    fails."""
    spec, _ = make_pruned_spec(scene, q, knot_time=config.baseline.knot_time,
                               config=config.dynamics, world_config=config.world)
    phi = build_phi(spec)
    x = phi.settle(initial_state(spec.layout, q[0], scene_box_states(scene)))
    worst = 0.0
    controls = list(q[1:]) + [q[-1]] * config.physics.hold_knots
    for u in controls:
        x, jam = phi.step_jam(x, u)
        if not np.all(np.isfinite(x)):
            return float("nan")
        worst = max(worst, float(jam.max(initial=0.0)))
    return worst


def measure_jam(plans: list[dict], config) -> None:
    """Adds each plan's jam measure (m, `path_jam`) as ``press``."""
    scene = None
    for i, plan in enumerate(sorted(plans, key=lambda p: p["scene"])):
        if scene is None or plan["scene"] != scene.name:
            scene = stored_scene(plan["scene"], config)
        plan["press"] = path_jam(scene, np.asarray(plan["q"], float), config)
        print(f"  {i + 1}/{len(plans)} {plan['scene']} {plan['planner']}: jam "
              f"{plan['press'] * 1000:.2f} mm, nominal {plan['nominal']}", flush=True)


def mean_interval(values: np.ndarray, seed: int) -> str:
    """'mean [lo, hi]': the mean and its 95 % bootstrap interval ('-' when empty)."""
    if len(values) == 0:
        return "-"
    lo, hi = bootstrap_interval(values, replace(ReportConfig(), bootstrap_seed=seed))
    return f"{values.mean():.2f} [{lo:.2f}, {hi:.2f}]"


def auc(score: np.ndarray, positive: np.ndarray) -> float:
    """P(a positive's score > a negative's), ties counted half (NaN without both)."""
    pos, neg = score[positive], score[~positive]
    if len(pos) == 0 or len(neg) == 0:
        return float("nan")
    greater = (pos[:, None] > neg[None, :]).sum() + 0.5 * (pos[:, None] == neg[None, :]).sum()
    return float(greater / (len(pos) * len(neg)))


def report(plans: list[dict], label: str, seed: int) -> None:
    """Prints the press table of ``plans`` (module docstring)."""
    plans = [p for p in plans if np.isfinite(p["press"])]
    depth = np.array([p["press"] for p in plans])
    p_kf = np.array([p["p_kf"] for p in plans])
    p_success = np.array([p["p_success"] for p in plans])
    nominal_kf = np.array([p["nominal"] == KF for p in plans])
    print(f"\n{label}: {len(plans)} plans, {int(nominal_kf.sum())} nominal kinematic failures; "
          f"AUC of the press depth against them {auc(depth, nominal_kf):.3f}")
    for mm in THRESHOLDS_MM:
        press = depth > mm / 1000.0
        for name, mask in (("press", press), ("no press", ~press)):
            print(f"  over {mm:4.1f} mm {name:8} {int(mask.sum()):4d} plans: P(kinematic "
                  f"failure) {mean_interval(p_kf[mask], seed)}, P(success) "
                  f"{mean_interval(p_success[mask], seed)}")


def main(argv=None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--db", action="append", required=True, help="experiment store")
    parser.add_argument("--configurations", nargs="*", default=[])
    parser.add_argument("--measure", default="press", choices=("press", "jam"),
                        help="the arm's geometric press, or phi's jam measure")
    parser.add_argument("--set", action="append", default=[], metavar="FIELD=VALUE",
                        help="configuration override for phi (--measure jam)")
    parser.add_argument("--variant", default="capsules", choices=VARIANTS,
                        help="the arm's geometry (the planner's cost geometry: capsules)")
    parser.add_argument("--normal-z", type=float, default=0.5,
                        help="up component of the box-to-arm normal that counts as a press")
    parser.add_argument("--substeps", type=int, default=4, help="configurations per interval")
    parser.add_argument("--seed", type=int, default=0, help="seed of the bootstrap")
    args = parser.parse_args(argv)
    if args.substeps < 1 or not -1.0 <= args.normal_z < 1.0:
        parser.error("--substeps must be >= 1 and --normal-z in [-1, 1)")
    try:
        plans = plans_with_replays(args.db, args.configurations)
    except StoreError as exc:
        print(exc, file=sys.stderr)
        return 2
    if not plans:
        print("no stored plan with robust replays", file=sys.stderr)
        return 2
    if args.measure == "jam":
        try:
            config = load_config(None, args.set)
        except InputError as exc:
            print(exc, file=sys.stderr)
            return 2
        measure_jam(plans, config)
        print(f"{len(plans)} distinct plans; phi's jam measure (m), largest knot")
    else:
        measure(plans, args.variant, args.substeps, args.normal_z)
        print(f"{len(plans)} distinct plans; the arm in '{args.variant}', a press: normal up "
              f"> {args.normal_z}, {args.substeps} configurations per knot interval")
    report(plans, "all plans", args.seed)
    for planner in sorted({p["planner"] for p in plans}):
        report([p for p in plans if p["planner"] == planner], planner, args.seed)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
