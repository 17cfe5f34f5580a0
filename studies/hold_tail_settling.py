#!/usr/bin/env python3
"""How long must phi's hold tail be for the boxes to have landed? (Table II's "all" times.)

    python studies/hold_tail_settling.py [SCENE ...] [--angles 4 5 ...] [--knots N]
        [--set FIELD=VALUE ...]

For each shipped scene (default: the behaviours tier's four) and approach angle (default the
tier's 4-9), plans the baseline candidate, builds the full phi stage's problem about it
(`stage.stage_problem`: pruned phi, boxes settled under the arm at the start) and rolls the
path out followed by ``--knots`` knots of the held arm (default 20: 4 s at 0.2 s knots).
Prints per plan: the first tail knot after which every kept box stays quiet (|v| + 0.1 m x |w|
under ``QUIET_SPEED``) or has fallen (its centre 0.3 m below its start: phi has no
floor, so a fallen box never settles; "-" if never), the largest tilt (rad) and the boxes fallen
at the end of the configured hold tail (``physics.hold_knots``) and at the end of the long
tail, and the boxes whose tilt crosses the judge's tipping threshold (``evaluation.max_tilt``)
only after the configured tail. A summary line gives the quantiles of the settling knot: a tail
shorter than most of them prices boxes mid-fall.

Exit status 2 with one line on bad input (an unknown scene, an angle out of range).

Its dated results: docs/log/decisions.md, docs/log/physics_planner.md.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from drake_clutter.common.config import ConfigError, load_config
from drake_clutter.common.typed_yaml import EXIT_USAGE
from drake_clutter.experiments.specs import load_spec
from drake_clutter.phi.derivatives import box_speeds
from drake_clutter.phi.state import box_state_to_pose
from drake_clutter.planners.approach import approach_angles
from drake_clutter.planners.baseline import plan_baseline
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.physics.stage import stage_problem
from drake_clutter.scene.scenes import SceneError, load_shipped_scene


def _tilts_and_drops(layout, x, x0) -> tuple[np.ndarray, np.ndarray]:
    """Each kept box's tilt (rad) and centre drop below its start (m) in state x."""
    tilts, drops = [], []
    for b, b0 in zip(layout.boxes(x), layout.boxes(x0), strict=True):
        z_axis = box_state_to_pose(b).rotation().matrix()[:, 2]
        tilts.append(float(np.arccos(np.clip(z_axis[2], -1.0, 1.0))))
        drops.append(float(b0[6] - b[6]))
    return np.array(tilts), np.array(drops)


QUIET_SPEED = 0.01  # m/s: a box whose |v| + 0.1 m x |w| is below this has settled
FALLEN_DROP = 0.3  # m: a box centre this far below its start has left the board (phi has
# no floor: such a box falls for ever and never settles)


def _settled_knot(layout, xs: np.ndarray, x0: np.ndarray, quiet_speed: float) -> int | None:
    """The first index k such that every state from k on has every box quiet or fallen."""
    quiet = []
    for x in xs:
        speed = box_speeds(layout, x)
        _, drops = _tilts_and_drops(layout, x, x0)
        moving = (speed > quiet_speed) & (drops < FALLEN_DROP)
        quiet.append(not moving.any())
    for k in range(len(quiet)):
        if all(quiet[k:]):
            return k
    return None


def measure(name: str, angle: int, config, knots: int) -> dict:
    """The settling figures of one plan (see the module docstring)."""
    scene = load_shipped_scene(name)
    alphas = approach_angles(config.baseline)
    (candidate,) = plan_baseline(scene, config.baseline, alphas=[alphas[angle]])
    if not candidate.ok:
        return {"scene": name, "angle": angle, "error": candidate.reason}
    q = candidate.trajectory.q
    with stage_problem(PlanningContext(scene, config), q, "capsules") as problem:
        layout, dynamics = problem.dynamics.layout, problem.dynamics
        x0 = problem.z0[:layout.nx]
        xs = dynamics.rollout(x0, q[1:])
        tail = dynamics.rollout(xs[-1], np.tile(q[-1], (knots, 1)))
    hold = config.physics.hold_knots
    settled = _settled_knot(layout, tail, x0, QUIET_SPEED)
    tilt_hold, drop_hold = _tilts_and_drops(layout, tail[min(hold, knots)], x0)
    tilt_end, drop_end = _tilts_and_drops(layout, tail[-1], x0)
    threshold = config.evaluation.max_tilt
    late = [layout.box_names[i] for i in range(layout.num_boxes)
            if tilt_end[i] > threshold >= tilt_hold[i]]
    return {"scene": name, "angle": angle, "settled": settled,
            "tilt_hold": float(tilt_hold.max(initial=0.0)),
            "tilt_end": float(tilt_end.max(initial=0.0)),
            "drop_hold": float(drop_hold.max(initial=0.0)),
            "drop_end": float(drop_end.max(initial=0.0)), "late": late,
            "fallen_hold": int(np.sum(drop_hold >= FALLEN_DROP)),
            "fallen_end": int(np.sum(drop_end >= FALLEN_DROP))}


def main(argv: list[str] | None = None) -> int:
    """Parses the arguments, measures every plan, prints the table and the summary."""
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[1])
    parser.add_argument("scenes", nargs="*")
    parser.add_argument("--angles", type=int, nargs="+")
    parser.add_argument("--knots", type=int, default=20)
    parser.add_argument("--set", action="append", default=[], dest="overrides")
    args = parser.parse_args(argv)
    tier = load_spec("behaviours")[0]
    names = args.scenes or list(tier.shipped)
    angles = args.angles or list(tier.angles)
    try:
        config = load_config(None, ["dynamics.workers=0", *args.overrides])
        for name in names:
            load_shipped_scene(name)
        count = len(approach_angles(config.baseline))
        bad = [a for a in angles if not 0 <= a < count]
        if bad:
            raise ConfigError("<arguments>", "--angles", f"must be in 0..{count - 1}, got {bad}")
        if args.knots < 1:
            raise ConfigError("<arguments>", "--knots", f"must be at least 1, got {args.knots}")
    except (ConfigError, SceneError) as exc:
        print(f"hold_tail_settling: {exc}", file=sys.stderr)
        return EXIT_USAGE
    hold = config.physics.hold_knots
    print(f"hold tail {hold} knots; rolled out {args.knots}; quiet below "
          f"{QUIET_SPEED} m/s; tipping at {config.evaluation.max_tilt:.3f} rad")
    print(f"{'scene':22} {'angle':>5} {'settled':>7} {'tilt@hold':>9} {'tilt@end':>8} "
          f"{'fallen@hold':>11} {'fallen@end':>10}  tipped after the hold")
    settled = []
    for name in names:
        for angle in angles:
            r = measure(name, angle, config, args.knots)
            if "error" in r:
                print(f"{name:22} {angle:5d}  no baseline plan: {r['error']}")
                continue
            settled.append(r["settled"] if r["settled"] is not None else args.knots + 1)
            print(f"{name:22} {angle:5d} {r['settled'] if r['settled'] is not None else '-':>7} "
                  f"{r['tilt_hold']:9.3f} {r['tilt_end']:8.3f} {r['fallen_hold']:11d} "
                  f"{r['fallen_end']:10d}  {', '.join(r['late']) or '-'}")
    if settled:
        q = np.percentile(settled, [50, 75, 90, 100])
        print(f"settling knot (after Delta; {args.knots + 1} = never): median {q[0]:.0f}, "
              f"75 % {q[1]:.0f}, 90 % {q[2]:.0f}, max {q[3]:.0f}; within the hold tail "
              f"({hold}): {sum(s <= hold for s in settled)} of {len(settled)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
