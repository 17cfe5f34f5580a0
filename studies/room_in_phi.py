#!/usr/bin/env python3
"""Do the rearrange planner's pushes make room in phi, or only on the board?

    python studies/room_in_phi.py --db STORE.db [--why "not accepted" rearranged] [--skip N]
        [--limit N] [--bullet]

For every rearrange row of a store whose record says the search found sequences ("not
accepted": none was accepted; "rearranged": one was), the search is run again for that angle
(deterministic: the reach is the same initialization's push row's path, the budget unlimited),
and each goal's pushes alone (the plan up to the reach's first knot, held there for
``phi_judge.hold_knots`` knots) are rolled out in every member of the judge in phi. At the end,
with the boxes where phi left them, the region to clear (`board.reach_region`) is read again:
room is made in a member when no box other than the target enters it by more than
``rearrange.deep``. Also per member: a box fallen or tipped past ``evaluation.max_tilt``, and
how far the target moved (mm).

With ``--bullet`` each goal's whole plan (the pushes, then the reach) is also replayed by the
robust judge (K = ``evaluation.robust_replays``): a study of whether phi refuses what Bullet
would grade well, beside the push answer's stored robust P(success). No planner reads it.

What it decides: where sequences were not accepted although phi's pushes made room, the
reach from the state they leave is what fails (replanning the pushes from phi's states cannot
help); where phi's pushes did not make room, a receding-horizon search from phi's states
could. Its dated results: docs/log/rearrange.md.
"""

from __future__ import annotations

import argparse
import sys
from collections import Counter

import numpy as np

WHYS = ("not accepted", "rearranged")


def rows_to_study(rows: list[dict], whys: tuple[str, ...]) -> list[tuple[dict, dict]]:
    """(rearrange row, push row of the same initialization) whose record's outcome is in
    ``whys`` ("rearranged": the record chose a sequence)."""
    push = {(r["scene"], r["angle"], r["config_hash"]): r for r in rows if r["planner"] == "push"}
    out = []
    for r in rows:
        details = ((r.get("plan") or {}).get("details") or {})
        why = "rearranged" if details.get("chosen", "push") != "push" else details.get("why")
        key = (r["scene"], r["angle"], r["config_hash"])
        if r["planner"] == "rearrange" and why in whys and key in push:
            if (push[key].get("plan") or {}).get("trajectory"):
                out.append((r, push[key]))
    return out


def pushes_only(goal) -> np.ndarray:
    """A goal's pushes as one knot path (K, 8): every push starts and ends at the reach's
    first knot."""
    return np.vstack([*(p[:-1] for p in goal.paths), goal.paths[-1][-1:]])


def room_in_members(scene, config, geometry, prefix: np.ndarray, region: np.ndarray,
                    knot_time: float) -> list[dict]:
    """Per member of the judge in phi: whether ``prefix`` leaves the region clear (the boxes
    where phi left them), the crowd's deepest entry beyond ``rearrange.deep`` (m; 0 with room),
    the boxes fallen or tipped, and how far the target moved (m)."""
    from pydrake.math import RigidTransform, RotationMatrix

    from drake_clutter.planners.members import member_world
    from drake_clutter.planners.phi_judge import box_fates, judged_rollouts
    from drake_clutter.planners.rearrange.board import crowding_at

    names = [b.name for b in scene.boxes]
    out = []
    for member in range(config.phi_judge.members):
        world, cfg = member_world(scene, config, member)
        final = judged_rollouts(world, {"prefix": prefix}, cfg, knot_time)["prefix"]
        if final.final_boxes is None:
            out.append({"failed": True})
            continue
        p, R, fallen, tipped = box_fates(world, geometry, final.final_boxes, config.evaluation)
        poses = {n: RigidTransform(RotationMatrix(R[i]), p[i]) for i, n in enumerate(names)}
        crowd = crowding_at(geometry, region, poses, config.rearrange.deep)
        i = names.index(scene.target)
        out.append({"failed": False, "depth": max(crowd.values(), default=0.0),
                    "room": not crowd,
                    "spoilt": [(n, "fallen" if f else "tipped")
                               for n, f, t in zip(names, fallen, tipped, strict=True) if f or t],
                    "target": float(np.linalg.norm(p[i][:2] - geometry.rest_pose(
                        scene.target).translation()[:2]))})
    return out


def study_row(row: dict, push_row: dict, config, bullet: bool = False) -> list[dict]:
    """Every goal of the row's search again, with its members' readings, its whole plan's
    verdict in phi as recorded (None where it was not judged) and, with ``bullet``, its whole
    plan's robust P(success) in Bullet."""
    from drake_clutter.evaluation.judge import evaluate
    from drake_clutter.experiments.specs import stored_scene
    from drake_clutter.planners.budget import Deadline
    from drake_clutter.planners.context import PlanningContext
    from drake_clutter.planners.rearrange.board import reach_region
    from drake_clutter.planners.rearrange.planner import sequence_path
    from drake_clutter.planners.rearrange.search import search_room
    from drake_clutter.planners.tool_path import approach_frame
    from drake_clutter.trajectory import Trajectory

    scene = stored_scene(row["scene"], config)
    context = PlanningContext(scene, config)
    geometry = context.arm()
    path = Trajectory.from_data(push_row["plan"]["trajectory"])
    reach = path.q
    region = reach_region(reach, config.rearrange.region_knots)
    rotation = geometry.tool_jacobian(reach[-1])[0].rotation().matrix()
    found = search_room(geometry, context.clearance, approach_frame(geometry, reach), region,
                        reach[0], rotation, config, Deadline(None))
    details = row["plan"]["details"]
    out = []
    for i, goal in enumerate(found.goals):
        members = room_in_members(scene, config, geometry, pushes_only(goal), region,
                                  config.baseline.knot_time)
        verdict = (details.get("verdicts") or {}).get(f"room{i}")
        pushed = {m.box for m in goal.moves}
        shoved = {b for m in goal.moves for b in m.moved} - pushed
        judged = None
        if bullet:
            q = sequence_path(goal, reach)
            plan = Trajectory(np.arange(len(q)) * config.baseline.knot_time, q)
            judged = evaluate(scene, plan, config.evaluation).robust.p_success
        out.append({"members": members, "pushes": len(goal.moves), "pushed": pushed,
                    "bullet": judged, "push_bullet": push_row["p_success"] or 0.0,
                    "shoved": shoved, "target": scene.target,
                    "p_phi": None if verdict is None else verdict["p_success"],
                    "chosen": details.get("chosen") == f"room{i}"})
    return out


def room_share(goal: dict) -> float:
    """The share of a goal's members in which its pushes made room."""
    return float(np.mean([m.get("room", False) for m in goal["members"]]))


def summary(label: str, goals: list[dict], acceptance: float) -> None:
    """The share of goals whose pushes made room in phi in at least ``acceptance`` of the
    members, and how their whole plans read in phi."""
    if not goals:
        print(f"{label}: no goals")
        return
    share = [room_share(g) for g in goals]
    spoiled = [np.mean([bool(m.get("spoilt")) for m in g["members"]]) for g in goals]
    made = [s >= acceptance for s in share]
    print(f"{label}: {len(goals)} goals; room made in phi in >= {acceptance:.0%} of members: "
          f"{sum(made)} ({np.mean(made):.0%}); mean share of members with room "
          f"{np.mean(share):.2f}; with a box fallen or tipped {np.mean(spoiled):.2f}")
    judged = [(s, g["p_phi"]) for s, g in zip(share, goals, strict=True)
              if g["p_phi"] is not None]
    for ok in (True, False):
        ps = [p for s, p in judged if (s >= acceptance) == ok]
        if ps:
            print(f"  room {'made' if ok else 'not made'}: {len(ps)} judged, whole plan's "
                  f"P(success) in phi mean {np.mean(ps):.2f}, at 0: {sum(p == 0 for p in ps)}")
    both = [(g["p_phi"], g["bullet"], g["push_bullet"]) for g in goals
            if g.get("bullet") is not None and g["p_phi"] is not None]
    if both:
        phi, bul, push = (np.array(v) for v in zip(*both, strict=True))
        print(f"  Bullet, whole plans judged in phi ({len(both)}): robust P(success) mean "
              f"{bul.mean():.3f} (the push answers {push.mean():.3f}); above the push answer "
              f"{int(np.sum(bul > push))}, equal {int(np.sum(bul == push))}, below "
              f"{int(np.sum(bul < push))}; phi 0 and Bullet above 0: "
              f"{int(np.sum((phi == 0) & (bul > 0)))}; phi above 0 and Bullet 0: "
              f"{int(np.sum((phi > 0) & (bul == 0)))}")
    roles = Counter(f"{_role(name, g)} {how}" for g in goals for m in g["members"]
                    for name, how in m.get("spoilt", []))
    print(f"  boxes tipped or fallen, by role: {dict(roles)}")
    moved = [m["target"] for g in goals for m in g["members"] if not m.get("failed")]
    print(f"  target moved by the pushes (mm): median {1000 * np.median(moved):.1f}, "
          f"p90 {1000 * np.percentile(moved, 90):.1f}")


def _role(name: str, goal: dict) -> str:
    """What a box was to a goal's pushes: the target, pushed, shoved ahead, or a bystander."""
    if name == goal["target"]:
        return "target"
    return "pushed" if name in goal["pushed"] else "shoved" if name in goal["shoved"] \
        else "bystander"


def main(argv: list[str] | None = None) -> int:
    from drake_clutter.common.config import ConfigError, config_from_data
    from drake_clutter.experiments.store import Store

    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--db", required=True)
    parser.add_argument("--why", nargs="+", default=list(WHYS), choices=WHYS)
    parser.add_argument("--skip", type=int, default=0, help="rows skipped per outcome first")
    parser.add_argument("--limit", type=int, default=0, help="rows read per outcome (0: all)")
    parser.add_argument("--bullet", action="store_true",
                        help="also replay each goal's whole plan in the robust judge")
    args = parser.parse_args(argv)
    try:
        with Store(args.db, read_only=True) as store:
            rows, configs = store.rows(), store.configurations()
    except Exception as err:  # an unreadable store is one line, not a traceback
        print(f"room_in_phi: --db: {err}", file=sys.stderr)
        return 2
    for why in args.why:
        todo = rows_to_study(rows, (why,))
        todo = todo[args.skip:args.skip + args.limit] if args.limit else todo[args.skip:]
        goals = []
        for row, push_row in todo:
            try:
                config = config_from_data(configs[row["config_hash"]]["config"])
            except ConfigError as err:
                print(f"room_in_phi: --db: {err}", file=sys.stderr)
                return 2
            found = study_row(row, push_row, config, args.bullet)
            goals += found
            shares = [f"{room_share(g):.2f}" for g in found]
            print(f"  {row['scene']} angle {row['angle']}: room shares {shares}, phi P "
                  f"{[g['p_phi'] for g in found]}, Bullet P {[g['bullet'] for g in found]} "
                  f"(push answer {push_row['p_success']})", flush=True)
        summary(f"{why} ({len(todo)} rows)", goals,
                config.rearrange.acceptance if todo else 0.0)
    return 0


if __name__ == "__main__":
    sys.exit(main())
