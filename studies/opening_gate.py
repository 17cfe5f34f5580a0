#!/usr/bin/env python3
"""Would a gripper opened only as wide as the target needs leave the grasp uncrowded? A
geometry gate before any planner opens the gripper less than fully (Sec. V's c_grp_open).

    python studies/opening_gate.py [--scenes fridge:12:14015,14016 ...] [--angles 4 6 7 9]
        [--margins 0.02 0.01]

For each generated scene (kind:level:seeds) and approach angle, the baseline's path is the
reach. At its pre-grasp pose (`rearrange.board.reach_region`, one knot) the boxes other than
the target that the capsule arm with the open gripper enters by more than
``rearrange.deep`` are counted (`board.crowding`), with the gripper fully open (0.09 m) and
opened to the target's extent across the pads (along y_G, its centre's offset included)
plus each margin (m, both pads together), at most fully open. Printed: one line per
initialization, then the crowded initializations, those the fitted opening leaves clear,
and the crowding boxes summed, per opening.

Its dated results: docs/log/rearrange.md.
"""

from __future__ import annotations

import argparse
import sys

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.rearrange.board import crowding, reach_region, world_poses
from drake_clutter.planners.registry import run_planners
from drake_clutter.planners.tool_path import ARM
from drake_clutter.robot import pr2
from drake_clutter.scene.generators import generate_scene

DENSE_PROBE = ["fridge:12:14015,14016,14017", "fridge:16:16015,16016,16017",
               "bookshelf:15:5015,5016,5017", "bookshelf:20:6015,6016,6017"]


def needed_opening(geometry, q_last: np.ndarray) -> float:
    """The opening (m) at which the target at rest just fits between the pads at the
    pre-grasp ``q_last`` (8,): twice its half extent along y_G plus its centre's offset."""
    poses = world_poses(geometry, {})
    X_WT = poses[geometry.scene.target]
    X_WG = geometry.tool_jacobian(q_last)[0]
    R_GT = X_WG.rotation().matrix().T @ X_WT.rotation().matrix()
    size = np.asarray(geometry.scene.target_box.size, float)
    half_y = float((np.abs(R_GT) @ (size / 2))[1])
    offset = float((X_WG.inverse() @ X_WT.translation())[1])
    return 2.0 * (half_y + abs(offset))


def initialization(scene, index: int, config, margins: list[float]) -> dict | None:
    """Crowding boxes at the pre-grasp fully open and fitted (per margin); None: no reach."""
    (candidate,) = run_planners(scene, config, ["baseline"], angles=[index])["baseline"]
    if not candidate.ok:
        return None
    geometry = PlanningContext(scene, config).arm()
    region = reach_region(np.asarray(candidate.trajectory.q, float), 1)
    need = needed_opening(geometry, region[-1])
    out = {"full": len(crowding(geometry, region, {}, config.rearrange.deep)), "need": need}
    for margin in margins:
        fitted = region.copy()
        fitted[:, ARM] = min(pr2.GRIPPER_MAX_OPENING, need + margin)
        out[margin] = len(crowding(geometry, fitted, {}, config.rearrange.deep))
    return out


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=DENSE_PROBE,
                        help="kind:level:seed,seed,...")
    parser.add_argument("--angles", type=int, nargs="+", default=[4, 6, 7, 9])
    parser.add_argument("--margins", type=float, nargs="+", default=[0.02, 0.01])
    args = parser.parse_args(argv)
    try:
        specs = [(k, int(n), [int(s) for s in seeds.split(",")])
                 for k, n, seeds in (item.split(":") for item in args.scenes)]
    except ValueError as err:
        print(f"opening_gate: --scenes: expected kind:level:seed,..., {err}", file=sys.stderr)
        return 2
    config = load_config()
    results = []
    for kind, level, seeds in specs:
        for seed in seeds:
            scene = generate_scene(kind, level, seed, config.generator)
            for index in args.angles:
                r = initialization(scene, index, config, args.margins)
                print(f"{kind} {level} {seed} angle {index}: " + (
                    "no reach" if r is None else f"needs {r['need'] * 1e3:.0f} mm, crowding "
                    f"{r['full']} fully open, " + ", ".join(
                        f"{r[m]} at +{m * 1e3:.0f} mm" for m in args.margins)), flush=True)
                if r is not None and r["full"]:
                    results.append(r)
    print(f"crowded fully open: {len(results)}, boxes {sum(r['full'] for r in results)}")
    for m in args.margins:
        print(f"fitted +{m * 1e3:.0f} mm: clear {sum(r[m] == 0 for r in results)}, boxes "
              f"{sum(r[m] for r in results)}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
