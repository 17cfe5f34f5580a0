#!/usr/bin/env python3
"""Can the rearrange planner's pushes make room in dense clutter, by geometry alone? The gate
before phi judges any sequence.

    python studies/room_actions.py [--scenes fridge:12:14015,14016 ...] [--angles 3 5 8 10]
        [--seconds 60] [--set FIELD=VALUE ...]

For each generated scene (kind:level:seeds) and approach angle, the baseline's path is the
reach (cheap, and the push planner's reach where no bent path wins). The region to clear
(`rearrange.board.reach_region`) is read with the boxes at rest; where it is crowded, the beam
search (`rearrange.search.search_room`, the configuration's ``rearrange`` settings) looks for
sequences of pushes after which it is clear, each push with a joint path that reaches its
contact pose off the other boxes and the shelf. Printed: one line per initialization, then the
initializations crowded, those with a sequence found, the board's pushes and how many the
action paths refused, the goals' moves and those quasi-static mechanics says tip their box
(`actions.push_tip_ratio` above 1), and the refusals by cause (the last way in tried: the
arm enters a box that itself crowds the region, another box, the target; the shelf; the
gripper already touching the box; G missing its targets; the path leaving the judge's
limits).

Its dated results: docs/log/rearrange.md.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from collections import Counter

import numpy as np

from drake_clutter.common.config import load_config
from drake_clutter.common.typed_yaml import InputError
from drake_clutter.planners.budget import Deadline
from drake_clutter.planners.context import PlanningContext
from drake_clutter.planners.rearrange.board import crowding, reach_region
from drake_clutter.planners.rearrange.search import search_room
from drake_clutter.planners.registry import run_planners
from drake_clutter.planners.tool_path import approach_frame
from drake_clutter.scene.generators import generate_scene

DEFAULT_SCENES = ["fridge:12:14015,14016,14017", "fridge:16:16015,16016,16017",
                  "bookshelf:15:5015,5016,5017", "bookshelf:20:6015,6016,6017"]


def cause(reason: str, crowd: set[str]) -> str:
    """The cause of one refused action (its last way in's reason), in a few words."""
    last = reason.split(": ", 1)[-1].split("; ")[-1]
    found = re.search(r"enters (\S+) by", last)
    if found:
        box = found.group(1)
        return ("enters the target" if box == "target" else
                "enters a crowding box" if box in crowd else "enters another box")
    for key in ("shelf", "touches", "misses", "limits"):
        if key in last:
            return {"shelf": "meets the shelf", "touches": "touches the box first",
                    "misses": "G misses its targets", "limits": "leaves the limits"}[key]
    return last


def initialization(scene, index: int, config, seconds: float) -> dict:
    """One initialization's result: crowd, goals, pushes, refusals by cause, seconds."""
    context = PlanningContext(scene, config)
    geometry = context.arm()
    (candidate,) = run_planners(scene, config, ["baseline"], angles=[index])["baseline"]
    if not candidate.ok:
        return {"status": "no reach"}
    q = candidate.trajectory.q
    region = reach_region(q, config.rearrange.region_knots)
    crowd = crowding(geometry, region, {}, config.rearrange.deep)
    if not crowd:
        return {"status": "clear"}
    frame = approach_frame(geometry, q)
    rotation = geometry.tool_jacobian(q[-1])[0].rotation().matrix()
    tic = time.perf_counter()
    found = search_room(geometry, context.clearance, frame, region, q[0], rotation, config,
                        Deadline(seconds))
    return {"status": "room" if found.goals else "no room", "crowd": len(crowd),
            "goals": [len(g.moves) for g in found.goals], "pushes": found.pushes,
            "refused": found.refused, "seconds": time.perf_counter() - tic,
            "causes": Counter(cause(r, set(crowd)) for r in found.reasons),
            "moves": sum(len(g.moves) for g in found.goals),
            "tipping": sum(m.tip_ratio > 1.0 for g in found.goals for m in g.moves)}


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--scenes", nargs="+", default=DEFAULT_SCENES,
                        help="kind:level:seed,seed,...")
    parser.add_argument("--angles", type=int, nargs="+", default=[3, 5, 8, 10])
    parser.add_argument("--seconds", type=float, default=60.0, help="search budget, s")
    parser.add_argument("--set", dest="overrides", action="append", default=[])
    args = parser.parse_args(argv)
    try:
        config = load_config(None, args.overrides)
        specs = [(k, int(n), [int(s) for s in seeds.split(",")])
                 for k, n, seeds in (item.split(":") for item in args.scenes)]
    except (InputError, ValueError) as err:
        print(f"room_actions: {err}", file=sys.stderr)
        return 2
    results = []
    for kind, level, seeds in specs:
        for seed in seeds:
            scene = generate_scene(kind, level, seed, config.generator)
            for index in args.angles:
                r = initialization(scene, index, config, args.seconds) | {
                    "env": kind, "level": level}
                results.append(r)
                print(f"{kind} {level} {seed} angle {index}: {r['status']}"
                      + (f", crowd {r['crowd']}, goals {r['goals']}, pushes {r['pushes']}, "
                         f"refused {r['refused']}, {r['seconds']:.1f} s" if "crowd" in r
                         else ""), flush=True)
    summary(results)
    return 0


def summary(results: list[dict]) -> None:
    """Per environment and level, then the refusals' causes pooled."""
    print("| env | level | initializations | crowded | room found | pushes | refused | "
          "search s (median) |\n|---|---:|---:|---:|---:|---:|---:|---:|")
    for key in sorted({(r["env"], r["level"]) for r in results}):
        rs = [r for r in results if (r["env"], r["level"]) == key]
        crowded = [r for r in rs if "crowd" in r]
        print(f"| {key[0]} | {key[1]} | {len(rs)} | {len(crowded)} | "
              f"{sum(r['status'] == 'room' for r in crowded)} | "
              f"{sum(r['pushes'] for r in crowded)} | {sum(r['refused'] for r in crowded)} | "
              f"{np.median([r['seconds'] for r in crowded]) if crowded else 0:.1f} |")
    moves = sum(r.get("moves", 0) for r in results)
    print(f"goals' moves: {moves}, mechanics says {sum(r.get('tipping', 0) for r in results)} "
          "of them tip the pushed box")
    causes = sum((r["causes"] for r in results if "causes" in r), Counter())
    print("refusals by cause:", ", ".join(f"{k} {v}" for k, v in causes.most_common()))


if __name__ == "__main__":
    sys.exit(main())
